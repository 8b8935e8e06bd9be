// Hostile and mistaken inputs (issue 18): headers claiming more data than the file holds,
// truncated gzip streams and TIFF strips, files that are not regular files, NRRD data files
// outside the header's folder, and many-page TIFFs. Every case must end in a strata::Error
// naming the file and what was expected, in memory bounded by the data actually present.
//
// This binary counts allocations (operator new below): a single allocation larger than
// kAllocationCap is refused with std::bad_alloc and recorded, so a reader that allocates what a
// header claims before checking the file fails here instead of exhausting the machine.

#include <atomic>
#include <chrono>
#include <cstdint>
#include <cstdlib>
#include <fcntl.h>
#include <filesystem>
#include <fstream>
#include <new>
#include <string>
#include <sys/stat.h>
#include <thread>
#include <unistd.h>
#include <vector>
#include <zlib.h>

#include <gtest/gtest.h>

#include "core/error.h"
#include "input/detail/readers.h"
#include "input/read_slice_stack.h"
#include "support/input_files.h"

namespace {

constexpr std::size_t kAllocationCap = std::size_t(256) << 20;
std::atomic<std::size_t> g_largest_allocation{0};

}  // namespace

// note: the replacement pair below is malloc/free on purpose; GCC sees only half of it inlined
#pragma GCC diagnostic ignored "-Wmismatched-new-delete"

void* operator new(std::size_t size) {
    std::size_t seen = g_largest_allocation.load();
    while (size > seen && !g_largest_allocation.compare_exchange_weak(seen, size)) {
    }
    if (size > kAllocationCap) {
        throw std::bad_alloc();
    }
    if (void* p = std::malloc(size == 0 ? 1 : size)) {
        return p;
    }
    throw std::bad_alloc();
}
void operator delete(void* p) noexcept {
    std::free(p);
}
void operator delete(void* p, std::size_t) noexcept {
    std::free(p);
}

namespace strata {
namespace {

namespace fs = std::filesystem;
using test::encode;
using test::gzip;
using test::put;
using test::throws_error;
using test::write_file;

fs::path temp_dir() {
    return test::current_test_dir("hostile_");
}

SliceStack read(const fs::path& path, ReadOptions options = {}) {
    Report report;
    return read_slice_stack(path, options, report);
}

/// Largest single allocation made while `f` runs.
template <typename F>
std::size_t largest_allocation_in(F&& f) {
    g_largest_allocation = 0;
    f();
    return g_largest_allocation.load();
}

/// A NIfTI-1 header (uint8, 1 mm, no transform) claiming `dims`, followed by 4 zero bytes.
std::string nifti1_header(std::int16_t nx, std::int16_t ny, std::int16_t nz) {
    std::string h(352, '\0');
    put<std::int32_t>(h, 0, 348, false);
    const std::int16_t dim[8] = {3, nx, ny, nz, 1, 1, 1, 1};
    for (int d = 0; d < 8; ++d) {
        put<std::int16_t>(h, 40 + 2 * d, dim[d], false);
        put<float>(h, 76 + 4 * d, d >= 1 && d <= 3 ? 1.0f : 0.0f, false);
    }
    put<std::int16_t>(h, 70, 2, false);
    put<std::int16_t>(h, 72, 8, false);
    put<float>(h, 108, 352.0f, false);
    h[123] = 2;
    std::memcpy(h.data() + 344, "n+1\0", 4);
    return h;
}

std::string nrrd_header(const std::string& sizes, const std::string& encoding) {
    return "NRRD0004\ntype: uchar\ndimension: 3\nsizes: " + sizes + "\nencoding: " + encoding +
           "\nspace: left-posterior-superior\nspace directions: (1,0,0) (0,1,0) (0,0,1)\n\n";
}

// ---------------------------------------------------------------------------------------------
// Memory bombs: sizes claimed by headers are checked against the data present before allocating

TEST(HostileInput, NiftiClaimingGigabytesInKilobytesIsRefusedWithoutAllocating) {
    const fs::path file =
        write_file(temp_dir() / "bomb.nii", nifti1_header(4096, 4096, 255) + std::string(3500, 1));
    const std::size_t largest = largest_allocation_in([&] {
        EXPECT_TRUE(throws_error([&] { read(file); }, ErrorCode::InvalidInput,
                                 "bomb.nii: truncated: expected 4278190080 bytes of voxel data"));
    });
    EXPECT_LT(largest, std::size_t(64) << 20);
}

TEST(HostileInput, GzipNiftiClaimingGigabytesAllocatesOnlyWhatArrives) {
    const fs::path file = write_file(temp_dir() / "bomb.nii.gz",
                                     gzip(nifti1_header(1024, 1024, 1000) + std::string(5000, 1)));
    const std::size_t largest = largest_allocation_in([&] {
        EXPECT_TRUE(throws_error([&] { read(file); }, ErrorCode::InvalidInput,
                                 "bomb.nii.gz: truncated: expected 1048576000 bytes"));
    });
    EXPECT_LT(largest, std::size_t(64) << 20);
}

TEST(HostileInput, NrrdClaimingGigabytesIsRefusedWithoutAllocating) {
    const fs::path dir = temp_dir();
    const fs::path raw =
        write_file(dir / "bomb.nrrd", nrrd_header("1024 1024 1000", "raw") + std::string(3000, 1));
    const fs::path gz = write_file(
        dir / "bombgz.nrrd", nrrd_header("1024 1024 1000", "gzip") + gzip(std::string(3000, 1)));
    const std::size_t largest = largest_allocation_in([&] {
        EXPECT_TRUE(throws_error([&] { read(raw); }, ErrorCode::InvalidInput,
                                 "bomb.nrrd: truncated: expected 1048576000 bytes"));
        EXPECT_TRUE(throws_error([&] { read(gz); }, ErrorCode::InvalidInput,
                                 "bombgz.nrrd: truncated: expected 1048576000 bytes"));
    });
    EXPECT_LT(largest, std::size_t(64) << 20);
}

/// A PNG of `width` x `height` 8-bit grey pixels whose IDAT holds only a few bytes.
std::string forged_png(std::uint32_t width, std::uint32_t height) {
    const auto chunk = [](const std::string& type, const std::string& data) {
        std::string c(4, '\0');
        put<std::uint32_t>(c, 0, static_cast<std::uint32_t>(data.size()), true);
        c += type + data;
        std::string crc(4, '\0');
        const std::string body = type + data;
        put<std::uint32_t>(crc, 0,
                           static_cast<std::uint32_t>(
                               crc32(0, reinterpret_cast<const Bytef*>(body.data()), body.size())),
                           true);
        return c + crc;
    };
    std::string ihdr(13, '\0');
    put<std::uint32_t>(ihdr, 0, width, true);
    put<std::uint32_t>(ihdr, 4, height, true);
    ihdr[8] = 8;  // bit depth
    ihdr[9] = 0;  // greyscale
    return std::string("\x89PNG\r\n\x1a\n", 8) + chunk("IHDR", ihdr) +
           chunk("IDAT", std::string("\x78\x9c\x03\x00\x00\x00\x00\x01", 8)) + chunk("IEND", "");
}

TEST(HostileInput, PngClaimingHugeSizeIsRefusedWithoutAllocating) {
    const fs::path dir = temp_dir() / "slices";
    fs::create_directories(dir);
    write_file(dir / "s0.png", forged_png(60000, 60000));
    const std::size_t largest = largest_allocation_in([&] {
        EXPECT_TRUE(throws_error([&] { read(dir); }, ErrorCode::InvalidInput,
                                 "s0.png: header claims 3600000000 pixels"));
    });
    EXPECT_LT(largest, std::size_t(64) << 20);
}

// ---------------------------------------------------------------------------------------------
// TIFF files assembled here (little-endian, one strip or several per page)

struct TiffPage {
    std::uint32_t width = 0;
    std::uint32_t height = 0;
    std::uint32_t rows_per_strip = 0;   // 0: the whole page in one strip
    std::vector<std::string> strips;    // stored bytes of each strip
    std::vector<std::uint32_t> counts;  // StripByteCounts; empty: the strips' sizes
    std::uint16_t compression = 1;      // 1 none, 8 deflate
};

std::string tiff_file(const std::vector<TiffPage>& pages) {
    std::string out(8, '\0');
    out[0] = 'I';
    out[1] = 'I';
    put<std::uint16_t>(out, 2, 42, false);
    std::size_t link = 4;  // where the offset of the next IFD goes
    for (const TiffPage& page : pages) {
        std::vector<std::uint32_t> offsets;
        for (const std::string& strip : page.strips) {
            offsets.push_back(static_cast<std::uint32_t>(out.size()));
            out += strip;
        }
        if (out.size() % 2 != 0) {
            out.push_back('\0');
        }
        // arrays of more than one value live outside the IFD
        const auto put_array = [&](const std::vector<std::uint32_t>& values) {
            const auto at = static_cast<std::uint32_t>(out.size());
            for (std::uint32_t v : values) {
                std::string b(4, '\0');
                put<std::uint32_t>(b, 0, v, false);
                out += b;
            }
            return at;
        };
        std::vector<std::uint32_t> counts = page.counts;
        if (counts.empty()) {
            for (const std::string& strip : page.strips) {
                counts.push_back(static_cast<std::uint32_t>(strip.size()));
            }
        }
        const bool many = offsets.size() > 1;
        const std::uint32_t offsets_at = many ? put_array(offsets) : offsets.at(0);
        const std::uint32_t counts_at = many ? put_array(counts) : counts.at(0);
        struct Entry {
            std::uint16_t tag, type;
            std::uint32_t count, value;
        };
        const std::uint32_t rows = page.rows_per_strip == 0 ? page.height : page.rows_per_strip;
        const std::vector<Entry> entries = {
            {256, 4, 1, page.width},
            {257, 4, 1, page.height},
            {258, 3, 1, 8},
            {259, 3, 1, page.compression},
            {262, 3, 1, 1},
            {273, 4, static_cast<std::uint32_t>(offsets.size()), offsets_at},
            {277, 3, 1, 1},
            {278, 4, 1, rows},
            {279, 4, static_cast<std::uint32_t>(counts.size()), counts_at},
        };
        const auto ifd = static_cast<std::uint32_t>(out.size());
        put<std::uint32_t>(out, link, ifd, false);
        std::string block(2 + 12 * entries.size() + 4, '\0');
        put<std::uint16_t>(block, 0, static_cast<std::uint16_t>(entries.size()), false);
        for (std::size_t e = 0; e < entries.size(); ++e) {
            put<std::uint16_t>(block, 2 + 12 * e, entries[e].tag, false);
            put<std::uint16_t>(block, 4 + 12 * e, entries[e].type, false);
            put<std::uint32_t>(block, 6 + 12 * e, entries[e].count, false);
            if (entries[e].type == 3 && entries[e].count == 1) {
                put<std::uint16_t>(block, 10 + 12 * e, static_cast<std::uint16_t>(entries[e].value),
                                   false);
            } else {
                put<std::uint32_t>(block, 10 + 12 * e, entries[e].value, false);
            }
        }
        out += block;
        link = ifd + 2 + 12 * entries.size();
    }
    return out;
}

std::string zlib_compress(const std::string& bytes) {
    uLongf size = compressBound(static_cast<uLong>(bytes.size()));
    std::string out(size, '\0');
    compress(reinterpret_cast<Bytef*>(out.data()), &size,
             reinterpret_cast<const Bytef*>(bytes.data()), static_cast<uLong>(bytes.size()));
    out.resize(size);
    return out;
}

std::string noise(std::size_t size, std::uint32_t seed) {
    std::string bytes(size, '\0');
    for (char& b : bytes) {
        seed = seed * 1664525u + 1013904223u;
        b = static_cast<char>((seed >> 24) % 5);
    }
    return bytes;
}

TEST(HostileInput, TiffReadsStripsExactly) {
    const std::string pixels = noise(128 * 64, 7);
    TiffPage page{128, 64, 16, {}, {}, 1};
    for (int s = 0; s < 4; ++s) {
        page.strips.push_back(pixels.substr(s * 128 * 16, 128 * 16));
    }
    const fs::path file = write_file(temp_dir() / "ok.tif", tiff_file({page, page}));
    const SliceStack stack = read(file);
    ASSERT_EQ(stack.depth, 2u);
    for (std::size_t n = 0; n < pixels.size(); ++n) {
        ASSERT_EQ(stack.labels[n], static_cast<unsigned char>(pixels[n])) << n;
        ASSERT_EQ(stack.labels[pixels.size() + n], static_cast<unsigned char>(pixels[n])) << n;
    }
}

TEST(HostileInput, TiffWithAShortStripIsRefused) {
    const std::string pixels = noise(128 * 64, 3);
    TiffPage page{128, 64, 0, {pixels.substr(0, 2000)}, {}, 1};
    const fs::path file = write_file(temp_dir() / "short.tif", tiff_file({page}));
    EXPECT_TRUE(
        throws_error([&] { read(file); }, ErrorCode::InvalidInput, "short.tif page 0: strip 0: "));
}

TEST(HostileInput, TiffWithATruncatedCompressedStripIsRefused) {
    const std::string pixels = noise(128 * 64, 5);
    const std::string packed = zlib_compress(pixels);
    TiffPage page{128, 64, 0, {packed.substr(0, packed.size() / 2)}, {}, 8};
    const fs::path file = write_file(temp_dir() / "cut.tif", tiff_file({page}));
    EXPECT_TRUE(throws_error([&] { read(file); }, ErrorCode::InvalidInput,
                             "cut.tif page 0: strip 0: decoded"));
}

TEST(HostileInput, TiffStripPastTheEndOfTheFileIsRefused) {
    TiffPage page{64, 64, 0, {std::string(100, 1)}, {4096}, 1};
    const fs::path file = write_file(temp_dir() / "past.tif", tiff_file({page}));
    EXPECT_TRUE(
        throws_error([&] { read(file); }, ErrorCode::InvalidInput, "run past the end of the file"));
}

TEST(HostileInput, TiffClaimingHugeSizeIsRefusedWithoutAllocating) {
    TiffPage page{46000, 46000, 0, {std::string(64, 1)}, {}, 8};
    const fs::path file = write_file(temp_dir() / "huge.tif", tiff_file({page}));
    const std::size_t largest = largest_allocation_in([&] {
        EXPECT_TRUE(throws_error([&] { read(file); }, ErrorCode::InvalidInput,
                                 "huge.tif page 0: strip 0: 64 stored bytes cannot hold"));
    });
    EXPECT_LT(largest, std::size_t(64) << 20);
}

/// Bytes this process has read through read(2) and the like so far (/proc/self/io "rchar").
std::uint64_t bytes_read_so_far() {
    std::ifstream io("/proc/self/io");
    std::string key;
    std::uint64_t value = 0;
    while (io >> key >> value) {
        if (key == "rchar:") {
            return value;
        }
    }
    return 0;
}

TEST(HostileInput, ManyPageTiffIsReadInOnePass) {
    // note: a reader that walks the directory chain from the start for every page reads the
    // IFDs N^2/2 times; one pass reads each byte a small constant number of times
    TiffPage page{8, 8, 0, {std::string(64, 2)}, {}, 1};
    const std::vector<TiffPage> pages(4000, page);
    const std::string bytes = tiff_file(pages);
    const fs::path file = write_file(temp_dir() / "pages.tif", bytes);
    const std::uint64_t before = bytes_read_so_far();
    const SliceStack stack = read(file);
    const std::uint64_t read_bytes = bytes_read_so_far() - before;
    ASSERT_EQ(stack.depth, 4000u);
    EXPECT_EQ(stack.labels.back(), 2);
    EXPECT_LT(read_bytes, 8 * bytes.size() + (1u << 20))
        << "read " << read_bytes << " bytes for a file of " << bytes.size();
}

// ---------------------------------------------------------------------------------------------
// gzip streams must end with their CRC and length trailer

TEST(HostileInput, GzipWithoutTrailerIsRefused) {
    const fs::path dir = temp_dir();
    const std::string nifti = gzip(nifti1_header(4, 3, 2) + std::string(24, 1));
    const fs::path a = write_file(dir / "cut.nii.gz", nifti.substr(0, nifti.size() - 8));
    EXPECT_TRUE(throws_error([&] { read(a); }, ErrorCode::InvalidInput,
                             "cut.nii.gz: truncated gzip stream: it ends without its CRC"));
    const std::string data = gzip(std::string(24, 1));
    const fs::path b = write_file(dir / "cut.nrrd",
                                  nrrd_header("4 3 2", "gzip") + data.substr(0, data.size() - 8));
    EXPECT_TRUE(throws_error([&] { read(b); }, ErrorCode::InvalidInput,
                             "cut.nrrd: truncated gzip stream: it ends without its CRC"));
    // the complete files read
    write_file(dir / "whole.nii.gz", nifti);
    EXPECT_EQ(read(dir / "whole.nii.gz").labels.size(), 24u);
    write_file(dir / "whole.nrrd", nrrd_header("4 3 2", "gzip") + data);
    EXPECT_EQ(read(dir / "whole.nrrd").labels.size(), 24u);
}

// ---------------------------------------------------------------------------------------------
// Files that are not regular files

/// For two seconds, opens and closes the FIFO `path` for writing whenever a reader waits on it,
/// so that a reader that opens it gets an empty stream instead of blocking forever.
std::thread feed_fifo(const fs::path& path) {
    return std::thread([path] {
        const auto end = std::chrono::steady_clock::now() + std::chrono::seconds(2);
        while (std::chrono::steady_clock::now() < end) {
            const int fd = ::open(path.c_str(), O_WRONLY | O_NONBLOCK);
            if (fd >= 0) {
                ::close(fd);
            }
            std::this_thread::sleep_for(std::chrono::milliseconds(5));
        }
    });
}

TEST(HostileInput, FifoAsNrrdDataFileIsRefused) {
    const fs::path dir = temp_dir();
    ASSERT_EQ(::mkfifo((dir / "data.raw").c_str(), 0600), 0);
    const fs::path header = write_file(
        dir / "a.nhdr",
        "NRRD0004\ntype: uchar\ndimension: 3\nsizes: 4 3 2\nencoding: raw\ndata file: data.raw\n");
    std::thread writer = feed_fifo(dir / "data.raw");
    EXPECT_TRUE(throws_error([&] { read(header); }, ErrorCode::InvalidInput,
                             "a.nhdr: data file data.raw: "));
    EXPECT_TRUE(
        throws_error([&] { read(header); }, ErrorCode::InvalidInput, "is not a regular file"));
    writer.join();
}

TEST(HostileInput, FifoOrDeviceAsInputOrColourTableIsRefused) {
    const fs::path dir = temp_dir();
    const fs::path input = write_file(dir / "a.nii", nifti1_header(4, 3, 2) + std::string(24, 1));
    ASSERT_EQ(::mkfifo((dir / "table.txt").c_str(), 0600), 0);
    ReadOptions options;
    options.color_table = dir / "table.txt";
    std::thread writer = feed_fifo(dir / "table.txt");
    EXPECT_TRUE(throws_error([&] { read(input, options); }, ErrorCode::InvalidInput,
                             "is not a regular file"));
    writer.join();
    options.color_table = "/dev/zero";
    EXPECT_TRUE(throws_error([&] { read(input, options); }, ErrorCode::InvalidInput,
                             "colour table /dev/zero is not a regular file"));
    options.color_table = dir / "absent.txt";
    EXPECT_TRUE(throws_error([&] { read(input, options); }, ErrorCode::InvalidInput,
                             "no such colour table file"));
    ASSERT_EQ(::mkfifo((dir / "in.nii").c_str(), 0600), 0);
    std::thread input_writer = feed_fifo(dir / "in.nii");
    EXPECT_TRUE(throws_error([&] { read(dir / "in.nii"); }, ErrorCode::InvalidInput,
                             "in.nii: not a regular file or folder"));
    input_writer.join();
    EXPECT_TRUE(throws_error([&] { read("/dev/zero"); }, ErrorCode::InvalidInput,
                             "not a regular file or folder"));
}

TEST(HostileInput, SymlinkLoopInImageFolderIsRefused) {
    const fs::path dir = temp_dir();
    fs::create_symlink(dir / "s1.png", dir / "s1.png");
    write_file(dir / "s0.png", forged_png(4, 4));
    EXPECT_TRUE(throws_error([&] { read(dir); }, ErrorCode::InvalidInput, "s1.png"));
}

// ---------------------------------------------------------------------------------------------
// NRRD detached data files lie beside their header unless the user names them

TEST(HostileInput, NrrdDataFileOutsideTheHeaderFolderIsRefusedUnlessNamed) {
    const fs::path dir = temp_dir();
    fs::create_directories(dir / "inner");
    write_file(dir / "outside.raw", std::string(24, 1));
    const std::string fields = "NRRD0004\ntype: uchar\ndimension: 3\nsizes: 4 3 2\nencoding: raw\n";
    const fs::path relative =
        write_file(dir / "inner" / "rel.nhdr", fields + "data file: ../outside.raw\n");
    EXPECT_TRUE(throws_error([&] { read(relative); }, ErrorCode::InvalidInput,
                             "lies outside the folder of rel.nhdr"));
    const fs::path absolute = write_file(
        dir / "inner" / "abs.nhdr", fields + "data file: " + (dir / "outside.raw").string() + "\n");
    EXPECT_TRUE(
        throws_error([&] { read(absolute); }, ErrorCode::InvalidInput, "--allow-data-file"));
    fs::create_symlink(dir / "outside.raw", dir / "inner" / "link.raw");
    const fs::path linked =
        write_file(dir / "inner" / "link.nhdr", fields + "data file: link.raw\n");
    EXPECT_TRUE(throws_error([&] { read(linked); }, ErrorCode::InvalidInput, "lies outside"));
    const fs::path device =
        write_file(dir / "inner" / "dev.nhdr", fields + "data file: /dev/urandom\n");
    EXPECT_TRUE(throws_error([&] { read(device); }, ErrorCode::InvalidInput, "not a regular file"));

    ReadOptions allowed;
    allowed.allowed_data_file = dir / "outside.raw";
    EXPECT_EQ(read(relative, allowed).labels.size(), 24u);
    EXPECT_EQ(read(absolute, allowed).labels.size(), 24u);
    // beside the header: read as before
    write_file(dir / "inner" / "beside.raw", std::string(24, 1));
    EXPECT_EQ(read(write_file(dir / "inner" / "ok.nhdr", fields + "data file: beside.raw\n"))
                  .labels.size(),
              24u);
}

}  // namespace
}  // namespace strata
