// TIFF label images (one slice, or one slice per page), read with libtiff so that every strip and
// tile is checked: its stored size against the file before anything is decoded (a header
// claiming 46000^2 pixels in a few KiB is refused without allocating), its decoded size after
// (a truncated strip is an error, not zeros). Pages are read in file order, one directory after
// the other, so N pages take linear time.

#include <algorithm>
#include <cstdarg>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <string>
#include <tiffio.h>
#include <vector>

#include "core/error.h"
#include "input/detail/readers.h"
#include "input/detail/tiff.h"

namespace strata::detail {

namespace {

// note: libtiff reports through global handlers; the last message is kept for the error text
thread_local std::string g_tiff_message;

void on_tiff_error(const char* module, const char* format, va_list args) {
    char buffer[512];
    std::vsnprintf(buffer, sizeof(buffer), format, args);
    g_tiff_message = (module != nullptr ? std::string(module) + ": " : std::string()) + buffer;
}

void on_tiff_warning(const char*, const char*, va_list) {}

/// Decoded bytes per stored byte a TIFF compression scheme can reach at most (deflate
/// kMaxDeflateRatio, LZW 12-bit codes up to 4096 bytes each, PackBits 128 bytes per 2; others:
/// kMaxOtherRatio).
std::uint64_t max_ratio(std::uint16_t compression) {
    switch (compression) {
        case COMPRESSION_NONE:
            return 1;
        case COMPRESSION_PACKBITS:
            return 64;
        case COMPRESSION_ADOBE_DEFLATE:
        case COMPRESSION_DEFLATE:
            return kMaxDeflateRatio;
        default:
            return kMaxOtherRatio;
    }
}

/// How a page stores its pixels: sample type and channels, strips or tiles.
struct PageLayout {
    std::uint16_t bits = 1;
    std::uint16_t channels = 1;
    std::uint16_t compression = COMPRESSION_NONE;
    std::uint64_t pixel_bytes = 0;
    std::uint64_t row_bytes = 0;
    bool tiled = false;
    std::uint32_t blocks = 0;  ///< strips or tiles
    std::uint32_t tile_width = 0;
    std::uint32_t tile_height = 0;
    std::uint32_t rows_per_strip = 0;

    /// Decoded bytes of a whole tile, or of a full strip.
    std::uint64_t block_bytes() const {
        return tiled ? std::uint64_t(tile_width) * tile_height * pixel_bytes
                     : row_bytes * rows_per_strip;
    }
};

/// The current page's layout, refused unless it holds a 2D label image of 8- or 16-bit unsigned
/// samples (interleaved when several) in as many strips or tiles as its size needs.
PageLayout page_layout(TIFF* tif,
                       std::uint32_t width,
                       std::uint32_t height,
                       const std::string& where) {
    PageLayout layout;
    std::uint16_t& bits = layout.bits;
    std::uint16_t& channels = layout.channels;
    std::uint16_t sample_format = SAMPLEFORMAT_UINT;
    std::uint16_t planar = PLANARCONFIG_CONTIG;
    std::uint16_t& compression = layout.compression;
    std::uint32_t depth = 1;
    TIFFGetFieldDefaulted(tif, TIFFTAG_BITSPERSAMPLE, &bits);
    TIFFGetFieldDefaulted(tif, TIFFTAG_SAMPLESPERPIXEL, &channels);
    TIFFGetFieldDefaulted(tif, TIFFTAG_SAMPLEFORMAT, &sample_format);
    TIFFGetFieldDefaulted(tif, TIFFTAG_PLANARCONFIG, &planar);
    TIFFGetFieldDefaulted(tif, TIFFTAG_COMPRESSION, &compression);
    TIFFGetFieldDefaulted(tif, TIFFTAG_IMAGEDEPTH, &depth);
    if (depth > 1) {
        throw Error(ErrorCode::Unsupported, where + ": volume image with depth " +
                                                std::to_string(depth) + ", expected a 2D slice");
    }
    if ((bits != 8 && bits != 16) || sample_format != SAMPLEFORMAT_UINT) {
        throw Error(ErrorCode::Unsupported,
                    where + ": pixel type " + std::to_string(bits) + "-bit " +
                        (sample_format == SAMPLEFORMAT_UINT ? "unsigned" : "signed or real") +
                        ", expected 8- or 16-bit unsigned integer labels");
    }
    if (channels < 1) {
        throw Error(ErrorCode::InvalidInput, where + ": image has no channels");
    }
    if (channels > 1 && planar != PLANARCONFIG_CONTIG) {
        throw Error(ErrorCode::Unsupported,
                    where +
                        ": channels stored in separate planes, expected interleaved channels "
                        "or a single channel");
    }
    layout.pixel_bytes = std::uint64_t(channels) * (bits / 8);
    layout.row_bytes = layout.pixel_bytes * width;

    const bool tiled = layout.tiled = TIFFIsTiled(tif) != 0;
    const std::uint32_t blocks = layout.blocks =
        tiled ? TIFFNumberOfTiles(tif) : TIFFNumberOfStrips(tif);
    std::uint32_t& tile_width = layout.tile_width;
    std::uint32_t& tile_height = layout.tile_height;
    std::uint32_t& rows_per_strip = layout.rows_per_strip;
    rows_per_strip = height;
    if (tiled) {
        TIFFGetField(tif, TIFFTAG_TILEWIDTH, &tile_width);
        TIFFGetField(tif, TIFFTAG_TILELENGTH, &tile_height);
        if (tile_width == 0 || tile_height == 0) {
            throw Error(ErrorCode::InvalidInput,
                        where + ": tile size " + std::to_string(tile_width) + "x" +
                            std::to_string(tile_height) + ", expected positive");
        }
    } else {
        TIFFGetFieldDefaulted(tif, TIFFTAG_ROWSPERSTRIP, &rows_per_strip);
        rows_per_strip = std::clamp<std::uint32_t>(rows_per_strip, 1, height);
    }
    const std::uint64_t expected_blocks =
        tiled ? std::uint64_t((width + tile_width - 1) / tile_width) *
                    ((height + tile_height - 1) / tile_height)
              : (std::uint64_t(height) + rows_per_strip - 1) / rows_per_strip;
    if (blocks != expected_blocks) {
        throw Error(ErrorCode::InvalidInput,
                    where + ": " + std::to_string(blocks) + (tiled ? " tiles" : " strips") +
                        ", expected " + std::to_string(expected_blocks) + " for " +
                        std::to_string(width) + "x" + std::to_string(height) + " pixels");
    }
    return layout;
}

/// Every strip (tile) is checked against the file before anything is decoded: its stored bytes
/// lie in the file and can decode to the bytes it must hold.
void check_blocks(TIFF* tif,
                  const PageLayout& layout,
                  std::uint32_t height,
                  std::uint64_t file_bytes,
                  const std::string& where) {
    const auto [bits, channels, compression, pixel_bytes, row_bytes, tiled, blocks, tile_width,
                tile_height, rows_per_strip] = layout;
    const std::uint64_t block_bytes = layout.block_bytes();
    std::uint64_t* offsets = nullptr;
    std::uint64_t* counts = nullptr;
    if (!TIFFGetField(tif, tiled ? TIFFTAG_TILEOFFSETS : TIFFTAG_STRIPOFFSETS, &offsets) ||
        !TIFFGetField(tif, tiled ? TIFFTAG_TILEBYTECOUNTS : TIFFTAG_STRIPBYTECOUNTS, &counts) ||
        offsets == nullptr || counts == nullptr) {
        throw Error(ErrorCode::InvalidInput,
                    where + ": no " + (tiled ? "tile" : "strip") + " offsets or byte counts");
    }
    for (std::uint32_t b = 0; b < blocks; ++b) {
        const std::uint64_t need =
            tiled ? block_bytes
                  : row_bytes * std::min<std::uint64_t>(rows_per_strip,
                                                        height - std::uint64_t(b) * rows_per_strip);
        const std::string name = (tiled ? " tile " : " strip ") + std::to_string(b);
        if (offsets[b] > file_bytes || counts[b] > file_bytes - offsets[b]) {
            throw Error(ErrorCode::InvalidInput,
                        where + ":" + name + ": " + std::to_string(counts[b]) +
                            " bytes at offset " + std::to_string(offsets[b]) +
                            " run past the end of the file (" + std::to_string(file_bytes) +
                            " bytes), expected them in the file");
        }
        if (counts[b] * max_ratio(compression) < need) {
            throw Error(ErrorCode::InvalidInput,
                        where + ":" + name + ": " + std::to_string(counts[b]) +
                            " stored bytes cannot hold its " + std::to_string(need) +
                            " bytes of pixels (truncated?), expected a complete " +
                            (tiled ? "tile" : "strip"));
        }
    }
}

/// Decodes the page's strips (tiles) into `slice`, refusing a pixel whose colour channels differ.
void decode_blocks(TIFF* tif,
                   const PageLayout& layout,
                   std::uint32_t width,
                   std::uint32_t height,
                   const std::string& where,
                   std::vector<std::uint16_t>& slice) {
    const auto [bits, channels, compression, pixel_bytes, row_bytes, tiled, blocks, tile_width,
                tile_height, rows_per_strip] = layout;
    const std::uint64_t block_bytes = layout.block_bytes();
    std::vector<unsigned char> block(block_bytes);
    slice.resize(std::size_t(width) * height);
    std::uint16_t* out = slice.data();
    const int colour_channels = (channels == 2 || channels == 4) ? channels - 1 : channels;
    const auto value = [&](const unsigned char* pixel, int c) -> std::uint16_t {
        if (bits == 8) {
            return pixel[c];
        }
        std::uint16_t v = 0;
        std::memcpy(&v, pixel + 2 * c, 2);  // note: libtiff returns native byte order
        return v;
    };
    const auto store = [&](const unsigned char* pixel, std::uint32_t x, std::uint32_t y) {
        const std::uint16_t first = value(pixel, 0);
        for (int c = 1; c < colour_channels; ++c) {
            if (value(pixel, c) != first) {
                throw Error(ErrorCode::Unsupported,
                            where + ": colour image with differing channels at pixel (" +
                                std::to_string(x) + ", " + std::to_string(y) +
                                "), expected a single-channel (greyscale) label image");
            }
        }
        out[std::size_t(y) * width + x] = first;
    };
    for (std::uint32_t b = 0; b < blocks; ++b) {
        g_tiff_message.clear();
        const std::string name = (tiled ? " tile " : " strip ") + std::to_string(b);
        if (tiled) {
            const tmsize_t got =
                TIFFReadEncodedTile(tif, b, block.data(), static_cast<tmsize_t>(block_bytes));
            if (got != static_cast<tmsize_t>(block_bytes)) {
                throw Error(ErrorCode::InvalidInput,
                            where + ":" + name + ": decoded " +
                                std::to_string(std::max<tmsize_t>(got, 0)) + " of " +
                                std::to_string(block_bytes) + " bytes" +
                                (g_tiff_message.empty() ? "" : " (" + g_tiff_message + ")") +
                                ", expected a complete tile");
            }
            const std::uint32_t across = (width + tile_width - 1) / tile_width;
            const std::uint32_t x0 = (b % across) * tile_width;
            const std::uint32_t y0 = (b / across) * tile_height;
            for (std::uint32_t y = y0; y < std::min(height, y0 + tile_height); ++y) {
                for (std::uint32_t x = x0; x < std::min(width, x0 + tile_width); ++x) {
                    store(
                        block.data() + (std::size_t(y - y0) * tile_width + (x - x0)) * pixel_bytes,
                        x, y);
                }
            }
        } else {
            const std::uint32_t y0 = b * rows_per_strip;
            const std::uint32_t rows = std::min(rows_per_strip, height - y0);
            const std::uint64_t need = row_bytes * rows;
            const tmsize_t got =
                TIFFReadEncodedStrip(tif, b, block.data(), static_cast<tmsize_t>(need));
            if (got != static_cast<tmsize_t>(need)) {
                throw Error(ErrorCode::InvalidInput,
                            where + ":" + name + ": decoded " +
                                std::to_string(std::max<tmsize_t>(got, 0)) + " of " +
                                std::to_string(need) + " bytes" +
                                (g_tiff_message.empty() ? "" : " (" + g_tiff_message + ")") +
                                ", expected a complete strip");
            }
            for (std::uint32_t y = y0; y < y0 + rows; ++y) {
                for (std::uint32_t x = 0; x < width; ++x) {
                    store(block.data() + std::size_t(y - y0) * row_bytes + x * pixel_bytes, x, y);
                }
            }
        }
    }
}

}  // namespace

TiffFile::TiffFile(const std::filesystem::path& file) : file_(file) {
    TIFFSetErrorHandler(on_tiff_error);
    TIFFSetWarningHandler(on_tiff_warning);
    g_tiff_message.clear();
    std::error_code ec;
    file_bytes_ = std::filesystem::file_size(file, ec);
    if (ec) {
        throw Error(ErrorCode::Io, file.string() + ": cannot read size: " + ec.message());
    }
    // note: "m": no memory mapping, so a file shrinking under us is a read error, not SIGBUS
    tif_ = TIFFOpen(file.c_str(), "rm");
    if (tif_ == nullptr) {
        throw Error(ErrorCode::InvalidInput,
                    file.string() + ": cannot read TIFF: " +
                        (g_tiff_message.empty() ? "not a TIFF file" : g_tiff_message));
    }
}

TiffFile::~TiffFile() {
    TIFFClose(tif_);
}

std::uint32_t TiffFile::count_pages() {
    const tdir_t pages = TIFFNumberOfDirectories(tif_);
    if (!TIFFSetDirectory(tif_, 0)) {
        throw Error(ErrorCode::InvalidInput, file_.string() + ": cannot read the first page");
    }
    return pages;
}

bool TiffFile::next_page() {
    return TIFFReadDirectory(tif_) == 1;
}

std::pair<std::uint32_t, std::uint32_t> TiffFile::size() const {
    std::uint32_t width = 0;
    std::uint32_t height = 0;
    TIFFGetField(tif_, TIFFTAG_IMAGEWIDTH, &width);
    TIFFGetField(tif_, TIFFTAG_IMAGELENGTH, &height);
    return {width, height};
}

void TiffFile::read_page(std::uint32_t width,
                         std::uint32_t height,
                         const std::string& where,
                         std::vector<std::uint16_t>& slice,
                         bool& warned_channels,
                         Report& report) {
    const auto [page_width, page_height] = size();
    if (page_width == 0 || page_height == 0) {
        throw Error(ErrorCode::InvalidInput, where + ": empty image " + std::to_string(page_width) +
                                                 "x" + std::to_string(page_height));
    }
    if (page_width != width || page_height != height) {
        throw Error(ErrorCode::InvalidInput,
                    where + ": size " + std::to_string(page_width) + "x" +
                        std::to_string(page_height) + ", expected " + std::to_string(width) + "x" +
                        std::to_string(height) + " (the size of the first slice)");
    }
    const PageLayout layout = page_layout(tif_, width, height, where);
    check_blocks(tif_, layout, height, file_bytes_, where);
    decode_blocks(tif_, layout, width, height, where, slice);
    const std::uint16_t channels = layout.channels;
    if (channels > 1 && !warned_channels) {
        warned_channels = true;
        report.warn(
            "input", where,
            std::to_string(channels) + " channels with equal colour values; using the first");
    }
}

SliceStack read_multipage_tiff(const std::filesystem::path& file,
                               const ReadOptions& options,
                               Report& report) {
    TiffFile tiff(file);
    SliceStack stack;
    stack.source = file.string();
    stack.source_frame = "none";
    const std::uint32_t pages = tiff.count_pages();
    const auto [width, height] = tiff.size();
    if (width == 0 || height == 0) {
        throw Error(ErrorCode::InvalidInput,
                    file.string() + ": empty image, expected positive size");
    }
    if (pages > (1u << 24)) {
        throw Error(ErrorCode::InvalidInput, file.string() + ": more than 2^24 pages");
    }
    check_stack_dimensions(width, height, pages, file.string(), options.max_bytes);
    stack.width = width;
    stack.height = height;
    stack.depth = pages;
    // note: one page at a time, each checked before its labels are allocated
    bool warned = false;
    std::vector<std::uint16_t> slice;
    for (std::uint32_t k = 0; k < pages; ++k) {
        if (k > 0 && !tiff.next_page()) {
            throw Error(ErrorCode::InvalidInput, file.string() + ": cannot read page " +
                                                     std::to_string(k) + " of " +
                                                     std::to_string(pages));
        }
        tiff.read_page(width, height, file.filename().string() + " page " + std::to_string(k),
                       slice, warned, report);
        if (k == 0) {
            // note: no more pages than the file's bytes can decode to
            const std::uint64_t can_hold =
                std::max<std::uint64_t>(1, tiff.file_bytes() * 4096 / (stack.slice_size() * 2));
            stack.labels.reserve(stack.slice_size() * std::min<std::uint64_t>(pages, can_hold));
        }
        stack.labels.insert(stack.labels.end(), slice.begin(), slice.end());
        if (options.progress) {
            options.progress("slices", k + 1, stack.depth);
        }
    }
    return stack;
}

}  // namespace strata::detail
