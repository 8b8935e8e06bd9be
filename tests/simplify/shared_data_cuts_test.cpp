// Every cut of the multiresolution models of the real data in ../shared/data, checked as it is
// drawn: each stack is reconstructed as `strata build` does (default options), written as a
// progressive glTF and read back, and the cuts are taken from the decoded file: those `strata
// extract` writes (uniform bounds of 0.25 to 4 mm), every level, random cameras, random regions
// of interest and random mixes (any set of refined groups, closed upwards: whatever a viewer can
// draw). Each must be, in the file's storage frame (what the viewer draws) and in LPS mm rounded
// to float32 (what `extract` writes to PLY/OBJ/STL), a closed, outward 2-manifold with the
// components and genera of the full-resolution surface, without self-intersections or
// degenerate triangles (exact check: find_self_intersections); and the same clusters of the
// in-memory model must lie within the declared bound by the independent oracle
// (test::measure_cut_error). And no group adds a fold (an edge over 90 degrees) to the part of
// the surface it simplifies. The small inputs here (the volcano also as planar contours, each
// structure on its own stack as `strata build` reconstructs planar contours); the torso,
// TotalSegmentator, the breast RTSTRUCT's contours and a sample of the FreeSurfer labels in
// large_data_cuts_test (`slow`).
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <iostream>
#include <map>
#include <random>
#include <set>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "core/report.h"
#include "exporters/progressive_gltf.h"
#include "exporters/read_progressive_gltf.h"
#include "input/planar_contours.h"
#include "input/read_slice_stack.h"
#include "mesh/mesh_checks.h"
#include "mesh/self_intersection.h"
#include "pipeline/reconstruct.h"
#include "pipeline/reconstruct_contours.h"
#include "simplify/multires_dag.h"
#include "support/cut_checks.h"
#include "support/test_paths.h"

namespace strata {
namespace {

namespace fs = std::filesystem;

/// `mesh` with every coordinate rounded to float32, as the mesh files store it.
TriMesh as_float32(TriMesh mesh) {
    for (Vec3& p : mesh.positions) {
        for (int a = 0; a < 3; ++a) {
            p[a] = double(float(p[a]));
        }
    }
    return mesh;
}

/// Folds among the edges shared by two triangles of `clusters` of `m` (slice space): edges whose
/// triangles' normals n, m have n . m < slack |n| |m| (slack 0: turning by more than 90 degrees).
std::size_t interior_folds(const MultiresMesh& m,
                           const std::vector<std::uint32_t>& clusters,
                           double slack) {
    std::map<std::pair<std::uint32_t, std::uint32_t>, std::vector<Vec3>> normals;
    for (const std::uint32_t c : clusters) {
        const MultiresCluster& cluster = m.clusters[c];
        for (const auto& t : cluster.triangles) {
            const std::array<std::uint32_t, 3> ids{cluster.vertices[t[0]], cluster.vertices[t[1]],
                                                   cluster.vertices[t[2]]};
            const Vec3 n = cross(m.positions[ids[1]] - m.positions[ids[0]],
                                 m.positions[ids[2]] - m.positions[ids[0]]);
            for (int i = 0; i < 3; ++i) {
                normals[{std::min(ids[i], ids[(i + 1) % 3]), std::max(ids[i], ids[(i + 1) % 3])}]
                    .push_back(n);
            }
        }
    }
    std::size_t folds = 0;
    for (const auto& [edge, n] : normals) {
        if (n.size() == 2 && dot(n[0], n[1]) < slack * norm(n[0]) * norm(n[1])) {
            ++folds;
        }
    }
    return folds;
}

/// Expects no group of `m` to have more folds (over 90 degrees) among the edges inside it after
/// its simplification than before (collapses may keep or remove folds, never add one).
void expect_no_fold_added(const MultiresMesh& m) {
    for (std::size_t g = 0; g < m.groups.size(); ++g) {
        const MultiresGroup& group = m.groups[g];
        // note: a hair of slack either way, so rounding of nearly right angles cannot decide
        const std::size_t before = interior_folds(m, group.consumed, 1e-9);
        const std::size_t after = interior_folds(m, group.produced, -1e-9);
        EXPECT_LE(after, before) << "group " << g << " (level " << group.level << ")";
    }
}

/// The sphere around every cluster sphere of the file's model (scene metres).
Sphere scene_sphere(const MultiresMesh& model) {
    Vec3 center;
    for (const MultiresCluster& c : model.clusters) {
        center = center + (1.0 / double(model.clusters.size())) * c.bounds.center;
    }
    double radius = 0.0;
    for (const MultiresCluster& c : model.clusters) {
        radius = std::max(radius, norm(c.bounds.center - center) + c.bounds.radius);
    }
    return {center, radius};
}

Vec3 random_direction(std::mt19937& rng) {
    std::normal_distribution<double> normal;
    const Vec3 d{normal(rng), normal(rng), normal(rng)};
    return (1.0 / std::max(norm(d), 1e-12)) * d;
}

struct Tally {
    std::size_t objects = 0;
    std::size_t cuts = 0;
    std::size_t triangles = 0;  ///< over every cut checked
};

/// Reconstructs `stack`, writes and reads back its progressive model and checks, per object, the
/// cuts `extract` writes, every level, and `random_cuts` each of camera, region and mixed cuts.
void check_stack(const SliceStack& stack, const std::string& name, int random_cuts, Tally& tally) {
    Report report;
    const Reconstruction r = reconstruct(stack, {}, report);
    std::vector<ProgressiveObject> objects;
    std::map<std::int64_t, std::size_t> surface_of;  // label -> index into r.surfaces
    for (std::size_t i = 0; i < r.surfaces.size(); ++i) {
        if (r.models[i].grid_step > 0.0 && !r.models[i].clusters.empty()) {
            ProgressiveObject object;
            object.name = "label " + std::to_string(r.surfaces[i].label);
            object.label = r.surfaces[i].label;
            object.srgb = {0.5, 0.5, 0.5};
            object.model = &r.models[i];
            objects.push_back(object);
            surface_of[r.surfaces[i].label] = i;
        }
    }
    ASSERT_FALSE(objects.empty()) << name << ": no object on a grid";
    const fs::path file = test::fresh_temp_dir("shared_data_cuts_" + name) / "model.glb";
    write_progressive_gltf(file, objects, slice_frame(stack, r.slice_spacing_px), SceneInfo{});
    const ProgressiveFile decoded = read_progressive_gltf(file);
    ASSERT_EQ(decoded.objects.size(), objects.size()) << name;
    std::mt19937 rng(17);
    for (const ProgressiveFileObject& object : decoded.objects) {
        SCOPED_TRACE(name + " label " + std::to_string(object.label));
        const std::size_t i = surface_of.at(object.label);
        const MultiresMesh& model = r.models[i];
        const MultiresMesh& read = object.model;
        // The file's clusters are the model's: the cluster ids of a cut select the same triangles.
        ASSERT_EQ(read.clusters.size(), model.clusters.size());
        ASSERT_EQ(read.groups.size(), model.groups.size());
        for (std::size_t c = 0; c < model.clusters.size(); ++c) {
            ASSERT_EQ(read.clusters[c].triangles.size(), model.clusters[c].triangles.size());
        }
        // the file's bounds against the finest level are the model's, rounded up with its errors
        // (3 significant digits: less than 1 % each)
        for (std::size_t g = 0; g < model.groups.size(); ++g) {
            EXPECT_LE(read.groups[g].fine_error_px, read.groups[g].error_px) << "group " << g;
            EXPECT_GE(
                read.groups[g].fine_error_px * (model.groups[g].error_px / read.groups[g].error_px),
                model.groups[g].fine_error_px * 0.989)
                << "group " << g;
        }
        const std::vector<int> genera = test::sorted_genera(check_mesh(r.surfaces[i].mesh));
        expect_no_fold_added(model);
        std::vector<std::pair<std::string, MultiresCut>> cuts;
        for (const double mm : {0.25, 0.5, 1.0, 2.0, 4.0}) {
            cuts.emplace_back("extract " + std::to_string(mm) + " mm",
                              select_cut_by_error(read, mm / 1000.0));
        }
        for (std::uint32_t level = 0; level < level_count(read); ++level) {
            cuts.emplace_back("level " + std::to_string(level), select_cut_at_level(read, level));
        }
        const Sphere all = scene_sphere(read);
        for (int k = 0; k < random_cuts; ++k) {
            ScreenCamera camera;
            const double distance = std::uniform_real_distribution<double>(1.05, 6.0)(rng);
            camera.position = all.center + distance * all.radius * random_direction(rng);
            const double pixels = std::uniform_real_distribution<double>(0.5, 8.0)(rng);
            cuts.emplace_back("camera " + std::to_string(k),
                              select_cut_for_camera(read, camera, pixels));
            const MultiresCluster& at = read.clusters[std::uniform_int_distribution<std::size_t>(
                0, read.clusters.size() - 1)(rng)];
            const Sphere region{at.bounds.center,
                                std::uniform_real_distribution<double>(0.0, 0.3)(rng) * all.radius};
            const double outside_mm = std::uniform_real_distribution<double>(0.5, 8.0)(rng);
            cuts.emplace_back("region " + std::to_string(k),
                              select_cut_in_region(read, region, 0.0, outside_mm / 1000.0));
            const double p = std::uniform_real_distribution<double>(0.1, 0.9)(rng);
            std::vector<char> refine(read.groups.size());
            for (char& g : refine) {
                g = std::bernoulli_distribution(p)(rng) ? 1 : 0;
            }
            cuts.emplace_back("mix " + std::to_string(k),
                              select_cut(read, [&](const MultiresGroup& g) {
                                  return refine[std::size_t(&g - read.groups.data())] != 0;
                              }));
        }
        std::set<std::vector<std::uint32_t>> seen;
        ++tally.objects;
        for (const auto& [what, cut] : cuts) {
            if (!seen.insert(cut.clusters).second) {
                continue;
            }
            SCOPED_TRACE(what);
            ++tally.cuts;
            const TriMesh storage = cut_mesh(read, cut);
            tally.triangles += storage.triangles.size();
            {
                SCOPED_TRACE("storage frame (as drawn)");
                test::expect_embedded_surface(storage, genera);
            }
            {
                SCOPED_TRACE("LPS mm, float32 (as extracted)");
                test::expect_embedded_surface(as_float32(file_cut_to_patient(object, cut)), genera);
            }
            // The same clusters in memory, slice space, against the declared bound (px).
            MultiresCut in_memory{cut.clusters, 0.0};
            for (const std::uint32_t c : cut.clusters) {
                const std::int32_t p = model.clusters[c].producer;
                in_memory.error_px =
                    std::max(in_memory.error_px, p < 0 ? model.full_resolution_error_px
                                                       : model.groups[std::size_t(p)].error_px);
                if (p >= 0) {
                    in_memory.fine_error_px = std::max(in_memory.fine_error_px,
                                                       model.groups[std::size_t(p)].fine_error_px);
                }
            }
            const TriMesh mesh = cut_mesh(model, in_memory);
            ASSERT_EQ(mesh.triangles.size(), storage.triangles.size());
            const test::CutErrorReport measured =
                test::measure_cut_error(mesh, r.contours, r.surfaces[i].label, r.slice_spacing_px);
            EXPECT_TRUE(measured.problems.empty())
                << (measured.problems.empty() ? std::string() : measured.problems.front());
            EXPECT_LE(measured.max_px(), in_memory.error_px + 1e-9)
                << "section " << measured.max_section_px << " px, cap " << measured.max_cap_px
                << " px, coverage " << measured.max_coverage_px << " px";
            // every full-resolution vertex within the bound against the finest level
            EXPECT_LE(test::max_point_distance_px(r.surfaces[i].mesh.positions, mesh),
                      in_memory.fine_error_px + 1e-9);
        }
    }
}

SliceStack read_stack(const fs::path& path) {
    Report report;
    return read_slice_stack(path, {}, report);
}

void run(const std::string& name, const SliceStack& stack, int random_cuts) {
    const auto start = std::chrono::steady_clock::now();
    Tally tally;
    check_stack(stack, name, random_cuts, tally);
    std::cout << name << ": " << tally.objects << " objects, " << tally.cuts << " cuts, "
              << tally.triangles << " triangles checked; "
              << std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count()
              << " s\n";
}

/// Every structure of a planar contour file (RTSTRUCT, contour JSON) on its own stack, as
/// reconstruct_contours builds it for `strata build` (scan-converted on the common frame's grid
/// at the default pitch), checked as above in that stack's slice space.
void run_contours(const std::string& name, const fs::path& path, int random_cuts) {
    Report report;
    const PlanarContours contours = clean_planar_contours(read_raw_contours(path.string(), ""),
                                                          ContourCleaningOptions{}, report);
    const ContourGridOptions grid;
    const ContourFrame frame = contour_frame(contours, grid, report);
    for (std::size_t i = 0; i < contours.objects.size(); ++i) {
        const ContourStack roi =
            contour_stack(contours.objects[i], frame.stack.label_table[i].value, frame, grid);
        if (roi.stack.depth > 0) {
            run(name + " " + contours.objects[i].name, roi.stack, random_cuts);
        }
    }
}

TEST(SharedDataCuts, PyradiomicsLungTumor) {
    run("pyradiomics_lung_tumor",
        read_stack(test::shared_data_dir() / "pyradiomics_lung_tumor/lung2_label.nrrd"), 6);
}

TEST(SharedDataCuts, PyradiomicsBrainTumor) {
    run("pyradiomics_brain_tumor",
        read_stack(test::shared_data_dir() / "pyradiomics_brain_tumor/brain1_label.nrrd"), 6);
}

TEST(SharedDataCuts, TerrainVolcano) {
    run("terrain_volcano", read_stack(test::shared_data_dir() / "terrain_volcano"), 6);
}

// The same terrain as planar contours (contours.json, the strata contour JSON).
TEST(SharedDataCuts, TerrainVolcanoContours) {
    run_contours("terrain_volcano/contours.json",
                 test::shared_data_dir() / "terrain_volcano/contours.json", 3);
}

// Folds on small models too: clusters of 256 triangles make many groups per surface.
TEST(SharedDataCuts, NoGroupAddsAFoldWithSmallClusters) {
    for (const char* input : {"pyradiomics_lung_tumor/lung2_label.nrrd", "terrain_volcano",
                              "pyradiomics_brain_tumor/brain1_label.nrrd"}) {
        SCOPED_TRACE(input);
        Report report;
        ReconstructOptions options;
        options.multires.cluster_triangles = 256;
        // note: at the default 0.2 levels shrink so fast that one of these surfaces has only 4
        // groups; the test was written with 0.35, where the brain tumour has 4 since its domes'
        // vertices rise by their triangles' shortfall (caps.cpp unbias_dome)
        options.multires.keep_fraction = 0.4;
        const Reconstruction r =
            reconstruct(read_stack(test::shared_data_dir() / input), options, report);
        for (const MultiresMesh& m : r.models) {
            EXPECT_GT(m.groups.size(), 4u);
            expect_no_fold_added(m);
        }
    }
}

#ifdef STRATA_LARGE_DATA
/// `stack` with every label but those in `keep` cleared.
SliceStack keep_labels(SliceStack stack, const std::vector<std::uint16_t>& keep) {
    std::vector<std::string> selectors;
    for (const std::uint16_t v : keep) {
        selectors.push_back(std::to_string(v));
    }
    select_labels(stack, selectors);
    return stack;
}

// The larger inputs (`slow`, Release only: about 2 min of CPU).
TEST(SharedDataCuts, NiivueTorso) {
    run("niivue_torso", read_stack(test::shared_data_dir() / "niivue_torso/torsoLabel.nii.gz"), 3);
}

TEST(SharedDataCuts, TotalSegmentatorAbdomen) {
    run("totalsegmentator_abdomen",
        read_stack(test::shared_data_dir() / "totalsegmentator_abdomen/example_seg.nii.gz"), 3);
}

// The breast RTSTRUCT's structures as contour JSON at the default pitch (0.58 mm): its leaned
// stack-end walls once met only after snapping to the grid (settle_end_leans checks the snapped
// positions since).
TEST(SharedDataCuts, DicompylerBreastRtstructContours) {
    run_contours("dicompyler_breast_rtstruct/contours.json",
                 test::shared_data_dir() / "dicompyler_breast_rtstruct/contours.json", 1);
}

// Every 32nd of the FreeSurfer parcellation's 188 labels (all of them take an hour here; the
// cortical ribbons are the largest surfaces of the data).
TEST(SharedDataCuts, FreesurferAparcAsegSampledLabels) {
    const SliceStack stack = read_stack(test::shared_data_dir() / "freesurfer_aparc_aseg");
    std::vector<std::uint16_t> keep;
    for (std::size_t i = 0; i < stack.label_table.size(); i += 32) {
        keep.push_back(stack.label_table[i].value);
    }
    run("freesurfer_aparc_aseg", keep_labels(stack, keep), 1);
}
#endif

}  // namespace
}  // namespace strata
