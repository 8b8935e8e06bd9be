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
//   separable scheme with feature tracking).
//
// Everything runs in doubled integer coordinates (node (X, Y) is at (X / 2, Y / 2) px from the
// window origin), so squared distances are exact integers and the tie rule (smallest site index
// among the nearest sites) is decided exactly: the column pass keeps, per node, the nearest site
// of its column with that rule; the row pass orders parabolas by (value, site index), under which
// "the later parabola wins" is still a right half-line of x, which is all the envelope needs.
#include "distance/distance_field.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <mutex>
#include <string>

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

/// Box of the pixels equal to `label` on slice k.
PixelBox label_box(const SliceStack& stack, std::uint32_t k, std::uint16_t label) {
    PixelBox box{INT64_MAX, INT64_MAX, INT64_MIN, INT64_MIN};
    const auto slice = stack.slice(k);
    for (std::int64_t y = 0; y < stack.height; ++y) {
        const std::uint16_t* row = slice.data() + y * stack.width;
        for (std::int64_t x = 0; x < stack.width; ++x) {
            if (row[x] == label) {
                box.x0 = std::min(box.x0, x);
                box.x1 = std::max(box.x1, x + 1);
                box.y0 = std::min(box.y0, y);
                box.y1 = y + 1;
            }
        }
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

/// Per-thread buffers, reused from call to call (no allocation per node, few per field).
struct Scratch {
    std::vector<std::uint8_t> mask;          // window pixels + 1 background pixel of padding
    std::vector<std::int8_t> side;           // per node: -1 inside, +1 outside, 0 on a contour
    std::vector<std::int32_t> column_row;    // column pass: row of the last / next site
    std::vector<std::uint32_t> column_site;  // column pass: that site
    std::vector<std::int32_t> apex;          // row envelope: column x' of each parabola
    std::vector<std::int64_t> height;        // row envelope: f(x'), squared column distance
    std::vector<std::uint32_t> site;         // row envelope: the site of that column
    std::vector<std::int32_t> start;         // row envelope: first x the parabola owns
};

Scratch& thread_scratch() {
    thread_local Scratch scratch;
    return scratch;
}

// note: branch-free selects, so that the column passes vectorize (GCC 12 does not if-convert
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
/// and sb < sa. The difference of the parabolas falls linearly in x, so it keeps winning after.
std::int64_t first_win(std::int64_t a,
                       std::int64_t fa,
                       std::uint32_t sa,
                       std::int64_t b,
                       std::int64_t fb,
                       std::uint32_t sb) {
    const std::int64_t num = (fb + b * b) - (fa + a * a);
    const std::int64_t den = 2 * (b - a);
    // note: |num| < 2^51, so the double quotient truncated is within one of the floor
    std::int64_t q = static_cast<std::int64_t>(static_cast<double>(num) / static_cast<double>(den));
    q -= q * den > num ? 1 : 0;
    q += (q + 1) * den <= num ? 1 : 0;
    return q + 1 - static_cast<std::int64_t>((q * den == num) & (sb < sa));
}

/// The field of `label` on slice k over `window` (pixel box of the label on slices k-1..k+1)
/// grown by `margin` pixels; `own` is the label's box on slice k.
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
    field.closest.assign(nodes, kNoSite);
    field.distance_px.resize(nodes);
    std::uint32_t* closest = field.closest.data();
    float* distance = field.distance_px.data();

    // ---- sites: contour points and unit-segment midpoints, marked in `closest`
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

    Scratch& scratch = thread_scratch();

    // ---- window mask, one pixel of background padding (pixels outside the image are
    // background), then the side of every node
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
    const std::size_t width = static_cast<std::size_t>(nx);
    scratch.side.resize(nodes);
    std::int8_t* side = scratch.side.data();
    for (std::int64_t Y = 0; Y < ny; ++Y) {
        classify_row(scratch.mask.data(), mask_width, Y, nx,
                     side + static_cast<std::size_t>(Y) * width);
    }
    auto mismatch = [&](std::int64_t Y, std::int64_t X, bool is_site) {
        return Error(ErrorCode::InvalidInput,
                     where(k, label) + ": the contours do not match the label image at (" +
                         format_px(field.origin_x + 0.5 * X) + ", " +
                         format_px(field.origin_y + 0.5 * Y) + "): " +
                         (is_site ? "a contour point with equal pixels around it"
                                  : "a boundary between pixels on no contour"));
    };

    // ---- column pass: per node the nearest site of its column, ties to the smaller site index:
    // its distance in `distance` (an exact small integer, or >= kFar: none) and site in `closest`
    constexpr std::int32_t kFar = std::int32_t(1) << 24;  // beyond any distance in the window
    scratch.column_row.assign(width, -2 * kFar);
    scratch.column_site.assign(width, kNoSite);
    std::int32_t* row_of = scratch.column_row.data();
    std::uint32_t* site_of = scratch.column_site.data();
    for (std::int64_t Y = 0; Y < ny; ++Y) {
        std::uint32_t* c = closest + static_cast<std::size_t>(Y) * width;
        float* d = distance + static_cast<std::size_t>(Y) * width;
        const std::int8_t* sd = side + static_cast<std::size_t>(Y) * width;
        const std::int32_t y = static_cast<std::int32_t>(Y);
        std::uint32_t bad = 0;
        for (std::size_t X = 0; X < width; ++X) {
            const std::uint32_t s = c[X];
            const std::uint32_t is_site = all_if(s != kNoSite);
            bad |= is_site ^ all_if(sd[X] == 0);
            const std::int32_t r = pick(is_site, y, row_of[X]);
            const std::uint32_t nearest = pick(is_site, s, site_of[X]);
            row_of[X] = r;
            site_of[X] = nearest;
            c[X] = nearest;
            d[X] = static_cast<float>(y - r);
        }
        if (bad) {
            for (std::size_t X = 0;; ++X) {
                if ((d[X] == 0.0f) != (sd[X] == 0)) {
                    throw mismatch(Y, static_cast<std::int64_t>(X), d[X] == 0.0f);
                }
            }
        }
    }
    std::fill(row_of, row_of + width, 2 * kFar);
    std::fill(site_of, site_of + width, kNoSite);
    for (std::int64_t Y = ny - 1; Y >= 0; --Y) {
        std::uint32_t* c = closest + static_cast<std::size_t>(Y) * width;
        float* d = distance + static_cast<std::size_t>(Y) * width;
        const std::int32_t y = static_cast<std::int32_t>(Y);
        for (std::size_t X = 0; X < width; ++X) {
            const float above = d[X];
            const std::uint32_t above_site = c[X];
            const std::uint32_t is_site = all_if(above == 0.0f);
            const std::int32_t r = pick(is_site, y, row_of[X]);
            const std::uint32_t below_site = pick(is_site, above_site, site_of[X]);
            row_of[X] = r;
            site_of[X] = below_site;
            const float below = static_cast<float>(r - y);
            const std::uint32_t take =
                all_if((below < above) | ((below == above) & (below_site < above_site)));
            d[X] = take ? below : above;
            c[X] = pick(take, below_site, above_site);
        }
    }

    // ---- row pass: lower envelope of the columns' parabolas, signed by the node's side
    scratch.apex.resize(width);
    scratch.height.resize(width);
    scratch.site.resize(width);
    scratch.start.resize(width);
    std::int32_t* apex = scratch.apex.data();
    std::int64_t* height = scratch.height.data();
    std::uint32_t* site = scratch.site.data();
    std::int32_t* start = scratch.start.data();
    for (std::int64_t Y = 0; Y < ny; ++Y) {
        std::uint32_t* c = closest + static_cast<std::size_t>(Y) * width;
        float* d = distance + static_cast<std::size_t>(Y) * width;
        const std::int8_t* sd = side + static_cast<std::size_t>(Y) * width;
        std::int64_t count = 0;
        for (std::int64_t X = 0; X < nx; ++X) {
            if (d[X] >= static_cast<float>(kFar)) {
                continue;  // no site in this column
            }
            const std::int64_t dy = static_cast<std::int64_t>(d[X]);
            const std::int64_t f = dy * dy;
            const std::uint32_t s = c[X];
            // drop parabolas the new one beats wherever they would own
            while (count > 0) {
                const std::int64_t z = start[count - 1];
                const std::int64_t a = apex[count - 1];
                const std::int64_t diff =
                    (f + (z - X) * (z - X)) - (height[count - 1] + (z - a) * (z - a));
                if (diff < 0 || (diff == 0 && s < site[count - 1])) {
                    --count;
                } else {
                    break;
                }
            }
            std::int64_t from = 0;
            if (count > 0) {
                from = first_win(apex[count - 1], height[count - 1], site[count - 1], X, f, s);
                if (from >= nx) {
                    continue;  // note: never wins inside the window
                }
            }
            apex[count] = static_cast<std::int32_t>(X);
            height[count] = f;
            site[count] = s;
            start[count] = static_cast<std::int32_t>(from);
            ++count;
        }
        for (std::int64_t e = 0; e < count; ++e) {
            const std::int64_t end = e + 1 < count ? start[e + 1] : nx;
            const double a = apex[e];
            const double f = static_cast<double>(height[e]);  // note: exact, below 2^53
            const std::uint32_t s = site[e];
            for (std::int64_t X = start[e]; X < end; ++X) {
                const double dx = static_cast<double>(X) - a;
                const float r = static_cast<float>(0.5 * std::sqrt(f + dx * dx));
                d[X] = static_cast<float>(sd[X]) * r;  // note: sites have side 0 and r 0
                c[X] = s;
            }
        }
    }

    // ---- lower bound outside the window (see DistanceField)
    field.outside_window_px = static_cast<double>(
        std::min({own.x0 - ox, ox + pw - own.x1, own.y0 - oy, oy + ph - own.y1}));
    return field;
}

}  // namespace

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
    std::vector<std::int32_t> label_index(65536, -1);
    for (std::size_t i = 0; i < labels.size(); ++i) {
        label_index[labels[i]] = static_cast<std::int32_t>(i);
    }
    if (!labels.empty()) {
        margin_pixels(options.margin_px, 0, labels.front());  // validate before any work
    }

    std::vector<std::vector<PixelBox>> boxes(stack.depth);
    parallel_for(stack.depth, options.threads, [&](std::size_t k) {
        boxes[k] = label_boxes(stack, static_cast<std::uint32_t>(k), label_index, labels.size());
    });

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
