// Signed distance fields with closest-point maps (Klein, Schilling, Strasser, section 4.1: every
// pixel gets its distance to the contours and a pointer to the closest contour pixel). The paper
// fills regions around each contour pixel; we compute the same exact Euclidean feature transform
// with separable lower envelopes, on the half-pixel grid so that every contour point is a node:
//
// - P. F. Felzenszwalb, D. P. Huttenlocher, "Distance Transforms of Sampled Functions", Theory of
//   Computing 8(19), 2012: squared distance to the sites = min over columns x' of
//   f(x', y) + (x - x')^2, where f is the 1D column transform; the minimum over parabolas of equal
//   curvature is their lower envelope, built left to right in linear time.
// - C. R. Maurer, R. Qi, V. Raghavan, "A linear time algorithm for computing exact Euclidean
//   distance transforms of binary images in arbitrary dimensions", IEEE PAMI 25(2), 2003 (the same
//   separable scheme with feature tracking; its test for removing the middle of three parabolas
//   needs no division).
//
// Everything runs in doubled integer coordinates (node (X, Y) is at (X / 2, Y / 2) px from the
// window origin), so squared distances are exact integers and the tie rule (smallest site index
// among the nearest sites) is decided exactly. One sweep over the rows does both passes: per
// column it follows the nearest site above and below (the sites bucketed by row), so each node's
// nearest site in its column, with that rule, is known when its row is reached; the row's
// envelope then orders parabolas by (value, site index), i.e. takes the site index as an
// infinitesimal added to the heights, under which no two parabolas are equal at an integer x and
// Maurer's removal test stays exact. The result is written once, and each square is rooted in
// float where that is exact (distances up to 2048 px).
//
// One file: the window's phases (sites, mask, sites by row, the row sweep with its lower
// envelope) share one thread's scratch buffers and the branch-free helpers their loops
// vectorize with; the field's queries below read the same layout.
#include "distance/distance_field.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <mutex>
#include <string>

#if defined(__SSE2__)
#include <emmintrin.h>
#endif
#if defined(__linux__)
#include <sys/mman.h>
#endif

#include "core/error.h"
#include "core/parallel.h"
#include "core/pixel_box.h"

namespace strata {

namespace {

constexpr std::uint32_t kNoSite = std::numeric_limits<std::uint32_t>::max();
/// Largest window: node rows and columns stay below 2^24 (column distances are exact in a float,
/// squared doubled distances below 2^53) and the field below 2^30 nodes (8 GiB).
constexpr std::int64_t kMaxNodesPerSide = std::int64_t(1) << 24;
constexpr std::int64_t kMaxNodes = std::int64_t(1) << 30;
/// A node row beyond any distance in a window.
constexpr std::int32_t kFar = std::int32_t(1) << 24;

/// Box of the pixels equal to `label` on slice k.
PixelBox label_box(const SliceStack& stack, std::uint32_t k, std::uint16_t label) {
    PixelBox box{INT64_MAX, INT64_MAX, INT64_MIN, INT64_MIN};
    const auto slice = stack.slice(k);
    const std::int64_t width = stack.width;
    for (std::int64_t y = 0; y < stack.height; ++y) {
        const std::uint16_t* row = slice.data() + y * width;
        // note: a test that vectorizes first, as most rows do not hold a given label; then the
        // row is searched only outside the box found so far
        std::uint32_t any = 0;
        for (std::int64_t x = 0; x < width; ++x) {
            any |= static_cast<std::uint32_t>(row[x] == label);
        }
        if (any == 0) {
            continue;
        }
        for (std::int64_t x = 0; x < std::min(box.x0, width); ++x) {
            if (row[x] == label) {
                box.x0 = x;
                break;
            }
        }
        for (std::int64_t x = width - 1; x >= std::max<std::int64_t>(box.x1, 0); --x) {
            if (row[x] == label) {
                box.x1 = x + 1;
                break;
            }
        }
        box.y0 = std::min(box.y0, y);
        box.y1 = y + 1;
    }
    return box.empty() ? PixelBox{} : box;
}

/// Boxes of all labels on slice k in one scan, indexed through `label_index` (-1: not wanted).
std::vector<PixelBox> label_boxes(const SliceStack& stack,
                                  std::uint32_t k,
                                  const std::vector<std::int32_t>& label_index,
                                  std::size_t label_count) {
    std::vector<PixelBox> boxes(label_count, PixelBox{INT64_MAX, INT64_MAX, INT64_MIN, INT64_MIN});
    const auto slice = stack.slice(k);
    for (std::int64_t y = 0; y < stack.height; ++y) {
        const std::uint16_t* row = slice.data() + y * stack.width;
        std::int64_t x = 0;
        while (x < stack.width) {
            // note: runs of one value are handled at once; label maps are mostly long runs
            const std::uint16_t value = row[x];
            const std::int64_t run_start = x;
            while (x < stack.width && row[x] == value) {
                ++x;
            }
            const std::int32_t l = value == 0 ? -1 : label_index[value];
            if (l < 0) {
                continue;
            }
            PixelBox& b = boxes[static_cast<std::size_t>(l)];
            b.x0 = std::min(b.x0, run_start);
            b.x1 = std::max(b.x1, x);
            b.y0 = std::min(b.y0, y);
            b.y1 = y + 1;
        }
    }
    for (PixelBox& b : boxes) {
        if (b.empty()) {
            b = PixelBox{};
        }
    }
    return boxes;
}

/// Per-thread buffers, reused from call to call (no allocation per node, few per field; apart from
/// the mask, all are per site, per row or per column).
struct Scratch {
    std::vector<std::uint8_t> mask;          // window pixels + 1 background pixel of padding
    std::vector<std::int8_t> side;           // one row: -1 inside, +1 outside, 0 on a contour
    std::vector<std::int32_t> site_x;        // per site: its node (X, Y)
    std::vector<std::int32_t> site_y;        //
    std::vector<std::uint32_t> row_begin;    // sites by row: row Y's are row_site[row_begin[Y]..]
    std::vector<std::uint32_t> row_site;     //
    std::vector<std::int32_t> next_row;      // per row_site entry: the next site below in its
    std::vector<std::uint32_t> next_site;    // column (row >= kFar: none)
    std::vector<std::int32_t> above_row;     // per column: nearest site at or above the row
    std::vector<std::uint32_t> above_site;   //
    std::vector<std::int32_t> below_row;     // per column: nearest site at or below the row
    std::vector<std::uint32_t> below_site;   //
    std::vector<std::int32_t> column_dy;     // one row: distance to the column's nearest site
    std::vector<std::uint32_t> column_site;  // one row: that site
    std::vector<std::int32_t> apex;          // row envelope: column X' of each parabola
    std::vector<std::int64_t> height;        // row envelope: f(X'), squared column distance
    std::vector<std::int64_t> offset;        // row envelope: f(X') + X'^2
    std::vector<std::uint32_t> site;         // row envelope: the site of that column
    std::vector<std::int64_t> start;         // row envelope: first x the parabola owns
};

Scratch& thread_scratch() {
    thread_local Scratch scratch;
    return scratch;
}

// note: branch-free selects, so that the loops using them vectorize (GCC 12 does not if-convert
// the equivalent conditional expressions there)
std::uint32_t all_if(bool b) {
    return 0u - static_cast<std::uint32_t>(b);
}
template <class T>
T pick(std::uint32_t mask, T a, T b) {
    static_assert(sizeof(T) == 4);
    const auto ua = static_cast<std::uint32_t>(a);
    const auto ub = static_cast<std::uint32_t>(b);
    return static_cast<T>((ua & mask) | (ub & ~mask));
}

/// v = n copies of `value`. On Linux, large buffers are first marked for transparent huge pages,
/// as numpy does for arrays of 4 MiB and more: the first write to fresh memory then faults once
/// per 2 MiB instead of once per 4 KiB, which is most of the cost of a large field's allocation.
template <class T>
void assign_large(std::vector<T>& v, std::size_t n, T value) {
#if defined(__linux__) && defined(MADV_HUGEPAGE)
    constexpr std::uintptr_t kHugePage = std::uintptr_t(1) << 21;
    if (n * sizeof(T) >= 2 * kHugePage) {
        v.reserve(n);
        const auto begin = reinterpret_cast<std::uintptr_t>(v.data());
        const std::uintptr_t from = (begin + kHugePage - 1) & ~(kHugePage - 1);
        const std::uintptr_t to = (begin + n * sizeof(T)) & ~(kHugePage - 1);
        if (from < to) {
            // note: only a hint, its failure changes nothing
            madvise(reinterpret_cast<void*>(from), to - from, MADV_HUGEPAGE);
        }
    }
#endif
    v.assign(n, value);
}

std::string where(std::uint32_t k, std::uint16_t label) {
    return "distance field, slice " + std::to_string(k) + ", label " + std::to_string(label);
}

std::string format_px(double v) {
    std::string s = std::to_string(v);
    s.erase(s.find_last_not_of('0') + 1);
    if (!s.empty() && s.back() == '.') {
        s.pop_back();
    }
    return s;
}

std::int64_t margin_pixels(double margin_px, std::uint32_t k, std::uint16_t label) {
    if (!std::isfinite(margin_px) || margin_px < 0.0 ||
        margin_px > static_cast<double>(kMaxNodesPerSide)) {
        throw Error(ErrorCode::InvalidInput, where(k, label) + ": margin_px " +
                                                 format_px(margin_px) +
                                                 ", expected a finite value in [0, 2^24]");
    }
    return static_cast<std::int64_t>(std::ceil(margin_px));
}

/// -1 inside, +1 outside, 0 boundary (must be a site) for every node of row Y (doubled, window
/// relative). `mask` has `mask_width` = window pixels + 2 columns; padded pixel (u, v) is window
/// pixel (u - 1, v - 1), so node X of a centre row looks at u = (X + 1) / 2.
void classify_row(const std::uint8_t* mask,
                  std::size_t mask_width,
                  std::int64_t Y,
                  std::int64_t nx,
                  std::int8_t* side) {
    auto pair = [](std::uint8_t a, std::uint8_t b) -> std::int8_t {
        return a != b ? 0 : (a ? -1 : 1);
    };
    const std::int64_t pixels = (nx - 1) / 2;
    if (Y % 2 != 0) {
        // pixel centres (odd X) and vertical edge midpoints (even X)
        const std::uint8_t* r = mask + static_cast<std::size_t>((Y + 1) / 2) * mask_width;
        for (std::int64_t c = 0; c < pixels; ++c) {
            side[2 * c] = pair(r[c], r[c + 1]);
            side[2 * c + 1] = r[c + 1] ? -1 : 1;
        }
        side[2 * pixels] = pair(r[pixels], r[pixels + 1]);
        return;
    }
    // pixel corners (even X) and horizontal edge midpoints (odd X)
    const std::uint8_t* ra = mask + static_cast<std::size_t>(Y / 2) * mask_width;
    const std::uint8_t* rb = ra + mask_width;
    auto corner = [&](std::int64_t c) -> std::int8_t {
        const int sum = ra[c] + ra[c + 1] + rb[c] + rb[c + 1];
        if (sum == 0) {
            return 1;
        }
        if (sum == 4 || (sum == 2 && ra[c] == rb[c + 1])) {
            return -1;  // note: a saddle corner is cut off by the contour, inside
        }
        return 0;
    };
    for (std::int64_t c = 0; c < pixels; ++c) {
        side[2 * c] = corner(c);
        side[2 * c + 1] = pair(ra[c + 1], rb[c + 1]);
    }
    side[2 * pixels] = corner(pixels);
}

/// First integer x at which parabola (apex b, height fb, site sb) beats (apex a < b, fa, sa)
/// under the order (value, site index): x 2 (b - a) > num = (fb + b^2) - (fa + a^2), or equal
/// and sb < sa (`later_site_wins`). The difference of the parabolas falls linearly in x, so it
/// keeps winning after. `den` = 2 (b - a).
std::int64_t first_win(std::int64_t num, std::int64_t den, bool later_site_wins) {
    // note: |num| < 2^51, so the double quotient truncated is within one of the floor
    std::int64_t q = static_cast<std::int64_t>(static_cast<double>(num) / static_cast<double>(den));
    q -= q * den > num ? 1 : 0;
    q += (q + 1) * den <= num ? 1 : 0;
    return q + 1 - static_cast<std::int64_t>((q * den == num) & later_site_wins);
}

/// Sign of n1 / d1 - n2 / d2 for d1, d2 > 0, exact: by products when `small` (|n| < 2^41,
/// d < 2^21), else by floor quotients and remainders (|n| < 2^62, d < 2^31).
int compare_fractions(
    std::int64_t n1, std::int64_t d1, std::int64_t n2, std::int64_t d2, bool small) {
    if (small) {
        const std::int64_t lhs = n1 * d2;
        const std::int64_t rhs = n2 * d1;
        return (lhs > rhs) - (lhs < rhs);
    }
    auto floor_div = [](std::int64_t n, std::int64_t d) {
        const std::int64_t q = n / d;
        return q - static_cast<std::int64_t>((n % d != 0) & (n < 0));
    };
    const std::int64_t q1 = floor_div(n1, d1);
    const std::int64_t q2 = floor_div(n2, d2);
    if (q1 != q2) {
        return q1 > q2 ? 1 : -1;
    }
    const std::int64_t lhs = (n1 - q1 * d1) * d2;
    const std::int64_t rhs = (n2 - q2 * d2) * d1;
    return (lhs > rhs) - (lhs < rhs);
}

/// Whether the middle of three parabolas with apexes a1 < a2 < a3 (g = f + a^2, site s) is
/// nowhere alone at the bottom under the order (value, site index): taking the site index as an
/// infinitesimal added to the heights, every two parabolas meet at one point and none are equal
/// at an integer x, and the middle one is hidden when it meets the first at or after it meets
/// the third (Maurer, Qi, Raghavan's removal test, exact in integers).
bool is_hidden(std::int64_t a1,
               std::int64_t g1,
               std::uint32_t s1,
               std::int64_t a2,
               std::int64_t g2,
               std::uint32_t s2,
               std::int64_t a3,
               std::int64_t g3,
               std::uint32_t s3,
               bool small) {
    const std::int64_t d12 = a2 - a1;
    const std::int64_t d23 = a3 - a2;
    const int order = compare_fractions(g2 - g1, d12, g3 - g2, d23, small);
    if (order != 0) {
        return order > 0;
    }
    const std::int64_t e12 = static_cast<std::int64_t>(s2) - static_cast<std::int64_t>(s1);
    const std::int64_t e23 = static_cast<std::int64_t>(s3) - static_cast<std::int64_t>(s2);
    return e12 * d23 >= e23 * d12;  // note: |e| < 2^30, d < 2^24
}

/// The row's lower envelope, as a stack of parabolas.
struct Envelope {
    std::int32_t* apex;    ///< column X' of each parabola, increasing
    std::int64_t* height;  ///< f(X'), squared column distance
    std::int64_t* offset;  ///< f(X') + X'^2
    std::uint32_t* site;   ///< the site of that column
};

/// Builds the lower envelope of the parabolas f(X') + (x - X')^2 (f = column_dy^2, site
/// column_site) of the columns X' < nx with a site (column_dy < far), left to right, dropping
/// every parabola that is nowhere alone at the bottom under the order (value, site index);
/// returns their number. `kSmall`: at most 2^20 nodes per side (64-bit products suffice).
template <bool kSmall>
std::int64_t lower_envelope(const std::int32_t* column_dy,
                            const std::uint32_t* column_site,
                            std::int64_t nx,
                            std::int32_t far,
                            const Envelope& out) {
    std::int64_t count = 0;
    // note: the top two parabolas are kept in registers, out of the loop's memory dependencies
    std::int64_t a1 = 0;
    std::int64_t g1 = 0;
    std::uint32_t s1 = 0;
    std::int64_t a2 = 0;
    std::int64_t g2 = 0;
    std::uint32_t s2 = 0;
    for (std::int64_t X = 0; X < nx; ++X) {
        const std::int64_t dy = column_dy[X];
        if (dy >= far) {
            continue;  // no site in this column
        }
        const std::int64_t f = dy * dy;
        if (X > 0 && X + 1 < nx) {
            // note: beaten everywhere by its neighbour columns' parabolas (strictly, so whatever
            // the sites) when 2 f > f_left + f_right + 2
            const std::int64_t left = column_dy[X - 1];
            const std::int64_t right = column_dy[X + 1];
            if (left < far && right < far && 2 * f > left * left + right * right + 2) {
                continue;
            }
        }
        const std::int64_t g = f + X * X;
        const std::uint32_t s = column_site[X];
        while (count >= 2 && is_hidden(a1, g1, s1, a2, g2, s2, X, g, s, kSmall)) {
            --count;
            a2 = a1;
            g2 = g1;
            s2 = s1;
            if (count >= 2) {
                a1 = out.apex[count - 2];
                g1 = out.offset[count - 2];
                s1 = out.site[count - 2];
            }
        }
        out.apex[count] = static_cast<std::int32_t>(X);
        out.height[count] = f;
        out.offset[count] = g;
        out.site[count] = s;
        ++count;
        a1 = a2;
        g1 = g2;
        s1 = s2;
        a2 = X;
        g2 = g;
        s2 = s;
    }
    return count;
}

/// The field's window of nodes: its pixel origin and size, and its node counts per side.
struct Window {
    std::int64_t ox = 0;
    std::int64_t oy = 0;
    std::int64_t pw = 0;  ///< window pixels per row
    std::int64_t ph = 0;
    std::int64_t nx = 0;  ///< nodes per row: 2 pw + 1
    std::int64_t ny = 0;
};

/// The sites of `label`'s contours on slice k: contour points and unit-segment midpoints, each
/// marked in `closest` and numbered in `field.sites` (nodes in scratch.site_x and site_y).
void add_contour_sites(const SliceContourSet& set,
                       std::uint32_t k,
                       std::uint16_t label,
                       const Window& w,
                       DistanceField& field,
                       std::uint32_t* closest,
                       Scratch& scratch) {
    const std::int64_t nx = w.nx;
    const std::int64_t ny = w.ny;
    auto node_of = [&](Vec2 p, std::size_t c, std::size_t i, std::int64_t& X, std::int64_t& Y) {
        const double dx = 2.0 * (p.x - field.origin_x);
        const double dy = 2.0 * (p.y - field.origin_y);
        if (!(dx >= 0 && dy >= 0 && dx < static_cast<double>(nx) && dy < static_cast<double>(ny)) ||
            dx != std::floor(dx) || dy != std::floor(dy)) {
            throw Error(ErrorCode::InvalidInput,
                        where(k, label) + ": point " + std::to_string(i) + " (" + format_px(p.x) +
                            ", " + format_px(p.y) + ") of contour " + std::to_string(c) +
                            " is off the half-pixel grid or outside the label's pixels");
        }
        X = static_cast<std::int64_t>(dx);
        Y = static_cast<std::int64_t>(dy);
    };
    auto add_site = [&](std::int64_t X, std::int64_t Y, ContourSite site) {
        std::uint32_t& slot = closest[static_cast<std::size_t>(Y * nx + X)];
        if (slot != kNoSite) {
            throw Error(ErrorCode::InvalidInput,
                        where(k, label) + ": contours " + std::to_string(site.contour) + " and " +
                            std::to_string(field.sites[slot].contour) + " meet at (" +
                            format_px(field.origin_x + 0.5 * X) + ", " +
                            format_px(field.origin_y + 0.5 * Y) + ")");
        }
        slot = static_cast<std::uint32_t>(field.sites.size());
        field.sites.push_back(site);
        scratch.site_x.push_back(static_cast<std::int32_t>(X));
        scratch.site_y.push_back(static_cast<std::int32_t>(Y));
    };
    for (std::size_t c = 0; c < set.contours.size(); ++c) {
        const Contour& contour = set.contours[c];
        if (contour.label != label) {
            continue;
        }
        const std::size_t n = contour.points.size();
        std::int64_t X = 0;
        std::int64_t Y = 0;
        std::int64_t next_x = 0;
        std::int64_t next_y = 0;
        if (n > 0) {
            node_of(contour.points[0], c, 0, next_x, next_y);
        }
        for (std::size_t i = 0; i < n; ++i) {
            X = next_x;
            Y = next_y;
            node_of(contour.points[(i + 1) % n], c, (i + 1) % n, next_x, next_y);
            const std::int64_t sx = std::abs(next_x - X);
            const std::int64_t sy = std::abs(next_y - Y);
            const bool unit = (sx == 2 && sy == 0) || (sx == 0 && sy == 2);
            if (!unit && !(sx + sy == 1) && !(sx == 1 && sy == 1)) {
                throw Error(ErrorCode::InvalidInput,
                            where(k, label) + ": contour " + std::to_string(c) + " steps " +
                                format_px(0.5 * std::hypot(double(sx), double(sy))) +
                                " px from point " + std::to_string(i) +
                                ", expected 1, 0.5 or sqrt(1/2) px");
            }
            add_site(X, Y, {static_cast<std::uint32_t>(c), static_cast<std::uint32_t>(i), false});
            if (unit) {
                add_site((X + next_x) / 2, (Y + next_y) / 2,
                         {static_cast<std::uint32_t>(c), static_cast<std::uint32_t>(i), true});
            }
        }
    }
    if (field.sites.empty()) {
        throw Error(ErrorCode::InvalidInput,
                    where(k, label) + ": the label is absent from the slice (no contour)");
    }
    field.site_nodes.resize(field.sites.size());
    for (std::size_t s = 0; s < field.sites.size(); ++s) {
        field.site_nodes[s] = {scratch.site_x[s], scratch.site_y[s]};
    }
}

/// The label's pixels over the window with one pixel of background padding (pixels outside the
/// image are background), in scratch.mask; returns its row length.
std::size_t fill_window_mask(const SliceStack& stack,
                             std::uint32_t k,
                             std::uint16_t label,
                             const Window& w,
                             Scratch& scratch) {
    const std::int64_t ox = w.ox;
    const std::int64_t oy = w.oy;
    const std::int64_t pw = w.pw;
    const std::int64_t ph = w.ph;
    const std::size_t mask_width = static_cast<std::size_t>(pw + 2);
    scratch.mask.assign(mask_width * static_cast<std::size_t>(ph + 2), 0);
    {
        const auto slice = stack.slice(k);
        const std::int64_t x_begin = std::max<std::int64_t>(ox - 1, 0);
        const std::int64_t x_end = std::min<std::int64_t>(ox + pw + 1, stack.width);
        const std::int64_t y_begin = std::max<std::int64_t>(oy - 1, 0);
        const std::int64_t y_end = std::min<std::int64_t>(oy + ph + 1, stack.height);
        for (std::int64_t y = y_begin; y < y_end; ++y) {
            const std::uint16_t* row = slice.data() + y * stack.width;
            std::uint8_t* m =
                scratch.mask.data() + static_cast<std::size_t>(y - oy + 1) * mask_width;
            for (std::int64_t x = x_begin; x < x_end; ++x) {
                m[x - ox + 1] = row[x] == label;
            }
        }
    }
    return mask_width;
}

/// The sites by row (counting sort), and for each the next site below in its column; the
/// per-column cursors start at the bottom.
void sort_sites_by_row(const Window& w, std::size_t site_count, Scratch& scratch) {
    const std::int64_t ny = w.ny;
    const std::size_t width = static_cast<std::size_t>(w.nx);
    const std::int32_t* site_x = scratch.site_x.data();
    const std::int32_t* site_y = scratch.site_y.data();
    scratch.row_begin.assign(static_cast<std::size_t>(ny) + 1, 0);
    std::uint32_t* row_begin = scratch.row_begin.data();
    for (std::size_t s = 0; s < site_count; ++s) {
        ++row_begin[site_y[s] + 1];
    }
    for (std::int64_t Y = 0; Y < ny; ++Y) {
        row_begin[Y + 1] += row_begin[Y];
    }
    scratch.row_site.resize(site_count);
    std::uint32_t* row_site = scratch.row_site.data();
    for (std::size_t s = 0; s < site_count; ++s) {
        row_site[row_begin[site_y[s]]++] = static_cast<std::uint32_t>(s);
    }
    for (std::int64_t Y = ny; Y > 0; --Y) {
        row_begin[Y] = row_begin[Y - 1];  // note: the placing loop moved each begin to its end
    }
    row_begin[0] = 0;
    scratch.above_row.assign(width, -2 * kFar);
    scratch.above_site.assign(width, kNoSite);
    scratch.below_row.assign(width, 2 * kFar);
    scratch.below_site.assign(width, kNoSite);
    std::int32_t* below_row = scratch.below_row.data();
    std::uint32_t* below_site = scratch.below_site.data();
    scratch.next_row.resize(site_count);
    scratch.next_site.resize(site_count);
    std::int32_t* next_row = scratch.next_row.data();
    std::uint32_t* next_site = scratch.next_site.data();
    for (std::int64_t Y = ny - 1; Y >= 0; --Y) {
        for (std::uint32_t e = row_begin[Y]; e < row_begin[Y + 1]; ++e) {
            const std::uint32_t s = row_site[e];
            const std::int32_t X = site_x[s];
            next_row[e] = below_row[X];
            next_site[e] = below_site[X];
            below_row[X] = static_cast<std::int32_t>(Y);
            below_site[X] = s;
        }
    }
}

/// Per row: the nearest site of each column (ties to the smaller site index), then the lower
/// envelope of the columns' parabolas, signed by the node's side; checks on the way that the
/// row's sites are exactly its boundary nodes.
void sweep_rows(std::uint32_t k,
                std::uint16_t label,
                const Window& w,
                std::size_t mask_width,
                DistanceField& field,
                std::uint32_t* closest,
                Scratch& scratch) {
    const std::int64_t nx = w.nx;
    const std::int64_t ny = w.ny;
    const std::size_t width = static_cast<std::size_t>(nx);
    scratch.side.resize(width);
    std::int8_t* side = scratch.side.data();
    auto mismatch = [&](std::int64_t Y, std::int64_t X, bool is_site) {
        return Error(ErrorCode::InvalidInput,
                     where(k, label) + ": the contours do not match the label image at (" +
                         format_px(field.origin_x + 0.5 * X) + ", " +
                         format_px(field.origin_y + 0.5 * Y) + "): " +
                         (is_site ? "a contour point with equal pixels around it"
                                  : "a boundary between pixels on no contour"));
    };

    const std::int32_t* site_x = scratch.site_x.data();
    const std::uint32_t* row_begin = scratch.row_begin.data();
    const std::uint32_t* row_site = scratch.row_site.data();
    std::int32_t* above_row = scratch.above_row.data();
    std::uint32_t* above_site = scratch.above_site.data();
    std::int32_t* below_row = scratch.below_row.data();
    std::uint32_t* below_site = scratch.below_site.data();
    const std::int32_t* next_row = scratch.next_row.data();
    const std::uint32_t* next_site = scratch.next_site.data();
    scratch.column_dy.resize(width);
    scratch.column_site.resize(width);
    scratch.apex.resize(width);
    scratch.height.resize(width);
    scratch.offset.resize(width);
    scratch.site.resize(width);
    scratch.start.resize(width + 1);
    std::int32_t* column_dy = scratch.column_dy.data();
    std::uint32_t* column_site = scratch.column_site.data();
    std::int32_t* apex = scratch.apex.data();
    std::int64_t* height = scratch.height.data();
    std::int64_t* offset = scratch.offset.data();
    std::uint32_t* site = scratch.site.data();
    std::int64_t* start = scratch.start.data();
    const Envelope envelope{apex, height, offset, site};
    // note: with at most 2^20 nodes per side the envelope's products fit in 64 bits
    const bool small = nx <= (std::int64_t(1) << 20) && ny <= (std::int64_t(1) << 20);
    for (std::int64_t Y = 0; Y < ny; ++Y) {
        std::uint32_t* c = closest + static_cast<std::size_t>(Y) * width;
        const std::int32_t y = static_cast<std::int32_t>(Y);

        // the sites of this row (marked in `closest`) must be exactly its boundary nodes
        classify_row(scratch.mask.data(), mask_width, Y, nx, side);
        std::uint32_t bad = 0;
        for (std::size_t X = 0; X < width; ++X) {
            bad |= all_if(c[X] != kNoSite) ^ all_if(side[X] == 0);
        }
        if (bad) {
            for (std::size_t X = 0;; ++X) {
                if ((c[X] != kNoSite) != (side[X] == 0)) {
                    throw mismatch(Y, static_cast<std::int64_t>(X), c[X] != kNoSite);
                }
            }
        }

        const std::uint32_t row_sites_begin = row_begin[Y];
        const std::uint32_t row_sites_end = row_begin[Y + 1];
        for (std::uint32_t e = row_sites_begin; e < row_sites_end; ++e) {
            const std::uint32_t s = row_site[e];
            const std::int32_t X = site_x[s];
            above_row[X] = y;
            above_site[X] = s;
            below_row[X] = y;
            below_site[X] = s;
        }
        for (std::size_t X = 0; X < width; ++X) {
            const std::int32_t up = y - above_row[X];
            const std::int32_t down = below_row[X] - y;
            const std::uint32_t up_site = above_site[X];
            const std::uint32_t down_site = below_site[X];
            const std::uint32_t take = all_if((down < up) | ((down == up) & (down_site < up_site)));
            column_dy[X] = pick(take, down, up);
            column_site[X] = pick(take, down_site, up_site);
        }
        for (std::uint32_t e = row_sites_begin; e < row_sites_end; ++e) {
            const std::int32_t X = site_x[row_site[e]];
            below_row[X] = next_row[e];
            below_site[X] = next_site[e];
        }

        const std::int64_t count =
            small ? lower_envelope<true>(column_dy, column_site, nx, kFar, envelope)
                  : lower_envelope<false>(column_dy, column_site, nx, kFar, envelope);
        // note: the parabolas meet in increasing order, so the first wins are non-decreasing
        // (an envelope parabola may own no integer x)
        start[0] = 0;
        for (std::int64_t e = 1; e < count; ++e) {
            start[e] = std::clamp<std::int64_t>(
                first_win(offset[e] - offset[e - 1], 2 * (apex[e] - apex[e - 1]),
                          site[e] < site[e - 1]),
                0, nx);
        }
        start[count] = nx;

        // the closest site of every node, and its side (DistanceField::at recomputes the
        // distance from them)
        for (std::int64_t e = 0; e < count; ++e) {
            const std::uint32_t site_of = site[e];
            for (std::int64_t X = start[e]; X < start[e + 1]; ++X) {
                c[X] = site_of;
            }
        }
        for (std::size_t X = 0; X < width; ++X) {
            c[X] |= all_if(side[X] < 0) & DistanceField::kInside;  // note: sites have side 0
        }
    }
}

/// The field of `label` on slice k over `window` (pixel box of the label on slices k-1..k+1)
/// grown by `margin` pixels; `own` is the label's box on slice k.
/// Packs the nodes' values (closest site | kInside, row-major) into `field` (see
/// DistanceField::node_offsets).
void pack_nodes(const std::vector<std::uint32_t>& values, DistanceField& field) {
    constexpr std::size_t kBlock = DistanceField::kBlockNodes;
    constexpr std::uint32_t kSpan = DistanceField::kOffsetInside;  // offsets below 2^15
    const std::size_t blocks = (values.size() + kBlock - 1) / kBlock;
    assign_large(field.node_offsets, values.size(), std::uint16_t{0});
    field.block_bases.assign(blocks, 0);
    field.wide_values.clear();
    for (std::size_t b = 0; b < blocks; ++b) {
        const std::size_t first = b * kBlock;
        const std::size_t last = std::min(first + kBlock, values.size());
        std::uint32_t lo = ~std::uint32_t(0);
        std::uint32_t hi = 0;
        for (std::size_t n = first; n < last; ++n) {
            const std::uint32_t site = values[n] & ~DistanceField::kInside;
            lo = std::min(lo, site);
            hi = std::max(hi, site);
        }
        if (hi - lo < kSpan) {
            field.block_bases[b] = lo;
            for (std::size_t n = first; n < last; ++n) {
                const std::uint32_t v = values[n];
                const std::uint32_t inside = (v & DistanceField::kInside) != 0 ? kSpan : 0;
                field.node_offsets[n] =
                    static_cast<std::uint16_t>(((v & ~DistanceField::kInside) - lo) | inside);
            }
        } else {
            const std::size_t w = field.wide_values.size() / kBlock;
            field.block_bases[b] = DistanceField::kWideBlock | static_cast<std::uint32_t>(w);
            field.wide_values.insert(field.wide_values.end(), values.begin() + first,
                                     values.begin() + last);
            field.wide_values.resize((w + 1) * kBlock, 0);
        }
    }
    field.wide_values.shrink_to_fit();
}

DistanceField field_in_window(const SliceStack& stack,
                              const SliceContourSet& set,
                              std::uint32_t k,
                              std::uint16_t label,
                              const PixelBox& own,
                              const PixelBox& window,
                              std::int64_t margin) {
    if (own.empty()) {
        throw Error(ErrorCode::InvalidInput,
                    where(k, label) + ": the label is absent from the slice (no pixel)");
    }
    DistanceField field;
    field.label = label;
    field.slice = k;
    const std::int64_t ox = window.x0 - margin;
    const std::int64_t oy = window.y0 - margin;
    const std::int64_t pw = window.x1 - window.x0 + 2 * margin;  // window pixels per row
    const std::int64_t ph = window.y1 - window.y0 + 2 * margin;
    const std::int64_t nx = 2 * pw + 1;
    const std::int64_t ny = 2 * ph + 1;
    if (nx >= kMaxNodesPerSide || ny >= kMaxNodesPerSide || nx * ny > kMaxNodes) {
        throw Error(ErrorCode::InvalidInput, where(k, label) + ": window of " + std::to_string(nx) +
                                                 " x " + std::to_string(ny) +
                                                 " nodes is too large (at most 2^30 nodes, 2^24 " +
                                                 "per side); reduce margin_px");
    }
    field.origin_x = static_cast<double>(ox);
    field.origin_y = static_cast<double>(oy);
    field.nx = static_cast<std::uint32_t>(nx);
    field.ny = static_cast<std::uint32_t>(ny);
    const std::size_t nodes = static_cast<std::size_t>(nx * ny);
    std::vector<std::uint32_t> closest;
    assign_large(closest, nodes, kNoSite);
    Scratch& scratch = thread_scratch();
    scratch.site_x.clear();
    scratch.site_y.clear();

    const Window w{ox, oy, pw, ph, nx, ny};
    add_contour_sites(set, k, label, w, field, closest.data(), scratch);
    const std::size_t mask_width = fill_window_mask(stack, k, label, w, scratch);
    sort_sites_by_row(w, field.sites.size(), scratch);
    sweep_rows(k, label, w, mask_width, field, closest.data(), scratch);
    pack_nodes(closest, field);

    // ---- lower bound outside the window (see DistanceField)
    field.outside_window_px = static_cast<double>(
        std::min({own.x0 - ox, ox + pw - own.x1, own.y0 - oy, oy + ph - own.y1}));
    return field;
}

}  // namespace

void DistanceField::distance_row(std::uint32_t j,
                                 std::uint32_t i0,
                                 std::uint32_t count,
                                 float* out) const {
    // note: the row's values unpacked in chunks, so the loops below stay as simple as on a
    // plain array
    constexpr std::uint32_t kChunk = 256;
    if (count > kChunk) {
        for (std::uint32_t done = 0; done < count; done += kChunk) {
            distance_row(j, i0 + done, std::min(kChunk, count - done), out + done);
        }
        return;
    }
    std::array<std::uint32_t, kChunk> values;
    const std::size_t first = node_index(i0, j);
    for (std::uint32_t k = 0; k < count; ++k) {
        values[k] = node_value(first + k);
    }
    const std::uint32_t* row = values.data();
    constexpr std::int64_t kExactFloat = std::int64_t(1) << 24;  // squares up to here: float path
    bool exact_float = true;
    for (std::uint32_t k = 0; k < count; ++k) {
        const std::array<std::int32_t, 2>& s = site_nodes[row[k] & ~kInside];
        const std::int64_t dx = std::int64_t(i0) + k - s[0];
        const std::int64_t dy = std::int64_t(j) - s[1];
        const std::int64_t n = dx * dx + dy * dy;
        exact_float = exact_float && n <= kExactFloat;
        out[k] = static_cast<float>(n);
    }
    if (!exact_float) {
        for (std::uint32_t k = 0; k < count; ++k) {
            out[k] = at(i0 + k, j);
        }
        return;
    }
    // note: 0.5f * sqrtf(float(n)) == float(0.5 * sqrt(double(n))) (what `at` computes) for every
    // n <= 2^24 (the double rounding is innocuous; checked for every n)
    std::uint32_t k = 0;
#if defined(__SSE2__)
    // note: intrinsics, as std::sqrt does not vectorize while it may set errno; kInside is the
    // float sign bit
    const __m128 half = _mm_set1_ps(0.5f);
    const __m128i inside = _mm_set1_epi32(static_cast<int>(kInside));
    for (; k + 4 <= count; k += 4) {
        const __m128 r = _mm_mul_ps(half, _mm_sqrt_ps(_mm_loadu_ps(out + k)));
        const __m128i v = _mm_loadu_si128(reinterpret_cast<const __m128i*>(row + k));
        _mm_storeu_ps(out + k, _mm_or_ps(r, _mm_castsi128_ps(_mm_and_si128(v, inside))));
    }
#endif
    for (; k < count; ++k) {
        const float r = 0.5f * std::sqrt(out[k]);
        out[k] = (row[k] & kInside) != 0 ? -r : r;
    }
}

DistanceField compute_distance_field(const SliceStack& stack,
                                     const SliceContourSet& set,
                                     std::uint32_t k,
                                     std::uint16_t label,
                                     const DistanceOptions& options) {
    if (k >= stack.depth) {
        throw Error(ErrorCode::InvalidInput, where(k, label) +
                                                 ": slice out of range, the stack has " +
                                                 std::to_string(stack.depth) + " slices");
    }
    const std::int64_t margin = margin_pixels(options.margin_px, k, label);
    const PixelBox own = label_box(stack, k, label);
    PixelBox window = own;
    if (k > 0) {
        window = window.united(label_box(stack, k - 1, label));
    }
    if (k + 1 < stack.depth) {
        window = window.united(label_box(stack, k + 1, label));
    }
    return field_in_window(stack, set, k, label, own, window, margin);
}

LabelBoxes compute_label_boxes(const SliceStack& stack,
                               const SliceContours& contours,
                               unsigned threads) {
    LabelBoxes result;
    result.labels = contour_labels(contours);
    const std::vector<std::int32_t> label_index = index_of_labels(result.labels);
    result.boxes.resize(stack.depth);
    parallel_for(stack.depth, threads, [&](std::size_t k) {
        result.boxes[k] =
            label_boxes(stack, static_cast<std::uint32_t>(k), label_index, result.labels.size());
    });
    return result;
}

std::vector<SliceDistanceFields> compute_distance_fields(const SliceStack& stack,
                                                         const SliceContours& contours,
                                                         const DistanceOptions& options) {
    if (contours.slices.size() != stack.depth || contours.width != stack.width ||
        contours.height != stack.height) {
        throw Error(ErrorCode::InvalidInput,
                    "distance fields: contours of " + std::to_string(contours.width) + "x" +
                        std::to_string(contours.height) + " with " +
                        std::to_string(contours.slices.size()) + " slices, expected " +
                        std::to_string(stack.width) + "x" + std::to_string(stack.height) +
                        " with " + std::to_string(stack.depth) + " slices (the stack's)");
    }
    const std::vector<std::uint16_t> labels = contour_labels(contours);
    const std::vector<std::int32_t> label_index = index_of_labels(labels);
    if (!labels.empty()) {
        margin_pixels(options.margin_px, 0, labels.front());  // validate before any work
    }

    LabelBoxes scanned;
    const LabelBoxes* known = options.boxes;
    if (known == nullptr) {
        scanned = compute_label_boxes(stack, contours, options.threads);
        known = &scanned;
    } else if (known->labels != labels || known->boxes.size() != stack.depth) {
        throw Error(ErrorCode::Internal,
                    "distance fields: label boxes of other labels or another stack");
    }
    const std::vector<std::vector<PixelBox>>& boxes = known->boxes;

    std::vector<SliceDistanceFields> result(stack.depth);
    std::mutex progress_mutex;
    std::size_t done = 0;
    parallel_for(stack.depth, options.threads, [&](std::size_t k) {
        const SliceContourSet& set = contours.slices[k];
        const std::uint32_t slice = static_cast<std::uint32_t>(k);
        std::vector<std::uint16_t> slice_labels;
        for (const SliceLabelRegions& regions : set.labels) {
            slice_labels.push_back(regions.label);
        }
        std::sort(slice_labels.begin(), slice_labels.end());
        slice_labels.erase(std::unique(slice_labels.begin(), slice_labels.end()),
                           slice_labels.end());
        for (const std::uint16_t label : slice_labels) {
            if (!options.labels.empty() &&
                !std::binary_search(options.labels.begin(), options.labels.end(), label)) {
                continue;
            }
            const std::size_t l = static_cast<std::size_t>(label_index[label]);
            const std::int64_t margin = margin_pixels(options.margin_px, slice, label);
            PixelBox window = boxes[k][l];
            if (k > 0) {
                window = window.united(boxes[k - 1][l]);
            }
            if (k + 1 < stack.depth) {
                window = window.united(boxes[k + 1][l]);
            }
            result[k].fields.push_back(
                field_in_window(stack, set, slice, label, boxes[k][l], window, margin));
        }
        if (options.progress) {
            std::lock_guard<std::mutex> lock(progress_mutex);
            options.progress("distance slices", ++done, stack.depth);
        }
    });
    return result;
}

}  // namespace strata
