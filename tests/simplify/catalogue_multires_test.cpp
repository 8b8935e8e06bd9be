// Multiresolution models of every catalogue phantom (except T32, 4096 x 4096: too large here) and
// of real data from ../shared/data: the cut of every level and a few random cameras must be closed,
// oriented manifolds with the components and genera of the full-resolution surface, positive
// volume and no self-intersection (exact), within their declared error bound as measured by the
// independent oracle (test::measure_cut_error: exact distances to the original contours).
#include <algorithm>
#include <chrono>
#include <cstdint>
#include <iostream>
#include <limits>
#include <random>
#include <set>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "core/report.h"
#include "input/read_slice_stack.h"
#include "mesh/mesh_checks.h"
#include "mesh/self_intersection.h"
#include "phantom/catalogue.h"
#include "pipeline/reconstruct.h"
#include "simplify/multires_dag.h"
#include "support/cut_checks.h"
#include "support/test_paths.h"

namespace strata {
namespace {

/// What the checked cuts of one stack came to.
struct Tally {
    std::size_t cuts = 0;
    double max_ratio = 0.0;         ///< measured / declared error
    double max_coarse_ratio = 0.0;  ///< the same over cuts declaring more than level 0's bound
    std::uint32_t max_levels = 0;
    std::size_t triangles = 0;  ///< full-resolution triangles, all labels
};

/// Checks one cut of model `i` of `r`: closed oriented manifold, genera of the full-resolution
/// surface `genera`, positive volume, no self-intersection, oracle within the declared bound.
void check_cut(const Reconstruction& r,
               std::size_t i,
               const std::vector<int>& genera,
               const MultiresCut& cut,
               const std::string& what,
               Tally& tally) {
    SCOPED_TRACE(what);
    const TriMesh mesh = cut_mesh(r.models[i], cut);
    const test::CutErrorReport measured =
        test::expect_valid_cut(mesh, r, i, genera, cut.error_px, cut.fine_error_px);
    ++tally.cuts;
    if (cut.error_px > 0.0) {
        const double ratio = measured.max_px() / cut.error_px;
        tally.max_ratio = std::max(tally.max_ratio, ratio);
        if (cut.error_px > r.models[i].full_resolution_error_px) {
            tally.max_coarse_ratio = std::max(tally.max_coarse_ratio, ratio);
        }
    }
}

/// A camera at 1.05 to 6 times the radius of the box around `m`'s vertices from its centre,
/// in a uniformly random direction.
ScreenCamera random_camera(const MultiresMesh& m, std::mt19937& rng) {
    const Sphere box = test::box_sphere(m);
    std::normal_distribution<double> normal;
    Vec3 direction{normal(rng), normal(rng), normal(rng)};
    direction = (1.0 / std::max(norm(direction), 1e-12)) * direction;
    const double distance = std::uniform_real_distribution<double>(1.05, 6.0)(rng);
    ScreenCamera camera;
    camera.position = box.center + distance * box.radius * direction;
    return camera;
}

/// Reconstructs `stack` with clusters of 256 triangles and checks, for every label's model, the
/// cut of every level and of `cameras` random cameras (seeded 42). Surfaces that failed the
/// pipeline's verification (kept at one level) are left out and listed.
Tally check_stack(const SliceStack& stack, int cameras) {
    Report report;
    ReconstructOptions options;
    options.multires.cluster_triangles = 256;
    const Reconstruction r = reconstruct(stack, options, report);
    Tally tally;
    EXPECT_EQ(r.models.size(), r.surfaces.size());
    std::mt19937 rng(42);
    for (std::size_t i = 0; i < r.models.size(); ++i) {
        const ObjectSurface& surface = r.surfaces[i];
        SCOPED_TRACE("label " + std::to_string(surface.label));
        if (!surface.verification.ok()) {
            std::cout << "label " << surface.label << " skipped: surface failed verification ("
                      << surface.verification.problem << ")\n";
            continue;
        }
        const MultiresMesh& m = r.models[i];
        const std::vector<int> genera = test::sorted_genera(check_mesh(surface.mesh));
        const std::uint32_t levels = level_count(m);
        tally.max_levels = std::max(tally.max_levels, levels);
        tally.triangles += surface.mesh.triangles.size();
        std::set<std::vector<std::uint32_t>> seen;
        for (std::uint32_t level = 0; level < levels; ++level) {
            const MultiresCut cut = select_cut_at_level(m, level);
            seen.insert(cut.clusters);
            check_cut(r, i, genera, cut, "level " + std::to_string(level), tally);
        }
        for (int k = 0; k < cameras; ++k) {
            const ScreenCamera camera = random_camera(m, rng);
            const double max_screen_px = std::uniform_real_distribution<double>(0.5, 8.0)(rng);
            const MultiresCut cut = select_cut_for_camera(m, camera, max_screen_px);
            if (seen.insert(cut.clusters).second) {
                check_cut(
                    r, i, genera, cut,
                    "camera " + std::to_string(k) + " (" + std::to_string(max_screen_px) + " px)",
                    tally);
            }
        }
    }
    return tally;
}

void print(const std::string& name, const Tally& tally, double seconds) {
    std::cout << name << ": " << tally.triangles << " triangles, up to " << tally.max_levels
              << " levels, " << tally.cuts << " cuts; max measured / declared " << tally.max_ratio
              << " (coarser than level 0: " << tally.max_coarse_ratio << "); " << seconds << " s\n";
}

double seconds_since(std::chrono::steady_clock::time_point start) {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

class CatalogueMultires : public testing::TestWithParam<std::string> {};

TEST_P(CatalogueMultires, LevelAndCameraCutsAreValidWithinTheirBounds) {
    const auto start = std::chrono::steady_clock::now();
    const Tally tally = check_stack(make_phantom(GetParam()).stack, 2);
    print(GetParam(), tally, seconds_since(start));
}

std::vector<std::string> catalogue_cases() {
    std::vector<std::string> names = phantom_names();
    // note: T32 (4096 x 4096 x 10) is the large-data test's
    std::erase(names, "t32_huge_contour");
    return names;
}

INSTANTIATE_TEST_SUITE_P(Phantoms,
                         CatalogueMultires,
                         testing::ValuesIn(catalogue_cases()),
                         [](const testing::TestParamInfo<std::string>& param) {
                             return param.param;
                         });

/// `stack` with every label not in `keep` cleared (and dropped from the label table).
SliceStack keep_labels(SliceStack stack, const std::vector<std::uint16_t>& keep) {
    const auto kept = [&](std::uint16_t v) {
        return std::find(keep.begin(), keep.end(), v) != keep.end();
    };
    for (std::uint16_t& v : stack.labels) {
        if (!kept(v)) {
            v = 0;
        }
    }
    std::erase_if(stack.label_table, [&](const LabelInfo& l) { return !kept(l.value); });
    return stack;
}

TEST(SharedDataMultires, NiivueTorsoLevelCutsAreValidWithinTheirBounds) {
    const auto start = std::chrono::steady_clock::now();
    Report report;
    const SliceStack stack =
        read_slice_stack(test::shared_data_dir() / "niivue_torso/torsoLabel.nii.gz", {}, report);
    const std::vector<std::uint16_t> labels = present_labels(stack);
    ASSERT_GE(labels.size(), 3u);
    // The first, middle and last label present.
    const Tally tally = check_stack(
        keep_labels(stack, {labels.front(), labels[labels.size() / 2], labels.back()}), 0);
    print("niivue_torso (3 labels)", tally, seconds_since(start));
}

TEST(SharedDataMultires, PyradiomicsLungLevelCutsAreValidWithinTheirBounds) {
    const auto start = std::chrono::steady_clock::now();
    Report report;
    const SliceStack stack = read_slice_stack(
        test::shared_data_dir() / "pyradiomics_lung_tumor/lung2_label.nrrd", {}, report);
    const Tally tally = check_stack(stack, 0);
    print("pyradiomics_lung_tumor", tally, seconds_since(start));
}

}  // namespace
}  // namespace strata
