#include "pipeline/reconstruct_contours.h"

#include <algorithm>
#include <cmath>
#include <iterator>
#include <limits>
#include <sstream>
#include <vector>

#include "core/error.h"
#include "pipeline/contour_distance.h"

namespace strata {

namespace {

struct Extent {
    double lo_u = std::numeric_limits<double>::infinity();
    double lo_v = std::numeric_limits<double>::infinity();
    double hi_u = -std::numeric_limits<double>::infinity();
    double hi_v = -std::numeric_limits<double>::infinity();
    bool empty() const { return !(lo_u <= hi_u); }
};

Extent object_extent(const ContourObject& object) {
    Extent e;
    for (const ContourPlane& plane : object.planes) {
        for (const PlaneContour& c : plane.contours) {
            for (const Vec2 p : c.points) {
                e.lo_u = std::min(e.lo_u, p.x);
                e.hi_u = std::max(e.hi_u, p.x);
                e.lo_v = std::min(e.lo_v, p.y);
                e.hi_v = std::max(e.hi_v, p.y);
            }
        }
    }
    return e;
}

std::string text(double v) {
    std::ostringstream out;
    out.precision(4);
    out << v;
    return out.str();
}

Affine3 plane_affine(const PlanarContours& contours, double pitch, double gap, Vec3 corner) {
    // corner: (u, v, w) of the centre of voxel (0, 0, 0)
    Affine3 a;
    const Vec3 columns[3] = {pitch * contours.axis_u, pitch * contours.axis_v,
                             gap * contours.normal};
    for (int r = 0; r < 3; ++r) {
        for (int c = 0; c < 3; ++c) {
            a.linear[r][c] = columns[c][r];
        }
    }
    a.translation = contours.origin + corner.x * contours.axis_u + corner.y * contours.axis_v +
                    corner.z * contours.normal;
    return a;
}

std::uint16_t object_label(const PlanarContours& contours, std::size_t index) {
    const std::int32_t number = contours.objects[index].number;
    bool unique = number >= 1 && number <= 65535;
    for (std::size_t j = 0; j < contours.objects.size() && unique; ++j) {
        unique = j == index || contours.objects[j].number != number;
    }
    return unique ? std::uint16_t(number) : std::uint16_t(index + 1);
}

/// One plane's input polygons in frame px (pixel i covers [i, i + 1], x = 0 at u0).
PolygonEdges plane_edges(const ContourPlane& plane, const ContourFrame& frame) {
    std::vector<std::vector<Vec2>> polygons;
    for (const PlaneContour& c : plane.contours) {
        std::vector<Vec2>& polygon = polygons.emplace_back();
        for (const Vec2 uv : c.points) {
            polygon.push_back(
                {(uv.x - frame.u0) / frame.pitch_mm, (uv.y - frame.v0) / frame.pitch_mm});
        }
    }
    return PolygonEdges(std::move(polygons));
}

/// An upper bound, within 0.005 px, of the largest distance from a point of segment ab to
/// `index`'s polygons, or `floor` when that largest distance is at most `floor`. Branch and bound
/// on halvings: the distance is 1-Lipschitz, so a piece of length l whose ends are at da and db
/// stays below (da + db + l) / 2.
double segment_sup_distance(const PolygonEdges& index, Vec2 a, Vec2 b, double floor) {
    struct Piece {
        Vec2 a, b;
        double da, db;
    };
    double result = floor;
    std::vector<Piece> stack{{a, b, index.distance(a), index.distance(b)}};
    while (!stack.empty()) {
        const Piece piece = stack.back();
        stack.pop_back();
        result = std::max({result, piece.da, piece.db});
        const double length = norm(piece.b - piece.a);
        const double upper = 0.5 * (piece.da + piece.db + length);
        if (upper <= result) {
            continue;
        }
        if (length <= 0.01) {
            result = upper;
            continue;
        }
        const Vec2 m = 0.5 * (piece.a + piece.b);
        const double dm = index.distance(m);
        stack.push_back({piece.a, m, piece.da, dm});
        stack.push_back({m, piece.b, dm, piece.db});
    }
    return result;
}

/// The z map of one structure from its slice space to the frame (piecewise linear through the
/// planes) and what it does to error bounds measured before it (see remap_bounds).
class PlaneMap {
public:
    PlaneMap(const ContourStack& roi, const ContourFrame& frame) : roi_(roi), frame_(frame) {
        d_ = slice_spacing_px(roi.stack);
        const std::vector<double>& w = roi.plane_w;
        for (std::size_t k = 0; k < w.size(); ++k) {
            z_.push_back((w[k] - frame.first_w) / frame.pitch_mm);
        }
        const double uniform = w.size() > 1 ? (w.back() - w.front()) / double(w.size() - 1) : 1.0;
        for (std::size_t k = 0; k + 1 < w.size(); ++k) {
            const double slope = (w[k + 1] - w[k]) / uniform;
            stretch_ = std::max(stretch_, slope);
            affine_ = affine_ && std::abs(slope - 1.0) <= 1e-9;
        }
    }

    /// True when the map is a translation in z (evenly spaced planes): nothing to re-measure.
    bool affine() const { return affine_; }
    /// The map's Lipschitz constant: the largest plane gap over the mean gap, at least 1.
    double stretch() const { return stretch_; }
    std::size_t planes() const { return z_.size(); }
    /// Frame z of plane k.
    double plane_z(std::size_t k) const { return z_[k]; }
    /// Slice-space z of plane k.
    double slice_z(std::size_t k) const { return double(k) * d_; }
    double map(double z) const { return contour_to_frame(roi_, frame_, {0.0, 0.0, z}).z; }

    /// The index of the slab [k d, (k + 1) d] holding slice-space z values z0 <= z1, or -1 when
    /// they are in no single slab (the map bends between them).
    std::int64_t slab(double z0, double z1) const {
        const double eps = 1e-9 * std::max(1.0, std::abs(z1));
        const double k = std::floor((z0 + eps) / d_);
        return z1 <= (k + 1.0) * d_ + eps ? std::int64_t(k) : -1;
    }

    /// Largest |map(sum l_i z_i) - sum l_i map(z_i)| over the convex combinations of slice-space
    /// z values in [z0, z1]: the oscillation of the map minus its chord over [z0, z1] (the map is
    /// linear between planes, so the extremes are at planes inside).
    double chord_gap(double z0, double z1) const {
        const double f0 = map(z0);
        const double f1 = map(z1);
        double lo = 0.0;
        double hi = 0.0;
        if (z1 > z0) {
            const auto k0 = std::int64_t(std::ceil(z0 / d_));
            const auto k1 = std::int64_t(std::floor(z1 / d_));
            for (std::int64_t k = std::max<std::int64_t>(k0, 0);
                 k <= std::min<std::int64_t>(k1, std::int64_t(z_.size()) - 1); ++k) {
                const double z = double(k) * d_;
                const double h = z_[std::size_t(k)] - (f0 + (z - z0) * (f1 - f0) / (z1 - z0));
                lo = std::min(lo, h);
                hi = std::max(hi, h);
            }
        }
        return hi - lo;
    }

private:
    const ContourStack& roi_;
    const ContourFrame& frame_;
    double d_ = 1.0;
    std::vector<double> z_;
    double stretch_ = 1.0;
    bool affine_ = true;
};

/// Makes `model`'s bounds, measured in `roi`'s slice space (evenly spaced planes), true in the
/// frame after the plane map; `slice_z`: every position's slice-space z before the map,
/// `model.positions` already mapped. Between two planes the map is linear, so a triangle within
/// one slab keeps its sections and its bound; for each group:
/// - to the contours: every produced triangle spanning several slabs is cut by every plane it
///   meets in the frame, and the section measured against that plane's input polygons (exact
///   distances, branch and bound to 0.005 px);
/// - from the contours: a contour point within e of the surface in slice space stays within
///   stretch * e of the mapped surface, plus the largest z gap between a mapped triangle and the
///   map of its points (chord_gap over its z range), since the map moves points in z only.
/// The bound becomes the larger of the two, then monotone along the DAG again.
void remap_bounds(MultiresMesh& model,
                  const std::vector<double>& slice_z,
                  const PlaneMap& map,
                  const std::vector<PolygonEdges>& polygons) {
    const double stretch = map.stretch();
    for (MultiresGroup& g : model.groups) {
        double to_contours = g.error_px;
        double gap = 0.0;
        for (const std::uint32_t id : g.produced) {
            const MultiresCluster& c = model.clusters[id];
            for (const auto& t : c.triangles) {
                const std::uint32_t v[3] = {c.vertices[t[0]], c.vertices[t[1]], c.vertices[t[2]]};
                const double z0 = std::min({slice_z[v[0]], slice_z[v[1]], slice_z[v[2]]});
                const double z1 = std::max({slice_z[v[0]], slice_z[v[1]], slice_z[v[2]]});
                if (map.slab(z0, z1) >= 0) {
                    continue;
                }
                gap = std::max(gap, map.chord_gap(z0, z1));
                const Vec3 p[3] = {model.positions[v[0]], model.positions[v[1]],
                                   model.positions[v[2]]};
                const double f0 = std::min({p[0].z, p[1].z, p[2].z});
                const double f1 = std::max({p[0].z, p[1].z, p[2].z});
                for (std::size_t k = 0; k < map.planes(); ++k) {
                    const double z = map.plane_z(k);
                    const double eps = 1e-9 * std::max(1.0, std::abs(z));
                    if (z < f0 - eps || z > f1 + eps) {
                        continue;
                    }
                    // the section: the in-plane vertices and the crossings of the other edges
                    std::vector<Vec2> ends;
                    for (int i = 0; i < 3; ++i) {
                        const Vec3 a = p[i];
                        const Vec3 b = p[(i + 1) % 3];
                        const bool a_in = std::abs(a.z - z) <= eps;
                        const bool b_in = std::abs(b.z - z) <= eps;
                        if (a_in) {
                            ends.push_back({a.x, a.y});
                        } else if (!b_in && (a.z < z) != (b.z < z)) {
                            const double s = (z - a.z) / (b.z - a.z);
                            ends.push_back({a.x + s * (b.x - a.x), a.y + s * (b.y - a.y)});
                        }
                    }
                    const PolygonEdges& index = polygons[k];
                    if (ends.size() == 1) {
                        to_contours = std::max(to_contours, index.distance(ends[0]));
                    }
                    for (std::size_t i = 0; i + 1 < ends.size(); ++i) {
                        for (std::size_t j = i + 1; j < ends.size(); ++j) {
                            to_contours =
                                segment_sup_distance(index, ends[i], ends[j], to_contours);
                        }
                    }
                }
            }
        }
        g.error_px = std::max(to_contours, stretch * g.error_px + gap);
    }
    // monotone again: a group's bound is never below that of a group whose clusters it consumes
    for (MultiresGroup& g : model.groups) {
        for (const std::uint32_t id : g.consumed) {
            const std::int32_t producer = model.clusters[id].producer;
            if (producer >= 0) {
                g.error_px = std::max(g.error_px, model.groups[std::size_t(producer)].error_px);
            }
        }
    }
}

}  // namespace

ContourFrame contour_frame(const PlanarContours& contours,
                           const ContourGridOptions& options,
                           Report& report) {
    ContourFrame frame;
    std::vector<double> planes;
    Extent all;
    double largest = 0.0;
    std::vector<Extent> extents;
    for (const ContourObject& object : contours.objects) {
        extents.push_back(object_extent(object));
        const Extent& e = extents.back();
        for (const ContourPlane& plane : object.planes) {
            planes.push_back(plane.w);
        }
        if (e.empty()) {
            continue;
        }
        all.lo_u = std::min(all.lo_u, e.lo_u);
        all.lo_v = std::min(all.lo_v, e.lo_v);
        all.hi_u = std::max(all.hi_u, e.hi_u);
        all.hi_v = std::max(all.hi_v, e.hi_v);
        largest = std::max({largest, e.hi_u - e.lo_u, e.hi_v - e.lo_v});
    }
    std::sort(planes.begin(), planes.end());
    std::vector<double> distinct;
    for (const double w : planes) {
        if (distinct.empty() || w - distinct.back() > 0.01) {
            distinct.push_back(w);
        }
    }
    std::vector<double> gaps;
    for (std::size_t i = 0; i + 1 < distinct.size(); ++i) {
        gaps.push_back(distinct[i + 1] - distinct[i]);
    }
    std::sort(gaps.begin(), gaps.end());
    const double gap = gaps.empty() ? 1.0 : gaps[gaps.size() / 2];

    double pitch = options.pitch_mm;
    std::string why = "given";
    if (!(pitch > 0.0)) {
        if (contours.reference) {
            pitch = std::max(contours.reference->pixel_mm[0], contours.reference->pixel_mm[1]) / 4;
            why = "a quarter of the reference grid's pixel";
        } else {
            pitch = largest > 0.0 ? largest / 1024.0 : 1.0;
            why = "the largest structure's extent / 1024";
        }
        // coarsen until every structure fits max_voxels
        for (std::size_t i = 0; i < contours.objects.size(); ++i) {
            const Extent& e = extents[i];
            if (e.empty()) {
                continue;
            }
            const double margin = 2.0 * options.margin_px + 2.0;
            const double slices = double(contours.objects[i].planes.size());
            while ((std::ceil((e.hi_u - e.lo_u) / pitch) + margin) *
                       (std::ceil((e.hi_v - e.lo_v) / pitch) + margin) * slices >
                   double(options.max_voxels)) {
                pitch *= 1.25;
                why = "coarsened to fit " + std::to_string(options.max_voxels) +
                      " voxels per structure";
            }
        }
    }
    if (!(pitch > 0.0) || !std::isfinite(pitch) ||
        std::max(all.hi_u - all.lo_u, all.hi_v - all.lo_v) / pitch > 1e9) {
        throw Error(ErrorCode::InvalidInput, contours.source + ": a pixel pitch of " + text(pitch) +
                                                 " mm is too fine for contours spanning " +
                                                 text(largest) +
                                                 " mm; expected at most 1e9 pixels across");
    }
    frame.pitch_mm = pitch;
    frame.slice_spacing_px = gap / pitch;
    frame.first_w = distinct.empty() ? 0.0 : distinct.front();
    if (all.empty()) {
        all = {0, 0, 0, 0};
    }
    const double margin = options.margin_px * pitch;
    if (contours.reference) {
        // align the pixel corners with the reference grid's
        const PlaneGrid& g = *contours.reference;
        const Vec3 corner = g.origin - (0.5 * g.pixel_mm[0]) * g.row_direction -
                            (0.5 * g.pixel_mm[1]) * g.column_direction - contours.origin;
        const double cu = dot(corner, contours.axis_u);
        const double cv = dot(corner, contours.axis_v);
        frame.u0 = cu - std::ceil((cu - (all.lo_u - margin)) / pitch) * pitch;
        frame.v0 = cv - std::ceil((cv - (all.lo_v - margin)) / pitch) * pitch;
    } else {
        frame.u0 = std::floor(all.lo_u / pitch) * pitch - margin;
        frame.v0 = std::floor(all.lo_v / pitch) * pitch - margin;
    }
    SliceStack& s = frame.stack;
    s.width = std::uint32_t(std::ceil((all.hi_u + margin - frame.u0) / pitch));
    s.height = std::uint32_t(std::ceil((all.hi_v + margin - frame.v0) / pitch));
    s.depth = 0;  // note: no voxels; the structures have their own stacks
    s.index_to_world = plane_affine(
        contours, pitch, gap, {frame.u0 + 0.5 * pitch, frame.v0 + 0.5 * pitch, frame.first_w});
    s.source = contours.source;
    s.source_frame = contours.frame;
    for (std::size_t i = 0; i < contours.objects.size(); ++i) {
        const ContourObject& object = contours.objects[i];
        const std::uint16_t label = object_label(contours, i);
        const bool colored = object.color != ColorSrgb8{0, 0, 0};
        s.label_table.push_back(
            {label, object.name, colored ? object.color : palette_color(label)});
    }
    report.warn("input", contours.source,
                "contours scan-converted on a " + text(pitch) + " mm pixel grid (" + why +
                    "); planes " + text(gap) + " mm apart (median) in slice space");
    return frame;
}

ContourStack contour_stack(const ContourObject& object,
                           std::uint16_t label,
                           const ContourFrame& frame,
                           const ContourGridOptions& options) {
    ContourStack roi;
    const Extent e = object_extent(object);
    if (object.planes.empty() || e.empty()) {
        return roi;
    }
    const double pitch = frame.pitch_mm;
    const auto m = std::int64_t(options.margin_px);
    roi.offset_x = std::int64_t(std::floor((e.lo_u - frame.u0) / pitch)) - m;
    roi.offset_y = std::int64_t(std::floor((e.lo_v - frame.v0) / pitch)) - m;
    const std::int64_t x1 = std::int64_t(std::ceil((e.hi_u - frame.u0) / pitch)) + m;
    const std::int64_t y1 = std::int64_t(std::ceil((e.hi_v - frame.v0) / pitch)) + m;
    SliceStack& s = roi.stack;
    const auto depth = std::uint64_t(object.planes.size());
    check_stack_dimensions(std::uint64_t(x1 - roi.offset_x), std::uint64_t(y1 - roi.offset_y),
                           depth,
                           "ROI " + std::to_string(object.number) + " (" + object.name + ")");
    s.width = std::uint32_t(x1 - roi.offset_x);
    s.height = std::uint32_t(y1 - roi.offset_y);
    s.depth = std::uint32_t(depth);
    for (const ContourPlane& plane : object.planes) {
        roi.plane_w.push_back(plane.w);
    }
    const double gap = depth > 1 ? (roi.plane_w.back() - roi.plane_w.front()) / double(depth - 1)
                                 : frame.slice_spacing_px * pitch;
    const double corner_u = frame.u0 + (double(roi.offset_x) + 0.5) * pitch;
    const double corner_v = frame.v0 + (double(roi.offset_y) + 0.5) * pitch;
    PlanarContours axes;  // note: only the axes are read
    axes.axis_u = frame.stack.index_to_world.column(0);
    axes.axis_v = frame.stack.index_to_world.column(1);
    axes.normal = frame.stack.index_to_world.column(2);
    axes.axis_u = (1.0 / norm(axes.axis_u)) * axes.axis_u;
    axes.axis_v = (1.0 / norm(axes.axis_v)) * axes.axis_v;
    axes.normal = (1.0 / norm(axes.normal)) * axes.normal;
    const Vec3 frame_corner = frame.stack.index_to_world.translation -
                              (frame.u0 + 0.5 * pitch) * axes.axis_u -
                              (frame.v0 + 0.5 * pitch) * axes.axis_v - frame.first_w * axes.normal;
    axes.origin = frame_corner;
    s.index_to_world = plane_affine(axes, pitch, gap, {corner_u, corner_v, roi.plane_w.front()});
    s.labels.assign(s.slice_size() * depth, 0);
    s.label_table.push_back({label, object.name, object.color});
    s.source = object.name;
    s.source_frame = frame.stack.source_frame;

    std::vector<double> crossings;
    for (std::uint32_t k = 0; k < s.depth; ++k) {
        std::span<std::uint16_t> slice = s.slice(k);
        for (std::uint32_t j = 0; j < s.height; ++j) {
            const double y = corner_v + double(j) * pitch;  // row j's pixel centres
            crossings.clear();
            for (const PlaneContour& c : object.planes[k].contours) {
                const std::size_t n = c.points.size();
                for (std::size_t i = 0; i < n; ++i) {
                    const Vec2 a = c.points[i];
                    const Vec2 b = c.points[(i + 1) % n];
                    if ((a.y > y) != (b.y > y)) {
                        const double x = a.x + (y - a.y) * (b.x - a.x) / (b.y - a.y);
                        crossings.push_back((x - corner_u) / pitch);  // in column units
                    }
                }
            }
            std::sort(crossings.begin(), crossings.end());
            for (std::size_t i = 0; i + 1 < crossings.size(); i += 2) {
                const auto from = std::max<std::int64_t>(0, std::int64_t(std::ceil(crossings[i])));
                const auto to =
                    std::min<std::int64_t>(s.width, std::int64_t(std::ceil(crossings[i + 1])));
                for (std::int64_t col = from; col < to; ++col) {
                    slice[std::size_t(j) * s.width + std::size_t(col)] = label;
                }
            }
        }
    }
    return roi;
}

Vec3 contour_to_frame(const ContourStack& roi, const ContourFrame& frame, Vec3 p) {
    const std::vector<double>& w = roi.plane_w;
    const double d = slice_spacing_px(roi.stack);
    const double k = p.z / d;
    double at = w.front();
    if (w.size() == 1) {
        at += k * d * frame.pitch_mm;
    } else {
        const auto i = std::size_t(std::clamp(std::floor(k), 0.0, double(w.size() - 2)));
        at = w[i] + (k - double(i)) * (w[i + 1] - w[i]);
    }
    return {p.x + double(roi.offset_x), p.y + double(roi.offset_y),
            (at - frame.first_w) / frame.pitch_mm};
}

Reconstruction reconstruct_contours(const PlanarContours& contours,
                                    const ContourFrame& frame,
                                    const ContourGridOptions& grid,
                                    const ReconstructOptions& options,
                                    Report& report) {
    Reconstruction result;
    result.slice_spacing_px = frame.slice_spacing_px;
    for (std::size_t i = 0; i < contours.objects.size(); ++i) {
        const ContourObject& object = contours.objects[i];
        const std::uint16_t label = frame.stack.label_table[i].value;
        const ContourStack roi = contour_stack(object, label, frame, grid);
        if (roi.stack.depth == 0) {
            continue;
        }
        Reconstruction part = reconstruct(roi.stack, options, report);
        for (const StageTiming& t : part.timings) {
            auto it = std::find_if(result.timings.begin(), result.timings.end(),
                                   [&](const StageTiming& s) { return s.stage == t.stage; });
            if (it == result.timings.end()) {
                result.timings.push_back(t);
            } else {
                it->seconds += t.seconds;
                it->cpu_seconds += t.cpu_seconds;
            }
        }
        const PlaneMap map(roi, frame);
        std::vector<PolygonEdges> polygons;
        if (!map.affine()) {
            for (const ContourPlane& plane : object.planes) {
                polygons.push_back(plane_edges(plane, frame));
            }
        }
        for (ObjectSurface& surface : part.surfaces) {
            for (Vec3& p : surface.mesh.positions) {
                p = contour_to_frame(roi, frame, p);
            }
            result.surfaces.push_back(std::move(surface));
        }
        std::move(part.repairs.begin(), part.repairs.end(), std::back_inserter(result.repairs));
        for (MultiresMesh& model : part.models) {
            // The bounds are against the traced pixel boundary; it lies within half a pixel
            // diagonal of the polygons (a boundary edge separates an inside pixel centre from an
            // outside one, so the polygon crosses the segment between them).
            model.full_resolution_error_px += kScanConversionPx;
            for (MultiresGroup& g : model.groups) {
                g.error_px += kScanConversionPx;
            }
            std::vector<double> slice_z;
            for (Vec3& p : model.positions) {
                slice_z.push_back(p.z);
                p = contour_to_frame(roi, frame, p);
            }
            if (!map.affine()) {
                remap_bounds(model, slice_z, map, polygons);
            }
            for (MultiresCluster& c : model.clusters) {
                c.bounds.center = contour_to_frame(roi, frame, c.bounds.center);
                c.bounds.radius *= map.stretch();
            }
            for (MultiresGroup& g : model.groups) {
                g.bounds.center = contour_to_frame(roi, frame, g.bounds.center);
                g.bounds.radius *= map.stretch();
            }
            result.models.push_back(std::move(model));
        }
    }
    return result;
}

}  // namespace strata
