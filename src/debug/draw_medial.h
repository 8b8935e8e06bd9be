#pragma once

#include <cstdint>

#include "contours/slice_contours.h"
#include "core/rgb_image.h"
#include "debug/draw_contours.h"
#include "distance/distance_field.h"
#include "medial/medial_axis.h"

namespace strata {

/// Debug picture of the medial axis between slices k and k+1 (like the paper's Fig. 4): the
/// summed field D_k + D_k+1 colour coded (blue negative, red positive, darker bands every 2 px),
/// the contours of slice k (yellow) and k+1 (cyan), the medial curves (white) and, for every
/// `correspondence_step`-th medial point, lines to its closest sites on slice k (green) and
/// k+1 (magenta).
RgbImage draw_medial_axis(const SliceContourSet& lower,
                          const SliceContourSet& upper,
                          const SliceDistanceFields& lower_fields,
                          const SliceDistanceFields& upper_fields,
                          const MedialAxis& axis,
                          const DebugView& view,
                          int correspondence_step = 8);

}  // namespace strata
