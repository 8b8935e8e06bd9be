#pragma once

#include <stdexcept>
#include <string>

namespace strata {

/// Why an operation failed; the CLI maps it to an exit code (InvalidInput/Unsupported -> 2,
/// Io/Internal -> 1).
enum class ErrorCode {
    InvalidInput,  ///< the input is malformed, truncated, inconsistent or out of range
    Unsupported,   ///< the input is well formed but uses something strata does not handle
    Io,            ///< a file could not be opened, read or written
    Internal,      ///< a bug or a third-party failure; never caused by the input alone
};

/// The one exception type strata throws. The message says what, where, and what was expected:
/// "slice 17 (scan_017.png): size 512x500, expected 512x512".
class Error : public std::runtime_error {
public:
    Error(ErrorCode code, const std::string& message) : std::runtime_error(message), code_(code) {}

    ErrorCode code() const noexcept { return code_; }

private:
    ErrorCode code_;
};

/// Short name of an error code ("invalid input", "unsupported", "I/O", "internal").
const char* to_string(ErrorCode code) noexcept;

}  // namespace strata
