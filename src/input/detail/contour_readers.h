#pragma once

// Planar contour readers behind read_raw_contours(); internal to strata_input.

#include <string>
#include <string_view>

#include "input/planar_contours.h"

namespace strata::detail {

/// True for a DICOM Contour Geometric Type strata reads: CLOSED_PLANAR, OPEN_PLANAR,
/// OPEN_NONPLANAR or POINT (RawContour::geometric_type).
inline bool is_contour_geometric_type(std::string_view type) {
    return type == "CLOSED_PLANAR" || type == "OPEN_PLANAR" || type == "OPEN_NONPLANAR" ||
           type == "POINT";
}

/// True when `path` is a file with the DICOM preamble ("DICM" at byte 128).
bool is_dicom_file(const std::string& path);

/// DICOM RTSTRUCT (DCMTK dcmdata): every ROI with number, name, ROI Display Color, RT ROI
/// Interpreted Type and its contours; the reference grid from `reference_ct` (a file or a
/// folder) or from a CT in the RTSTRUCT's folder with the same Frame of Reference UID.
RawContourSet read_rtstruct(const std::string& path, const std::string& reference_ct);

/// Contour JSON ("format": "planar contours v1", schema/contours.schema.json).
RawContourSet read_contour_json(const std::string& path);

}  // namespace strata::detail
