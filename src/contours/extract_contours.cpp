// Contour extraction on the pixel-corner grid (Klein, Schilling, Strasser, section 2.I.1):
// crack following around 8-connected foreground / 4-connected background components, with saddle
// corners cut through the background so that every contour is a simple polygon; nesting from the
// component structure; links between slices from the reference volume R of docs/test-catalogue.md.

#include "contours/extract_contours.h"

#include <algorithm>
#include <array>
#include <cstdint>
#include <mutex>

#include "contours/simplify_contours.h"
#include "core/error.h"
#include "core/parallel.h"
#include "core/pixel_box.h"

namespace strata {

namespace {

using Window = PixelBox;

/// Connected components of one label on one slice inside a window padded by one background
/// pixel. Grid pixel (gx, gy) is image pixel (x0 - 1 + gx, y0 - 1 + gy).
/// Numbering is independent of the window as long as it holds every pixel of the label:
/// foreground components in row-major order of their first pixel; background component 0 is
/// the outside (connected to the padding), holes from 1 in row-major order.
struct ComponentGrid {
    Window window;
    std::int64_t width = 0;   // window width + 2
    std::int64_t height = 0;  // window height + 2
    std::vector<std::int32_t>
        component;  // foreground: id >= 0 in fg numbering; background: -1 - id
    std::uint32_t foreground_count = 0;
    std::uint32_t background_count = 0;

    bool is_foreground(std::int64_t gx, std::int64_t gy) const {
        return component[gy * width + gx] >= 0;
    }
    std::int32_t at(std::int64_t gx, std::int64_t gy) const { return component[gy * width + gx]; }
    /// Component code of an image pixel; pixels outside the window are the outside background.
    std::int32_t at_image(std::int64_t x, std::int64_t y) const {
        const std::int64_t gx = x - window.x0 + 1;
        const std::int64_t gy = y - window.y0 + 1;
        if (gx < 0 || gy < 0 || gx >= width || gy >= height) {
            return -1;
        }
        return at(gx, gy);
    }
};

ComponentGrid label_components(const SliceStack& stack,
                               std::uint32_t k,
                               std::uint16_t label,
                               const Window& window) {
    ComponentGrid g;
    g.window = window;
    g.width = window.x1 - window.x0 + 2;
    g.height = window.y1 - window.y0 + 2;
    constexpr std::int32_t kUnset = INT32_MIN;
    g.component.assign(static_cast<std::size_t>(g.width * g.height), kUnset);
    std::vector<std::uint8_t> fg(g.component.size(), 0);
    const auto slice = stack.slice(k);
    for (std::int64_t y = window.y0; y < window.y1; ++y) {
        const std::uint16_t* row = slice.data() + y * stack.width;
        std::uint8_t* out = fg.data() + (y - window.y0 + 1) * g.width + 1;
        for (std::int64_t x = window.x0; x < window.x1; ++x) {
            out[x - window.x0] = row[x] == label ? 1 : 0;
        }
    }
    std::vector<std::int64_t> stack_px;
    auto flood = [&](std::int64_t start, std::int32_t code, bool foreground) {
        g.component[start] = code;
        stack_px.clear();
        stack_px.push_back(start);
        while (!stack_px.empty()) {
            const std::int64_t p = stack_px.back();
            stack_px.pop_back();
            const std::int64_t px = p % g.width;
            const std::int64_t py = p / g.width;
            for (std::int64_t dy = -1; dy <= 1; ++dy) {
                for (std::int64_t dx = -1; dx <= 1; ++dx) {
                    if ((dx == 0 && dy == 0) || (!foreground && dx != 0 && dy != 0)) {
                        continue;
                    }
                    const std::int64_t nx = px + dx;
                    const std::int64_t ny = py + dy;
                    if (nx < 0 || ny < 0 || nx >= g.width || ny >= g.height) {
                        continue;
                    }
                    const std::int64_t q = ny * g.width + nx;
                    if (g.component[q] == kUnset && (fg[q] != 0) == foreground) {
                        g.component[q] = code;
                        stack_px.push_back(q);
                    }
                }
            }
        }
    };
    flood(0, -1, false);  // the padding ring and everything connected to it: the outside
    g.background_count = 1;
    for (std::int64_t p = 0; p < static_cast<std::int64_t>(g.component.size()); ++p) {
        if (g.component[p] != kUnset) {
            continue;
        }
        if (fg[p] != 0) {
            flood(p, static_cast<std::int32_t>(g.foreground_count++), true);
        } else {
            flood(p, -1 - static_cast<std::int32_t>(g.background_count++), false);
        }
    }
    return g;
}

// Directions counter-clockwise in the (x, y) frame: +x, +y, -x, -y.
constexpr std::array<std::int64_t, 4> kDx = {1, 0, -1, 0};
constexpr std::array<std::int64_t, 4> kDy = {0, 1, 0, -1};

/// Pixels ahead-left and ahead-right of corner (cx, cy) when heading `dir`, and the pixels left
/// and right of the edge leaving (cx, cy) in direction `dir`, as grid pixel offsets from the
/// corner (pixel (cx + ox, cy + oy)).
struct CornerPixels {
    std::array<std::int64_t, 2> left;
    std::array<std::int64_t, 2> right;
};
constexpr std::array<CornerPixels, 4> kEdgePixels = {{
    {{0, 0}, {0, -1}},    // +x: left (x, y), right (x, y-1)
    {{-1, 0}, {0, 0}},    // +y: left (x-1, y), right (x, y)
    {{-1, -1}, {-1, 0}},  // -x: left (x-1, y-1), right (x-1, y)
    {{0, -1}, {-1, -1}},  // -y: left (x, y-1), right (x-1, y-1)
}};

struct TracedContour {
    std::vector<Vec2> points;
    std::int32_t foreground = 0;
    std::int32_t background = 0;
    bool is_hole = false;
};

/// Traces every contour of a component grid.
std::vector<TracedContour> trace_grid(const ComponentGrid& g) {
    const std::int64_t cw = g.width + 1;  // corners per row
    std::vector<std::uint8_t> visited(static_cast<std::size_t>(cw * (g.height + 1)), 0);
    std::vector<TracedContour> result;
    const double ox = static_cast<double>(g.window.x0 - 1);
    const double oy = static_cast<double>(g.window.y0 - 1);

    auto trace_from = [&](std::int64_t sx, std::int64_t sy, int sdir) {
        TracedContour c;
        const auto& first = kEdgePixels[sdir];
        c.foreground = g.at(sx + first.left[0], sy + first.left[1]);
        c.background = -1 - g.at(sx + first.right[0], sy + first.right[1]);
        std::int64_t x = sx;
        std::int64_t y = sy;
        int dir = sdir;
        for (;;) {
            visited[y * cw + x] |= static_cast<std::uint8_t>(1u << dir);
            x += kDx[dir];
            y += kDy[dir];
            // pixels ahead of the corner: the edge pixels of the straight continuation
            const auto& ahead = kEdgePixels[dir];
            const bool front_left = g.is_foreground(x + ahead.left[0], y + ahead.left[1]);
            const bool front_right = g.is_foreground(x + ahead.right[0], y + ahead.right[1]);
            int next = dir;
            bool saddle = false;
            if (front_left && !front_right) {
                next = dir;
            } else if (!front_left && !front_right) {
                next = (dir + 1) % 4;
            } else if (front_left && front_right) {
                next = (dir + 3) % 4;
            } else {
                next = (dir + 3) % 4;  // saddle: 8-connected foreground turns right
                saddle = true;
            }
            if (saddle) {
                // note: a unit edge between two saddles yields its midpoint twice: keep one
                const Vec2 in{ox + x - 0.5 * kDx[dir], oy + y - 0.5 * kDy[dir]};
                if (c.points.empty() || !(c.points.back() == in)) {
                    c.points.push_back(in);
                }
                c.points.push_back({ox + x + 0.5 * kDx[next], oy + y + 0.5 * kDy[next]});
            } else {
                c.points.push_back({ox + static_cast<double>(x), oy + static_cast<double>(y)});
            }
            dir = next;
            if (x == sx && y == sy && dir == sdir) {
                break;
            }
        }
        if (c.points.size() > 1 && c.points.front() == c.points.back()) {
            c.points.pop_back();
        }
        // rotate to a canonical start: the least point in row-major order
        auto least = std::min_element(c.points.begin(), c.points.end(), [](Vec2 a, Vec2 b) {
            return a.y < b.y || (a.y == b.y && a.x < b.x);
        });
        std::rotate(c.points.begin(), least, c.points.end());
        // exact signed area on the half-pixel grid (doubled coordinates are integers)
        std::int64_t area2 = 0;
        const std::size_t n = c.points.size();
        for (std::size_t i = 0; i < n; ++i) {
            const Vec2 a = c.points[i];
            const Vec2 b = c.points[(i + 1) % n];
            area2 += static_cast<std::int64_t>(2 * a.x) * static_cast<std::int64_t>(2 * b.y) -
                     static_cast<std::int64_t>(2 * b.x) * static_cast<std::int64_t>(2 * a.y);
        }
        c.is_hole = area2 < 0;
        result.push_back(std::move(c));
    };

    for (std::int64_t gy = 1; gy + 1 < g.height; ++gy) {
        for (std::int64_t gx = 1; gx + 1 < g.width; ++gx) {
            if (!g.is_foreground(gx, gy)) {
                continue;
            }
            // sides of a foreground pixel facing background, as (start corner, direction)
            const std::array<std::array<std::int64_t, 3>, 4> sides = {{
                {gx, gy, 0},          // low-y side, +x
                {gx + 1, gy, 1},      // high-x side, +y
                {gx + 1, gy + 1, 2},  // high-y side, -x
                {gx, gy + 1, 3},      // low-x side, -y
            }};
            const std::array<std::array<std::int64_t, 2>, 4> neighbours = {
                {{gx, gy - 1}, {gx + 1, gy}, {gx, gy + 1}, {gx - 1, gy}}};
            for (int s = 0; s < 4; ++s) {
                if (g.is_foreground(neighbours[s][0], neighbours[s][1])) {
                    continue;
                }
                const auto [cx, cy, dir] = sides[s];
                if ((visited[cy * cw + cx] & (1u << dir)) == 0) {
                    trace_from(cx, cy, static_cast<int>(dir));
                }
            }
        }
    }
    return result;
}

/// Bounding windows of the labels on slice k, indexed like `labels`.
std::vector<Window> label_windows(const SliceStack& stack,
                                  std::uint32_t k,
                                  const std::vector<std::uint16_t>& labels,
                                  const std::vector<std::int32_t>& label_index) {
    std::vector<Window> windows(labels.size(), Window{INT64_MAX, INT64_MAX, INT64_MIN, INT64_MIN});
    std::vector<bool> seen(labels.size(), false);
    const auto slice = stack.slice(k);
    for (std::int64_t y = 0; y < stack.height; ++y) {
        const std::uint16_t* row = slice.data() + y * stack.width;
        for (std::int64_t x = 0; x < stack.width; ++x) {
            const std::int32_t l = row[x] == 0 ? -1 : label_index[row[x]];
            if (l < 0) {
                continue;
            }
            Window& w = windows[l];
            seen[l] = true;
            w.x0 = std::min(w.x0, x);
            w.y0 = std::min(w.y0, y);
            w.x1 = std::max(w.x1, x + 1);
            w.y1 = std::max(w.y1, y + 1);
        }
    }
    for (std::size_t l = 0; l < labels.size(); ++l) {
        if (!seen[l]) {
            windows[l] = Window{};
        }
    }
    return windows;
}

}  // namespace

SliceContourSet trace_slice_contours(const SliceStack& stack,
                                     std::uint32_t k,
                                     const std::vector<std::uint16_t>& labels) {
    const std::vector<std::int32_t> label_index = index_of_labels(labels);
    const std::vector<Window> windows = label_windows(stack, k, labels, label_index);
    SliceContourSet set;
    for (std::size_t l = 0; l < labels.size(); ++l) {
        if (windows[l].empty()) {
            continue;
        }
        const ComponentGrid grid = label_components(stack, k, labels[l], windows[l]);
        std::vector<TracedContour> traced = trace_grid(grid);
        std::sort(traced.begin(), traced.end(), [](const TracedContour& a, const TracedContour& b) {
            const Vec2 pa = a.points.front();
            const Vec2 pb = b.points.front();
            return pa.y < pb.y || (pa.y == pb.y && pa.x < pb.x);
        });
        SliceLabelRegions regions;
        regions.label = labels[l];
        regions.foreground_count = grid.foreground_count;
        regions.background_count = grid.background_count;
        regions.outer_contour.assign(grid.foreground_count, -1);
        regions.hole_contour.assign(grid.background_count, -1);
        const std::int32_t base = static_cast<std::int32_t>(set.contours.size());
        for (std::size_t i = 0; i < traced.size(); ++i) {
            TracedContour& t = traced[i];
            Contour c;
            c.label = labels[l];
            c.is_hole = t.is_hole;
            c.region = static_cast<std::uint32_t>(t.is_hole ? t.background : t.foreground);
            c.points = std::move(t.points);
            const std::int32_t id = base + static_cast<std::int32_t>(i);
            std::int32_t& slot = t.is_hole ? regions.hole_contour[t.background]
                                           : regions.outer_contour[t.foreground];
            if (slot != -1) {
                throw Error(ErrorCode::Internal, "slice " + std::to_string(k) + ", label " +
                                                     std::to_string(labels[l]) +
                                                     ": region with two " +
                                                     (t.is_hole ? "hole" : "outer") + " contours");
            }
            slot = id;
            set.contours.push_back(std::move(c));
        }
        // parents: a hole's parent is the outer contour of its foreground; an outer contour's
        // parent is the hole contour of the background around it (none for the outside)
        for (std::size_t i = 0; i < traced.size(); ++i) {
            Contour& c = set.contours[base + i];
            const TracedContour& t = traced[i];
            c.parent = t.is_hole ? regions.outer_contour[t.foreground]
                                 : (t.background == 0 ? -1 : regions.hole_contour[t.background]);
        }
        set.labels.push_back(std::move(regions));
    }
    // nesting depth by following parents (memoised)
    std::vector<std::int32_t> depth(set.contours.size(), -1);
    for (std::size_t i = 0; i < set.contours.size(); ++i) {
        std::vector<std::size_t> chain;
        std::size_t c = i;
        while (depth[c] < 0 && set.contours[c].parent >= 0) {
            chain.push_back(c);
            c = static_cast<std::size_t>(set.contours[c].parent);
            if (chain.size() > set.contours.size()) {
                throw Error(ErrorCode::Internal, "slice " + std::to_string(k) + ": nesting cycle");
            }
        }
        std::int32_t d = depth[c] >= 0 ? depth[c] : 0;
        depth[c] = d;
        while (!chain.empty()) {
            depth[chain.back()] = ++d;
            chain.pop_back();
        }
    }
    for (std::size_t i = 0; i < set.contours.size(); ++i) {
        set.contours[i].depth = static_cast<std::uint32_t>(depth[i]);
    }
    return set;
}

std::vector<RegionLink> link_slices(const SliceStack& stack,
                                    std::uint32_t k,
                                    const SliceContourSet& lower,
                                    const SliceContourSet& upper,
                                    const std::vector<std::uint16_t>& labels) {
    const std::vector<std::int32_t> label_index = index_of_labels(labels);
    const std::vector<Window> lower_windows = label_windows(stack, k, labels, label_index);
    const std::vector<Window> upper_windows = label_windows(stack, k + 1, labels, label_index);
    std::vector<RegionLink> links;
    auto has_label = [](const SliceContourSet& set, std::uint16_t label) {
        return std::any_of(set.labels.begin(), set.labels.end(),
                           [&](const SliceLabelRegions& r) { return r.label == label; });
    };
    for (std::size_t l = 0; l < labels.size(); ++l) {
        const std::uint16_t label = labels[l];
        if (!has_label(lower, label) || !has_label(upper, label)) {
            continue;  // an empty slice breaks every link of this label
        }
        const Window window = lower_windows[l].united(upper_windows[l]);
        const ComponentGrid a = label_components(stack, k, label, window);
        const ComponentGrid b = label_components(stack, k + 1, label, window);
        // Middle layer of R: foreground = both foreground (8-connected), background = either
        // background (4-connected).
        const std::int64_t w = a.width;
        const std::int64_t h = a.height;
        std::vector<std::int32_t> mid(static_cast<std::size_t>(w * h), -1);
        std::vector<std::int64_t> todo;
        std::int32_t next_code = 0;
        auto is_mid_fg = [&](std::int64_t p) { return a.component[p] >= 0 && b.component[p] >= 0; };
        for (std::int64_t p = 0; p < w * h; ++p) {
            if (mid[p] >= 0) {
                continue;
            }
            const bool fg = is_mid_fg(p);
            RegionLink link;
            link.lower_slice = k;
            link.label = label;
            link.is_background = !fg;
            const std::int32_t code = next_code++;
            mid[p] = code;
            todo.assign(1, p);
            std::vector<std::uint32_t> lower_set;
            std::vector<std::uint32_t> upper_set;
            while (!todo.empty()) {
                const std::int64_t q = todo.back();
                todo.pop_back();
                ++link.pixels;
                if (fg) {
                    lower_set.push_back(static_cast<std::uint32_t>(a.component[q]));
                    upper_set.push_back(static_cast<std::uint32_t>(b.component[q]));
                } else {
                    if (a.component[q] < 0) {
                        lower_set.push_back(static_cast<std::uint32_t>(-1 - a.component[q]));
                    }
                    if (b.component[q] < 0) {
                        upper_set.push_back(static_cast<std::uint32_t>(-1 - b.component[q]));
                    }
                }
                const std::int64_t qx = q % w;
                const std::int64_t qy = q / w;
                for (std::int64_t dy = -1; dy <= 1; ++dy) {
                    for (std::int64_t dx = -1; dx <= 1; ++dx) {
                        if ((dx == 0 && dy == 0) || (!fg && dx != 0 && dy != 0)) {
                            continue;
                        }
                        const std::int64_t nx = qx + dx;
                        const std::int64_t ny = qy + dy;
                        if (nx < 0 || ny < 0 || nx >= w || ny >= h) {
                            continue;
                        }
                        const std::int64_t r = ny * w + nx;
                        if (mid[r] < 0 && is_mid_fg(r) == fg) {
                            mid[r] = code;
                            todo.push_back(r);
                        }
                    }
                }
            }
            auto unique_sorted = [](std::vector<std::uint32_t>& v) {
                std::sort(v.begin(), v.end());
                v.erase(std::unique(v.begin(), v.end()), v.end());
            };
            unique_sorted(lower_set);
            unique_sorted(upper_set);
            link.lower_regions = std::move(lower_set);
            link.upper_regions = std::move(upper_set);
            const bool touches_hole =
                (!link.lower_regions.empty() && link.lower_regions.back() != 0) ||
                (!link.upper_regions.empty() && link.upper_regions.back() != 0);
            if (fg || touches_hole) {
                links.push_back(std::move(link));
            }
        }
    }
    return links;
}

SliceContours extract_contours(const SliceStack& stack, const ContourOptions& options) {
    std::vector<std::uint16_t> labels;
    for (const LabelInfo& info : stack.label_table) {
        if (info.value != 0) {
            labels.push_back(info.value);
        }
    }
    std::sort(labels.begin(), labels.end());
    labels.erase(std::unique(labels.begin(), labels.end()), labels.end());

    SliceContours result;
    result.width = stack.width;
    result.height = stack.height;
    result.tolerance_px = options.tolerance_px;
    result.slices.resize(stack.depth);
    SimplifyOptions simplify;
    simplify.tolerance_px = options.tolerance_px;
    simplify.edge_midpoints = options.edge_midpoints;
    std::mutex progress_mutex;
    std::size_t done = 0;
    parallel_for(stack.depth, options.threads, [&](std::size_t k) {
        SliceContourSet set = trace_slice_contours(stack, static_cast<std::uint32_t>(k), labels);
        simplify_contours(set.contours, simplify);
        result.slices[k] = std::move(set);
        if (options.progress) {
            std::lock_guard<std::mutex> lock(progress_mutex);
            options.progress("contour slices", ++done, stack.depth);
        }
    });
    std::vector<std::vector<RegionLink>> pair_links(stack.depth > 0 ? stack.depth - 1 : 0);
    parallel_for(pair_links.size(), options.threads, [&](std::size_t k) {
        pair_links[k] = link_slices(stack, static_cast<std::uint32_t>(k), result.slices[k],
                                    result.slices[k + 1], labels);
    });
    for (auto& links : pair_links) {
        result.links.insert(result.links.end(), std::make_move_iterator(links.begin()),
                            std::make_move_iterator(links.end()));
    }
    return result;
}

}  // namespace strata
