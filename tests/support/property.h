#pragma once

#include <cstdlib>

namespace strata::test {

/// Iterations of a seeded property test: STRATA_PROPERTY_ITERATIONS when set to a positive
/// number, else `fallback`.
inline int property_iterations(int fallback) {
    if (const char* env = std::getenv("STRATA_PROPERTY_ITERATIONS")) {
        const int n = std::atoi(env);
        if (n > 0) {
            return n;
        }
    }
    return fallback;
}

}  // namespace strata::test
