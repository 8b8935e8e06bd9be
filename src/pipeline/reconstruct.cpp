#include "pipeline/reconstruct.h"

#include <chrono>

namespace strata {

namespace {

class StageClock {
public:
    explicit StageClock(std::vector<StageTiming>& timings) : timings_(timings) {}
    void done(std::string stage) {
        const auto now = std::chrono::steady_clock::now();
        timings_.push_back({std::move(stage), std::chrono::duration<double>(now - last_).count()});
        last_ = now;
    }

private:
    std::vector<StageTiming>& timings_;
    std::chrono::steady_clock::time_point last_ = std::chrono::steady_clock::now();
};

}  // namespace

Reconstruction reconstruct(const SliceStack& stack,
                           const ReconstructOptions& options,
                           Report& report) {
    Reconstruction result;
    StageClock clock(result.timings);
    ContourOptions contour_options = options.contours;
    contour_options.threads = options.threads;
    if (!contour_options.progress) {
        contour_options.progress = options.progress;
    }
    result.contours = extract_contours(stack, contour_options);
    clock.done("contours");

    DistanceOptions distance_options = options.distance;
    distance_options.threads = options.threads;
    if (!distance_options.progress) {
        distance_options.progress = options.progress;
    }
    result.fields = compute_distance_fields(stack, result.contours, distance_options);
    clock.done("distance");

    MedialOptions medial_options = options.medial;
    medial_options.threads = options.threads;
    if (!medial_options.progress) {
        medial_options.progress = options.progress;
    }
    result.medial_axes = extract_medial_axes(result.contours, result.fields, medial_options);
    clock.done("medial");
    for (std::uint32_t k = 0; k < stack.depth; ++k) {
        if (result.contours.slices[k].contours.empty() && k > 0 && k + 1 < stack.depth &&
            !result.contours.slices[k - 1].contours.empty() &&
            !result.contours.slices[k + 1].contours.empty()) {
            report.warn("contours", "slice " + std::to_string(k),
                        "empty slice inside the stack: objects are split there");
        }
    }
    return result;
}

}  // namespace strata
