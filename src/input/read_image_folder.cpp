// Folders of 2D label images and multi-page TIFFs: TIFF with libtiff, other formats with the
// OpenImageIO module (detail/image_files.h).

#include <algorithm>
#include <cctype>
#include <fstream>
#include <set>
#include <string>
#include <tuple>
#include <vector>

#include <nlohmann/json.hpp>

#include "core/error.h"
#include "input/detail/image_files.h"
#include "input/detail/readers.h"
#include "input/detail/tiff.h"

namespace strata::detail {

namespace {

namespace fs = std::filesystem;

const std::set<std::string> kImageExtensions = {".png", ".tif", ".tiff", ".jpg", ".jpeg",
                                                ".bmp", ".pgm", ".pnm",  ".ppm", ".gif"};

std::string lower(std::string s) {
    std::transform(s.begin(), s.end(), s.begin(),
                   [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
    return s;
}

/// Natural order: digit runs compare as numbers ("slice_2" < "slice_10").
bool natural_less(const std::string& a, const std::string& b) {
    std::size_t i = 0;
    std::size_t j = 0;
    while (i < a.size() && j < b.size()) {
        const bool da = std::isdigit(static_cast<unsigned char>(a[i]));
        const bool db = std::isdigit(static_cast<unsigned char>(b[j]));
        if (da && db) {
            std::size_t ie = i;
            std::size_t je = j;
            while (ie < a.size() && std::isdigit(static_cast<unsigned char>(a[ie]))) {
                ++ie;
            }
            while (je < b.size() && std::isdigit(static_cast<unsigned char>(b[je]))) {
                ++je;
            }
            // compare numerically without overflow: strip leading zeros, then length, then text
            std::size_t is = i;
            std::size_t js = j;
            while (is + 1 < ie && a[is] == '0') {
                ++is;
            }
            while (js + 1 < je && b[js] == '0') {
                ++js;
            }
            if (ie - is != je - js) {
                return ie - is < je - js;
            }
            const int c = a.compare(is, ie - is, b, js, je - js);
            if (c != 0) {
                return c < 0;
            }
            i = ie;
            j = je;
        } else {
            if (a[i] != b[j]) {
                return a[i] < b[j];
            }
            ++i;
            ++j;
        }
    }
    return a.size() - i < b.size() - j;
}

struct Sidecar {
    bool present = false;
    fs::path file;
    std::array<std::uint64_t, 3> dims{};
    Affine3 index_to_world;
    bool has_affine = false;
    std::string frame = "none";
    bool binary255 = false;
    std::vector<LabelInfo> labels;
};

/// Converts an affine given in `frame` to LPS. RAS (and ENU, read as x east = right,
/// y north = anterior, z up = superior) negate the first two rows.
Affine3 to_lps(Affine3 a, const std::string& frame) {
    if (frame == "RAS" || frame == "ENU") {
        for (int r = 0; r < 2; ++r) {
            for (int c = 0; c < 3; ++c) {
                a.linear[r][c] = -a.linear[r][c];
            }
            a.translation[r] = -a.translation[r];
        }
    }
    return a;
}

Sidecar read_sidecar(const fs::path& file) {
    Sidecar meta;
    meta.present = true;
    meta.file = file;
    std::ifstream in(file);
    if (!in) {
        throw Error(ErrorCode::Io, file.string() + ": cannot open");
    }
    nlohmann::json j;
    try {
        j = nlohmann::json::parse(in);
    } catch (const nlohmann::json::exception& e) {
        throw Error(ErrorCode::InvalidInput, file.string() + ": not valid JSON: " + e.what());
    }
    const std::string where = file.string();
    try {
        if (!j.is_object()) {
            throw Error(ErrorCode::InvalidInput, where + ": expected a JSON object");
        }
        if (j.contains("dims")) {
            const auto& d = j.at("dims");
            if (!d.is_array() || d.size() != 3) {
                throw Error(ErrorCode::InvalidInput,
                            where + ": 'dims' must be an array of 3 positive integers");
            }
            for (int i = 0; i < 3; ++i) {
                if (!d[i].is_number_integer() || d[i].get<std::int64_t>() <= 0) {
                    throw Error(ErrorCode::InvalidInput,
                                where + ": 'dims' must be an array of 3 positive integers");
                }
                meta.dims[i] = d[i].get<std::uint64_t>();
            }
        }
        if (j.contains("frame")) {
            meta.frame = j.at("frame").get<std::string>();
            if (meta.frame != "RAS" && meta.frame != "LPS" && meta.frame != "ENU" &&
                meta.frame != "none") {
                throw Error(ErrorCode::Unsupported,
                            where + ": frame '" + meta.frame + "', expected RAS, LPS, ENU or none");
            }
        }
        if (j.contains("index_to_world_mm")) {
            const auto& m = j.at("index_to_world_mm");
            if (!m.is_array() || m.size() < 3) {
                throw Error(ErrorCode::InvalidInput,
                            where + ": 'index_to_world_mm' must be a 4x4 (or 3x4) matrix");
            }
            Affine3 a;
            for (int r = 0; r < 3; ++r) {
                if (!m[r].is_array() || m[r].size() != 4) {
                    throw Error(ErrorCode::InvalidInput,
                                where + ": row " + std::to_string(r) +
                                    " of 'index_to_world_mm' must have 4 numbers");
                }
                for (int c = 0; c < 3; ++c) {
                    a.linear[r][c] = m[r][c].get<double>();
                }
                a.translation[r] = m[r][3].get<double>();
            }
            meta.index_to_world = to_lps(a, meta.frame);
            meta.has_affine = true;
        } else if (j.contains("spacing_mm")) {
            const auto& s = j.at("spacing_mm");
            if (!s.is_array() || s.size() != 3) {
                throw Error(ErrorCode::InvalidInput, where + ": 'spacing_mm' must have 3 numbers");
            }
            Affine3 a;
            for (int i = 0; i < 3; ++i) {
                a.linear[i][i] = s[i].get<double>();
            }
            if (j.contains("origin_mm")) {
                for (int i = 0; i < 3; ++i) {
                    a.translation[i] = j.at("origin_mm").at(i).get<double>();
                }
            }
            meta.index_to_world = to_lps(a, meta.frame);
            meta.has_affine = true;
        }
        meta.binary255 = j.value("value_type", std::string("labels")) == "binary255";
        if (j.contains("labels")) {
            const auto& labels = j.at("labels");
            if (!labels.is_object()) {
                throw Error(ErrorCode::InvalidInput,
                            where + ": 'labels' must be an object {\"value\": \"name\"}");
            }
            const nlohmann::json colors = j.value("colors", nlohmann::json::object());
            for (const auto& [key, value] : labels.items()) {
                std::size_t used = 0;
                long v = -1;
                try {
                    v = std::stol(key, &used);
                } catch (const std::exception&) {
                }
                if (used != key.size() || v < 1 || v > 65535) {
                    throw Error(ErrorCode::InvalidInput,
                                where + ": label key '" + key + "', expected an integer 1..65535");
                }
                LabelInfo info{static_cast<std::uint16_t>(v), value.get<std::string>(),
                               palette_color(static_cast<std::uint16_t>(v))};
                if (colors.contains(key)) {
                    const auto& c = colors.at(key);
                    for (int i = 0; i < 3; ++i) {
                        info.color[i] =
                            static_cast<std::uint8_t>(std::clamp(c.at(i).get<int>(), 0, 255));
                    }
                }
                meta.labels.push_back(info);
            }
        }
    } catch (const nlohmann::json::exception& e) {
        throw Error(ErrorCode::InvalidInput, where + ": unexpected field type: " + e.what());
    }
    if (meta.has_affine) {
        check_spacing({norm(meta.index_to_world.column(0)), norm(meta.index_to_world.column(1)),
                       norm(meta.index_to_world.column(2))},
                      where);
    }
    return meta;
}

/// Reads one single-channel 8/16-bit image (subimage `page`) into `out` (width*height values).
/// `where` names the slice for messages.
void read_label_image(ImageFile& in,
                      int page,
                      std::uint32_t width,
                      std::uint32_t height,
                      const std::string& where,
                      std::uint16_t* out,
                      Report& report) {
    const StrataImageSpec& spec = in.spec();
    if (spec.width <= 0 || spec.height <= 0) {
        throw Error(ErrorCode::InvalidInput, where + ": empty image " + std::to_string(spec.width) +
                                                 "x" + std::to_string(spec.height));
    }
    if (std::uint32_t(spec.width) != width || std::uint32_t(spec.height) != height) {
        throw Error(ErrorCode::InvalidInput,
                    where + ": size " + std::to_string(spec.width) + "x" +
                        std::to_string(spec.height) + ", expected " + std::to_string(width) + "x" +
                        std::to_string(height) + " (the size of the first slice)");
    }
    if (spec.depth > 1) {
        throw Error(ErrorCode::Unsupported, where + ": volume image with depth " +
                                                std::to_string(spec.depth) +
                                                ", expected a 2D slice");
    }
    const bool is8 = spec.pixel_type == kStrataPixelU8;
    const bool is16 = spec.pixel_type == kStrataPixelU16;
    if (!is8 && !is16) {
        throw Error(ErrorCode::Unsupported, where + ": pixel type " +
                                                std::string(spec.format_name) +
                                                ", expected 8- or 16-bit unsigned integer labels");
    }
    const int channels = spec.channels;
    if (channels < 1) {
        throw Error(ErrorCode::InvalidInput, where + ": image has no channels");
    }
    const std::size_t n = std::size_t(width) * height;
    std::vector<std::uint16_t> pixels(n * std::size_t(channels));
    bool ok = false;
    std::string error;
    if (is8) {
        std::vector<std::uint8_t> raw(n * std::size_t(channels));
        ok = in.read(page, channels, false, raw.data(), error);
        std::copy(raw.begin(), raw.end(), pixels.begin());
    } else {
        ok = in.read(page, channels, true, pixels.data(), error);
    }
    if (!ok) {
        throw Error(ErrorCode::InvalidInput, where + ": cannot decode image data: " + error);
    }
    // Colour or grey+alpha label images: accept when every colour channel agrees (alpha ignored).
    const int colour_channels = (channels == 2 || channels == 4) ? channels - 1 : channels;
    for (std::size_t p = 0; p < n; ++p) {
        const std::uint16_t* px = &pixels[p * std::size_t(channels)];
        for (int c = 1; c < colour_channels; ++c) {
            if (px[c] != px[0]) {
                throw Error(ErrorCode::Unsupported,
                            where + ": colour image with differing channels at pixel (" +
                                std::to_string(p % width) + ", " + std::to_string(p / width) +
                                "), expected a single-channel (greyscale) label image");
            }
        }
        out[p] = px[0];
    }
    if (channels > 1 && page == 0) {
        report.warn(
            "input", where,
            std::to_string(channels) + " channels with equal colour values; using the first");
    }
}

bool is_tiff(const fs::path& file) {
    const std::string ext = lower(file.extension().string());
    return ext == ".tif" || ext == ".tiff";
}

/// Refuses an image file whose bytes cannot decode to `pixels` pixels (a header claiming
/// 60000^2 pixels in 100 bytes) before anything is allocated for it: PNG is deflate
/// (kMaxDeflateRatio); other formats are bounded by kMaxOtherRatio (TIFF strips are checked one
/// by one when read).
void check_image_holds(const fs::path& file, std::uint64_t pixels) {
    std::error_code ec;
    const std::uint64_t bytes = fs::file_size(file, ec);
    if (ec) {
        throw Error(ErrorCode::Io, file.string() + ": cannot read size: " + ec.message());
    }
    const std::uint64_t ratio =
        lower(file.extension().string()) == ".png" ? kMaxDeflateRatio : kMaxOtherRatio;
    const std::uint64_t can_hold = bytes * ratio + 4096;
    if (pixels > can_hold) {
        throw Error(ErrorCode::InvalidInput,
                    file.string() + ": header claims " + std::to_string(pixels) +
                        " pixels but the file's " + std::to_string(bytes) +
                        " bytes can hold at most " + std::to_string(can_hold) +
                        ", expected image data for every pixel (truncated or forged header?)");
    }
}

}  // namespace

SliceStack read_image_folder(const fs::path& folder, const ReadOptions& options, Report& report) {
    // Layouts: FOLDER/*.png (+ FOLDER/meta.json), FOLDER/slices/*.png + FOLDER/meta.json, or
    // FOLDER = .../slices with the sidecar one level up.
    fs::path image_dir = folder;
    Sidecar meta;
    if (fs::is_regular_file(folder / "meta.json")) {
        meta = read_sidecar(folder / "meta.json");
        if (fs::is_directory(folder / "slices")) {
            image_dir = folder / "slices";
        }
    } else if (folder.filename() == "slices" &&
               fs::is_regular_file(folder.parent_path() / "meta.json")) {
        meta = read_sidecar(folder.parent_path() / "meta.json");
    }

    std::vector<std::string> names;
    std::error_code ec;
    for (auto it = fs::directory_iterator(image_dir, ec); !ec && it != fs::directory_iterator();
         it.increment(ec)) {
        const fs::directory_entry& entry = *it;
        const std::string name = entry.path().filename().string();
        if (name.empty() || name[0] == '.' ||
            kImageExtensions.count(lower(entry.path().extension().string())) == 0) {
            continue;
        }
        // note: an image name that is a link loop, a FIFO or a folder is refused, not skipped
        std::error_code status_ec;
        const fs::file_type type = entry.status(status_ec).type();
        if (status_ec || type != fs::file_type::regular) {
            throw Error(ErrorCode::InvalidInput,
                        entry.path().string() + ": " +
                            (status_ec ? status_ec.message()
                                       : std::string("not a regular file (a FIFO, device or "
                                                     "folder)")) +
                            ", expected an image file");
        }
        names.push_back(name);
    }
    if (ec) {
        throw Error(ErrorCode::Io, image_dir.string() + ": cannot list folder: " + ec.message());
    }
    if (names.empty()) {
        throw Error(ErrorCode::InvalidInput,
                    image_dir.string() +
                        ": no image files (png, tif, tiff, jpg, bmp, pgm, ...) in this folder");
    }
    std::sort(names.begin(), names.end(), natural_less);

    SliceStack stack;
    stack.source = folder.string();
    stack.source_frame = meta.present ? meta.frame : "none";
    if (is_tiff(image_dir / names[0])) {
        TiffFile first(image_dir / names[0]);
        std::tie(stack.width, stack.height) = first.size();
    } else {
        const ImageFile first(image_dir / names[0]);
        const StrataImageSpec& spec = first.spec();
        stack.width = static_cast<std::uint32_t>(std::max(spec.width, 0));
        stack.height = static_cast<std::uint32_t>(std::max(spec.height, 0));
    }
    if (stack.width == 0 || stack.height == 0) {
        throw Error(ErrorCode::InvalidInput,
                    (image_dir / names[0]).string() + ": empty image, expected positive size");
    }
    stack.depth = static_cast<std::uint32_t>(names.size());
    if (meta.present && meta.dims[0] != 0 &&
        (meta.dims[0] != stack.width || meta.dims[1] != stack.height ||
         meta.dims[2] != stack.depth)) {
        throw Error(ErrorCode::InvalidInput,
                    meta.file.string() + ": dims " + std::to_string(meta.dims[0]) + "x" +
                        std::to_string(meta.dims[1]) + "x" + std::to_string(meta.dims[2]) +
                        " disagree with the images: " + std::to_string(stack.width) + "x" +
                        std::to_string(stack.height) + "x" + std::to_string(stack.depth));
    }
    check_stack_dimensions(stack.width, stack.height, stack.depth, folder.string(),
                           options.max_bytes);
    for (const std::string& name : names) {
        check_image_holds(image_dir / name, stack.slice_size());
    }
    stack.labels.assign(stack.slice_size() * stack.depth, 0);
    bool warned_channels = false;
    for (std::uint32_t k = 0; k < stack.depth; ++k) {
        const fs::path file = image_dir / names[k];
        const std::string where = "slice " + std::to_string(k) + " (" + names[k] + ")";
        if (is_tiff(file)) {
            TiffFile tiff(file);
            std::vector<std::uint16_t> slice;
            tiff.read_page(stack.width, stack.height, where, slice, warned_channels, report);
            std::copy(slice.begin(), slice.end(), stack.slice(k).begin());
        } else {
            ImageFile in(file);
            read_label_image(in, 0, stack.width, stack.height, where, stack.slice(k).data(),
                             report);
        }
        if (options.progress) {
            options.progress("slices", k + 1, stack.depth);
        }
    }
    if (meta.binary255) {
        for (std::uint16_t& v : stack.labels) {
            if (v != 0 && v != 255) {
                throw Error(ErrorCode::InvalidInput,
                            meta.file.string() + ": value_type binary255 but the images hold " +
                                std::to_string(v) + ", expected only 0 and 255");
            }
        }
    }
    if (meta.has_affine) {
        stack.index_to_world = meta.index_to_world;
    }
    stack.label_table = meta.labels;
    return stack;
}

SliceStack read_single_image(const fs::path& file, const ReadOptions& options, Report& report) {
    if (is_tiff(file)) {
        return read_multipage_tiff(file, options, report);
    }
    ImageFile in(file);
    SliceStack stack;
    stack.source = file.string();
    stack.source_frame = "none";
    const StrataImageSpec& spec = in.spec();
    if (spec.width <= 0 || spec.height <= 0) {
        throw Error(ErrorCode::InvalidInput,
                    file.string() + ": empty image, expected positive size");
    }
    stack.width = static_cast<std::uint32_t>(spec.width);
    stack.height = static_cast<std::uint32_t>(spec.height);
    stack.depth = 1;
    check_stack_dimensions(stack.width, stack.height, 1, file.string(), options.max_bytes);
    check_image_holds(file, stack.slice_size());
    stack.labels.assign(stack.slice_size(), 0);
    read_label_image(in, 0, stack.width, stack.height, file.filename().string(),
                     stack.labels.data(), report);
    if (options.progress) {
        options.progress("slices", 1, 1);
    }
    return stack;
}

}  // namespace strata::detail
