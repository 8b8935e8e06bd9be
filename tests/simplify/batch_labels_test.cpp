// reconstruct() takes the labels through the stages in batches (ReconstructOptions::
// batch_labels) so that one batch's distance fields and medial axes are in memory at a time:
// the surfaces, models, medial axes and warnings are the same for any batch size (the batches
// take the labels with the most contour points first, so results come out of label order and
// are put back in it).

#include <array>
#include <map>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "phantom/catalogue.h"
#include "pipeline/reconstruct.h"

namespace strata {
namespace {

struct Built {
    Reconstruction result;
    std::vector<std::string> warnings;
};

Built build(const SliceStack& stack, std::size_t batch_labels, bool keep_medial_axes = true) {
    ReconstructOptions options;
    options.keep_fields = false;
    options.keep_medial_axes = keep_medial_axes;
    options.batch_labels = batch_labels;
    options.threads = 2;
    Built b;
    Report report;
    b.result = reconstruct(stack, options, report);
    for (const Warning& e : report.warnings) {
        b.warnings.push_back(e.stage + "|" + e.where + "|" + e.message);
    }
    return b;
}

void expect_same(const Built& a, const Built& b) {
    ASSERT_EQ(a.result.surfaces.size(), b.result.surfaces.size());
    ASSERT_EQ(a.result.models.size(), b.result.models.size());
    for (std::size_t i = 0; i < a.result.surfaces.size(); ++i) {
        const ObjectSurface& s = a.result.surfaces[i];
        const ObjectSurface& t = b.result.surfaces[i];
        EXPECT_EQ(s.label, t.label);
        EXPECT_EQ(s.grid_step, t.grid_step);
        ASSERT_EQ(s.mesh.positions.size(), t.mesh.positions.size()) << "label " << s.label;
        for (std::size_t v = 0; v < s.mesh.positions.size(); ++v) {
            EXPECT_EQ(s.mesh.positions[v].x, t.mesh.positions[v].x);
            EXPECT_EQ(s.mesh.positions[v].y, t.mesh.positions[v].y);
            EXPECT_EQ(s.mesh.positions[v].z, t.mesh.positions[v].z);
        }
        EXPECT_EQ(s.mesh.triangles, t.mesh.triangles) << "label " << s.label;
        const MultiresMesh& m = a.result.models[i];
        const MultiresMesh& n = b.result.models[i];
        ASSERT_EQ(m.clusters.size(), n.clusters.size()) << "label " << s.label;
        for (std::size_t c = 0; c < m.clusters.size(); ++c) {
            EXPECT_EQ(m.clusters[c].vertices, n.clusters[c].vertices);
            EXPECT_EQ(m.clusters[c].triangles, n.clusters[c].triangles);
        }
        ASSERT_EQ(m.groups.size(), n.groups.size());
        for (std::size_t g = 0; g < m.groups.size(); ++g) {
            EXPECT_EQ(m.groups[g].error_px, n.groups[g].error_px);
        }
    }
    ASSERT_EQ(a.result.medial_axes.size(), b.result.medial_axes.size());
    for (std::size_t k = 0; k < a.result.medial_axes.size(); ++k) {
        const MedialAxis& x = a.result.medial_axes[k];
        const MedialAxis& y = b.result.medial_axes[k];
        ASSERT_EQ(x.curves.size(), y.curves.size()) << "pair " << k;
        for (std::size_t c = 0; c < x.curves.size(); ++c) {
            EXPECT_EQ(x.curves[c].label, y.curves[c].label);
            EXPECT_EQ(x.curves[c].points.size(), y.curves[c].points.size());
        }
        ASSERT_EQ(x.unmatched.size(), y.unmatched.size()) << "pair " << k;
        for (std::size_t r = 0; r < x.unmatched.size(); ++r) {
            EXPECT_EQ(x.unmatched[r].on_upper, y.unmatched[r].on_upper);
            EXPECT_EQ(x.unmatched[r].contour, y.unmatched[r].contour);
            EXPECT_EQ(x.unmatched[r].first, y.unmatched[r].first);
            EXPECT_EQ(x.unmatched[r].count, y.unmatched[r].count);
        }
    }
    ASSERT_EQ(a.result.medial_counts.size(), b.result.medial_counts.size());
    for (std::size_t i = 0; i < a.result.medial_counts.size(); ++i) {
        const MedialCounts& x = a.result.medial_counts[i];
        const MedialCounts& y = b.result.medial_counts[i];
        EXPECT_EQ(x.label, y.label);
        EXPECT_EQ(x.curves, y.curves);
        EXPECT_EQ(x.points, y.points);
        EXPECT_EQ(x.unmatched_runs, y.unmatched_runs);
        EXPECT_EQ(x.unmatched_points, y.unmatched_points);
    }
    EXPECT_EQ(a.warnings, b.warnings);
    std::vector<std::string> stages_a, stages_b;
    for (const StageTiming& t : a.result.timings) {
        stages_a.push_back(t.stage);
    }
    for (const StageTiming& t : b.result.timings) {
        stages_b.push_back(t.stage);
    }
    EXPECT_EQ(stages_a, stages_b);
}

TEST(BatchLabels, SameOutputForAnyBatchSize) {
    // the demo scene (4 labels, touching and nested objects) with one more label on the slices
    // of the others, so batches split labels that share slices and contour sets
    SliceStack stack = make_phantom("scene").stack;
    for (std::uint32_t k = 10; k < 30; ++k) {
        for (std::uint32_t j = 60; j < 80; ++j) {
            for (std::uint32_t i = 5; i < 25; ++i) {
                stack.labels[(std::size_t(k) * stack.height + j) * stack.width + i] = 9;
            }
        }
    }
    stack.label_table.push_back({9, "box", palette_color(9)});
    const Built all = build(stack, 0);
    ASSERT_EQ(all.result.surfaces.size(), 5u);
    for (std::size_t batch : {1u, 2u, 3u}) {
        SCOPED_TRACE("batch " + std::to_string(batch));
        expect_same(all, build(stack, batch));
    }
}

TEST(BatchLabels, MedialCountsWithoutTheAxesAreThoseOfTheKeptAxes) {
    // batches of one label: each batch's axes are counted and freed, and the counts must be
    // what counting every kept axis of a one-batch build gives
    const SliceStack stack = make_phantom("scene").stack;
    const Built kept = build(stack, 0);
    const Built freed = build(stack, 1, false);
    EXPECT_TRUE(freed.result.medial_axes.empty());
    std::map<std::uint16_t, std::array<std::uint64_t, 4>> expected;
    for (const MedialAxis& axis : kept.result.medial_axes) {
        for (const MedialCurve& curve : axis.curves) {
            expected[curve.label][0] += 1;
            expected[curve.label][1] += curve.points.size();
        }
        for (const UnmatchedRun& run : axis.unmatched) {
            const SliceContourSet& set =
                kept.result.contours.slices[axis.lower_slice + (run.on_upper ? 1 : 0)];
            const std::uint16_t label = set.contours[run.contour].label;
            expected[label][2] += 1;
            expected[label][3] += run.count;
        }
    }
    ASSERT_EQ(expected.size(), 4u);  // the scene's four labels
    ASSERT_EQ(freed.result.medial_counts.size(), expected.size());
    std::size_t i = 0;
    for (const auto& [label, counts] : expected) {
        const MedialCounts& c = freed.result.medial_counts[i++];
        EXPECT_EQ(c.label, label);
        EXPECT_EQ(c.curves, counts[0]) << "label " << label;
        EXPECT_EQ(c.points, counts[1]) << "label " << label;
        EXPECT_EQ(c.unmatched_runs, counts[2]) << "label " << label;
        EXPECT_EQ(c.unmatched_points, counts[3]) << "label " << label;
        EXPECT_GT(c.points, 0u) << "label " << label;
    }
}

}  // namespace
}  // namespace strata
