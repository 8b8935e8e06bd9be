// Written bounding spheres are rounded up (issue 24): the DAG table stores each group's sphere as
// float32, and a viewer's screen-space error and region tests rely on it containing the group
// (schema/README.md: "radii rounded up so that each still contains its exact sphere"). The reader
// checks containment with a relative slack of 1e-6 (for other writers), which rounding to the
// nearest float passes; here, without slack, every written sphere must contain the exact sphere
// it was written from (computed here from the model in memory and the file's own node matrices)
// and every decoded vertex of its clusters.
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "exporters/progressive_gltf.h"
#include "exporters/read_progressive_gltf.h"
#include "phantom/catalogue.h"
#include "pipeline/reconstruct.h"
#include "support/test_paths.h"

namespace strata {
namespace {

namespace fs = std::filesystem;

/// `m` (column-major 4 x 4, as glTF) applied to a point, in binary64.
std::array<double, 3> apply(const std::array<double, 16>& m, double x, double y, double z) {
    std::array<double, 3> out{};
    for (int k = 0; k < 3; ++k) {
        out[k] = m[12 + k] + m[k] * x + m[4 + k] * y + m[8 + k] * z;
    }
    return out;
}

double distance(const std::array<double, 3>& a, const std::array<double, 3>& b) {
    return std::hypot(a[0] - b[0], a[1] - b[1], a[2] - b[2]);
}

struct Frame {
    std::string name;
    SliceFrame frame;
};

TEST(SphereRounding, WrittenSpheresContainTheirExactSpheresAndVerticesWithoutSlack) {
    const Phantom phantom = make_phantom("torus");
    ReconstructOptions options;
    options.multires.cluster_triangles = 128;
    options.multires.root_triangles = 32;
    Report report;
    const Reconstruction result = reconstruct(phantom.stack, options, report);
    ASSERT_EQ(result.models.size(), 1u);
    const MultiresMesh& model = result.models[0];
    ASSERT_GE(model.groups.size(), 8u);
    const double d = result.slice_spacing_px;
    // note: two frames, so that centres and radii round differently (a CT's, and one far from
    // its origin with uneven pixels)
    std::vector<Frame> frames(2);
    frames[0].name = "ct";
    frames[0].frame.linear = {0.7, 0, 0, 0, 0.7, 0, 0, 0, 0.7};
    frames[0].frame.origin = {-120.5, 33.25, 410.0};
    frames[0].frame.error_mm_per_px = 0.7;
    frames[1].name = "far";
    frames[1].frame.linear = {0.83, 0, 0, 0, 0.61, 0, 0, 0, 1.3};
    frames[1].frame.origin = {2345.125, -1777.3, 999.9};
    frames[1].frame.error_mm_per_px = 0.83;
    const fs::path dir = test::fresh_temp_dir("sphere_rounding");
    std::size_t checked = 0;
    for (Frame& f : frames) {
        SCOPED_TRACE(f.name);
        f.frame.slice_spacing_px = d;
        ProgressiveObject object;
        object.name = "torus";
        object.label = 1;
        object.srgb = {0.8, 0.5, 0.25};
        object.volume_ml = 1.0;
        object.model = &model;
        SceneInfo info;
        info.source = "phantom torus";
        info.generator = "strata test";
        const fs::path file = dir / (f.name + ".glb");
        write_progressive_gltf(file, {object}, f.frame, info);
        const ProgressiveFile read = read_progressive_gltf(file);
        ASSERT_EQ(read.objects.size(), 1u);
        const ProgressiveFileObject& o = read.objects[0];
        ASSERT_EQ(o.model.groups.size(), model.groups.size());
        // slice space -> storage frame: (x, y, z / d) (no mirror in these frames); the largest
        // stretch of slice space -> scene is the longest column of that map
        const std::array<double, 16>& m = o.to_scene;
        const double scale = std::max({std::hypot(m[0], m[1], m[2]), std::hypot(m[4], m[5], m[6]),
                                       std::hypot(m[8], m[9], m[10]) / d});
        for (std::size_t g = 0; g < model.groups.size(); ++g) {
            const Sphere& exact = model.groups[g].bounds;
            const Sphere& written = o.model.groups[g].bounds;
            ASSERT_EQ(o.model.groups[g].level, model.groups[g].level) << "group " << g;
            const std::array<double, 3> centre =
                apply(m, exact.center.x, exact.center.y, exact.center.z / d);
            const std::array<double, 3> stored{written.center.x, written.center.y,
                                               written.center.z};
            const double r = written.radius;
            // the frame map is right: the stored centre is the exact one rounded to float32
            EXPECT_LE(
                distance(stored, centre),
                1e-7 * std::max({std::abs(centre[0]), std::abs(centre[1]), std::abs(centre[2])}))
                << "group " << g;
            // note: 1e-12 relative covers this test's own binary64 arithmetic, not float32
            // rounding (about 6e-8 relative)
            EXPECT_LE(distance(stored, centre) + exact.radius * scale, r * (1.0 + 1e-12))
                << "group " << g << ": written radius " << r
                << " does not contain the exact sphere "
                << "(radius " << exact.radius * scale << ", centre moved by "
                << distance(stored, centre) << ")";
            for (const auto* list : {&o.model.groups[g].consumed, &o.model.groups[g].produced}) {
                for (const std::uint32_t c : *list) {
                    for (const std::uint32_t v : o.model.clusters[c].vertices) {
                        const Vec3 p = o.model.positions[v];
                        EXPECT_LE(distance(stored, apply(m, p.x, p.y, p.z)), r * (1.0 + 1e-12))
                            << "group " << g << ", cluster " << c << ", vertex " << v;
                    }
                }
            }
            ++checked;
        }
    }
    EXPECT_EQ(checked, 2 * model.groups.size());
}

}  // namespace
}  // namespace strata
