#pragma once

#include <ctime>

namespace strata {

/// CPU time of the whole process (every thread, user + system) in seconds, for the CPU time of a
/// stage: the difference between two readings.
inline double process_cpu_seconds() {
    timespec t{};
    if (clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &t) != 0) {
        return 0.0;
    }
    return static_cast<double>(t.tv_sec) + 1e-9 * static_cast<double>(t.tv_nsec);
}

}  // namespace strata
