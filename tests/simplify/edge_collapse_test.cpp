// collapse_edges on small hand-built surfaces, one test per rule and documented refusal of
// src/simplify/edge_collapse.h. Each fixture leaves one or a few collapses possible and the test
// computes on its own (normals, creases, collinearity, edges, the cut-error oracle) why the
// simplifier must take or refuse them.

#include "simplify/edge_collapse.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <map>
#include <numbers>
#include <set>
#include <utility>
#include <vector>

#include <gtest/gtest.h>

#include "contours/extract_contours.h"
#include "core/error.h"
#include "distance/distance_field.h"
#include "mesh/tri_mesh.h"
#include "simplify/slice_error.h"
#include "support/cut_error.h"

namespace strata {
namespace {

using Tri = std::array<std::uint32_t, 3>;
constexpr double kInfinity = std::numeric_limits<double>::infinity();

Vec3 normal_of(const std::vector<Vec3>& p, const Tri& t) {
    return cross(p[t[1]] - p[t[0]], p[t[2]] - p[t[0]]);
}

/// A closed box-like surface: the top face z = top_z is a 3x3 grid over the square of half
/// width `top_half` around (cx, cy), its centre raised by `raise`; the bottom face z = 0 the
/// same grid of half width `bottom_half`; the sides join the two rings of 8. Outward CCW.
struct Box {
    std::vector<Vec3> positions;
    std::vector<Tri> triangles;
    static constexpr std::uint32_t kTopCentre = 8;
    static constexpr std::uint32_t kBottomCentre = 17;
    /// Ring positions 0..7 CCW seen from above: corner, edge midpoint, corner, ...; the top ring
    /// has ids 0..7, the bottom ring 9..16.
    static bool is_midpoint(std::uint32_t ring_id) { return ring_id % 9 % 2 == 1; }
};

Box make_box(double top_half,
             double bottom_half,
             double top_z,
             double raise,
             double cx = 0.0,
             double cy = 0.0) {
    static const std::array<std::array<double, 2>, 8> ring{
        {{-1, -1}, {0, -1}, {1, -1}, {1, 0}, {1, 1}, {0, 1}, {-1, 1}, {-1, 0}}};
    Box box;
    for (const auto& r : ring) {
        box.positions.push_back({cx + r[0] * top_half, cy + r[1] * top_half, top_z});
    }
    box.positions.push_back({cx, cy, top_z + raise});
    for (const auto& r : ring) {
        box.positions.push_back({cx + r[0] * bottom_half, cy + r[1] * bottom_half, 0.0});
    }
    box.positions.push_back({cx, cy, 0.0});
    for (std::uint32_t i = 0; i < 8; ++i) {
        const std::uint32_t n = (i + 1) % 8;
        box.triangles.push_back({Box::kTopCentre, i, n});
        box.triangles.push_back({Box::kBottomCentre, 9 + n, 9 + i});
        box.triangles.push_back({9 + i, 9 + n, n});
        box.triangles.push_back({9 + i, n, i});
    }
    return box;
}

/// Every undirected edge in exactly two triangles, once in each direction.
bool is_closed_oriented(const std::vector<Tri>& triangles) {
    std::map<std::pair<std::uint32_t, std::uint32_t>, int> directed;
    for (const Tri& t : triangles) {
        for (int i = 0; i < 3; ++i) {
            ++directed[{t[i], t[(i + 1) % 3]}];
        }
    }
    for (const auto& [edge, count] : directed) {
        const auto reverse = directed.find({edge.second, edge.first});
        if (count != 1 || reverse == directed.end() || reverse->second != 1) {
            return false;
        }
    }
    return true;
}

std::set<std::pair<std::uint32_t, std::uint32_t>> edges_of(const std::vector<Tri>& triangles) {
    std::set<std::pair<std::uint32_t, std::uint32_t>> edges;
    for (const Tri& t : triangles) {
        for (int i = 0; i < 3; ++i) {
            edges.insert(std::minmax(t[i], t[(i + 1) % 3]));
        }
    }
    return edges;
}

/// Edges whose two triangles' normals point apart (a crease over 90 degrees).
std::size_t fold_count(const std::vector<Vec3>& p, const std::vector<Tri>& triangles) {
    std::map<std::pair<std::uint32_t, std::uint32_t>, std::vector<Vec3>> normals;
    for (const Tri& t : triangles) {
        for (int i = 0; i < 3; ++i) {
            normals[std::minmax(t[i], t[(i + 1) % 3])].push_back(normal_of(p, t));
        }
    }
    std::size_t folds = 0;
    for (const auto& [edge, n] : normals) {
        folds += n.size() == 2 && dot(n[0], n[1]) < 0.0 ? 1 : 0;
    }
    return folds;
}

/// The triangles after moving vertex u onto v by hand (those with both removed).
std::vector<Tri> collapsed_by_hand(const std::vector<Tri>& triangles,
                                   std::uint32_t u,
                                   std::uint32_t v) {
    std::vector<Tri> out;
    for (Tri t : triangles) {
        if (std::count(t.begin(), t.end(), u) && std::count(t.begin(), t.end(), v)) {
            continue;
        }
        std::replace(t.begin(), t.end(), u, v);
        out.push_back(t);
    }
    return out;
}

/// Largest angle (radians) a triangle of u's star turns when u moves onto v.
double largest_turn(const std::vector<Vec3>& p,
                    const std::vector<Tri>& triangles,
                    std::uint32_t u,
                    std::uint32_t v) {
    double turn = 0.0;
    for (const Tri& t : triangles) {
        if (!std::count(t.begin(), t.end(), u) || std::count(t.begin(), t.end(), v)) {
            continue;
        }
        Tri moved = t;
        std::replace(moved.begin(), moved.end(), u, v);
        const Vec3 a = normal_of(p, t), b = normal_of(p, moved);
        turn = std::max(turn, std::acos(std::clamp(dot(a, b) / (norm(a) * norm(b)), -1.0, 1.0)));
    }
    return turn;
}

/// A triangle with its smallest id first (same orientation), for comparing triangle sets.
Tri canonical(Tri t) {
    std::rotate(t.begin(), std::min_element(t.begin(), t.end()), t.end());
    return t;
}

std::vector<Tri> canonical(std::vector<Tri> triangles) {
    for (Tri& t : triangles) {
        t = canonical(t);
    }
    std::sort(triangles.begin(), triangles.end());
    return triangles;
}

/// Replays `r.collapses` by hand from `triangles`, calling `check(before, u, v)` before each
/// one; expects to end at `r.triangles`.
template <class Check>
void replay(std::vector<Tri> triangles, const CollapseResult& r, Check check) {
    for (const auto& [u, v] : r.collapses) {
        check(triangles, u, v);
        triangles = collapsed_by_hand(triangles, u, v);
    }
    EXPECT_EQ(canonical(triangles), canonical(r.triangles));
}

bool removes(const CollapseResult& r, std::uint32_t vertex) {
    return std::any_of(r.collapses.begin(), r.collapses.end(),
                       [&](const auto& c) { return c.first == vertex; });
}

/// The bottom face and ring (ids 9..17): the top is free.
std::vector<std::uint32_t> bottom_of_box() {
    std::vector<std::uint32_t> locked;
    for (std::uint32_t v = 9; v < 18; ++v) {
        locked.push_back(v);
    }
    return locked;
}

/// A meter without slices: every triangle's error is 0, so only the geometric and topological
/// rules decide.
struct NoData {
    SliceContours contours;
    std::vector<SliceDistanceFields> fields;
    SliceErrorMeter meter{contours, fields, 1, 1.0};
};

CollapseResult collapse(const std::vector<Vec3>& positions,
                        const std::vector<Tri>& triangles,
                        std::vector<std::uint32_t> locked,
                        const CollapseOptions& options = {},
                        std::vector<Tri> obstacles = {}) {
    static const NoData none;
    CollapseProblem problem;
    problem.positions = &positions;
    problem.triangles = triangles;
    problem.triangle_error_px.assign(triangles.size(), 0.0);
    problem.locked = std::move(locked);
    problem.obstacles = std::move(obstacles);
    return collapse_edges(problem, none.meter, options);
}

TEST(CollapseEdges, TheBoxFixtureIsClosedAndOutward) {
    const Box box = make_box(1.0, 1.5, 1.0, 0.25);
    EXPECT_TRUE(is_closed_oriented(box.triangles));
    EXPECT_EQ(box.triangles.size(), 32u);
    // outward: positive volume (divergence theorem)
    double volume = 0.0;
    for (const Tri& t : box.triangles) {
        volume += dot(box.positions[t[0]], normal_of(box.positions, t)) / 6.0;
    }
    EXPECT_GT(volume, 0.0);
}

TEST(CollapseEdges, ATetrahedronKeepsItsFourVertices) {
    // Any collapse would leave vertices with two edges (a doubled triangle): the link condition
    // and the minimum degree refuse all twelve.
    const std::vector<Vec3> p{{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
    const std::vector<Tri> t{{0, 2, 1}, {0, 1, 3}, {0, 3, 2}, {1, 2, 3}};
    ASSERT_TRUE(is_closed_oriented(t));
    const CollapseResult r = collapse(p, t, {});
    EXPECT_TRUE(r.collapses.empty());
    EXPECT_EQ(r.triangles.size(), 4u);
}

TEST(CollapseEdges, RefusesVerticesOutsidePositionsAndEdgesOfThreeTriangles) {
    const Box box = make_box(1.0, 1.5, 1.0, 0.0);
    std::vector<Tri> out_of_range = box.triangles;
    out_of_range[5][1] = 18;
    EXPECT_THROW(collapse(box.positions, out_of_range, {}), Error);
    std::vector<Tri> three = box.triangles;
    three.push_back({0, 1, Box::kBottomCentre});  // a third triangle on edge 0-1
    EXPECT_THROW(collapse(box.positions, three, {}), Error);
}

TEST(CollapseEdges, LockedVerticesAndTheEdgesBetweenThemStay) {
    const Box box = make_box(1.0, 1.5, 1.0, 0.0);
    std::vector<std::uint32_t> locked;
    for (std::uint32_t v = 0; v < 18; ++v) {
        if (v % 3 == 0) {
            locked.push_back(v);
        }
    }
    const CollapseResult r = collapse(box.positions, box.triangles, locked);
    EXPECT_FALSE(r.collapses.empty());  // else the test says nothing
    for (const auto& [removed, kept] : r.collapses) {
        EXPECT_FALSE(std::binary_search(locked.begin(), locked.end(), removed)) << removed;
    }
    const auto before = edges_of(box.triangles);
    const auto after = edges_of(r.triangles);
    for (const auto& edge : before) {
        if (std::binary_search(locked.begin(), locked.end(), edge.first) &&
            std::binary_search(locked.begin(), locked.end(), edge.second)) {
            EXPECT_TRUE(after.count(edge)) << edge.first << "-" << edge.second;
        }
    }
    EXPECT_TRUE(is_closed_oriented(r.triangles));
}

TEST(CollapseEdges, NeverLeavesACollinearTriangle) {
    // Flat top, free: onto a corner, the centre's fan would join that corner to the two edge
    // midpoints beside it in line.
    const Box box = make_box(1.0, 1.5, 1.0, 0.0);
    for (std::uint32_t corner = 0; corner < 8; corner += 2) {
        bool collinear = false;
        for (const Tri& t : collapsed_by_hand(box.triangles, Box::kTopCentre, corner)) {
            collinear = collinear || norm(normal_of(box.positions, t)) == 0.0;
        }
        ASSERT_TRUE(collinear) << corner;  // the fixture offers the refusal
    }
    const CollapseResult r = collapse(box.positions, box.triangles, bottom_of_box());
    EXPECT_GE(r.collapses.size(), 2u);
    replay(box.triangles, r, [&](const std::vector<Tri>& before, std::uint32_t u, std::uint32_t v) {
        for (const Tri& t : collapsed_by_hand(before, u, v)) {
            EXPECT_GT(norm(normal_of(box.positions, t)), 0.0) << u << " onto " << v;
        }
    });
}

TEST(CollapseEdges, RefusesToTurnATriangleMoreThanAllowed) {
    // The top's centre raised by 0.25: removing it flattens part of its fan, which turns by
    // atan(0.25), about 14 degrees; the ring may collapse along the square's sides without any
    // turn.
    const Box box = make_box(1.0, 1.5, 1.0, 0.25);
    const double turn = largest_turn(box.positions, box.triangles, Box::kTopCentre, 1);
    EXPECT_NEAR(turn, std::atan(0.25), 1e-12);
    for (const double limit : {turn - 0.01, turn + 0.01}) {
        CollapseOptions options;
        options.min_normal_cos = std::cos(limit);
        const CollapseResult r = collapse(box.positions, box.triangles, bottom_of_box(), options);
        EXPECT_EQ(removes(r, Box::kTopCentre), limit > turn) << limit;
        replay(box.triangles, r,
               [&](const std::vector<Tri>& before, std::uint32_t u, std::uint32_t v) {
                   EXPECT_LE(largest_turn(box.positions, before, u, v), limit)
                       << u << " onto " << v;
               });
    }
}

TEST(CollapseEdges, RefusesToAddAFold) {
    // A box wider at the top than at the bottom: its sides face outward and 27 degrees down.
    // With the top's centre raised 35 degrees, the fan turns less than 90 degrees from the
    // sides; flat, it would turn more (a fold at every top edge). Turning the fan 35 degrees is
    // allowed, and on a box narrower at the top, whose sides face up, the centre goes.
    const double raise = std::tan(35.0 * std::numbers::pi / 180.0);
    const Box wide_top = make_box(1.0, 0.5, 1.0, raise);
    const Box narrow_top = make_box(1.0, 1.5, 1.0, raise);
    for (std::uint32_t m = 1; m < 8; m += 2) {
        ASSERT_LT(largest_turn(wide_top.positions, wide_top.triangles, Box::kTopCentre, m),
                  std::acos(CollapseOptions{}.min_normal_cos));
        const auto after = collapsed_by_hand(wide_top.triangles, Box::kTopCentre, m);
        ASSERT_GT(fold_count(wide_top.positions, after),
                  fold_count(wide_top.positions, wide_top.triangles))
            << m;
    }
    for (const Box* box : {&wide_top, &narrow_top}) {
        const CollapseResult r = collapse(box->positions, box->triangles, bottom_of_box());
        EXPECT_EQ(removes(r, Box::kTopCentre), box == &narrow_top);
        replay(box->triangles, r,
               [&](const std::vector<Tri>& before, std::uint32_t u, std::uint32_t v) {
                   EXPECT_LE(fold_count(box->positions, collapsed_by_hand(before, u, v)),
                             fold_count(box->positions, before))
                       << u << " onto " << v;
               });
    }
}

TEST(CollapseEdges, NewTrianglesDoNotCrossAnObstacle) {
    // An obstacle (a triangle of another part of the surface) standing through the top's plane
    // under its raised centre: a flattened top would cut it, the raised one does not.
    Box box = make_box(1.0, 1.5, 1.0, 0.25);
    const std::uint32_t o = static_cast<std::uint32_t>(box.positions.size());
    box.positions.push_back({-0.1, 0.0, 0.95});
    box.positions.push_back({0.1, 0.0, 0.95});
    box.positions.push_back({0.0, 0.0, 1.05});
    const std::vector<Tri> obstacle{{o, o + 1, o + 2}};
    EXPECT_TRUE(removes(collapse(box.positions, box.triangles, bottom_of_box()), Box::kTopCentre));
    EXPECT_FALSE(removes(collapse(box.positions, box.triangles, bottom_of_box(), {}, obstacle),
                         Box::kTopCentre));
}

TEST(CollapseEdges, StopsAtTheTargetTriangleCount) {
    const Box box = make_box(1.0, 1.5, 1.0, 0.0);
    CollapseOptions options;
    options.target_triangles = 30;
    const CollapseResult r = collapse(box.positions, box.triangles, {}, options);
    EXPECT_EQ(r.triangles.size(), 30u);  // one collapse removes two triangles
    EXPECT_EQ(r.collapses.size(), 1u);
}

/// Two slices of a 4x4 pixel square (pixels 2..5), 2 px apart, and the box on it: its rings are
/// the square's contour at z = 0 and z = 2.
struct SquareSlab {
    SliceStack stack;
    SliceContours contours;
    std::vector<SliceDistanceFields> fields;
    Box box;
    static constexpr double kSpacing = 2.0;

    SquareSlab() {
        stack.width = stack.height = 8;
        stack.depth = 2;
        stack.labels.assign(8 * 8 * 2, 0);
        for (std::uint32_t k = 0; k < 2; ++k) {
            for (std::uint32_t j = 2; j < 6; ++j) {
                for (std::uint32_t i = 2; i < 6; ++i) {
                    stack.labels[(k * 8 + j) * 8 + i] = 1;
                }
            }
        }
        stack.index_to_world.linear = {{{1, 0, 0}, {0, 1, 0}, {0, 0, kSpacing}}};
        stack.label_table.push_back({1, "square", {200, 80, 80}});
        contours = extract_contours(stack, ContourOptions{});
        fields = compute_distance_fields(stack, contours, DistanceOptions{});
        box = make_box(2.0, 2.0, kSpacing, 0.0, 4.0, 4.0);
    }
};

TEST(CollapseEdges, NeverExceedsTheErrorBound) {
    // The meter's bounds are upper bounds (the square's caps read 1.1 px where the truth is 0);
    // a collapse is refused when a triangle it creates would exceed max_error_px. Every run's
    // declared bounds hold by the oracle (exact distances to the contour polylines), and a bound
    // below the caps' stops collapses that an unbounded run makes.
    const SquareSlab slab;
    const SliceErrorMeter meter(slab.contours, slab.fields, 1, SquareSlab::kSpacing);
    CollapseProblem problem;
    problem.positions = &slab.box.positions;
    problem.triangles = slab.box.triangles;
    for (const Tri& t : slab.box.triangles) {
        problem.triangle_error_px.push_back(meter.triangle_error_px(
            {slab.box.positions[t[0]], slab.box.positions[t[1]], slab.box.positions[t[2]]}));
    }
    problem.locked = bottom_of_box();
    const auto input = canonical(slab.box.triangles);
    std::vector<std::size_t> collapses;
    for (const double max_error_px : {1.0, kInfinity}) {
        CollapseOptions options;
        options.max_error_px = max_error_px;
        const CollapseResult r = collapse_edges(problem, meter, options);
        collapses.push_back(r.collapses.size());
        for (std::size_t i = 0; i < r.triangles.size(); ++i) {
            if (!std::binary_search(input.begin(), input.end(), canonical(r.triangles[i]))) {
                EXPECT_LE(r.triangle_error_px[i], max_error_px) << "new triangle " << i;
            }
        }
        TriMesh mesh;
        mesh.positions = slab.box.positions;
        mesh.triangles = r.triangles;
        const test::CutErrorReport report =
            test::measure_cut_error(mesh, slab.contours, 1, SquareSlab::kSpacing);
        EXPECT_TRUE(report.problems.empty());
        EXPECT_LE(std::max(report.max_section_px, report.max_cap_px), r.max_error_px)
            << max_error_px;
    }
    EXPECT_LT(collapses[0], collapses[1]);
}

}  // namespace
}  // namespace strata
