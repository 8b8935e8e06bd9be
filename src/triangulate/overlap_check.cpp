// Triangulation, overlap check: whether the polygons of a slab overlap in the pattern of the
// pixels (the reference volume's topology); slabs where they do not go to the fallbacks.
#include <algorithm>
#include <cstddef>
#include <numeric>

#include "triangulate/detail/label_surface.h"

namespace strata::detail {

namespace {

/// Union-find over 0..n-1 (path halving).
class DisjointSets {
public:
    explicit DisjointSets(std::size_t n) : parent_(n) {
        std::iota(parent_.begin(), parent_.end(), std::size_t(0));
    }
    std::size_t find(std::size_t x) {
        while (parent_[x] != x) {
            x = parent_[x] = parent_[parent_[x]];
        }
        return x;
    }
    void join(std::size_t a, std::size_t b) { parent_[find(a)] = find(b); }

private:
    std::vector<std::size_t> parent_;
};

/// The pieces of the complement of the overlap of slab k's polygons (4-connected: across
/// edges only) that touch a hole of either slice, each with the background components it
/// touches, sorted.
BackgroundLinks background_pieces(const Cdt& cdt) {
    std::map<const void*, std::size_t> bg_index;
    std::vector<FaceHandle> bg_faces;
    for (FaceHandle f : cdt.all_face_handles()) {
        if (f->info().lower_region < 0 || f->info().upper_region < 0) {
            bg_index.emplace(&*f, bg_faces.size());
            bg_faces.push_back(f);
        }
    }
    DisjointSets bg_sets(bg_faces.size());
    for (std::size_t i = 0; i < bg_faces.size(); ++i) {
        for (int j = 0; j < 3; ++j) {
            const auto it = bg_index.find(&*bg_faces[i]->neighbor(j));
            if (it != bg_index.end()) {
                bg_sets.join(i, it->second);
            }
        }
    }
    std::map<std::size_t, std::pair<std::vector<std::uint32_t>, std::vector<std::uint32_t>>> touch;
    for (std::size_t i = 0; i < bg_faces.size(); ++i) {
        auto& [lower, upper] = touch[bg_sets.find(i)];
        const FaceInfo& info = bg_faces[i]->info();
        if (info.lower_region < 0) {
            lower.push_back(info.lower_background);
        }
        if (info.upper_region < 0) {
            upper.push_back(info.upper_background);
        }
    }
    BackgroundLinks polygon_bg;
    for (auto& [root, touched] : touch) {
        for (auto* v : {&touched.first, &touched.second}) {
            std::sort(v->begin(), v->end());
            v->erase(std::unique(v->begin(), v->end()), v->end());
        }
        const bool hole = std::any_of(touched.first.begin(), touched.first.end(),
                                      [](std::uint32_t b) { return b != 0; }) ||
                          std::any_of(touched.second.begin(), touched.second.end(),
                                      [](std::uint32_t b) { return b != 0; });
        if (hole) {
            polygon_bg.push_back(touched);
        }
    }
    std::sort(polygon_bg.begin(), polygon_bg.end());
    return polygon_bg;
}

}  // namespace

/// The surface joins regions a (slice k) and b (slice k+1) once per connected piece of their
/// polygons' overlap; the reference joins them once per piece of their pixels' overlap. Reports
/// slabs where the two disagree.
void LabelSurface::check_overlap_topology(Cdt& cdt, std::uint32_t k) {
    std::map<const void*, std::size_t> index;
    std::vector<FaceHandle> faces;
    for (FaceHandle f : cdt.finite_face_handles()) {
        if (f->info().lower_region >= 0 && f->info().upper_region >= 0) {
            index.emplace(&*f, faces.size());
            faces.push_back(f);
        }
    }
    DisjointSets sets(faces.size());
    for (std::size_t i = 0; i < faces.size(); ++i) {
        for (int j = 0; j < 3; ++j) {
            const FaceHandle n = faces[i]->neighbor(j);
            const auto it = index.find(&*n);
            if (it != index.end() && n->info().lower_region == faces[i]->info().lower_region &&
                n->info().upper_region == faces[i]->info().upper_region) {
                sets.join(i, it->second);
            }
        }
    }
    // Overlap pieces that touch at a contour point also join when the surface does not pass
    // through the vertical segment above it (no crossing wedge, no wall there): the solid is
    // connected around that segment, as the pixels are across a diagonal.
    for (VertexHandle v : cdt.finite_vertex_handles()) {
        if (v->info().lower < 0 || v->info().upper < 0) {
            continue;
        }
        std::vector<FaceHandle> around;
        if (vertical_at(cdt, v, k, around)) {
            continue;
        }
        std::size_t first = faces.size();
        for (const FaceHandle f : around) {
            const auto it = index.find(&*f);
            if (it == index.end()) {
                continue;
            }
            if (first == faces.size()) {
                first = it->second;
            } else if (faces[first]->info().lower_region == f->info().lower_region &&
                       faces[first]->info().upper_region == f->info().upper_region) {
                sets.join(first, it->second);
            }
        }
    }
    std::map<std::pair<std::uint32_t, std::uint32_t>, std::uint32_t> pieces;
    std::vector<bool> counted(faces.size(), false);
    for (std::size_t i = 0; i < faces.size(); ++i) {
        const std::size_t root = sets.find(i);
        if (!counted[root]) {
            counted[root] = true;
            ++pieces[{std::uint32_t(faces[i]->info().lower_region),
                      std::uint32_t(faces[i]->info().upper_region)}];
        }
    }
    const BackgroundLinks polygon_bg = background_pieces(cdt);
    if (polygon_bg != background_links_[k]) {
        ++surface_.topology_mismatches;
        mismatched_slabs_.push_back(k);
        issue(k, "contours overlap unlike the pixels: " + std::to_string(polygon_bg.size()) +
                     " background connection(s) through holes, pixels " +
                     std::to_string(background_links_[k].size()));
        return;
    }
    if (pieces != link_pieces_[k]) {
        std::size_t differ = 0;
        std::string example;
        auto note = [&](std::pair<std::uint32_t, std::uint32_t> pair, std::uint32_t polygons,
                        std::uint32_t pixels) {
            if (differ++ == 0) {
                example = ", e.g. regions " + std::to_string(pair.first) + " and " +
                          std::to_string(pair.second) + ": " + std::to_string(polygons) +
                          " polygon overlap(s), " + std::to_string(pixels) + " pixel overlap(s)";
            }
        };
        for (const auto& [pair, count] : pieces) {
            const auto it = link_pieces_[k].find(pair);
            const std::uint32_t pixels = it == link_pieces_[k].end() ? 0 : it->second;
            if (pixels != count) {
                note(pair, count, pixels);
            }
        }
        for (const auto& [pair, count] : link_pieces_[k]) {
            if (pieces.find(pair) == pieces.end()) {
                note(pair, 0, count);
            }
        }
        ++surface_.topology_mismatches;
        mismatched_slabs_.push_back(k);
        issue(k, "contours overlap unlike the pixels for " + std::to_string(differ) +
                     " region pair(s)" + example);
    }
}

/// Whether the surface passes through the vertical segment above contour point v (a crossing
/// wedge or a wall there); `around` receives v's incident faces in order.
bool LabelSurface::vertical_at(const Cdt& cdt,
                               VertexHandle v,
                               std::uint32_t k,
                               std::vector<FaceHandle>& around) const {
    Cdt::Face_circulator fc = cdt.incident_faces(v);
    const Cdt::Face_circulator done = fc;
    do {
        around.push_back(fc);
    } while (++fc != done);
    const std::size_t n = around.size();
    bool vertical = false;
    // Boundary edge between around[j] and around[j + 1], or kUnset when not a boundary.
    std::vector<Level> edge_class(n, kUnset);
    std::vector<Level> edge_class_next(n, kUnset);
    for (std::size_t j = 0; j < n; ++j) {
        const FaceHandle f = around[j];
        const FaceHandle g = around[(j + 1) % n];
        if (cdt.is_infinite(f) || cdt.is_infinite(g)) {
            continue;
        }
        const int e = f->index(g);
        const bool f_both = in_lower(f->info(), k) && in_upper(f->info(), k);
        const bool g_both = in_lower(g->info(), k) && in_upper(g->info(), k);
        const bool f_none = !in_lower(f->info(), k) && !in_upper(f->info(), k);
        const bool g_none = !in_lower(g->info(), k) && !in_upper(g->info(), k);
        if ((f_both && g_none) || (f_none && g_both)) {
            vertical = true;  // a wall
        }
        if (is_boundary(f, e, k)) {
            edge_class[j] = in_surface(f, k) ? boundary_class(f, e, k) : kUnset;
            edge_class_next[j] = in_surface(g, k) ? boundary_class(g, g->index(f), k) : kUnset;
        }
    }
    // A run of surface faces between two boundary edges with different classes crosses.
    for (std::size_t j = 0; j < n && !vertical; ++j) {
        if (edge_class_next[j] == kUnset) {
            continue;  // no surface run starts after edge j
        }
        const Level start = edge_class_next[j];
        for (std::size_t m = 1; m <= n; ++m) {
            const std::size_t e = (j + m) % n;
            if (edge_class[e] != kUnset ||
                is_boundary(around[e], around[e]->index(around[(e + 1) % n]), k)) {
                vertical = edge_class[e] != start;
                break;
            }
        }
    }
    return vertical;
}

}  // namespace strata::detail
