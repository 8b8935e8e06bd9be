#include "input/planar_contours.h"

#include <algorithm>
#include <array>
#include <cctype>
#include <cmath>
#include <map>
#include <numeric>
#include <sstream>

#include "core/error.h"

namespace strata {

namespace {

std::string format_mm(double v) {
    std::ostringstream out;
    out.precision(6);
    out << v;
    return out.str();
}

std::string roi_where(const RawRoi& roi) {
    return "ROI " + std::to_string(roi.number) + (roi.name.empty() ? "" : " (" + roi.name + ")");
}

Vec3 normalized(Vec3 a) {
    const double n = norm(a);
    return n > 0.0 ? (1.0 / n) * a : a;
}

/// Newell's normal of a closed polygon (twice the area vector); zero for degenerate ones.
Vec3 newell_normal(const std::vector<Vec3>& p) {
    Vec3 n;
    for (std::size_t i = 0; i < p.size(); ++i) {
        const Vec3 a = p[i];
        const Vec3 b = p[(i + 1) % p.size()];
        n.x += (a.y - b.y) * (a.z + b.z);
        n.y += (a.z - b.z) * (a.x + b.x);
        n.z += (a.x - b.x) * (a.y + b.y);
    }
    return n;
}

double signed_area(const std::vector<Vec2>& p) {
    double a = 0.0;
    for (std::size_t i = 0; i < p.size(); ++i) {
        a += cross(p[i], p[(i + 1) % p.size()]);
    }
    return 0.5 * a;
}

double segment_distance(Vec2 p, Vec2 a, Vec2 b) {
    const Vec2 ab = b - a;
    const double len2 = dot(ab, ab);
    double t = len2 > 0.0 ? dot(p - a, ab) / len2 : 0.0;
    t = std::clamp(t, 0.0, 1.0);
    return norm(p - (a + t * ab));
}

int orientation(Vec2 a, Vec2 b, Vec2 c) {
    const double v = cross(b - a, c - a);
    return (v > 0.0) - (v < 0.0);
}

bool segments_cross(Vec2 a, Vec2 b, Vec2 c, Vec2 d) {
    const int o1 = orientation(a, b, c);
    const int o2 = orientation(a, b, d);
    const int o3 = orientation(c, d, a);
    const int o4 = orientation(c, d, b);
    return o1 * o2 < 0 && o3 * o4 < 0;
}

/// Removes repeated points (closer than `eps`, the closing point included) and collinear points
/// (closer than `collinear` to the segment between their neighbours) of a closed polygon.
void remove_degenerate_points(std::vector<Vec2>& p,
                              double eps,
                              double collinear,
                              std::size_t& duplicates,
                              std::size_t& collinears) {
    std::vector<Vec2> out;
    out.reserve(p.size());
    for (const Vec2 q : p) {
        if (!out.empty() && norm(q - out.back()) < eps) {
            ++duplicates;
            continue;
        }
        out.push_back(q);
    }
    while (out.size() > 1 && norm(out.front() - out.back()) < eps) {
        out.pop_back();
        ++duplicates;
    }
    bool changed = true;
    while (changed && out.size() >= 3) {
        changed = false;
        std::vector<Vec2> kept;
        kept.reserve(out.size());
        for (std::size_t i = 0; i < out.size(); ++i) {
            const Vec2 prev = kept.empty() ? out[(i + out.size() - 1) % out.size()] : kept.back();
            const Vec2 next = out[(i + 1) % out.size()];
            if (segment_distance(out[i], prev, next) < collinear && norm(next - prev) >= eps) {
                ++collinears;
                changed = true;
                continue;
            }
            kept.push_back(out[i]);
        }
        out = std::move(kept);
    }
    p = std::move(out);
}

/// Pairs of non-adjacent edges that cross properly, and pairs of edges that run over each other in
/// opposite directions (keyhole cuts), of a closed polygon.
void count_self_crossings(const std::vector<Vec2>& p,
                          std::size_t& crossings,
                          std::size_t& keyholes) {
    const std::size_t n = p.size();
    std::vector<std::size_t> order(n);
    std::iota(order.begin(), order.end(), std::size_t{0});
    auto lo = [&](std::size_t e) { return std::min(p[e].x, p[(e + 1) % n].x); };
    auto hi = [&](std::size_t e) { return std::max(p[e].x, p[(e + 1) % n].x); };
    std::sort(order.begin(), order.end(),
              [&](std::size_t a, std::size_t b) { return lo(a) < lo(b); });
    for (std::size_t ia = 0; ia < n; ++ia) {
        const std::size_t a = order[ia];
        for (std::size_t ib = ia + 1; ib < n && lo(order[ib]) <= hi(a); ++ib) {
            const std::size_t b = order[ib];
            if ((a + 1) % n == b || (b + 1) % n == a) {
                continue;
            }
            const Vec2 a0 = p[a], a1 = p[(a + 1) % n], b0 = p[b], b1 = p[(b + 1) % n];
            if (segments_cross(a0, a1, b0, b1)) {
                ++crossings;
            } else if (orientation(a0, a1, b0) == 0 && orientation(a0, a1, b1) == 0 &&
                       dot(a1 - a0, b1 - b0) < 0.0) {
                const Vec2 d = a1 - a0;
                const double t0 = dot(b0 - a0, d), t1 = dot(b1 - a0, d);
                if (std::max(t0, t1) > 0.0 && std::min(t0, t1) < dot(d, d)) {
                    ++keyholes;
                }
            }
        }
    }
}

struct Counts {
    std::size_t duplicates = 0;
    std::size_t collinear = 0;
    std::size_t projected = 0;
    double largest_off_plane = 0.0;
    std::size_t opened = 0;
    std::size_t degenerate = 0;
    std::size_t points = 0;
    std::size_t self_crossing = 0;
    std::size_t keyholes = 0;
    std::size_t nonplanar = 0;
};

/// The plane normal: the reference grid's, else the area-weighted mean of the contours'.
Vec3 plane_normal(const RawContourSet& raw) {
    for (const RawRoi& roi : raw.rois) {
        for (const RawContour& c : roi.contours) {
            for (const Vec3 p : c.points) {
                if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z)) {
                    throw Error(ErrorCode::InvalidInput,
                                raw.source + ": " + c.where + ": a coordinate is not finite");
                }
            }
        }
    }
    if (raw.reference) {
        return normalized(cross(raw.reference->row_direction, raw.reference->column_direction));
    }
    Vec3 sum;
    for (const RawRoi& roi : raw.rois) {
        for (const RawContour& c : roi.contours) {
            if (c.geometric_type != "CLOSED_PLANAR" || c.points.size() < 3) {
                continue;
            }
            Vec3 n = newell_normal(c.points);
            // note: holes may wind either way; align every normal with the first
            if (dot(n, sum) < 0.0 || (dot(sum, sum) == 0.0 && n.z < 0.0)) {
                n = -1.0 * n;
            }
            sum = sum + n;
        }
    }
    return dot(sum, sum) > 0.0 ? normalized(sum) : Vec3{0, 0, 1};
}

/// One ROI's contours in the plane frame of `result` (its axes set), grouped by plane; what it
/// met on the way is counted in `counts`.
ContourObject clean_roi(const RawRoi& roi,
                        const PlanarContours& result,
                        const ContourCleaningOptions& options,
                        Counts& counts) {
    const Vec3 normal = result.normal;
    const Vec3 u = result.axis_u;
    const Vec3 v = result.axis_v;
    ContourObject object;
    object.number = roi.number;
    object.name = roi.name.empty() ? "ROI " + std::to_string(roi.number) : roi.name;
    object.interpreted_type = roi.interpreted_type;
    object.color = roi.color.value_or(ColorSrgb8{0, 0, 0});
    std::vector<std::pair<double, PlaneContour>> flat;
    for (const RawContour& c : roi.contours) {
        if (c.points.empty()) {
            ++counts.degenerate;
            continue;
        }
        if (c.geometric_type == "POINT") {
            object.markers.insert(object.markers.end(), c.points.begin(), c.points.end());
            ++counts.points;
            continue;
        }
        // Position along the normal: the mean; every point must be close to it.
        double w = 0.0;
        for (const Vec3 p : c.points) {
            w += dot(p, normal);
        }
        w /= double(c.points.size());
        double off = 0.0;
        for (const Vec3 p : c.points) {
            off = std::max(off, std::abs(dot(p, normal) - w));
        }
        if (off > options.max_off_plane_mm) {
            if (c.geometric_type == "OPEN_NONPLANAR") {
                object.markers.insert(object.markers.end(), c.points.begin(), c.points.end());
                ++counts.nonplanar;
                continue;
            }
            throw Error(ErrorCode::InvalidInput,
                        result.source + ": " + c.where + ": a point lies " + format_mm(off) +
                            " mm off the contour's plane (normal " + format_mm(normal.x) + ", " +
                            format_mm(normal.y) + ", " + format_mm(normal.z) +
                            "), expected planar contours on parallel planes (at most " +
                            format_mm(options.max_off_plane_mm) + " mm)");
        }
        if (off > options.plane_merge_mm) {
            ++counts.projected;
            counts.largest_off_plane = std::max(counts.largest_off_plane, off);
        }
        PlaneContour pc;
        pc.points.reserve(c.points.size());
        for (const Vec3 p : c.points) {
            pc.points.push_back({dot(p, u), dot(p, v)});
        }
        if (c.geometric_type != "CLOSED_PLANAR") {
            ++counts.opened;  // note: closed by the chord from its last point to its first
        }
        remove_degenerate_points(pc.points, options.duplicate_mm, options.collinear_mm,
                                 counts.duplicates, counts.collinear);
        if (pc.points.size() < 3 || std::abs(signed_area(pc.points)) < 1e-9) {
            ++counts.degenerate;
            for (const Vec3 p : c.points) {
                object.markers.push_back(p);
            }
            continue;
        }
        std::size_t crossings = 0;
        std::size_t keyholes = 0;
        count_self_crossings(pc.points, crossings, keyholes);
        counts.self_crossing += crossings > 0;
        counts.keyholes += keyholes > 0;
        flat.emplace_back(w, std::move(pc));
    }
    std::stable_sort(flat.begin(), flat.end(),
                     [](const auto& a, const auto& b) { return a.first < b.first; });
    for (auto& [w, contour] : flat) {
        if (object.planes.empty() || w - object.planes.back().w > options.plane_merge_mm) {
            object.planes.push_back({w, {}});
        }
        object.planes.back().contours.push_back(std::move(contour));
    }
    return object;
}

/// The warnings of one ROI: what cleaning it changed or left out.
void warn_counts(const Counts& counts,
                 const RawRoi& roi,
                 const ContourObject& object,
                 const std::string& where,
                 Report& report) {
    if (counts.duplicates > 0 || counts.collinear > 0) {
        report.warn("input", where,
                    std::to_string(counts.duplicates) + " repeated and " +
                        std::to_string(counts.collinear) +
                        " collinear contour points removed (the polygons are unchanged)");
    }
    if (counts.projected > 0) {
        report.warn("input", where,
                    std::to_string(counts.projected) + " contour(s) up to " +
                        format_mm(counts.largest_off_plane) +
                        " mm off their plane: projected onto it");
    }
    // What each single count means, in the order the warnings are given.
    struct CountWarning {
        std::size_t Counts::*count;
        const char* what;
    };
    static constexpr std::array<CountWarning, 4> kCountWarnings{{
        {&Counts::opened,
         " open contour(s) closed by the segment from their last point to their first"},
        {&Counts::self_crossing,
         " contour(s) cross themselves: their inside is taken by the even-odd rule"},
        {&Counts::keyholes,
         " contour(s) with keyhole cuts (edges running back over each other): the cut has no "
         "area, the hole stays a hole"},
        {&Counts::degenerate,
         " contour(s) with fewer than 3 distinct points or no area: kept as markers, not "
         "surfaces"},
    }};
    for (const CountWarning& warning : kCountWarnings) {
        if (counts.*warning.count > 0) {
            report.warn("input", where, std::to_string(counts.*warning.count) + warning.what);
        }
    }
    if (counts.points > 0 || counts.nonplanar > 0) {
        report.warn("input", where,
                    std::to_string(counts.points) + " POINT and " +
                        std::to_string(counts.nonplanar) +
                        " OPEN_NONPLANAR contour(s): kept as markers, not surfaces");
    }
    if (object.planes.empty()) {
        report.warn("input", where,
                    roi.contours.empty() ? "no contours: no surface"
                                         : "no closed contour with area: no surface");
    }
}

/// Plane spacing over all structures: uneven spacing and planes a structure skips.
void warn_plane_spacing(const PlanarContours& result,
                        const ContourCleaningOptions& options,
                        Report& report) {
    std::vector<double> all_planes;
    for (const ContourObject& object : result.objects) {
        for (const ContourPlane& plane : object.planes) {
            all_planes.push_back(plane.w);
        }
    }
    std::sort(all_planes.begin(), all_planes.end());
    std::vector<double> planes;
    for (const double w : all_planes) {
        if (planes.empty() || w - planes.back() > options.plane_merge_mm) {
            planes.push_back(w);
        }
    }
    if (planes.size() > 2) {
        double lo = planes[1] - planes[0];
        double hi = lo;
        for (std::size_t i = 1; i + 1 < planes.size(); ++i) {
            lo = std::min(lo, planes[i + 1] - planes[i]);
            hi = std::max(hi, planes[i + 1] - planes[i]);
        }
        if (hi - lo > options.plane_merge_mm) {
            report.warn("input", result.source,
                        "uneven plane spacing: " + format_mm(lo) + " to " + format_mm(hi) +
                            " mm between the " + std::to_string(planes.size()) + " planes");
        }
    }
    std::vector<double> gaps;
    for (std::size_t i = 0; i + 1 < planes.size(); ++i) {
        gaps.push_back(planes[i + 1] - planes[i]);
    }
    std::sort(gaps.begin(), gaps.end());
    const double median = gaps.empty() ? 0.0 : gaps[gaps.size() / 2];
    for (const ContourObject& object : result.objects) {
        std::size_t missing = 0;
        double widest = 0.0;
        for (std::size_t i = 0; i + 1 < object.planes.size(); ++i) {
            const double gap = object.planes[i + 1].w - object.planes[i].w;
            if (gap > 1.5 * median) {
                missing += std::size_t(std::llround(gap / median)) - 1;
                widest = std::max(widest, gap);
            }
        }
        if (missing > 0) {
            report.warn("input", "ROI " + std::to_string(object.number) + " (" + object.name + ")",
                        "about " + std::to_string(missing) +
                            " plane(s) inside its range carry no contour of it (gaps up to " +
                            format_mm(widest) + " mm where planes are " + format_mm(median) +
                            " mm apart): its surface is built between the planes it has");
        }
    }
}

}  // namespace

PlanarContours clean_planar_contours(const RawContourSet& raw,
                                     const ContourCleaningOptions& options,
                                     Report& report) {
    PlanarContours result;
    result.source = raw.source;
    result.frame = raw.frame;
    result.reference = raw.reference;
    const Vec3 normal = plane_normal(raw);
    // Axes: u is the patient x axis projected into the plane (the reference grid's row
    // direction when there is one), v = normal x u.
    Vec3 u = raw.reference ? raw.reference->row_direction : Vec3{1, 0, 0};
    u = u - dot(u, normal) * normal;
    if (norm(u) < 1e-6) {
        u = Vec3{0, 1, 0} - normal.y * normal;
    }
    u = normalized(u);
    const Vec3 v = cross(normal, u);
    result.axis_u = u;
    result.axis_v = v;
    result.normal = normal;
    const double tilt = std::acos(std::clamp(std::abs(normal.z), 0.0, 1.0)) * 180.0 / M_PI;
    if (tilt > 0.01) {
        report.warn("input", raw.source,
                    "the contour planes are tilted " + format_mm(tilt) +
                        " degrees from axial (normal " + format_mm(normal.x) + ", " +
                        format_mm(normal.y) + ", " + format_mm(normal.z) +
                        "): the planes are kept tilted, slices follow them");
    }

    for (const RawRoi& roi : raw.rois) {
        const std::string where = roi_where(roi);
        Counts counts;
        ContourObject object = clean_roi(roi, result, options, counts);
        if (roi.name.empty()) {
            report.warn("input", where, "no ROI name; named '" + object.name + "'");
        }
        warn_counts(counts, roi, object, where, report);
        result.objects.push_back(std::move(object));
    }
    warn_plane_spacing(result, options, report);
    return result;
}

void select_contour_objects(PlanarContours& contours, const std::vector<std::string>& selectors) {
    const auto lower = [](std::string t) {
        std::transform(t.begin(), t.end(), t.begin(),
                       [](unsigned char c) { return char(std::tolower(c)); });
        return t;
    };
    std::vector<bool> keep(contours.objects.size(), false);
    for (const std::string& selector : selectors) {
        bool found = false;
        for (std::size_t i = 0; i < contours.objects.size(); ++i) {
            const ContourObject& o = contours.objects[i];
            if (selector == std::to_string(o.number) || lower(selector) == lower(o.name)) {
                keep[i] = found = true;
            }
        }
        if (!found) {
            std::string names;
            for (const ContourObject& o : contours.objects) {
                names += (names.empty() ? "" : ", ") + std::to_string(o.number) + " " + o.name;
            }
            throw Error(ErrorCode::InvalidInput, "--labels: '" + selector +
                                                     "' names no structure of " + contours.source +
                                                     " (" + names + ")");
        }
    }
    std::vector<ContourObject> kept;
    for (std::size_t i = 0; i < contours.objects.size(); ++i) {
        if (keep[i]) {
            kept.push_back(std::move(contours.objects[i]));
        }
    }
    contours.objects = std::move(kept);
}

}  // namespace strata
