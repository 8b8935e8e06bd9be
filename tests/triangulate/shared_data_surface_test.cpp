// End to end on the real data of ../shared/data: every label of every file becomes a closed,
// outward 2-manifold without self-intersections, with the components and genus of the reference
// volume R. Checked here with the mesh core, the exact self-intersection test and the reference
// labeller, not with the pipeline's own verification (switched off). STRATA_LARGE_DATA selects
// the large cases (the 188-label parcellation, about 1.9 M triangles; the catalogue's 4096 x 4096
// T32), run outside the sanitizer build.
#include <algorithm>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "core/report.h"
#include "input/read_slice_stack.h"
#include "mesh/mesh_checks.h"
#include "mesh/self_intersection.h"
#include "phantom/catalogue.h"
#include "pipeline/reconstruct.h"
#include "support/reference_topology.h"
#include "support/test_paths.h"

namespace strata {
namespace {

// Independent checks of every surface of `stack`; returns the slabs split at the AND layer.
std::size_t check_surfaces(const SliceStack& stack) {
    Report report;
    ReconstructOptions options;
    options.simplify = false;  // surfaces only
    options.verify = false;
    const Reconstruction result = reconstruct(stack, options, report);
    EXPECT_EQ(result.surfaces.size(), present_labels(stack).size());
    std::size_t fallbacks = 0;
    for (const RepairRecord& repairs : result.repairs) {
        fallbacks += repairs.split_slabs;
    }
    for (const ObjectSurface& surface : result.surfaces) {
        SCOPED_TRACE("label " + std::to_string(surface.label));
        const MeshReport check = check_mesh(surface.mesh);
        EXPECT_TRUE(is_closed_manifold(check)) << check.problems.front();
        if (!is_closed_manifold(check)) {
            continue;
        }
        EXPECT_GT(check.signed_volume, 0.0);
        std::vector<int> genus;
        for (const MeshComponent& c : check.components) {
            genus.push_back(c.genus.value_or(-1));
        }
        std::vector<int> expected;
        for (const test::ReferenceSurface& s :
             test::reference_topology(stack, surface.label).surfaces) {
            expected.push_back(s.genus);
        }
        std::sort(genus.begin(), genus.end());
        std::sort(expected.begin(), expected.end());
        EXPECT_EQ(genus, expected);
        EXPECT_FALSE(has_self_intersections(surface.mesh));
        EXPECT_EQ(surface.topology_mismatches, 0u);
        EXPECT_EQ(surface.failed_slabs, 0u);
    }
    return fallbacks;
}

class SharedDataSurface : public testing::TestWithParam<std::string> {};

TEST_P(SharedDataSurface, EveryLabelIsAValidSurfaceWithReferenceTopology) {
    Report report;
    const SliceStack stack = read_slice_stack(test::shared_data_dir() / GetParam(), {}, report);
    const std::size_t fallbacks = check_surfaces(stack);
    std::cout << GetParam() << ": " << present_labels(stack).size() << " labels, " << fallbacks
              << " slabs split at the AND layer\n";
}

#ifdef STRATA_LARGE_DATA
INSTANTIATE_TEST_SUITE_P(Large, SharedDataSurface, testing::Values("freesurfer_aparc_aseg"));

// The catalogue's 4096 x 4096 case (T32), left out of the unit catalogue test for its size.
TEST(LargeCatalogueSurface, T32HugeContour) {
    check_surfaces(make_phantom("t32_huge_contour").stack);
}
#else
INSTANTIATE_TEST_SUITE_P(Files,
                         SharedDataSurface,
                         testing::Values("totalsegmentator_abdomen/example_seg.nii.gz",
                                         "niivue_torso/torsoLabel.nii.gz",
                                         "pyradiomics_lung_tumor/lung2_label.nrrd",
                                         "pyradiomics_brain_tumor/brain1_label.nrrd",
                                         "terrain_volcano"));
#endif

}  // namespace
}  // namespace strata
