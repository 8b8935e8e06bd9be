#pragma once

// Stored voxel values -> 16-bit labels, shared by the NIfTI and NRRD readers; internal to
// strata_input.

#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <string>
#include <type_traits>
#include <utility>
#include <vector>

#include "core/error.h"
#include "core/progress.h"
#include "input/detail/readers.h"
#include "input/detail/text.h"
#include "input/slice_stack.h"

namespace strata::detail {

// note: raw voxel bytes are streamed through a buffer of this size (a multiple of every voxel
// size), so memory use is bounded by the label images whatever the stored type
inline constexpr std::size_t kChunkBytes = std::size_t(1) << 20;

/// What the data stream behind a header can hold, so that a header claiming more than the file
/// can deliver is refused (or found truncated) before its labels are allocated.
struct DataBound {
    std::uint64_t max_bytes = UINT64_MAX;  ///< bytes the stream can deliver at most
    bool is_exact = false;                 ///< uncompressed: max_bytes is what is there
};

/// The value of type T stored at `bytes`; `swap`: the file's byte order is not ours.
template <typename T>
T load(const unsigned char* bytes, bool swap) {
    std::array<unsigned char, sizeof(T)> raw;
    std::memcpy(raw.data(), bytes, sizeof(T));
    if (swap) {
        std::reverse(raw.begin(), raw.end());
    }
    return std::bit_cast<T>(raw);
}

/// Stored voxel types the readers accept.
enum class ScalarType {
    Int8,
    UInt8,
    Int16,
    UInt16,
    Int32,
    UInt32,
    Int64,
    UInt64,
    Float32,
    Float64
};

/// Bytes per stored value of `type`.
inline std::size_t scalar_bytes(ScalarType type) {
    switch (type) {
        case ScalarType::Int8:
        case ScalarType::UInt8:
            return 1;
        case ScalarType::Int16:
        case ScalarType::UInt16:
            return 2;
        case ScalarType::Int32:
        case ScalarType::UInt32:
        case ScalarType::Float32:
            return 4;
        case ScalarType::Int64:
        case ScalarType::UInt64:
        case ScalarType::Float64:
            return 8;
    }
    return 1;
}

/// Label = stored * slope + inter (NIfTI's scl_slope and scl_inter); the default leaves stored
/// values as they are.
struct ValueScaling {
    double slope = 1.0;  // factor applied to each stored value
    double inter = 0.0;  // offset added after the factor
};

/// Converts stored voxel values, in raster order, into the labels of a stack; rejects the first
/// value that is not an integer label 0..65535 (after scaling) naming its voxel (i,j,k). Real
/// values within 1e-4 of an integer are rounded (float data written through resampling code).
class LabelDecoder {
public:
    /// `stack` has its size set; its labels grow as values arrive (never ahead of the data, so a
    /// header claiming more than the file holds allocates no more than the file's data).
    /// `where` prefixes messages; `progress` (may be empty) is called once per completed slice.
    /// Both must outlive the decoder.
    LabelDecoder(ScalarType type,
                 bool swap,
                 SliceStack& stack,
                 std::string where,
                 const ProgressFn& progress,
                 ValueScaling scaling = {})
        : type_(type),
          swap_(swap),
          is_scaled_(!(scaling.slope == 1.0 && scaling.inter == 0.0)),
          scaling_(scaling),
          stack_(stack),
          where_(std::move(where)),
          progress_(progress),
          total_(stack.slice_size() * stack.depth) {
        stack_.labels.clear();
    }

    /// Reserves the labels for the values `bound` can hold at most (all when that is more).
    void reserve(const DataBound& bound) {
        const std::uint64_t values = bound.max_bytes / scalar_bytes(type_);
        stack_.labels.reserve(static_cast<std::size_t>(std::min<std::uint64_t>(total_, values)));
    }

    /// Converts `count` stored values starting at `bytes` (count * scalar_bytes(type) bytes).
    void decode(const unsigned char* bytes, std::size_t count) {
        switch (type_) {
            case ScalarType::Int8:
                return decode_as<std::int8_t>(bytes, count);
            case ScalarType::UInt8:
                return decode_as<std::uint8_t>(bytes, count);
            case ScalarType::Int16:
                return decode_as<std::int16_t>(bytes, count);
            case ScalarType::UInt16:
                return decode_as<std::uint16_t>(bytes, count);
            case ScalarType::Int32:
                return decode_as<std::int32_t>(bytes, count);
            case ScalarType::UInt32:
                return decode_as<std::uint32_t>(bytes, count);
            case ScalarType::Int64:
                return decode_as<std::int64_t>(bytes, count);
            case ScalarType::UInt64:
                return decode_as<std::uint64_t>(bytes, count);
            case ScalarType::Float32:
                return decode_as<float>(bytes, count);
            case ScalarType::Float64:
                return decode_as<double>(bytes, count);
        }
    }

    /// Reads all the stack's stored values (labels.size() * scalar_bytes(type) bytes) through
    /// `read(buffer, size)`, which returns fewer than `size` bytes only at the end of the data,
    /// and converts them in chunks of kChunkBytes. Throws Error{InvalidInput} "<where>:
    /// truncated: expected N bytes of voxel data<context>, found M" when the data end early.
    /// `bound`: what the stream can hold; an exact bound short of the data is refused at once.
    template <typename ReadFn>
    void decode_all(ReadFn&& read, const std::string& context = "", const DataBound& bound = {}) {
        const std::size_t value_bytes = scalar_bytes(type_);
        const std::uint64_t expected = total_ * value_bytes;
        if (bound.is_exact && bound.max_bytes < expected) {
            throw Error(ErrorCode::InvalidInput, where_ + ": truncated: expected " +
                                                     std::to_string(expected) +
                                                     " bytes of voxel data" + context + ", found " +
                                                     std::to_string(bound.max_bytes));
        }
        reserve(bound);
        std::vector<unsigned char> chunk(std::min<std::uint64_t>(expected, kChunkBytes));
        std::uint64_t found = 0;
        while (found < expected) {
            const std::size_t ask = std::min<std::uint64_t>(expected - found, chunk.size());
            const std::size_t got = read(chunk.data(), ask);
            found += got;
            if (got < ask) {
                throw Error(ErrorCode::InvalidInput, where_ + ": truncated: expected " +
                                                         std::to_string(expected) +
                                                         " bytes of voxel data" + context +
                                                         ", found " + std::to_string(found));
            }
            decode(chunk.data(), got / value_bytes);
        }
    }

    /// Converts one stored value given as a number (NRRD's ascii encoding).
    void decode_value(double stored) {
        grow(1);
        store_real(stored);
        report_progress();
    }

private:
    /// Makes room for `count` more labels (geometric growth beyond what was reserved).
    void grow(std::size_t count) {
        if (stack_.labels.size() < next_ + count) {
            stack_.labels.resize(next_ + count);
        }
    }

    template <typename T>
    void decode_as(const unsigned char* bytes, std::size_t count) {
        grow(count);
        for (std::size_t n = 0; n < count; ++n, bytes += sizeof(T)) {
            const T stored = load<T>(bytes, swap_);
            if constexpr (std::is_integral_v<T>) {
                if (!is_scaled_) {
                    if (!std::in_range<std::uint16_t>(stored)) {
                        reject(std::to_string(stored), "");
                    }
                    stack_.labels[next_++] = static_cast<std::uint16_t>(stored);
                    continue;
                }
            }
            store_real(static_cast<double>(stored));
        }
        report_progress();
    }

    void store_real(double stored) {
        const double value = is_scaled_ ? stored * scaling_.slope + scaling_.inter : stored;
        const double rounded = std::nearbyint(value);
        if (!std::isfinite(value) || std::abs(value - rounded) > 1e-4 || rounded < 0.0 ||
            rounded > 65535.0) {
            reject(format_number(value),
                   is_scaled_ ? " (stored " + format_number(stored) + " * scl_slope " +
                                    format_number(scaling_.slope) + " + scl_inter " +
                                    format_number(scaling_.inter) + ")"
                              : "");
        }
        stack_.labels[next_++] = static_cast<std::uint16_t>(rounded);
    }

    [[noreturn]] void reject(const std::string& value, const std::string& detail) const {
        const std::size_t slice = stack_.slice_size();
        const std::size_t k = next_ / slice;
        const std::size_t j = (next_ % slice) / stack_.width;
        const std::size_t i = next_ % stack_.width;
        throw Error(ErrorCode::InvalidInput, where_ + ": voxel (" + std::to_string(i) + "," +
                                                 std::to_string(j) + "," + std::to_string(k) +
                                                 ") has value " + value + detail +
                                                 ", expected an integer label 0..65535");
    }

    void report_progress() {
        if (!progress_) {
            return;
        }
        const std::size_t done = next_ / stack_.slice_size();
        while (slices_reported_ < done) {
            progress_("slices", ++slices_reported_, stack_.depth);
        }
    }

    ScalarType type_;
    bool swap_;
    bool is_scaled_;
    ValueScaling scaling_;
    SliceStack& stack_;
    std::string where_;
    const ProgressFn& progress_;
    std::size_t total_;
    std::size_t next_ = 0;
    std::size_t slices_reported_ = 0;
};

}  // namespace strata::detail
