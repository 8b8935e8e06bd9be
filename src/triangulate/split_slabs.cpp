// Triangulation, last-resort fallback: slabs whose contours overlap unlike the pixels even
// unsimplified are split at the pixels' AND layer, a level half way between the slices with
// its own contours, distance field and links.
#include <algorithm>
#include <cmath>
#include <numeric>

#include "contours/extract_contours.h"
#include "triangulate/detail/label_surface.h"

namespace strata::detail {

namespace {

/// Where contours meet at a saddle corner v the tracer cuts the corner on one side (foreground
/// 8-connected). Moves that cut to distance r of v and cuts the opposite corner by the same
/// amount, so the region covers a small diamond around v: it overlaps whichever of the two
/// diagonal pixels a neighbouring slice has, and the overlap stays connected through v.
void widen_saddles(SliceContourSet& set, double r) {
    std::vector<Vec2> corners;
    for (Contour& c : set.contours) {
        const std::size_t n = c.points.size();
        for (std::size_t i = 0; i < n; ++i) {
            Vec2& a = c.points[i];
            Vec2& b = c.points[(i + 1) % n];
            if (std::abs(std::abs(a.x - b.x) - 0.5) > 1e-12 ||
                std::abs(std::abs(a.y - b.y) - 0.5) > 1e-12) {
                continue;
            }
            const Vec2 v{std::floor(a.x) == a.x ? a.x : b.x, std::floor(a.y) == a.y ? a.y : b.y};
            corners.push_back(v);
            a = v + (r / 0.5) * (a - v);
            b = v + (r / 0.5) * (b - v);
        }
    }
    for (Contour& c : set.contours) {
        std::vector<Vec2> out;
        const std::size_t n = c.points.size();
        for (std::size_t i = 0; i < n; ++i) {
            const Vec2 p = c.points[i];
            if (std::find(corners.begin(), corners.end(), p) == corners.end()) {
                out.push_back(p);
                continue;
            }
            for (const Vec2 q : {c.points[(i + n - 1) % n], c.points[(i + 1) % n]}) {
                const Vec2 d = q - p;
                out.push_back(p + (r / std::sqrt(dot(d, d))) * d);
            }
        }
        c.points = std::move(out);
        c.simplified.resize(c.points.size());
        std::iota(c.simplified.begin(), c.simplified.end(), 0u);
        c.edge_deviation_px.assign(c.points.size(), 0.0);
    }
}

}  // namespace

Levels split_slabs(const SliceStack& stack,
                   const SliceContours& contours,
                   const std::vector<SliceDistanceFields>& fields,
                   const std::vector<MedialAxis>& medial_axes,
                   std::uint16_t label,
                   const std::vector<bool>& split,
                   double d) {
    Levels levels;
    levels.contours.width = contours.width;
    levels.contours.height = contours.height;
    levels.contours.tolerance_px = contours.tolerance_px;
    auto label_fields = [&](const SliceDistanceFields& all) {
        SliceDistanceFields out;
        for (const DistanceField& f : all.fields) {
            if (f.label == label) {
                out.fields.push_back(f);
            }
        }
        return out;
    };
    std::vector<std::uint32_t> level_of(contours.slices.size());
    for (std::uint32_t k = 0; k < contours.slices.size(); ++k) {
        level_of[k] = std::uint32_t(levels.contours.slices.size());
        levels.contours.slices.push_back(contours.slices[k]);
        levels.fields.push_back(label_fields(fields[k]));
        levels.z.push_back(k * d);
        levels.slice_of.push_back(k);
        if (k + 1 >= contours.slices.size()) {
            break;
        }
        if (!split[k]) {
            MedialAxis axis;
            for (const MedialCurve& curve : medial_axes[k].curves) {
                if (curve.label == label) {
                    axis.curves.push_back(curve);
                }
            }
            levels.medial_axes.push_back(std::move(axis));
            continue;
        }
        // slice k, AND, slice k+1 of this label as a three-slice stack.
        SliceStack mini;
        mini.width = stack.width;
        mini.height = stack.height;
        mini.depth = 3;
        mini.labels.assign(mini.slice_size() * 3, 0);
        const auto lower = stack.slice(k);
        const auto upper = stack.slice(k + 1);
        for (std::size_t i = 0; i < mini.slice_size(); ++i) {
            const bool a = lower[i] == label;
            const bool b = upper[i] == label;
            mini.labels[i] = a ? label : 0;
            mini.labels[mini.slice_size() + i] = a && b ? label : 0;
            mini.labels[2 * mini.slice_size() + i] = b ? label : 0;
        }
        mini.label_table.push_back({label, "label", {}});
        const std::vector<std::uint16_t> only{label};
        const SliceContourSet set0 = trace_slice_contours(mini, 0, only);
        SliceContourSet mid = trace_slice_contours(mini, 1, only);
        const SliceContourSet set2 = trace_slice_contours(mini, 2, only);
        std::vector<RegionLink> down = link_slices(mini, 0, set0, mid, only);
        std::vector<RegionLink> up = link_slices(mini, 1, mid, set2, only);
        SliceDistanceFields mid_fields;
        if (!mid.contours.empty()) {
            mid_fields.fields.push_back(compute_distance_field(mini, mid, 1, label, {}));
        }
        widen_saddles(mid, 0.25);
        const auto m = std::uint32_t(levels.contours.slices.size());
        for (RegionLink& link : down) {
            link.lower_slice = m - 1;
            levels.contours.links.push_back(std::move(link));
        }
        for (RegionLink& link : up) {
            link.lower_slice = m;
            levels.contours.links.push_back(std::move(link));
        }
        levels.contours.slices.push_back(std::move(mid));
        levels.fields.push_back(std::move(mid_fields));
        levels.z.push_back((k + 0.5) * d);
        levels.slice_of.push_back(k);
        levels.medial_axes.emplace_back();
        levels.medial_axes.emplace_back();
    }
    for (const RegionLink& link : contours.links) {
        if (link.label == label && !split[link.lower_slice]) {
            RegionLink moved = link;
            moved.lower_slice = level_of[link.lower_slice];
            levels.contours.links.push_back(std::move(moved));
        }
    }
    std::stable_sort(
        levels.contours.links.begin(), levels.contours.links.end(),
        [](const RegionLink& a, const RegionLink& b) { return a.lower_slice < b.lower_slice; });
    return levels;
}

}  // namespace strata::detail
