#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "core/report.h"
#include "core/types.h"

namespace strata {

/// One contour as a file gives it: points in patient LPS mm (DICOM ContourData, or a contour
/// JSON plane's [x, y] at its z), before any cleaning.
struct RawContour {
    std::vector<Vec3> points;
    /// DICOM Contour Geometric Type: "CLOSED_PLANAR", "OPEN_PLANAR", "OPEN_NONPLANAR", "POINT".
    std::string geometric_type = "CLOSED_PLANAR";
    std::string where;  ///< for messages: "ROI 3 (Heart), contour 12"
};

/// One structure (ROI) as a file gives it.
struct RawRoi {
    std::int32_t number = 0;          ///< ROI Number (DICOM) or "number" (JSON)
    std::string name;                 ///< ROI Name; may be empty in the file
    std::optional<ColorSrgb8> color;  ///< ROI Display Color, when given
    std::string interpreted_type;     ///< RT ROI Interpreted Type ("ORGAN", "PTV", ...)
    std::vector<RawContour> contours;
};

/// A pixel grid that planes can be placed on (a referenced CT slice): patient LPS mm.
struct PlaneGrid {
    Vec3 origin;            ///< centre of the first pixel (ImagePositionPatient)
    Vec3 row_direction;     ///< unit vector along a row (increasing column)
    Vec3 column_direction;  ///< unit vector down a column (increasing row)
    double pixel_mm[2]{};   ///< spacing along the row and along the column
    std::uint32_t columns = 0;
    std::uint32_t rows = 0;
};

/// Every contour of a structure set as read: the input of clean_planar_contours.
struct RawContourSet {
    std::string source;                  ///< file the contours came from
    std::string frame;                   ///< "LPS" (DICOM) or the file's declared frame text
    std::vector<RawRoi> rois;            ///< in file order
    std::optional<PlaneGrid> reference;  ///< a CT grid, when one was given or referenced
};

/// A contour on its plane, cleaned: a closed polygon in the plane's (u, v) mm coordinates,
/// first point not repeated, no repeated or collinear points, at least 3 points, non-zero area.
struct PlaneContour {
    std::vector<Vec2> points;
};

/// The contours of one structure on one plane.
struct ContourPlane {
    double w = 0.0;  ///< position along the planes' normal, mm
    std::vector<PlaneContour> contours;
};

/// One structure after cleaning: its closed contours by plane (sorted by w, one entry per plane
/// carrying contours), and its markers (POINT contours and points-only ROIs), patient LPS mm.
struct ContourObject {
    std::int32_t number = 0;
    std::string name;  ///< never empty ("ROI N" when the file has none)
    ColorSrgb8 color{};
    std::string interpreted_type;
    std::vector<ContourPlane> planes;
    std::vector<Vec3> markers;
};

/// Cleaned planar contours in a common plane frame: patient point p has plane coordinates
/// (u, v, w) = (dot(p - origin, axis_u), dot(p - origin, axis_v), dot(p - origin, normal)).
/// The axes are orthonormal and right-handed (normal = axis_u x axis_v); for untilted axial
/// planes axis_u = +x (L), axis_v = +y (P), normal = +z (S).
struct PlanarContours {
    std::string source;
    std::string frame;
    Vec3 origin;
    Vec3 axis_u{1, 0, 0};
    Vec3 axis_v{0, 1, 0};
    Vec3 normal{0, 0, 1};
    std::optional<PlaneGrid> reference;
    std::vector<ContourObject> objects;  ///< every ROI of the file, in file order
};

/// How clean_planar_contours treats near-degenerate input.
struct ContourCleaningOptions {
    /// Points closer than this (mm) are one point; the repeated one is removed.
    double duplicate_mm = 1e-3;
    /// A point whose distance to the segment between its neighbours is below this (mm) is
    /// collinear and removed.
    double collinear_mm = 1e-4;
    /// Largest distance (mm) of a contour's points from its plane before it is refused as not
    /// planar; smaller departures are projected onto the plane and reported.
    double max_off_plane_mm = 0.5;
    /// Contours whose planes are closer than this (mm) share one plane.
    double plane_merge_mm = 0.01;
};

/// Cleans raw contours into planes, each step explicit and reported in `report` (stage "input",
/// one warning per kind and structure with counts): the common plane normal (from the reference
/// grid, else the contours' own normals; tilted planes are kept tilted), projection of every
/// contour into it (off-plane points beyond `max_off_plane_mm` are an error), grouping into
/// planes, closing points repeated, repeated and collinear points removed, open contours
/// (OPEN_PLANAR) closed by their chord, contours of fewer than 3 points or zero area kept as
/// markers, POINT contours as markers, self-intersecting contours and keyhole cuts counted (the
/// even-odd rule gives their inside), uneven plane spacing and planes missing inside a
/// structure's range named, empty structures named. Nothing is dropped without a warning.
/// \throw Error{InvalidInput} for non-finite coordinates, contours far from planar, or planes
///        not parallel (normals more than 1 degree apart).
PlanarContours clean_planar_contours(const RawContourSet& raw,
                                     const ContourCleaningOptions& options,
                                     Report& report);

/// Keeps only the objects named by `selectors` (an ROI number like "5" or a name like "Heart",
/// case-insensitive), in file order. Throws Error{InvalidInput} for a selector that matches no
/// object, listing the available ones.
void select_contour_objects(PlanarContours& contours, const std::vector<std::string>& selectors);

/// Reads planar contours from a DICOM RTSTRUCT file or a contour JSON file (format by content:
/// the DICOM preamble's "DICM", else JSON). `reference_ct` (optional) is a CT slice file or a
/// folder holding one, whose grid becomes PlanarContours::reference; for an RTSTRUCT without it,
/// a CT file in the RTSTRUCT's folder whose Frame of Reference UID matches is used when present.
/// \throw Error{InvalidInput} for malformed files (with what, where, expected),
///        Error{Unsupported} for well-formed files of another kind, Error{Io} for unreadable ones.
RawContourSet read_raw_contours(const std::string& path, const std::string& reference_ct);

/// True when `path` is a file strata reads as planar contours: a DICOM file (preamble "DICM")
/// or a JSON file whose "format" is "planar contours v1".
bool is_planar_contour_file(const std::string& path);

}  // namespace strata
