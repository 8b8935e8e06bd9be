#pragma once

#include <cstdint>
#include <vector>

#include "contours/slice_contours.h"
#include "core/progress.h"
#include "distance/distance_field.h"

namespace strata {

/// One point of a medial curve with its correspondences on both slices.
struct MedialPoint {
    Vec2 position;                   ///< px, in the slice plane
    ContourSite lower;               ///< closest site on slice k (contour index in slice k's set)
    ContourSite upper;               ///< closest site on slice k+1
    std::uint32_t lower_edge = 0;    ///< simplified edge of `lower.contour` holding that site
    std::uint32_t upper_edge = 0;    ///< simplified edge of `upper.contour` holding that site
    double lower_distance_px = 0.0;  ///< |position - lower site|
    double upper_distance_px = 0.0;  ///< |position - upper site|
};

/// One closed medial curve: a component of the boundary of {D_k + D_k+1 < 0}, oriented with
/// that region on its left (counter-clockwise around regions, clockwise around their holes,
/// like the contours). The last point connects to the first.
struct MedialCurve {
    std::uint16_t label = 0;
    std::vector<MedialPoint> points;
};

/// A run of consecutive original contour points (cyclic, inclusive) that no medial point
/// corresponds to: the contour has no partner there (paper section 5, Fig. 7).
struct UnmatchedRun {
    bool on_upper = false;      ///< false: a contour of slice k, true: of slice k+1
    std::uint32_t contour = 0;  ///< contour index in that slice's set
    std::uint32_t first = 0;    ///< first point of the run
    std::uint32_t count = 0;    ///< number of points (the whole contour when it has no partner)
};

/// The medial axes between slices k and k+1, all labels.
struct MedialAxis {
    std::uint32_t lower_slice = 0;
    std::vector<MedialCurve> curves;      ///< sorted by label, then by first point
    std::vector<UnmatchedRun> unmatched;  ///< sorted by (on_upper, contour, first)
};

/// How much medial axis one label has over every slice pair (a build's summary reports it).
struct MedialCounts {
    std::uint16_t label = 0;
    std::uint64_t curves = 0;
    std::uint64_t points = 0;            ///< medial points of those curves
    std::uint64_t unmatched_runs = 0;    ///< contour runs without a correspondence
    std::uint64_t unmatched_points = 0;  ///< contour points in those runs
};

/// Adds each label's curves, points, unmatched runs and unmatched points in `axes` (the medial
/// axes of `contours`' slice pairs) to its entry of `counts`, sorted by label, making the
/// entries of labels not there yet. Counting the axes of label batches one after another gives
/// what counting their merge gives, so the axes can go once counted.
void count_medial_axes(const std::vector<MedialAxis>& axes,
                       const SliceContours& contours,
                       std::vector<MedialCounts>& counts);

/// Options of the medial stage.
struct MedialOptions {
    /// Consecutive medial points whose correspondences skip contour points farther than this
    /// from the chord between the two corresponding sites make a jump: the skipped points have
    /// no correspondence (px). Smaller skips (the inner corners of pixel staircases) count as
    /// corresponded.
    double jump_px = 1.5;
    unsigned threads = 0;  ///< worker threads, 0 = all cores; output identical for any count
    ProgressFn progress;   ///< called per slice pair (may be empty)
    /// The labels whose curves and unmatched runs are extracted, increasing; empty: every label.
    /// Each label's are the same whichever others are extracted (only their fields are read).
    std::vector<std::uint16_t> labels;
};

/// Extracts the medial axes between slices k and k+1 (paper section 4.2): for every label
/// present on both, the zero set of D_k + D_k+1 traced as closed curves with sub-node positions
/// (linear interpolation along grid edges), each point with its closest sites on both slices;
/// plus the contour runs of either slice without correspondence (whole contours where the label
/// is absent on the other slice).
MedialAxis extract_medial_axis(const SliceContourSet& lower,
                               const SliceContourSet& upper,
                               const SliceDistanceFields& lower_fields,
                               const SliceDistanceFields& upper_fields,
                               std::uint32_t k,
                               const MedialOptions& options);

/// The medial stage: every consecutive slice pair, in parallel.
std::vector<MedialAxis> extract_medial_axes(const SliceContours& contours,
                                            const std::vector<SliceDistanceFields>& fields,
                                            const MedialOptions& options);

}  // namespace strata
