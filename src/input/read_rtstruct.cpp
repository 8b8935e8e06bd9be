// DICOM RTSTRUCT and CT grids through DCMTK's dcmdata (Debian libdcmtk-dev). DCMTK rather than
// GDCM: dcmdata gives element-level access with a status for every lookup, so a missing or broken
// element is named exactly in our messages, and it ships a CMake config (DCMTK::dcmdata).
// Its typed RT classes (dcmrt) refuse a whole file for one defect and hide which.

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <dcmtk/config/osconfig.h>
#include <dcmtk/dcmdata/dctk.h>
#include <dcmtk/oflog/oflog.h>
#include <filesystem>
#include <fstream>
#include <map>

#include "core/error.h"
#include "input/detail/contour_readers.h"

namespace strata::detail {

namespace {

[[noreturn]] void fail(const std::string& file, const std::string& what) {
    throw Error(ErrorCode::InvalidInput, file + ": " + what);
}

std::string get_string(DcmItem& item, const DcmTagKey& tag) {
    OFString value;
    if (item.findAndGetOFString(tag, value).good()) {
        return value.c_str();
    }
    return {};
}

/// Every value of a multi-valued decimal or integer string element, parsed strictly.
std::vector<double> get_numbers(DcmItem& item,
                                const DcmTagKey& tag,
                                const std::string& file,
                                const std::string& where) {
    // note: the raw value, backslash-separated; getOFStringArray is quadratic in the values
    const char* raw = nullptr;
    if (item.findAndGetString(tag, raw).bad() || raw == nullptr) {
        return {};
    }
    std::vector<double> values;
    const std::string text = raw;
    std::size_t start = 0;
    while (start <= text.size()) {
        std::size_t end = text.find('\\', start);
        if (end == std::string::npos) {
            end = text.size();
        }
        std::string token = text.substr(start, end - start);
        token.erase(0, token.find_first_not_of(' '));
        token.erase(token.find_last_not_of(' ') + 1);
        char* stop = nullptr;
        errno = 0;
        const double v = std::strtod(token.c_str(), &stop);
        if (token.empty() || stop != token.c_str() + token.size() || errno != 0 ||
            !std::isfinite(v)) {
            fail(file, where + ": value " + std::to_string(values.size() + 1) + " '" + token +
                           "' of " + DcmTag(tag).getTagName() + " is not a number");
        }
        values.push_back(v);
        start = end + 1;
    }
    return values;
}

DcmDataset* load(DcmFileFormat& file, const std::string& path) {
    if (!std::filesystem::is_regular_file(path)) {
        throw Error(ErrorCode::Io, path + ": cannot open the file");
    }
    // note: DCMTK logs its own parse errors to stderr; ours say what and where
    OFLog::configure(OFLogger::FATAL_LOG_LEVEL);
    const OFCondition status = file.loadFile(path.c_str());
    if (status.bad()) {
        fail(path, std::string("not a readable DICOM file (") + status.text() + ")");
    }
    return file.getDataset();
}

/// The grid of a CT (or any image) slice; nullopt when the file has no image plane.
std::optional<PlaneGrid> image_grid(DcmDataset& d, const std::string& path, bool required) {
    const std::vector<double> position = get_numbers(d, DCM_ImagePositionPatient, path, "image");
    const std::vector<double> orientation =
        get_numbers(d, DCM_ImageOrientationPatient, path, "image");
    const std::vector<double> spacing = get_numbers(d, DCM_PixelSpacing, path, "image");
    Uint16 rows = 0;
    Uint16 columns = 0;
    d.findAndGetUint16(DCM_Rows, rows);
    d.findAndGetUint16(DCM_Columns, columns);
    if (position.size() != 3 || orientation.size() != 6 || spacing.size() != 2 || rows == 0 ||
        columns == 0) {
        if (!required) {
            return std::nullopt;
        }
        fail(path,
             "not an image slice with a plane: expected Image Position (Patient) (3 values), "
             "Image Orientation (Patient) (6), Pixel Spacing (2), Rows and Columns");
    }
    PlaneGrid g;
    g.origin = {position[0], position[1], position[2]};
    g.row_direction = {orientation[0], orientation[1], orientation[2]};
    g.column_direction = {orientation[3], orientation[4], orientation[5]};
    const double nr = norm(g.row_direction);
    const double nc = norm(g.column_direction);
    if (std::abs(nr - 1.0) > 1e-3 || std::abs(nc - 1.0) > 1e-3 ||
        std::abs(dot(g.row_direction, g.column_direction)) > 1e-3) {
        fail(path, "Image Orientation (Patient) is not two orthogonal unit vectors");
    }
    g.row_direction = (1.0 / nr) * g.row_direction;
    g.column_direction = (1.0 / nc) * g.column_direction;
    // note: DICOM Pixel Spacing is (row spacing, column spacing): between rows first
    g.pixel_mm[0] = spacing[1];
    g.pixel_mm[1] = spacing[0];
    if (!(g.pixel_mm[0] > 0.0) || !(g.pixel_mm[1] > 0.0)) {
        fail(path, "Pixel Spacing must be positive");
    }
    g.columns = columns;
    g.rows = rows;
    return g;
}

bool has_dicom_preamble(const std::filesystem::path& path) {
    std::ifstream in(path, std::ios::binary);
    char magic[132] = {};
    in.read(magic, sizeof(magic));
    return in.gcount() == 132 && std::string(magic + 128, 4) == "DICM";
}

}  // namespace

bool is_dicom_file(const std::string& path) {
    return std::filesystem::is_regular_file(path) && has_dicom_preamble(path);
}

namespace {

/// The ROIs of the Structure Set ROI Sequence (number and name) into `result`, indexed by number
/// in `by_number`; returns their one frame of reference.
std::string read_rois(DcmDataset& d,
                      const std::string& path,
                      RawContourSet& result,
                      std::map<std::int32_t, std::size_t>& by_number) {
    // The frames of reference the structure set declares.
    std::vector<std::string> frames;
    DcmSequenceOfItems* frame_sequence = nullptr;
    if (d.findAndGetSequence(DCM_ReferencedFrameOfReferenceSequence, frame_sequence).good() &&
        frame_sequence != nullptr) {
        for (unsigned long i = 0; i < frame_sequence->card(); ++i) {
            frames.push_back(get_string(*frame_sequence->getItem(i), DCM_FrameOfReferenceUID));
        }
    }
    DcmSequenceOfItems* rois = nullptr;
    if (d.findAndGetSequence(DCM_StructureSetROISequence, rois).bad() || rois == nullptr) {
        fail(path, "no Structure Set ROI Sequence (3006,0020): expected one item per ROI");
    }
    std::string frame_uid;
    for (unsigned long i = 0; i < rois->card(); ++i) {
        DcmItem& item = *rois->getItem(i);
        const std::string where = "Structure Set ROI item " + std::to_string(i + 1);
        Sint32 number = 0;
        if (item.findAndGetSint32(DCM_ROINumber, number).bad()) {
            fail(path, where + ": no ROI Number (3006,0022)");
        }
        if (by_number.count(number) != 0) {
            fail(path, where + ": ROI Number " + std::to_string(number) + " appears twice");
        }
        const std::string frame = get_string(item, DCM_ReferencedFrameOfReferenceUID);
        if (frame.empty()) {
            fail(path, where + " (ROI " + std::to_string(number) +
                           "): no Referenced Frame of Reference UID (3006,0024)");
        }
        if (std::find(frames.begin(), frames.end(), frame) == frames.end()) {
            fail(path, where + " (ROI " + std::to_string(number) +
                           "): references frame of reference " + frame +
                           ", which the Referenced Frame of Reference Sequence (3006,0010) "
                           "does not declare");
        }
        if (!frame_uid.empty() && frame != frame_uid) {
            throw Error(ErrorCode::Unsupported, path + ": " + where +
                                                    ": ROIs in two frames of reference (" +
                                                    frame_uid + ", " + frame + "); expected one");
        }
        frame_uid = frame;
        RawRoi roi;
        roi.number = number;
        roi.name = get_string(item, DCM_ROIName);
        by_number[number] = result.rois.size();
        result.rois.push_back(std::move(roi));
    }
    return frame_uid;
}

/// The RT ROI Interpreted Type of each ROI that has one.
void read_interpreted_types(DcmDataset& d,
                            RawContourSet& result,
                            std::map<std::int32_t, std::size_t>& by_number) {
    DcmSequenceOfItems* observations = nullptr;
    if (d.findAndGetSequence(DCM_RTROIObservationsSequence, observations).good() &&
        observations != nullptr) {
        for (unsigned long i = 0; i < observations->card(); ++i) {
            DcmItem& item = *observations->getItem(i);
            Sint32 number = 0;
            if (item.findAndGetSint32(DCM_ReferencedROINumber, number).good() &&
                by_number.count(number) != 0) {
                result.rois[by_number[number]].interpreted_type =
                    get_string(item, DCM_RTROIInterpretedType);
            }
        }
    }
}

/// Contour `c` of an ROI Contour item's Contour Sequence.
RawContour read_contour(DcmItem& contour,
                        const std::string& path,
                        const std::string& where,
                        unsigned long c) {
    RawContour raw;
    raw.where = where + ", contour " + std::to_string(c + 1);
    raw.geometric_type = get_string(contour, DCM_ContourGeometricType);
    if (!is_contour_geometric_type(raw.geometric_type)) {
        fail(path, raw.where + ": Contour Geometric Type '" + raw.geometric_type +
                       "', expected CLOSED_PLANAR, OPEN_PLANAR, OPEN_NONPLANAR or "
                       "POINT");
    }
    const std::vector<double> data = get_numbers(contour, DCM_ContourData, path, raw.where);
    if (data.empty()) {
        fail(path, raw.where + ": no Contour Data (3006,0050)");
    }
    if (data.size() % 3 != 0) {
        fail(path, raw.where + ": Contour Data has " + std::to_string(data.size()) +
                       " values, expected x, y, z triplets (a multiple of 3)");
    }
    Sint32 count = 0;
    if (contour.findAndGetSint32(DCM_NumberOfContourPoints, count).good() &&
        std::size_t(count) * 3 != data.size()) {
        fail(path, raw.where + ": Number of Contour Points is " + std::to_string(count) +
                       " but Contour Data holds " + std::to_string(data.size() / 3) + " points");
    }
    for (std::size_t p = 0; p < data.size(); p += 3) {
        raw.points.push_back({data[p], data[p + 1], data[p + 2]});
    }
    return raw;
}

/// The colour and contours of each ROI from the ROI Contour Sequence.
void read_roi_contours(DcmDataset& d,
                       const std::string& path,
                       RawContourSet& result,
                       std::map<std::int32_t, std::size_t>& by_number) {
    DcmSequenceOfItems* contours = nullptr;
    if (d.findAndGetSequence(DCM_ROIContourSequence, contours).good() && contours != nullptr) {
        for (unsigned long i = 0; i < contours->card(); ++i) {
            DcmItem& item = *contours->getItem(i);
            std::string where = "ROI Contour item " + std::to_string(i + 1);
            Sint32 number = 0;
            if (item.findAndGetSint32(DCM_ReferencedROINumber, number).bad()) {
                fail(path, where + ": no Referenced ROI Number (3006,0084)");
            }
            if (by_number.count(number) == 0) {
                fail(path, where + ": Referenced ROI Number " + std::to_string(number) +
                               " is not in the Structure Set ROI Sequence");
            }
            RawRoi& roi = result.rois[by_number[number]];
            where =
                "ROI " + std::to_string(number) + (roi.name.empty() ? "" : " (" + roi.name + ")");
            const std::vector<double> color = get_numbers(item, DCM_ROIDisplayColor, path, where);
            if (color.size() == 3 && std::all_of(color.begin(), color.end(),
                                                 [](double c) { return c >= 0.0 && c <= 255.0; })) {
                roi.color = ColorSrgb8{std::uint8_t(color[0]), std::uint8_t(color[1]),
                                       std::uint8_t(color[2])};
            } else if (!color.empty()) {
                fail(path, where + ": ROI Display Color (3006,002A) must be 3 values 0-255");
            }
            DcmSequenceOfItems* sequence = nullptr;
            if (item.findAndGetSequence(DCM_ContourSequence, sequence).bad() ||
                sequence == nullptr) {
                continue;  // note: an ROI without contours; cleaning reports it
            }
            for (unsigned long c = 0; c < sequence->card(); ++c) {
                roi.contours.push_back(read_contour(*sequence->getItem(c), path, where, c));
            }
        }
    }
}

/// The reference grid: the given CT, else a CT beside the RTSTRUCT in the same frame.
std::optional<PlaneGrid> find_reference_grid(const std::string& path,
                                             const std::string& reference_ct,
                                             const std::string& frame_uid) {
    std::optional<PlaneGrid> reference;
    std::vector<std::filesystem::path> candidates;
    bool required = false;
    if (!reference_ct.empty()) {
        required = true;
        if (std::filesystem::is_directory(reference_ct)) {
            for (const auto& entry : std::filesystem::directory_iterator(reference_ct)) {
                candidates.push_back(entry.path());
            }
        } else {
            candidates.push_back(reference_ct);
        }
    } else {
        const std::filesystem::path folder = std::filesystem::path(path).parent_path();
        for (const auto& entry :
             std::filesystem::directory_iterator(folder.empty() ? "." : folder)) {
            candidates.push_back(entry.path());
        }
    }
    std::sort(candidates.begin(), candidates.end());
    for (const std::filesystem::path& candidate : candidates) {
        if (std::filesystem::equivalent(candidate, path) || !is_dicom_file(candidate.string())) {
            continue;
        }
        DcmFileFormat ct;
        DcmDataset& cd = *load(ct, candidate.string());
        if (get_string(cd, DCM_FrameOfReferenceUID) != frame_uid) {
            if (required && !std::filesystem::is_directory(reference_ct)) {
                fail(candidate.string(), "frame of reference " +
                                             get_string(cd, DCM_FrameOfReferenceUID) +
                                             " differs from the RTSTRUCT's " + frame_uid);
            }
            continue;
        }
        reference = image_grid(cd, candidate.string(), required);
        if (reference) {
            break;
        }
    }
    if (required && !reference) {
        fail(reference_ct, "no image slice in frame of reference " + frame_uid);
    }
    return reference;
}

}  // namespace

RawContourSet read_rtstruct(const std::string& path, const std::string& reference_ct) {
    DcmFileFormat file;
    DcmDataset& d = *load(file, path);
    RawContourSet result;
    result.source = path;
    result.frame = "LPS";
    const std::string modality = get_string(d, DCM_Modality);
    const std::string sop_class = get_string(d, DCM_SOPClassUID);
    if (modality != "RTSTRUCT" && sop_class != UID_RTStructureSetStorage) {
        throw Error(ErrorCode::Unsupported,
                    path + ": a DICOM file of modality '" + modality +
                        "', not an RTSTRUCT (expected Modality RTSTRUCT, SOP Class "
                        "1.2.840.10008.5.1.4.1.1.481.3); label images are read from NIfTI, "
                        "NRRD or image folders");
    }
    std::map<std::int32_t, std::size_t> by_number;
    const std::string frame_uid = read_rois(d, path, result, by_number);
    read_interpreted_types(d, result, by_number);
    read_roi_contours(d, path, result, by_number);
    result.reference = find_reference_grid(path, reference_ct, frame_uid);
    return result;
}

}  // namespace strata::detail
