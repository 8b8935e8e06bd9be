#include "contours/contour_stats.h"

#include <algorithm>
#include <map>

namespace strata {

std::vector<LabelContourStats> contour_stats(const SliceContours& contours) {
    std::map<std::uint16_t, LabelContourStats> by_label;
    for (const SliceContourSet& set : contours.slices) {
        for (const SliceLabelRegions& regions : set.labels) {
            LabelContourStats& s = by_label[regions.label];
            s.label = regions.label;
            ++s.slices;
        }
        for (const Contour& c : set.contours) {
            LabelContourStats& s = by_label[c.label];
            ++s.contours;
            s.holes += c.is_hole ? 1 : 0;
            s.max_depth = std::max(s.max_depth, c.depth);
            s.points_original += c.points.size();
            s.points_simplified += c.simplified.size();
            for (double d : c.edge_deviation_px) {
                s.max_deviation_px = std::max(s.max_deviation_px, d);
            }
        }
    }
    for (const RegionLink& link : contours.links) {
        LabelContourStats& s = by_label[link.label];
        s.label = link.label;
        (link.is_background ? s.hole_links : s.links) += 1;
    }
    std::vector<LabelContourStats> result;
    for (auto& [label, stats] : by_label) {
        result.push_back(stats);
    }
    return result;
}

}  // namespace strata
