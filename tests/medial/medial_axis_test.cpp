#include "medial/medial_axis.h"

#include <cmath>
#include <limits>

#include <gtest/gtest.h>

#include "contours/extract_contours.h"
#include "distance/distance_field.h"
#include "phantom/catalogue.h"

namespace strata {
namespace {

/// A stack whose slices are unions of discs: each disc is (slice, cx, cy, r, label); pixel
/// centres within r are foreground.
struct Disc {
    std::uint32_t slice;
    double cx, cy, r;
    std::uint16_t label = 1;
    bool hole = false;  ///< carve instead of fill
};

SliceStack disc_stack(std::uint32_t size, std::uint32_t depth, const std::vector<Disc>& discs) {
    SliceStack s;
    s.width = size;
    s.height = size;
    s.depth = depth;
    s.labels.assign(s.slice_size() * depth, 0);
    for (const Disc& d : discs) {
        for (std::uint32_t j = 0; j < size; ++j) {
            for (std::uint32_t i = 0; i < size; ++i) {
                const double dx = i + 0.5 - d.cx;
                const double dy = j + 0.5 - d.cy;
                if (dx * dx + dy * dy <= d.r * d.r) {
                    s.labels[(std::size_t(d.slice) * size + j) * size + i] = d.hole ? 0 : d.label;
                }
            }
        }
    }
    complete_label_table(s);
    return s;
}

struct Pipeline {
    SliceContours contours;
    std::vector<SliceDistanceFields> fields;
    std::vector<MedialAxis> axes;
};

Pipeline run(const SliceStack& stack) {
    Pipeline p;
    p.contours = extract_contours(stack, ContourOptions{});
    p.fields = compute_distance_fields(stack, p.contours, DistanceOptions{});
    p.axes = extract_medial_axes(p.contours, p.fields, MedialOptions{});
    return p;
}

double curve_area(const MedialCurve& c) {
    double a = 0;
    for (std::size_t i = 0; i < c.points.size(); ++i) {
        const Vec2 u = c.points[i].position;
        const Vec2 v = c.points[(i + 1) % c.points.size()].position;
        a += u.x * v.y - v.x * u.y;
    }
    return a / 2;
}

/// Every correspondence is (nearly) the nearest site of its slice, checked by brute force over
/// every contour point and segment midpoint of the label, and the recorded distances are exact.
void check_correspondences(const Pipeline& p) {
    for (const MedialAxis& axis : p.axes) {
        const SliceContourSet& lower = p.contours.slices[axis.lower_slice];
        const SliceContourSet& upper = p.contours.slices[axis.lower_slice + 1];
        for (const MedialCurve& curve : axis.curves) {
            for (const MedialPoint& m : curve.points) {
                for (int side = 0; side < 2; ++side) {
                    const SliceContourSet& set = side == 0 ? lower : upper;
                    const ContourSite& site = side == 0 ? m.lower : m.upper;
                    const double recorded = side == 0 ? m.lower_distance_px : m.upper_distance_px;
                    ASSERT_EQ(set.contours.at(site.contour).label, curve.label);
                    const double d = norm(m.position - site_position(set, site));
                    EXPECT_NEAR(d, recorded, 1e-9);
                    double best = std::numeric_limits<double>::infinity();
                    for (const Contour& c : set.contours) {
                        if (c.label != curve.label) {
                            continue;
                        }
                        for (std::size_t i = 0; i < c.points.size(); ++i) {
                            const Vec2 a = c.points[i];
                            const Vec2 b = c.points[(i + 1) % c.points.size()];
                            best = std::min(
                                {best, norm(m.position - a), norm(m.position - 0.5 * (a + b))});
                        }
                    }
                    // candidates come from the two grid nodes around the point: within 0.5 px
                    EXPECT_LE(d, best + 0.5 + 1e-9);
                }
                // on the medial axis both distances agree (interpolated zero of D_k + D_k+1)
                EXPECT_NEAR(m.lower_distance_px, m.upper_distance_px, 1.0);
            }
        }
    }
}

TEST(MedialAxis, ConcentricCirclesGiveTheMeanRadius) {
    const Pipeline p = run(disc_stack(128, 2, {{0, 64, 64, 20}, {1, 64, 64, 30}}));
    ASSERT_EQ(p.axes.size(), 1u);
    ASSERT_EQ(p.axes[0].curves.size(), 1u);
    const MedialCurve& curve = p.axes[0].curves[0];
    EXPECT_GT(curve_area(curve), 0.0);  // counter-clockwise like an outer contour
    double worst = 0;
    for (const MedialPoint& m : curve.points) {
        worst = std::max(worst, std::abs(norm(m.position - Vec2{64, 64}) - 25.0));
    }
    EXPECT_LE(worst, 0.5);
    EXPECT_TRUE(p.axes[0].unmatched.empty());
    check_correspondences(p);
}

TEST(MedialAxis, ShiftedCirclesGiveTheMidwayCircle) {
    const Pipeline p = run(disc_stack(128, 2, {{0, 54, 64, 20}, {1, 64, 64, 20}}));
    ASSERT_EQ(p.axes[0].curves.size(), 1u);
    double worst = 0;
    for (const MedialPoint& m : p.axes[0].curves[0].points) {
        worst = std::max(worst, std::abs(norm(m.position - Vec2{59, 64}) - 20.0));
    }
    EXPECT_LE(worst, 1.0);  // D_k + D_k+1 = 0 is not exactly a circle, but close
    check_correspondences(p);
}

TEST(MedialAxis, RingGivesOuterAndClockwiseInnerCurve) {
    const Pipeline p = run(disc_stack(
        128, 2,
        {{0, 64, 64, 40}, {0, 64, 64, 20, 1, true}, {1, 64, 64, 40}, {1, 64, 64, 10, 1, true}}));
    ASSERT_EQ(p.axes[0].curves.size(), 2u);
    int clockwise = 0;
    for (const MedialCurve& c : p.axes[0].curves) {
        if (curve_area(c) < 0) {
            ++clockwise;
            for (const MedialPoint& m : c.points) {
                EXPECT_NEAR(norm(m.position - Vec2{64, 64}), 15.0, 0.6);
            }
        }
    }
    EXPECT_EQ(clockwise, 1);
    check_correspondences(p);
}

TEST(MedialAxis, VanishingContourIsUnmatchedWhole) {
    // disc B exists on slice 0 only: no medial curve reaches it
    const Pipeline p = run(disc_stack(128, 2, {{0, 40, 64, 15}, {0, 95, 64, 10}, {1, 40, 64, 15}}));
    ASSERT_EQ(p.axes[0].curves.size(), 1u);
    const SliceContourSet& lower = p.contours.slices[0];
    ASSERT_EQ(lower.contours.size(), 2u);
    bool whole = false;
    for (const UnmatchedRun& run : p.axes[0].unmatched) {
        const Contour& c = (run.on_upper ? p.contours.slices[1] : lower).contours[run.contour];
        if (!run.on_upper && run.count == c.points.size() && c.points[0].x > 80) {
            whole = true;
        }
    }
    EXPECT_TRUE(whole);
}

TEST(MedialAxis, LabelAbsentOnNextSliceIsUnmatched) {
    const Pipeline p = run(disc_stack(64, 2, {{0, 32, 32, 10, 2}, {1, 32, 32, 10, 1}}));
    EXPECT_TRUE(p.axes[0].curves.empty());
    ASSERT_EQ(p.axes[0].unmatched.size(), 2u);  // both contours, whole
}

TEST(MedialAxis, BranchingOneToTwoCoversBothArms) {
    // an ellipse-like union on slice 0 splits into two discs on slice 1
    const Pipeline p = run(
        disc_stack(128, 2, {{0, 50, 64, 18}, {0, 78, 64, 18}, {1, 46, 64, 14}, {1, 82, 64, 14}}));
    ASSERT_FALSE(p.axes[0].curves.empty());
    // every upper contour has correspondences
    std::vector<bool> seen(p.contours.slices[1].contours.size(), false);
    for (const MedialCurve& c : p.axes[0].curves) {
        for (const MedialPoint& m : c.points) {
            seen[m.upper.contour] = true;
        }
    }
    for (bool s : seen) {
        EXPECT_TRUE(s);
    }
    check_correspondences(p);
}

TEST(MedialAxis, StarTipsHaveNoCorrespondence) {
    const Phantom star = make_phantom("t07_star_to_circle");
    const Pipeline p = run(star.stack);
    ASSERT_FALSE(p.axes.empty());
    int lower_runs = 0;
    for (const UnmatchedRun& run : p.axes[0].unmatched) {
        lower_runs += (!run.on_upper && run.count >= 3) ? 1 : 0;
    }
    EXPECT_GE(lower_runs, 1);
    check_correspondences(p);
}

TEST(MedialAxis, DeterministicForAnyThreadCount) {
    const Phantom y = make_phantom("t13_y_branch_1to2");
    const SliceContours contours = extract_contours(y.stack, ContourOptions{});
    DistanceOptions d1;
    d1.threads = 1;
    const auto fields = compute_distance_fields(y.stack, contours, d1);
    MedialOptions one;
    one.threads = 1;
    MedialOptions many;
    many.threads = 4;
    const auto a = extract_medial_axes(contours, fields, one);
    const auto b = extract_medial_axes(contours, fields, many);
    ASSERT_EQ(a.size(), b.size());
    for (std::size_t k = 0; k < a.size(); ++k) {
        ASSERT_EQ(a[k].curves.size(), b[k].curves.size());
        for (std::size_t c = 0; c < a[k].curves.size(); ++c) {
            ASSERT_EQ(a[k].curves[c].points.size(), b[k].curves[c].points.size());
            for (std::size_t i = 0; i < a[k].curves[c].points.size(); ++i) {
                EXPECT_EQ(a[k].curves[c].points[i].position, b[k].curves[c].points[i].position);
                EXPECT_EQ(a[k].curves[c].points[i].lower, b[k].curves[c].points[i].lower);
            }
        }
        EXPECT_EQ(a[k].unmatched.size(), b[k].unmatched.size());
    }
}

}  // namespace
}  // namespace strata
