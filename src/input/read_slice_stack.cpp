#include "input/read_slice_stack.h"

#include <algorithm>
#include <cctype>
#include <fstream>
#include <string>

#include "core/error.h"
#include "input/detail/readers.h"

namespace strata {

namespace {

namespace fs = std::filesystem;

std::string lower(std::string s) {
    std::transform(s.begin(), s.end(), s.begin(),
                   [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
    return s;
}

bool ends_with(const std::string& s, const std::string& suffix) {
    return s.size() >= suffix.size() &&
           s.compare(s.size() - suffix.size(), suffix.size(), suffix) == 0;
}

enum class Format { Folder, Nifti, Nrrd, Image, Unknown };

Format sniff(const fs::path& path) {
    if (fs::is_directory(path)) {
        return Format::Folder;
    }
    const std::string name = lower(path.filename().string());
    if (ends_with(name, ".nii") || ends_with(name, ".nii.gz")) {
        return Format::Nifti;
    }
    if (ends_with(name, ".nrrd") || ends_with(name, ".nhdr")) {
        return Format::Nrrd;
    }
    for (const char* ext : {".tif", ".tiff", ".png", ".jpg", ".jpeg", ".bmp", ".pgm", ".pnm"}) {
        if (ends_with(name, ext)) {
            return Format::Image;
        }
    }
    // By content: NRRD magic, or a NIfTI-1/2 header size in either byte order.
    std::ifstream in(path, std::ios::binary);
    char head[4] = {};
    in.read(head, 4);
    if (in.gcount() == 4) {
        if (std::string(head, 4) == "NRRD") {
            return Format::Nrrd;
        }
        const auto* u = reinterpret_cast<const unsigned char*>(head);
        const std::uint32_t le = u[0] | (u[1] << 8) | (u[2] << 16) | (std::uint32_t(u[3]) << 24);
        const std::uint32_t be = u[3] | (u[2] << 8) | (u[1] << 16) | (std::uint32_t(u[0]) << 24);
        if (le == 348 || be == 348 || le == 540 || be == 540) {
            return Format::Nifti;
        }
    }
    return Format::Unknown;
}

void apply_color_table(SliceStack& stack, const std::vector<LabelInfo>& table) {
    for (const LabelInfo& entry : table) {
        auto it = std::find_if(stack.label_table.begin(), stack.label_table.end(),
                               [&](const LabelInfo& l) { return l.value == entry.value; });
        if (it == stack.label_table.end()) {
            stack.label_table.push_back(entry);
        }
    }
}

/// The file or folder must exist and be a regular file or a folder (after links): a FIFO would
/// block and a device never end.
void check_input_path(const fs::path& path) {
    std::error_code ec;
    const fs::file_status status = fs::status(path, ec);
    if (status.type() == fs::file_type::not_found) {
        throw Error(ErrorCode::InvalidInput, path.string() + ": no such file or folder");
    }
    if (ec) {
        throw Error(ErrorCode::InvalidInput, path.string() + ": cannot resolve: " + ec.message() +
                                                 ", expected a label stack file or folder");
    }
    if (status.type() != fs::file_type::regular && status.type() != fs::file_type::directory) {
        throw Error(ErrorCode::InvalidInput,
                    path.string() +
                        ": not a regular file or folder (a FIFO, socket or device), expected a "
                        "label stack file or folder");
    }
}

SliceStack read_any(const fs::path& path, const ReadOptions& options, Report& report) {
    check_input_path(path);
    // note: the colour table first, so that a missing one is reported before a long read
    std::vector<LabelInfo> color_table;
    if (!options.color_table.empty()) {
        color_table = detail::read_color_table(options.color_table);
    }
    SliceStack stack;
    switch (sniff(path)) {
        case Format::Folder:
            stack = detail::read_image_folder(path, options, report);
            break;
        case Format::Nifti:
            stack = detail::read_nifti(path, options, report);
            break;
        case Format::Nrrd:
            stack = detail::read_nrrd(path, options, report);
            break;
        case Format::Image:
            stack = detail::read_single_image(path, options, report);
            break;
        case Format::Unknown: {
            const std::string ext = lower(path.extension().string());
            std::string hint;
            if (ext == ".mgz" || ext == ".mgh") {
                hint = " (FreeSurfer: convert with `mri_convert in.mgz out.nii.gz`)";
            } else if (ext == ".dcm") {
                hint =
                    " (of DICOM, strata reads RTSTRUCT contours with `strata build`/`info`; "
                    "export a DICOM SEG or image as NIfTI or NRRD)";
            }
            throw Error(ErrorCode::Unsupported,
                        path.string() + ": unknown input format" + hint +
                            "; expected a folder of images, a (multi-page) TIFF, NIfTI "
                            "(.nii, .nii.gz) or NRRD (.nrrd, .seg.nrrd, .nhdr)");
        }
    }
    check_spacing(stack.spacing_mm(), path.string());
    if (options.spacing_mm) {
        override_spacing(stack, *options.spacing_mm);
    }
    apply_color_table(stack, color_table);
    complete_label_table(stack);
    if (stack.label_table.empty()) {
        report.warn("input", path.string(), "every pixel is background (0): no objects");
    }
    return stack;
}

}  // namespace

SliceStack read_slice_stack(const fs::path& path, const ReadOptions& options, Report& report) {
    try {
        return read_any(path, options, report);
    } catch (const fs::filesystem_error& e) {
        // note: e.g. a symbolic link loop met while listing a folder
        throw Error(ErrorCode::InvalidInput,
                    path.string() + ": " + e.what() + ", expected readable files and folders");
    }
}

}  // namespace strata
