#pragma once

#include <string>
#include <vector>

#include "contours/extract_contours.h"
#include "contours/slice_contours.h"
#include "core/progress.h"
#include "core/report.h"
#include "distance/distance_field.h"
#include "input/slice_stack.h"
#include "medial/medial_axis.h"

namespace strata {

/// Options of the whole reconstruction, one struct per stage.
struct ReconstructOptions {
    ContourOptions contours;
    DistanceOptions distance;
    MedialOptions medial;
    unsigned threads = 0;  ///< worker threads of every stage, 0 = all cores
    ProgressFn progress;   ///< stage progress (may be empty)
};

/// Wall time of one stage.
struct StageTiming {
    std::string stage;
    double seconds = 0.0;
};

/// Everything the pipeline produced, stage by stage.
struct Reconstruction {
    SliceContours contours;
    std::vector<SliceDistanceFields> fields;  ///< one per slice
    std::vector<MedialAxis> medial_axes;      ///< one per consecutive slice pair
    std::vector<StageTiming> timings;
};

/// Runs the pipeline stages in order on `stack` (the only code that knows the stage order).
/// Notes degenerate input in `report`. Throws strata::Error from the stages.
Reconstruction reconstruct(const SliceStack& stack,
                           const ReconstructOptions& options,
                           Report& report);

}  // namespace strata
