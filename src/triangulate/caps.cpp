// Triangulation, end caps: a region without a partner on the next (previous) slice is closed by
// a dome beyond its plane, by walls and a planar cap at the stack's ends, or, alone on its
// slice, by a slab of thickness d/2.
#include <algorithm>
#include <array>
#include <cmath>
#include <cstddef>
#include <optional>

#include "mesh/self_intersection.h"
#include "triangulate/detail/label_surface.h"

namespace strata::detail {

namespace {

/// Whether q lies inside region `region` of the rings' triangulation (faces labelled), not on a
/// vertex or a constrained edge.
bool inside_region(const Cdt& cdt, Vec2 q, std::uint32_t region) {
    Cdt::Locate_type type;
    int li = 0;
    const FaceHandle face = cdt.locate(to_point(q), type, li);
    if (type == Cdt::VERTEX || type == Cdt::OUTSIDE_CONVEX_HULL ||
        type == Cdt::OUTSIDE_AFFINE_HULL || cdt.is_infinite(face) ||
        face->info().lower_region != std::int32_t(region)) {
        return false;
    }
    return !(type == Cdt::EDGE && cdt.is_constrained({face, li}));
}

/// How far a paraboloid goes on past the plane where its section has area `area`, when the plane
/// d before has area `partner_area`: H = d A / (A' - A); infinity where the areas do not shrink.
double paraboloid_height(double d, double area, double partner_area) {
    if (partner_area > area && area > 0.0) {
        return d * area / (partner_area - area);
    }
    return std::numeric_limits<double>::infinity();
}

/// The dome's rise over a point `depth` inside its contour: H (1 - (1 - depth / Dmax)^2).
double dome_rise(double height, double depth, double dmax) {
    const double u = 1.0 - std::min(depth / dmax, 1.0);
    return height * (1.0 - u * u);
}

/// Dmax: the depth of the deepest of the field's nodes in the box (lo, hi) for which
/// `inside(q)` holds (of the 256 deepest nodes inside the label); 0 when none does.
template <class Inside>
double deepest_inside(const DistanceField& field, Vec2 lo, Vec2 hi, const Inside& inside) {
    const DistanceField* f = &field;
    const double x0 = lo.x, y0 = lo.y, x1 = hi.x, y1 = hi.y;
    const double cell = DistanceField::kCellPx;
    const auto i0 =
        std::uint32_t(std::clamp(std::floor((x0 - f->origin_x) / cell), 0.0, double(f->nx - 1)));
    const auto i1 =
        std::uint32_t(std::clamp(std::ceil((x1 - f->origin_x) / cell), 0.0, double(f->nx - 1)));
    const auto j0 =
        std::uint32_t(std::clamp(std::floor((y0 - f->origin_y) / cell), 0.0, double(f->ny - 1)));
    const auto j1 =
        std::uint32_t(std::clamp(std::ceil((y1 - f->origin_y) / cell), 0.0, double(f->ny - 1)));
    std::vector<std::pair<float, std::uint32_t>> deep;  // (-D, node) inside the label
    for (std::uint32_t j = j0; j <= j1; ++j) {
        for (std::uint32_t i = i0; i <= i1; ++i) {
            const float v = f->at(i, j);
            if (v < 0.0f) {
                deep.emplace_back(v, j * f->nx + i);
            }
        }
    }
    std::sort(deep.begin(), deep.end());
    double dmax = 0.0;
    for (std::size_t n = 0; n < deep.size() && n < 256; ++n) {
        const std::uint32_t node = deep[n].second;
        if (inside(f->node_position(node % f->nx, node / f->nx))) {
            dmax = -double(deep[n].first);
            break;
        }
    }
    return dmax;
}

/// The inner edges of region `region` that join two contour vertices (they would lie in the slice
/// plane), as their midpoints, sorted and without repeats.
std::vector<Point> plane_chords(const Cdt& cdt, std::uint32_t region) {
    std::vector<Point> chords;
    for (FaceHandle face : cdt.finite_face_handles()) {
        if (face->info().lower_region != std::int32_t(region)) {
            continue;
        }
        for (int i = 0; i < 3; ++i) {
            const VertexHandle a = face->vertex(ccw(i));
            const VertexHandle b = face->vertex(cw(i));
            if (!cdt.is_constrained({face, i}) && a->info().steiner < 0 && b->info().steiner < 0) {
                chords.push_back(CGAL::midpoint(a->point(), b->point()));
            }
        }
    }
    std::sort(chords.begin(), chords.end());
    chords.erase(std::unique(chords.begin(), chords.end()), chords.end());
    return chords;
}

}  // namespace

/// Closes region `region` of slice k by planar caps: on top (normal +z) when it has no partner
/// above, below when none below; alone on its slice it becomes a slab of thickness d/2.
void LabelSurface::cap_region(std::uint32_t k, std::uint32_t region, bool top, bool bottom) {
    Cdt cdt;
    std::map<EdgeKey, EdgeOwner> owners;
    insert_rings(cdt, k, false, owners, region);
    flood_regions(cdt, k, owners);  // inside the region: lower_region >= 0
    std::vector<std::array<std::uint32_t, 3>>& out = surface_.mesh.triangles;
    const bool slab = top && bottom;
    // At the ends of the stack the object may go on out of it: its last slice stands for its
    // whole cell, as a voxel does, and the region is extended by d/2 (walls and a planar cap).
    // note: unless it visibly closes within the cap's reach (then a dome, as inside the stack).
    // A surface split at the AND layer (level_z_) is extended the same way; without, its end
    // slices were flat caps that folded over 90 degrees against slabs overhanging them.
    const bool stack_end =
        !slab && options_.cap_reach > 0.0 &&
        ((top && k + 1 == contours_.slices.size()) || (bottom && k == 0)) &&
        !(cap_height(k, region, top) < options_.cap_reach * options_.slice_spacing_px);
    const bool walls = slab || stack_end;
    if (!walls && !dome_cap(cdt, owners, k, region, top)) {
        // no dome (too small, or its refinement did not converge): planar
        cdt.clear();
        owners.clear();
        insert_rings(cdt, k, false, owners, region);
        flood_regions(cdt, k, owners);
    }
    // At a stack end the walls lean as the object does: each ring point moves in the plane by
    // the change of the signed distance over half a slab, taken from the slice before.
    const std::map<std::uint32_t, Vec2> lean =
        stack_end ? end_lean(cdt, k, region, top) : std::map<std::uint32_t, Vec2>{};
    std::map<std::uint32_t, std::array<std::uint32_t, 2>> lifted;  // ring id -> (below, above)
    auto lift = [&](std::uint32_t id) {
        auto it = lifted.find(id);
        if (it == lifted.end()) {
            const Vec3 p = surface_.mesh.positions[id];
            const double d = options_.slice_spacing_px;
            const double down = slab ? d / 4.0 : bottom ? d / 2.0 : 0.0;
            const double up = slab ? d / 4.0 : top ? d / 2.0 : 0.0;
            const auto moved = lean.find(id);
            const Vec2 q = moved != lean.end() ? moved->second : Vec2{p.x, p.y};
            const std::uint32_t below = down > 0.0 ? add_vertex(q, p.z - down) : id;
            const std::uint32_t above = up > 0.0 ? add_vertex(q, p.z + up) : id;
            if (!(q == Vec2{p.x, p.y})) {
                leans_.push_back({top ? above : below, Vec2{p.x, p.y}, q});
            }
            it = lifted.emplace(id, std::array<std::uint32_t, 2>{below, above}).first;
        }
        return it->second;
    };
    for (FaceHandle f : cdt.finite_face_handles()) {
        if (f->info().lower_region < 0) {
            continue;
        }
        std::array<std::uint32_t, 3> t{};
        bool on_contour = true;
        for (int i = 0; i < 3; ++i) {
            const VertexInfo& info = f->vertex(i)->info();
            // dome vertices carry their global id in `steiner`
            const std::int32_t id = info.lower >= 0 ? info.lower : info.steiner;
            on_contour = on_contour && id >= 0;
            t[std::size_t(i)] = std::uint32_t(id);
        }
        if (!on_contour) {
            ++surface_.failed_slabs;
            issue(k, "a cap vertex is not on the contour");
            continue;
        }
        if (walls) {
            if (top) {
                out.push_back({lift(t[0])[1], lift(t[1])[1], lift(t[2])[1]});
            }
            if (bottom) {
                out.push_back({lift(t[0])[0], lift(t[2])[0], lift(t[1])[0]});
            }
        } else if (top) {
            out.push_back(t);
        } else {
            out.push_back({t[0], t[2], t[1]});
        }
    }
    if (walls) {
        // Walls: contours keep the region on their left, so outward is to the right.
        for_each_region_ring(k, region, [&](const Ring& ring) {
            for (std::size_t i = 0; i < ring.ids.size(); ++i) {
                const auto p = lift(ring.ids[i]);
                const auto q = lift(ring.ids[(i + 1) % ring.ids.size()]);
                out.push_back({p[0], q[0], q[1]});
                out.push_back({p[0], q[1], p[1]});
            }
        });
    }
    if (slab) {
        surface_.caps += 2;
    } else {
        surface_.caps += 1;
    }
}

/// Where the ring points of region `region` go at the end of the stack (slice k, above when
/// `top`): a point p of the contour moves along its outward normal (the ring's direction over
/// 2 px each side) by the change of the signed distance over half a slab, extrapolated from the
/// previous slice, (D_prev(p) - D_k(p)) / 2, or where the slice before that is known from the
/// parabola through all three (so the extension leans as the object does, up to 45 degrees);
/// half or a quarter of that where a cap triangle would flip, and none (vertical walls, an
/// empty map) where it still would or without a previous field.
std::map<std::uint32_t, Vec2> LabelSurface::end_lean(const Cdt& cdt,
                                                     std::uint32_t k,
                                                     std::uint32_t region,
                                                     bool top) const {
    std::map<std::uint32_t, Vec2> offset;  // ring id -> its move at full lean
    const double d = options_.slice_spacing_px;
    const bool has_prev = top ? k >= 1 : k + 1 < contours_.slices.size();
    const DistanceField* here = field(k);
    const DistanceField* prev = has_prev ? field(top ? k - 1 : k + 1) : nullptr;
    if (here == nullptr || prev == nullptr) {
        return {};
    }
    // the change over d/2 from the change over the gap to the previous slice (d, or the half
    // slab of an AND layer, level_z_)
    const double half_slab =
        level_z_ == nullptr ? 0.5 : 0.5 * d / std::abs(slice_z(k) - slice_z(top ? k - 1 : k + 1));
    // the slice before that, for the change's own change (equal gaps only: not an AND layer)
    const bool has_second = level_z_ == nullptr && (top ? k >= 2 : k + 2 < contours_.slices.size());
    const DistanceField* second = has_second ? field(top ? k - 2 : k + 2) : nullptr;
    // Its field covers the label's pixels on its own and the neighbouring slices only; beyond
    // its window a point is outside the label there, at the distance to that slice's rings.
    // note: built on the first point outside the window only (most ends have none)
    std::optional<SegmentGrid> second_rings;
    auto second_value = [&](Vec2 q) {
        const double u = (q.x - second->origin_x) / DistanceField::kCellPx;
        const double v = (q.y - second->origin_y) / DistanceField::kCellPx;
        if (u >= 0.0 && v >= 0.0 && u <= second->nx - 1.0 && v <= second->ny - 1.0) {
            return sample_field(second, q);
        }
        if (!second_rings) {
            second_rings.emplace(rings_[top ? k - 2 : k + 2]);
        }
        return second_rings->distance(q);
    };
    const double reach = 2.0;
    for_each_region_ring(k, region, [&](const Ring& ring) {
        const std::size_t n = ring.points.size();
        for (std::size_t i = 0; i < n; ++i) {
            const Vec2 p = to_vec(ring.points[i]);
            // The ring's direction at p over at least `reach` px on each side (at most half the
            // ring): a pixel staircase's own steps would turn neighbouring points' normals
            // apart, and their leans would cross.
            auto along = [&](bool forward) {
                Vec2 q = p;
                for (std::size_t j = 1; j <= std::max<std::size_t>((n - 1) / 2, 1); ++j) {
                    q = to_vec(ring.points[forward ? (i + j) % n : (i + n - j) % n]);
                    if (dot(q - p, q - p) >= reach * reach) {
                        break;
                    }
                }
                return q;
            };
            // the region is on the left of the ring's direction: outward is to the right
            const Vec2 t = along(true) - along(false);
            const double length = std::sqrt(dot(t, t));
            if (!(length > 0.0)) {
                continue;
            }
            const Vec2 outward{t.y / length, -t.x / length};
            const double d0 = sample_field(here, p);
            const double d1 = sample_field(prev, p);
            double change = half_slab * (d1 - d0);
            if (second != nullptr) {
                // The parabola through the three slices' values at p, half a slab on: an edge
                // that slows down (the rounded end of a tube) or a side that stays put while
                // the section moves along it (the distance grows as the square of the move,
                // alike on both sides of the slice) is not pushed on by the last slab's change.
                // Not where slice k-2 differs by more than 1.5 slabs' worth of change: the
                // object begins or joins another there.
                const double d2 = second_value(p);
                if (std::abs(d2 - d1) <= 1.5 * d) {
                    change = 0.5 * (d1 - d0) - 0.375 * (d0 - 2.0 * d1 + d2);
                }
            }
            const double shift = std::clamp(change, -0.5 * d, 0.5 * d);
            offset[ring.ids[i]] = shift * outward;
        }
    });
    // The full lean, else half or a quarter of it, where no cap triangle flips.
    for (const double scale : {1.0, 0.5, 0.25}) {
        auto at = [&](VertexHandle v) {
            const std::int32_t id = v->info().lower;
            const auto it = id >= 0 ? offset.find(std::uint32_t(id)) : offset.end();
            const Vec2 p = to_vec(v->point());
            return it != offset.end() ? p + scale * it->second : p;
        };
        bool flips = false;
        for (FaceHandle f : cdt.finite_face_handles()) {
            if (f->info().lower_region < 0) {
                continue;
            }
            const Vec2 a = at(f->vertex(0));
            const Vec2 ab = at(f->vertex(1)) - a;
            const Vec2 ac = at(f->vertex(2)) - a;
            if (!(ab.x * ac.y - ab.y * ac.x > 1e-9)) {
                flips = true;
                break;
            }
        }
        if (!flips) {
            std::map<std::uint32_t, Vec2> lean;
            for (const auto& [id, move] : offset) {
                const Vec3 p = surface_.mesh.positions[id];
                lean[id] = Vec2{p.x, p.y} + scale * move;
            }
            return lean;
        }
    }
    return {};
}

/// The leans of cap_region are checked once every cap is made. The triangles beyond the stack's
/// end planes (walls, caps, domes, single-slice slabs) must not meet one another, as triangulated
/// and as the quantize stage will store them (snapped to each grid step it may take,
/// TriangulateOptions::grid_step), and no leaned triangle may fold over 90 degrees against a
/// neighbour that is not in a slice plane (the slab below a wall, the next wall). Each leaned
/// vertex of such a triangle gives back half its lean, then the rest; rounds go on until nothing
/// is found.
void LabelSurface::settle_end_leans() {
    if (leans_.empty()) {
        return;
    }
    TriMesh& mesh = surface_.mesh;
    const std::size_t vertices = mesh.positions.size();
    std::vector<std::int32_t> lean_of(vertices, -1);
    for (std::size_t i = 0; i < leans_.size(); ++i) {
        lean_of[leans_[i].id] = std::int32_t(i);
    }
    const double z_low = slice_z(0);
    const double z_high = slice_z(std::uint32_t(contours_.slices.size() - 1));
    // Beyond the end planes: any corner outside [z_low, z_high]; touching a leaned vertex.
    std::vector<std::uint32_t> beyond;
    std::vector<std::uint32_t> touched;
    for (std::uint32_t t = 0; t < mesh.triangles.size(); ++t) {
        bool out = false;
        bool leaned = false;
        for (const std::uint32_t v : mesh.triangles[t]) {
            out = out || mesh.positions[v].z < z_low || mesh.positions[v].z > z_high;
            leaned = leaned || lean_of[v] >= 0;
        }
        if (out) {
            beyond.push_back(t);
        }
        if (leaned) {
            touched.push_back(t);
        }
    }
    // The two faces of each edge of a leaned triangle.
    std::map<std::pair<std::uint32_t, std::uint32_t>, std::vector<std::uint32_t>> faces_of_edge;
    auto edge = [&](std::uint32_t t, int i) {
        const std::uint32_t a = mesh.triangles[t][std::size_t(i)];
        const std::uint32_t b = mesh.triangles[t][std::size_t((i + 1) % 3)];
        return std::pair{std::min(a, b), std::max(a, b)};
    };
    for (const std::uint32_t t : touched) {
        for (int i = 0; i < 3; ++i) {
            faces_of_edge[edge(t, i)];
        }
    }
    for (std::uint32_t t = 0; t < mesh.triangles.size(); ++t) {
        for (int i = 0; i < 3; ++i) {
            const auto it = faces_of_edge.find(edge(t, i));
            if (it != faces_of_edge.end()) {
                it->second.push_back(t);
            }
        }
    }
    auto normal = [&](std::uint32_t t) {
        const auto& c = mesh.triangles[t];
        const Vec3 n = cross(mesh.positions[c[1]] - mesh.positions[c[0]],
                             mesh.positions[c[2]] - mesh.positions[c[0]]);
        const double length = norm(n);
        return length > 0.0 ? (1.0 / length) * n : n;
    };
    auto flat = [&](std::uint32_t t) {
        const auto& c = mesh.triangles[t];
        return mesh.positions[c[0]].z == mesh.positions[c[1]].z &&
               mesh.positions[c[1]].z == mesh.positions[c[2]].z;
    };
    // The triangles beyond, on their own vertices (`global`: their ids in the mesh).
    TriMesh part;
    std::vector<std::uint32_t> global;
    {
        std::vector<std::uint32_t> local(vertices, std::uint32_t(-1));
        for (const std::uint32_t t : beyond) {
            std::array<std::uint32_t, 3> corners{};
            for (std::size_t i = 0; i < 3; ++i) {
                const std::uint32_t v = mesh.triangles[t][i];
                if (local[v] == std::uint32_t(-1)) {
                    local[v] = std::uint32_t(global.size());
                    global.push_back(v);
                }
                corners[i] = local[v];
            }
            part.triangles.push_back(corners);
        }
    }
    // The grid steps the quantize stage may store the surface at (snap_to_grid: beyond the end
    // planes every coordinate is rounded to the nearest multiple; z in slices, the grid frame).
    std::vector<double> steps;
    if (options_.grid_step > 0.0) {
        for (unsigned h = 0; h <= options_.grid_halvings; ++h) {
            steps.push_back(std::ldexp(options_.grid_step, -int(h)));
        }
    }
    const double d = options_.slice_spacing_px;
    auto snapped = [&](Vec3 p, double step) {
        const double slice = std::nearbyint(p.z / d);
        return Vec3{std::nearbyint(p.x / step) * step, std::nearbyint(p.y / step) * step,
                    slice * d == p.z ? slice : std::nearbyint(p.z / d / step) * step};
    };
    std::vector<int> halvings(leans_.size(), 0);
    for (int round = 0; round < 16; ++round) {
        std::vector<std::uint32_t> bad;  // triangles whose leaned corners give back
        for (std::size_t s = 0; s <= steps.size(); ++s) {
            part.positions.resize(global.size());
            for (std::size_t i = 0; i < global.size(); ++i) {
                const Vec3 p = mesh.positions[global[i]];
                part.positions[i] = s == 0 ? p : snapped(p, steps[s - 1]);
            }
            const SelfIntersections hits = find_self_intersections(part, 0);
            for (const auto& [a, b] : hits.pairs) {
                bad.push_back(beyond[a]);
                bad.push_back(beyond[b]);
            }
            for (const std::uint32_t t : hits.degenerate_triangles) {
                bad.push_back(beyond[t]);
            }
        }
        for (const auto& [e, faces] : faces_of_edge) {
            if (faces.size() != 2 || flat(faces[0]) || flat(faces[1])) {
                continue;
            }
            if (dot(normal(faces[0]), normal(faces[1])) < 0.0) {
                bad.push_back(faces[0]);
                bad.push_back(faces[1]);
            }
        }
        bool moved = false;
        std::vector<bool> done(leans_.size(), false);
        for (const std::uint32_t t : bad) {
            for (const std::uint32_t v : mesh.triangles[t]) {
                const std::int32_t i = lean_of[v];
                if (i < 0 || done[std::size_t(i)]) {
                    continue;
                }
                done[std::size_t(i)] = true;
                Lean& lean = leans_[std::size_t(i)];
                if (lean.leaned == lean.upright) {
                    continue;
                }
                // half the lean, then none
                lean.leaned = ++halvings[std::size_t(i)] >= 2
                                  ? lean.upright
                                  : lean.upright + 0.5 * (lean.leaned - lean.upright);
                mesh.positions[v].x = lean.leaned.x;
                mesh.positions[v].y = lean.leaned.y;
                moved = true;
            }
        }
        if (!moved) {
            return;
        }
    }
    // Still not settled: every wall upright, as without leans.
    for (Lean& lean : leans_) {
        lean.leaned = lean.upright;
        mesh.positions[lean.id].x = lean.upright.x;
        mesh.positions[lean.id].y = lean.upright.y;
    }
}

double LabelSurface::region_area(std::uint32_t slice, std::uint32_t region) const {
    double area = 0.0;  // outer contours count positive, holes negative
    for_each_region_ring(slice, region, [&](const Ring& ring) {
        for (std::size_t i = 0; i < ring.points.size(); ++i) {
            const Vec2 a = to_vec(ring.points[i]);
            const Vec2 b = to_vec(ring.points[(i + 1) % ring.points.size()]);
            area += 0.5 * (a.x * b.y - b.x * a.y);
        }
    });
    return area;
}

/// How far the object goes on past slice k where region `region` ends (above when `top`): a
/// paraboloid cut by planes d apart has H = d A / (A' - A), A the region's area and A' its
/// partners' on the other side (each shared between its partners here by area). Infinity
/// where the areas do not shrink.
double LabelSurface::cap_height(std::uint32_t k, std::uint32_t region, bool top) const {
    const double area = region_area(k, region);
    // The partners on the other side, and the share of each that leads to this region.
    double partner_area = 0.0;
    const std::uint32_t slab = top ? k - 1 : k;
    const std::uint32_t other = top ? k - 1 : k + 1;
    // d, or the half slab of an AND layer (level_z_)
    const double d =
        level_z_ == nullptr ? options_.slice_spacing_px : std::abs(slice_z(k) - slice_z(other));
    for (const auto& [pair, count] : link_pieces_[slab]) {
        const std::uint32_t here = top ? pair.second : pair.first;
        const std::uint32_t there = top ? pair.first : pair.second;
        if (here != region) {
            continue;
        }
        double siblings = 0.0;  // every region of slice k this partner leads to
        for (const auto& [pair2, count2] : link_pieces_[slab]) {
            if ((top ? pair2.first : pair2.second) == there) {
                siblings += region_area(k, top ? pair2.second : pair2.first);
            }
        }
        partner_area += region_area(other, there) * (siblings > 0.0 ? area / siblings : 1.0);
    }
    const double linear = paraboloid_height(d, area, partner_area);
    // Where the region, its one partner and that one's one partner beyond form a chain (each
    // linked to the next alone, none with holes), the three areas give a parabola in z: exact for a
    // sphere's cap (its section's area is pi (2 R h - h^2)), and for a ring's crest, whose sections
    // shrink faster than a paraboloid's near the top. Its first zero past slice k is the height.
    if (!std::isfinite(linear) || level_z_ != nullptr ||
        (top ? k < 2 : k + 2 >= contours_.slices.size())) {
        return linear;
    }
    auto only_partner = [&](std::uint32_t s, std::uint32_t r, bool up, std::uint32_t& partner) {
        // the one region of slice s -/+ 1 linked to region r of slice s, linked to r alone
        const std::uint32_t link_slab = up ? s : s - 1;
        std::uint32_t found = 0;
        std::uint32_t links = 0;
        for (const auto& [pair, count] : link_pieces_[link_slab]) {
            if ((up ? pair.first : pair.second) == r) {
                found = up ? pair.second : pair.first;
                ++links;
            }
        }
        if (links != 1) {
            return false;
        }
        for (const auto& [pair, count] : link_pieces_[link_slab]) {
            if ((up ? pair.second : pair.first) == found && (up ? pair.first : pair.second) != r) {
                return false;
            }
        }
        partner = found;
        return true;
    };
    auto rings = [&](std::uint32_t s, std::uint32_t r) {
        std::size_t n = 0;
        for_each_region_ring(s, r, [&](const Ring&) { ++n; });
        return n;
    };
    std::uint32_t first = 0;
    std::uint32_t second = 0;
    // and each without holes: a hole's area (a cavity beginning) is no part of how the outer
    // surface closes
    if (!only_partner(k, region, !top, first) || !only_partner(other, first, !top, second) ||
        rings(k, region) != 1 || rings(other, first) != 1 ||
        rings(top ? k - 2 : k + 2, second) != 1) {
        return linear;
    }
    const double a0 = area;
    const double a1 = region_area(other, first);
    const double a2 = region_area(top ? k - 2 : k + 2, second);
    // A(s) = a0 + b s + c s^2, s in slabs past slice k (a1 at s = -1, a2 at s = -2)
    const double b = 0.5 * (3.0 * a0 - 4.0 * a1 + a2);
    const double c = 0.5 * (a0 - 2.0 * a1 + a2);
    const double disc = b * b - 4.0 * c * a0;
    if (!(b < 0.0) || !(disc >= 0.0)) {
        return linear;
    }
    // the smaller positive root (with b < 0 and a0 > 0 there is one where c < 0, or c > 0 and
    // the discriminant is not negative)
    const double root = (2.0 * a0) / (-b + std::sqrt(disc));
    return root > 0.0 ? d * root : linear;
}

double LabelSurface::dome_height(double height) const {
    const double d = options_.slice_spacing_px;
    if (!std::isfinite(height)) {
        height = 0.5 * d;  // the areas do not shrink: half a slab on average
    }
    return std::min(height, options_.cap_reach * d);
}

/// Region `region` of slice k ends there (no partner above when `top`, else below). The object
/// goes on past the slice plane by some height in [0, d) that the slices do not show; the cap is
/// domed by the paraboloid that continues the slab it closes: over a point at distance D inside
/// the contour its height is H (1 - (1 - D / Dmax)^2), Dmax the region's largest D. H follows
/// from the shrinking areas A (this region) and A' (its partners on the other side, shared
/// between their partners here by area): a paraboloid cut by planes d apart has
/// H = d A / (A' - A). H is at most options.cap_reach d (half a slab where the areas do not
/// shrink). Adds Steiner vertices on a grid inside the region (vertex info `steiner`: their
/// global id); the contour keeps z_k, so the section at the slice plane is still the contour.
/// Returns false, with the triangulation to be built again, where no dome is made (a region
/// too small or too flat for one, or chords that would not go).
bool LabelSurface::dome_cap(Cdt& cdt,
                            const std::map<EdgeKey, EdgeOwner>& owners,
                            std::uint32_t k,
                            std::uint32_t region,
                            bool top) {
    const double d = options_.slice_spacing_px;
    const DistanceField* f = field(k);
    if (level_z_ != nullptr || options_.cap_reach <= 0.0 || f == nullptr) {
        return false;
    }
    const double height = dome_height(cap_height(k, region, top));

    // Dmax: the deepest field node inside this region.
    double x0 = 1e300, y0 = 1e300, x1 = -1e300, y1 = -1e300;
    for_each_region_ring(k, region, [&](const Ring& ring) {
        for (const Point& p : ring.points) {
            const Vec2 q = to_vec(p);
            x0 = std::min(x0, q.x);
            y0 = std::min(y0, q.y);
            x1 = std::max(x1, q.x);
            y1 = std::max(y1, q.y);
        }
    });
    const double dmax = deepest_inside(*f, {x0, y0}, {x1, y1},
                                       [&](Vec2 q) { return inside_region(cdt, q, region); });
    if (!(dmax > 1.0) || !(height > 0.0)) {
        return false;
    }
    // Grid points: spacing a third of Dmax (1 to 8 px), at least 1 px inside. Heights are at
    // least one quantization step of z (d / 16) so that no vertex snaps into the plane.
    const double step = std::clamp(dmax / 3.0, 1.0, 8.0);
    const double z = slice_z(k);
    const double sign = top ? 1.0 : -1.0;
    const double lowest = d / 16.0;
    if (height < 2.0 * lowest) {
        return false;
    }
    auto dome_height = [&](Vec2 q) {
        return std::max(dome_rise(height, std::max(-sample_field(f, q), 0.0), dmax), lowest);
    };
    std::vector<Vec2> points;
    for (double y = std::floor(y0 / step) * step + 0.5 * step; y < y1; y += step) {
        for (double x = std::floor(x0 / step) * step + 0.5 * step; x < x1; x += step) {
            const Vec2 q{x, y};
            if (-sample_field(f, q) >= 1.0 && inside_region(cdt, q, region)) {
                points.push_back(q);
            }
        }
    }
    if (points.empty()) {
        return false;
    }
    auto add = [&](const Point& p) {
        const VertexHandle v = cdt.insert(p);
        if (v->info().lower < 0 && v->info().steiner < 0) {
            const Vec2 q = to_vec(p);
            v->info().steiner = std::int32_t(add_vertex(q, z + sign * dome_height(q)));
        }
    };
    // note: the points were checked on the rings' triangulation (faces labelled), not between
    // insertions; Steiner points never split a constrained edge.
    for (const Vec2& q : points) {
        add(to_point(q));
    }
    // No inner edge may join two contour vertices: it would lie in the slice plane, inside the
    // region, and become part of the section there. Split such chords at their midpoints.
    for (int round = 0; round < 16; ++round) {
        flood_regions(cdt, k, owners);
        const std::vector<Point> chords = plane_chords(cdt, region);
        if (chords.empty()) {
            unbias_dome(cdt, region, z, sign, height, [&](Vec2 q) {
                return std::max(dome_rise(height, std::max(-sample_field(f, q), 0.0), dmax), 0.0);
            });
            return true;
        }
        for (const Point& p : chords) {
            add(p);
        }
    }
    return false;
}

/// Flat triangles under a dome that curves down to its rim lie inside it: each triangle of the
/// region is short by the mean of the dome over it less the mean of its corners' heights, e.
/// Each dome vertex rises by its share of that shortfall (e times the triangle's area, split
/// between its dome corners, over a third of its triangles' area), so that the triangles
/// enclose what the dome does; heights stay in [d/16, H], H the dome's top (`height`).
template <class Dome>
void LabelSurface::unbias_dome(
    const Cdt& cdt, std::uint32_t region, double z, double sign, double height, const Dome& dome) {
    TriMesh& mesh = surface_.mesh;
    std::map<std::int32_t, std::array<double, 2>> share;  // dome vertex -> (volume, area / 3)
    for (FaceHandle f : cdt.finite_face_handles()) {
        if (f->info().lower_region != std::int32_t(region)) {
            continue;
        }
        std::array<Vec2, 3> xy;
        std::array<double, 3> h{};
        int domed = 0;
        for (int i = 0; i < 3; ++i) {
            const VertexInfo& info = f->vertex(i)->info();
            xy[std::size_t(i)] = to_vec(f->vertex(i)->point());
            if (info.lower < 0 && info.steiner >= 0) {
                h[std::size_t(i)] = sign * (mesh.positions[std::size_t(info.steiner)].z - z);
                ++domed;
            }
        }
        if (domed == 0) {
            continue;
        }
        const double area = 0.5 * std::abs(cross(xy[1] - xy[0], xy[2] - xy[0]));
        double shortfall = 0.0;  // mean over six inner points of dome - linear
        int samples = 0;
        for (int i = 0; i < 3; ++i) {
            for (int j = 0; i + j < 3; ++j) {
                const double u = (i + 1.0 / 3.0) / 3.0;
                const double v = (j + 1.0 / 3.0) / 3.0;
                const Vec2 q = xy[0] + u * (xy[1] - xy[0]) + v * (xy[2] - xy[0]);
                const double linear = h[0] + u * (h[1] - h[0]) + v * (h[2] - h[0]);
                shortfall += dome(q) - linear;
                ++samples;
            }
        }
        shortfall /= samples;
        for (int i = 0; i < 3; ++i) {
            const VertexInfo& info = f->vertex(i)->info();
            if (info.lower < 0 && info.steiner >= 0) {
                std::array<double, 2>& s = share[info.steiner];
                s[0] += area * shortfall / domed;
                s[1] += area / 3.0;
            }
        }
    }
    const double d = options_.slice_spacing_px;
    for (const auto& [id, s] : share) {
        if (!(s[1] > 0.0)) {
            continue;
        }
        Vec3& p = mesh.positions[std::size_t(id)];
        const double h =
            std::clamp(sign * (p.z - z) + s[0] / s[1], d / 16.0, std::max(height, d / 16.0));
        p.z = z + sign * h;
    }
}

double LabelSurface::background_area(std::uint32_t slice, std::uint32_t component) const {
    double area = 0.0;
    for (std::uint32_t local = 0; local < rings_[slice].size(); ++local) {
        const Contour& c = contours_.slices[slice].contours[label_contours_[slice][local]];
        if (!c.is_hole || c.region != component) {
            continue;
        }
        const Ring& ring = rings_[slice][local];
        double twice = 0.0;
        for (std::size_t i = 0; i < ring.points.size(); ++i) {
            const Vec2 a = to_vec(ring.points[i]);
            const Vec2 b = to_vec(ring.points[(i + 1) % ring.points.size()]);
            twice += a.x * b.y - b.x * a.y;
        }
        area += 0.5 * std::abs(twice);
    }
    return area;
}

namespace {

/// Whether q lies inside the closed polygon `ring` (even-odd).
bool inside_ring(const std::vector<Vec2>& ring, Vec2 q) {
    bool inside = false;
    for (std::size_t i = 0, j = ring.size() - 1; i < ring.size(); j = i++) {
        const Vec2 a = ring[i];
        const Vec2 b = ring[j];
        if ((a.y > q.y) != (b.y > q.y) && q.x < a.x + (q.y - a.y) * (b.x - a.x) / (b.y - a.y)) {
            inside = !inside;
        }
    }
    return inside;
}

}  // namespace

/// How fast the dome that closes region `region` of slice k (above when `top`) draws in at its
/// rim: over depth D its height is H (1 - (1 - D / Dmax)^2), which rises 2 H / Dmax per px of
/// depth at the contour, so its section moves in by Dmax / (2 H) per px of height, d Dmax / (2 H)
/// per slab. That is how the signed distance of a point just outside the contour grows past the
/// slice plane: the slope a cubic height through slices k - 1 and k (k + 1 and k) takes at k
/// where no slice continues the region (lift.cpp). 0 where dome_cap makes no dome: walls at the
/// stack's end (cap_region's test), a region too small or too flat for one.
double LabelSurface::dome_rim_slope(std::uint32_t k,
                                    std::uint32_t region,
                                    bool top,
                                    double* height_px) const {
    const double d = options_.slice_spacing_px;
    const DistanceField* f = field(k);
    if (level_z_ != nullptr || options_.cap_reach <= 0.0 || f == nullptr) {
        return 0.0;
    }
    const double reach = cap_height(k, region, top);
    const bool stack_end = (top && k + 1 == contours_.slices.size()) || (!top && k == 0);
    if (stack_end && !(reach < options_.cap_reach * d)) {
        return 0.0;
    }
    const double height = dome_height(reach);
    std::vector<std::vector<Vec2>> rings;
    Vec2 lo{1e300, 1e300};
    Vec2 hi{-1e300, -1e300};
    for_each_region_ring(k, region, [&](const Ring& ring) {
        std::vector<Vec2>& r = rings.emplace_back();
        for (const Point& p : ring.points) {
            const Vec2 q = to_vec(p);
            r.push_back(q);
            lo = {std::min(lo.x, q.x), std::min(lo.y, q.y)};
            hi = {std::max(hi.x, q.x), std::max(hi.y, q.y)};
        }
    });
    const double dmax = deepest_inside(*f, lo, hi, [&](Vec2 q) {
        bool inside = false;  // even-odd over the outer contour and the holes
        for (const std::vector<Vec2>& r : rings) {
            inside = inside != inside_ring(r, q);
        }
        return inside;
    });
    if (!(dmax > 1.0) || !(height >= d / 8.0)) {
        return 0.0;
    }
    if (height_px != nullptr) {
        *height_px = height;
    }
    return d * dmax / (2.0 * height);
}

/// The cavities that close inside slab k. A hole contour of slice k (k+1) bounds a background
/// component; when no background of the other slice is linked to it, the label covers the
/// whole hole there and the slab's surface over the hole is the cavity's end. Like an end cap,
/// the cavity goes on past its last slice by a height the slices do not show: the paraboloid
/// that continues the cavity's slab on the other side, H = d A / (A' - A) from the hole's
/// area A and its partners' A' (shared by area), at most cap_reach d, half a slab where the
/// areas do not shrink. Only a hole with nothing inside it (no other contour of either slice)
/// is domed.
std::vector<LabelSurface::Pocket> LabelSurface::find_pockets(std::uint32_t k) const {
    std::vector<Pocket> pockets;
    if (level_z_ != nullptr || options_.cap_reach <= 0.0) {
        return pockets;
    }
    const double d = options_.slice_spacing_px;
    for (int side = 0; side < 2; ++side) {
        const std::uint32_t slice = k + std::uint32_t(side);
        const std::uint32_t other = side == 0 ? k + 1 : k;
        const DistanceField* f = field(slice);
        if (f == nullptr) {
            continue;
        }
        for (std::uint32_t local = 0; local < rings_[slice].size(); ++local) {
            const Contour& c = contours_.slices[slice].contours[label_contours_[slice][local]];
            if (!c.is_hole) {
                continue;
            }
            const std::uint32_t component = c.region;
            bool linked = false;
            for (const auto& [lower, upper] : background_links_[k]) {
                const auto& here = side == 0 ? lower : upper;
                const auto& there = side == 0 ? upper : lower;
                if (!there.empty() &&
                    std::find(here.begin(), here.end(), component) != here.end()) {
                    linked = true;
                }
            }
            if (linked) {
                continue;
            }
            Pocket pocket;
            pocket.upper = side == 1;
            pocket.field = f;
            for (const Point& p : rings_[slice][local].points) {
                pocket.ring.push_back(to_vec(p));
            }
            pocket.lo = pocket.hi = pocket.ring.front();
            for (const Vec2 p : pocket.ring) {
                pocket.lo = {std::min(pocket.lo.x, p.x), std::min(pocket.lo.y, p.y)};
                pocket.hi = {std::max(pocket.hi.x, p.x), std::max(pocket.hi.y, p.y)};
            }
            // Nothing inside: no other ring of either slice has a point in the hole.
            bool empty = true;
            for (const std::uint32_t s : {slice, other}) {
                for (std::uint32_t l = 0; l < rings_[s].size() && empty; ++l) {
                    if (s == slice && l == local) {
                        continue;
                    }
                    for (const Point& p : rings_[s][l].points) {
                        if (inside_ring(pocket.ring, to_vec(p))) {
                            empty = false;
                            break;
                        }
                    }
                }
            }
            if (!empty) {
                continue;
            }
            // Dmax: the largest field value at the field's nodes inside the hole.
            const double cell = DistanceField::kCellPx;
            for (double y = std::ceil((pocket.lo.y - f->origin_y) / cell) * cell + f->origin_y;
                 y <= pocket.hi.y; y += cell) {
                for (double x = std::ceil((pocket.lo.x - f->origin_x) / cell) * cell + f->origin_x;
                     x <= pocket.hi.x; x += cell) {
                    if (inside_ring(pocket.ring, {x, y})) {
                        pocket.dmax = std::max(pocket.dmax, sample_field(f, {x, y}));
                    }
                }
            }
            if (!(pocket.dmax > 1.0)) {
                continue;
            }
            // H from the hole's partners on the far side (slab k-1 for a hole of slice k).
            const double area = background_area(slice, component);
            double partner_area = 0.0;
            const bool far_exists = side == 0 ? k >= 1 : k + 2 < contours_.slices.size();
            if (far_exists) {
                const std::uint32_t far_slab = side == 0 ? k - 1 : k + 1;
                const std::uint32_t far_slice = side == 0 ? k - 1 : k + 2;
                for (const auto& [lower, upper] : background_links_[far_slab]) {
                    const auto& here = side == 0 ? upper : lower;
                    const auto& there = side == 0 ? lower : upper;
                    if (std::find(here.begin(), here.end(), component) == here.end()) {
                        continue;
                    }
                    double siblings = 0.0;
                    for (const std::uint32_t h : here) {
                        siblings += background_area(slice, h);
                    }
                    double far = 0.0;
                    for (const std::uint32_t t : there) {
                        far += background_area(far_slice, t);
                    }
                    partner_area += far * (siblings > 0.0 ? area / siblings : 1.0);
                }
            }
            pocket.height = dome_height(paraboloid_height(d, area, partner_area)) / d;
            pockets.push_back(std::move(pocket));
        }
    }
    return pockets;
}

double LabelSurface::pocket_t(Vec2 q, std::uint32_t k, double t) const {
    if (pockets_slab_ != std::int64_t(k)) {
        pockets_ = find_pockets(k);
        pockets_slab_ = k;
    }
    for (const Pocket& pocket : pockets_) {
        if (q.x < pocket.lo.x || q.y < pocket.lo.y || q.x > pocket.hi.x || q.y > pocket.hi.y ||
            !inside_ring(pocket.ring, q)) {
            continue;
        }
        const double dome =
            dome_rise(pocket.height, std::max(sample_field(pocket.field, q), 0.0), pocket.dmax);
        return pocket.upper ? std::min(t, 1.0 - dome) : std::max(t, dome);
    }
    return t;
}

}  // namespace strata::detail
