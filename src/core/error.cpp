#include "core/error.h"

namespace strata {

const char* to_string(ErrorCode code) noexcept {
    switch (code) {
        case ErrorCode::InvalidInput:
            return "invalid input";
        case ErrorCode::Unsupported:
            return "unsupported";
        case ErrorCode::Io:
            return "I/O";
        case ErrorCode::Internal:
            return "internal";
    }
    return "unknown";
}

}  // namespace strata
