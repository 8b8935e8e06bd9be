// Triangulation, set-up and regions: the contour rings of a label (its simplified contours with
// every point where a neighbouring slice's contour crosses, touches or overlaps them), their
// constrained triangulation, and the region of each slice every face lies in.
#include <algorithm>
#include <cstddef>
#include <deque>
#include <numeric>

#include <CGAL/Box_intersection_d/Box_with_info_d.h>
#include <CGAL/box_intersection_d.h>
#include <CGAL/intersections.h>

#include "triangulate/detail/label_surface.h"

namespace strata::detail {

void LabelSurface::collect_contours() {
    const std::size_t slices = contours_.slices.size();
    label_contours_.assign(slices, {});
    region_count_.assign(slices, 0);
    for (std::size_t k = 0; k < slices; ++k) {
        const SliceContourSet& set = contours_.slices[k];
        for (std::uint32_t c = 0; c < set.contours.size(); ++c) {
            if (set.contours[c].label == label_) {
                label_contours_[k].push_back(c);
            }
        }
        for (const SliceLabelRegions& regions : set.labels) {
            if (regions.label == label_) {
                region_count_[k] = regions.foreground_count;
            }
        }
    }
}

void LabelSurface::collect_links() {
    const std::size_t slices = contours_.slices.size();
    linked_up_.assign(slices, {});
    linked_down_.assign(slices, {});
    for (std::size_t k = 0; k < slices; ++k) {
        linked_up_[k].assign(region_count_[k], false);
        linked_down_[k].assign(region_count_[k], false);
    }
    link_pieces_.assign(slices, {});
    background_links_.assign(slices, {});
    for (const RegionLink& link : contours_.links) {
        if (link.label == label_ && link.is_background) {
            auto lower = link.lower_regions;
            auto upper = link.upper_regions;
            std::sort(lower.begin(), lower.end());
            std::sort(upper.begin(), upper.end());
            background_links_[link.lower_slice].emplace_back(lower, upper);
        }
    }
    for (auto& links : background_links_) {
        std::sort(links.begin(), links.end());
    }
    for (const RegionLink& link : contours_.links) {
        if (link.label != label_ || link.is_background || link.lower_regions.empty() ||
            link.upper_regions.empty()) {
            continue;
        }
        const std::uint32_t k = link.lower_slice;
        const std::uint32_t a = link.lower_regions.front();
        const std::uint32_t b = link.upper_regions.front();
        linked_up_[k][a] = true;
        linked_down_[k + 1][b] = true;
        ++link_pieces_[k][{a, b}];
    }
}

/// Exact crossings, touches and overlaps between the contours of slices k and k+1: every such
/// point is added to the edges it lies on, so both slabs and caps share it.
void LabelSurface::find_crossings(std::uint32_t k) {
    SlabCheckMemo* memo = checks_ != nullptr ? checks_->memo_.get() : nullptr;
    // note: only a build that checks the slabs takes them from checks_: points known exactly
    // (from an earlier build) can round to other doubles than fresh ones in a surface
    if (memo != nullptr && mode_ == TriangulateMode::kMismatchesOnly && memo->crossings_known[k] &&
        same_simplified_[k] && same_simplified_[k + 1]) {
        for (const SlabCheckMemo::Crossing& hit : memo->crossings[k]) {
            if (hit.overlap) {
                overlaps_.push_back({hit.segment, hit.a, hit.b});
            }
            for (const Point& p : hit.points) {
                splits_[k][hit.a[1]][hit.a[2]].push_back(p);
                splits_[k + 1][hit.b[1]][hit.b[2]].push_back(p);
            }
        }
        return;
    }
    std::vector<SlabCheckMemo::Crossing>* record = nullptr;
    if (memo != nullptr) {
        memo->crossings_known[k] = true;
        record = &memo->crossings[k];
        record->clear();
    }
    using Box = CGAL::Box_intersection_d::Box_with_info_d<double, 2, std::array<std::uint32_t, 3>>;
    std::array<std::vector<Box>, 2> boxes;
    std::array<std::vector<Segment>, 2> segments;
    for (int side = 0; side < 2; ++side) {
        const std::uint32_t slice = k + side;
        const std::vector<Contour>& all = contours_.slices[slice].contours;
        for (std::uint32_t local = 0; local < label_contours_[slice].size(); ++local) {
            const Contour& c = all[label_contours_[slice][local]];
            for_each_simplified_edge(c, [&](std::uint32_t e, Vec2 a, Vec2 b) {
                boxes[side].push_back(
                    segment_box<Box>(a, b, {local, e, std::uint32_t(segments[side].size())}));
                segments[side].push_back(Segment(to_point(a), to_point(b)));
            });
        }
    }
    if (boxes[0].empty() || boxes[1].empty()) {
        return;
    }
    std::vector<std::pair<std::array<std::uint32_t, 3>, std::array<std::uint32_t, 3>>> pairs;
    CGAL::box_intersection_d(
        boxes[0].begin(), boxes[0].end(), boxes[1].begin(), boxes[1].end(),
        [&](const Box& a, const Box& b) { pairs.emplace_back(a.info(), b.info()); },
        std::ptrdiff_t(10), CGAL::Box_intersection_d::CLOSED);
    std::sort(pairs.begin(), pairs.end());  // deterministic order
    for (const auto& [a, b] : pairs) {
        const Segment& sa = segments[0][a[2]];
        const Segment& sb = segments[1][b[2]];
        const auto hit = CGAL::intersection(sa, sb);
        if (!hit) {
            continue;
        }
        std::vector<Point> points;
        if (const Point* p = boost::get<Point>(&*hit)) {
            points.push_back(*p);
        } else if (const Segment* s = boost::get<Segment>(&*hit)) {
            points.push_back(s->source());
            points.push_back(s->target());
            overlaps_.push_back({*s, {k, a[0], a[1]}, {k + 1, b[0], b[1]}});
        }
        for (const Point& p : points) {
            splits_[k][a[0]][a[1]].push_back(p);
            splits_[k + 1][b[0]][b[1]].push_back(p);
        }
        if (record != nullptr) {
            SlabCheckMemo::Crossing& entry = record->emplace_back();
            entry.a = {k, a[0], a[1]};
            entry.b = {k + 1, b[0], b[1]};
            entry.points = std::move(points);
            if (const Segment* s = boost::get<Segment>(&*hit)) {
                entry.overlap = true;
                entry.segment = *s;
            }
        }
    }
}

/// Points on overlapping collinear edges of neighbouring slices are shared both ways, to a fixed
/// point (an edge may overlap edges of both neighbouring slices).
void LabelSurface::share_overlap_points() {
    auto list = [&](const std::array<std::uint32_t, 3>& e) -> std::vector<Point>& {
        return splits_[e[0]][e[1]][e[2]];
    };
    auto endpoints = [&](const std::array<std::uint32_t, 3>& e) {
        const Contour& c = contours_.slices[e[0]].contours[label_contours_[e[0]][e[1]]];
        const std::size_t n = c.simplified.size();
        return std::array<Point, 2>{to_point(c.points[c.simplified[e[2]]]),
                                    to_point(c.points[c.simplified[(e[2] + 1) % n]])};
    };
    // Worklist: an overlap is looked at again only when one of its edges gained a point.
    std::map<std::array<std::uint32_t, 3>, std::vector<std::size_t>> by_edge;
    for (std::size_t i = 0; i < overlaps_.size(); ++i) {
        by_edge[overlaps_[i].lower].push_back(i);
        by_edge[overlaps_[i].upper].push_back(i);
    }
    std::deque<std::size_t> work(overlaps_.size());
    std::iota(work.begin(), work.end(), std::size_t(0));
    std::vector<bool> queued(overlaps_.size(), true);
    while (!work.empty()) {
        const Overlap& o = overlaps_[work.front()];
        queued[work.front()] = false;
        work.pop_front();
        for (int dir = 0; dir < 2; ++dir) {
            const auto& from = dir == 0 ? o.lower : o.upper;
            const auto& to = dir == 0 ? o.upper : o.lower;
            const std::vector<Point>& source = list(from);  // another slice: not `target`
            std::vector<Point>& target = list(to);
            bool grew = false;
            auto share = [&](const Point& p) {
                if (o.segment.has_on(p) &&
                    std::find(target.begin(), target.end(), p) == target.end()) {
                    target.push_back(p);
                    grew = true;
                }
            };
            for (const Point& p : source) {
                share(p);
            }
            for (const Point& p : endpoints(from)) {
                share(p);
            }
            if (grew) {
                for (const std::size_t j : by_edge[to]) {
                    if (!queued[j]) {
                        queued[j] = true;
                        work.push_back(j);
                    }
                }
            }
        }
    }
}

void LabelSurface::build_rings() {
    const std::size_t slices = contours_.slices.size();
    rings_.assign(slices, {});
    for (std::uint32_t k = 0; k < slices; ++k) {
        const std::vector<Contour>& all = contours_.slices[k].contours;
        for (std::uint32_t local = 0; local < label_contours_[k].size(); ++local) {
            const Contour& c = all[label_contours_[k][local]];
            Ring ring;
            for_each_simplified_edge(c, [&](std::uint32_t e, Vec2 from, Vec2 to) {
                const Point a = to_point(from);
                const Point b = to_point(to);
                ring.points.push_back(a);
                std::vector<Point>& extra = splits_[k][local][e];
                std::sort(extra.begin(), extra.end(), [&](const Point& p, const Point& q) {
                    return CGAL::compare_distance_to_point(a, p, q) == CGAL::SMALLER;
                });
                for (const Point& p : extra) {
                    if (p != a && p != b && p != ring.points.back()) {
                        ring.points.push_back(p);
                    }
                }
            });
            for (const Point& p : ring.points) {
                ring.ids.push_back(add_vertex(to_vec(p), slice_z(k)));
            }
            rings_[k].push_back(std::move(ring));
        }
    }
}

void LabelSurface::insert_rings(Cdt& cdt,
                                std::uint32_t slice,
                                bool upper,
                                std::map<EdgeKey, EdgeOwner>& owners,
                                std::int64_t only_region) {
    for (std::uint32_t local = 0; local < rings_[slice].size(); ++local) {
        if (only_region >= 0 && owner_region(slice, local) != only_region) {
            continue;
        }
        const Ring& ring = rings_[slice][local];
        std::vector<VertexHandle> handles;
        handles.reserve(ring.points.size());
        for (std::size_t i = 0; i < ring.points.size(); ++i) {
            VertexHandle v = cdt.insert(ring.points[i]);
            (upper ? v->info().upper : v->info().lower) = std::int32_t(ring.ids[i]);
            handles.push_back(v);
        }
        for (std::size_t i = 0; i < handles.size(); ++i) {
            VertexHandle a = handles[i];
            VertexHandle b = handles[(i + 1) % handles.size()];
            cdt.insert_constraint(a, b);
            EdgeOwner& owner = owners[edge_key(a, b)];
            (upper ? owner.upper : owner.lower) = std::int32_t(local);
        }
    }
}

/// Walks from the infinite face, toggling the region across each contour edge.
std::size_t LabelSurface::flood_regions(Cdt& cdt,
                                        std::uint32_t k,
                                        const std::map<EdgeKey, EdgeOwner>& owners) {
    std::size_t unowned = 0;
    for (FaceHandle f : cdt.all_face_handles()) {
        f->info() = FaceInfo{};
    }
    std::deque<FaceHandle> queue;
    FaceHandle start = cdt.infinite_face();
    start->info().seen = true;
    queue.push_back(start);
    while (!queue.empty()) {
        const FaceHandle f = queue.front();
        queue.pop_front();
        for (int i = 0; i < 3; ++i) {
            const FaceHandle n = f->neighbor(i);
            if (n->info().seen) {
                continue;
            }
            FaceInfo state;
            state.lower_region = f->info().lower_region;
            state.upper_region = f->info().upper_region;
            state.lower_background = f->info().lower_background;
            state.upper_background = f->info().upper_background;
            if (cdt.is_constrained({f, i})) {
                const auto it = owners.find(edge_key(f->vertex(ccw(i)), f->vertex(cw(i))));
                if (it == owners.end()) {
                    ++unowned;
                }
                if (it != owners.end()) {
                    if (it->second.lower >= 0) {
                        const auto c = std::uint32_t(it->second.lower);
                        const auto r = std::int32_t(owner_region(k, c));
                        state.lower_region = state.lower_region == r ? -1 : r;
                        state.lower_background = background_beside(k, c);
                    }
                    if (it->second.upper >= 0) {
                        const auto c = std::uint32_t(it->second.upper);
                        const auto r = std::int32_t(owner_region(k + 1, c));
                        state.upper_region = state.upper_region == r ? -1 : r;
                        state.upper_background = background_beside(k + 1, c);
                    }
                }
            }
            state.seen = true;
            n->info() = state;
            queue.push_back(n);
        }
    }
    return unowned;
}

bool LabelSurface::in_lower(const FaceInfo& f, std::uint32_t k) const {
    return f.lower_region >= 0 && linked_up_[k][std::size_t(f.lower_region)];
}

bool LabelSurface::in_upper(const FaceInfo& f, std::uint32_t k) const {
    return f.upper_region >= 0 && linked_down_[k + 1][std::size_t(f.upper_region)];
}

bool LabelSurface::in_surface(FaceHandle f, std::uint32_t k) const {
    return in_lower(f->info(), k) != in_upper(f->info(), k);
}

bool LabelSurface::is_boundary(FaceHandle f, int i, std::uint32_t k) const {
    const FaceHandle n = f->neighbor(i);
    return in_lower(f->info(), k) != in_lower(n->info(), k) ||
           in_upper(f->info(), k) != in_upper(n->info(), k);
}

/// Level of the boundary edge opposite vertex i of the surface face f: on slice k's contour
/// (low), on slice k+1's (high); where both contours run along the edge, the face's own side.
Level LabelSurface::boundary_class(FaceHandle f, int i, std::uint32_t k) const {
    const FaceHandle n = f->neighbor(i);
    const bool lower_changes = in_lower(f->info(), k) != in_lower(n->info(), k);
    const bool upper_changes = in_upper(f->info(), k) != in_upper(n->info(), k);
    if (lower_changes && upper_changes) {
        return in_lower(f->info(), k) ? kLow : kHigh;
    }
    return lower_changes ? kLow : kHigh;
}

}  // namespace strata::detail
