#include <cmath>
#include <filesystem>
#include <fstream>
#include <sstream>

#include <nlohmann/json.hpp>

#include "core/error.h"
#include "input/detail/contour_readers.h"

namespace strata {

namespace detail {

namespace {

using Json = nlohmann::json;

[[noreturn]] void fail(const std::string& file, const std::string& what) {
    throw Error(ErrorCode::InvalidInput, file + ": " + what);
}

double number(const Json& value, const std::string& file, const std::string& at) {
    if (!value.is_number()) {
        fail(file, at + ": expected a number, found " + std::string(value.type_name()));
    }
    return value.get<double>();
}

std::string read_text(const std::string& path) {
    std::ifstream in(path, std::ios::binary);
    if (!in) {
        throw Error(ErrorCode::Io, path + ": cannot open the file");
    }
    std::ostringstream text;
    text << in.rdbuf();
    return text.str();
}

/// One contour of a slice: `cat` its place in the file, `z` the slice's position when `has_z`.
RawContour read_contour(const Json& contour,
                        const std::string& path,
                        const std::string& cat,
                        const std::string& roi_name,
                        bool has_z,
                        double z) {
    RawContour raw;
    raw.where = roi_name.empty() ? cat : cat + " (" + roi_name + ")";
    if (contour.contains("geometric_type")) {
        raw.geometric_type = contour["geometric_type"].is_string()
                                 ? contour["geometric_type"].get<std::string>()
                                 : "";
        if (!is_contour_geometric_type(raw.geometric_type)) {
            fail(path, cat +
                           ".geometric_type: expected CLOSED_PLANAR, OPEN_PLANAR, "
                           "OPEN_NONPLANAR or POINT");
        }
    }
    if (contour.contains("closed")) {
        if (!contour["closed"].is_boolean()) {
            fail(path, cat + ".closed: expected true or false");
        }
        if (!contour["closed"].get<bool>()) {
            raw.geometric_type = "OPEN_PLANAR";
        }
    }
    for (std::size_t p = 0; p < contour["points"].size(); ++p) {
        const Json& point = contour["points"][p];
        const std::string pat = cat + ".points[" + std::to_string(p) + "]";
        if (!point.is_array() || (point.size() != 2 && point.size() != 3) ||
            (point.size() == 2 && !has_z)) {
            fail(path, pat + ": expected [x, y] (on a slice with \"z\") or [x, y, z]");
        }
        Vec3 q{number(point[0], path, pat), number(point[1], path, pat), z};
        if (point.size() == 3) {
            q.z = number(point[2], path, pat);
        }
        raw.points.push_back(q);
    }
    return raw;
}

/// One structure of "rois" (`at` its place in the file): number, name, type, colour, contours.
RawRoi read_roi(const Json& roi, const std::string& path, std::size_t r, const std::string& at) {
    if (!roi.is_object()) {
        fail(path, at + ": expected an object");
    }
    RawRoi out;
    out.number = std::int32_t(r + 1);
    if (roi.contains("number")) {
        const double n = number(roi["number"], path, at + ".number");
        if (!(n >= -2147483648.0 && n <= 2147483647.0) || n != std::floor(n)) {
            fail(path, at + ".number: expected an integer (a 32-bit ROI Number)");
        }
        out.number = std::int32_t(n);
    }
    if (roi.contains("name")) {
        if (!roi["name"].is_string()) {
            fail(path, at + ".name: expected a string");
        }
        out.name = roi["name"].get<std::string>();
    }
    if (roi.contains("interpreted_type") && roi["interpreted_type"].is_string()) {
        out.interpreted_type = roi["interpreted_type"].get<std::string>();
    }
    if (roi.contains("color_rgb")) {
        const Json& c = roi["color_rgb"];
        if (!c.is_array() || c.size() != 3) {
            fail(path, at + ".color_rgb: expected [r, g, b], each 0-255");
        }
        ColorSrgb8 color{};
        for (int i = 0; i < 3; ++i) {
            const double v = number(c[std::size_t(i)], path, at + ".color_rgb");
            if (!(v >= 0.0 && v <= 255.0)) {
                fail(path, at + ".color_rgb: expected [r, g, b], each 0-255");
            }
            color[std::size_t(i)] = std::uint8_t(v);
        }
        out.color = color;
    }
    const Json slices = roi.value("slices", Json::array());
    if (!slices.is_array()) {
        fail(path, at + ".slices: expected an array");
    }
    for (std::size_t s = 0; s < slices.size(); ++s) {
        const Json& slice = slices[s];
        const std::string sat = at + ".slices[" + std::to_string(s) + "]";
        if (!slice.is_object() || !slice.contains("contours") || !slice["contours"].is_array()) {
            fail(path, sat + ": expected {\"z\": mm, \"contours\": [...]}");
        }
        const bool has_z = slice.contains("z");
        const double z = has_z ? number(slice["z"], path, sat + ".z") : 0.0;
        const Json& contours = slice["contours"];
        for (std::size_t c = 0; c < contours.size(); ++c) {
            const Json& contour = contours[c];
            const std::string cat = sat + ".contours[" + std::to_string(c) + "]";
            if (!contour.is_object() || !contour.contains("points") ||
                !contour["points"].is_array()) {
                fail(path, cat + ": expected {\"points\": [[x, y], ...]}");
            }
            out.contours.push_back(read_contour(contour, path, cat, out.name, has_z, z));
        }
    }
    return out;
}

}  // namespace

RawContourSet read_contour_json(const std::string& path) {
    Json root;
    try {
        root = Json::parse(read_text(path));
    } catch (const Json::parse_error& e) {
        fail(path, std::string("not valid JSON (") + e.what() + ")");
    }
    if (!root.is_object() || root.value("format", Json()) != "planar contours v1") {
        fail(path,
             "expected a JSON object with \"format\": \"planar contours v1\" "
             "(schema/contours.schema.json)");
    }
    RawContourSet result;
    result.source = path;
    result.frame = root.value("frame", Json("")).is_string() ? root.value("frame", "") : "";
    if (!root.contains("rois") || !root["rois"].is_array()) {
        fail(path, "\"rois\" must be an array of structures");
    }
    const Json& rois = root["rois"];
    for (std::size_t r = 0; r < rois.size(); ++r) {
        result.rois.push_back(read_roi(rois[r], path, r, "rois[" + std::to_string(r) + "]"));
    }
    return result;
}

}  // namespace detail

bool is_planar_contour_file(const std::string& path) {
    if (!std::filesystem::is_regular_file(path)) {
        return false;
    }
    if (detail::is_dicom_file(path)) {
        return true;
    }
    std::ifstream in(path, std::ios::binary);
    std::string head(4096, '\0');
    in.read(head.data(), std::streamsize(head.size()));
    head.resize(std::size_t(in.gcount()));
    return head.find("\"planar contours v1\"") != std::string::npos;
}

RawContourSet read_raw_contours(const std::string& path, const std::string& reference_ct) {
    if (detail::is_dicom_file(path)) {
        return detail::read_rtstruct(path, reference_ct);
    }
    RawContourSet result = detail::read_contour_json(path);
    if (!reference_ct.empty()) {
        throw Error(ErrorCode::InvalidInput,
                    path + ": --reference-ct applies to DICOM RTSTRUCT input, not contour JSON");
    }
    return result;
}

}  // namespace strata
