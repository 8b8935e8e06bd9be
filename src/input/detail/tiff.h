#pragma once

// TIFF pages through libtiff with every strip and tile checked; internal to strata_input.

#include <cstdint>
#include <filesystem>
#include <string>
#include <utility>
#include <vector>

#include "core/report.h"

typedef struct tiff TIFF;

namespace strata::detail {

/// An open TIFF file, read page by page in file order.
class TiffFile {
public:
    /// Throws Error{InvalidInput} when `file` is not a readable TIFF.
    explicit TiffFile(const std::filesystem::path& file);
    ~TiffFile();
    TiffFile(const TiffFile&) = delete;
    TiffFile& operator=(const TiffFile&) = delete;

    /// Number of pages (walks the directory chain once); the current page is the first after.
    std::uint32_t count_pages();
    /// Moves to the next page; false after the last.
    bool next_page();
    /// Size of the file in bytes.
    std::uint64_t file_bytes() const { return file_bytes_; }
    /// Width and height of the current page.
    std::pair<std::uint32_t, std::uint32_t> size() const;
    /// Reads the current page, which must be `width` x `height` 8/16-bit unsigned, into `slice`
    /// (resized to width * height labels once the page's strips are checked). Every strip or tile
    /// is checked against the file before decoding and must decode completely; Error{InvalidInput}
    /// names `where`, the strip and the sizes. Warns once (`warned_channels`) about equal colour
    /// channels.
    void read_page(std::uint32_t width,
                   std::uint32_t height,
                   const std::string& where,
                   std::vector<std::uint16_t>& slice,
                   bool& warned_channels,
                   Report& report);

private:
    std::filesystem::path file_;
    std::uint64_t file_bytes_ = 0;
    TIFF* tif_ = nullptr;
};

}  // namespace strata::detail
