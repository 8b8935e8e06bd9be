// Tests of the distance stage. The property test compares every node of fields on random masks
// with a brute force written here (distance to every site, the tie rule, even-odd point in
// polygon on the contours); each iteration runs on its own std::mt19937 seeded from a
// std::mt19937(42) stream (the seed is in the failure message); more iterations with
// STRATA_PROPERTY_ITERATIONS.
#include "distance/distance_field.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <limits>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "contours/extract_contours.h"
#include "core/error.h"
#include "support/property.h"

namespace strata {
namespace {

using test::property_iterations;

SliceStack make_stack(std::uint32_t width, std::uint32_t height, std::uint32_t depth) {
    SliceStack s;
    s.width = width;
    s.height = height;
    s.depth = depth;
    s.labels.assign(s.slice_size() * depth, 0);
    return s;
}

void set_pixel(SliceStack& s, std::uint32_t i, std::uint32_t j, std::uint32_t k, std::uint16_t v) {
    s.labels[(std::size_t(k) * s.height + j) * s.width + i] = v;
}

void fill_box(SliceStack& s,
              std::uint32_t k,
              std::uint32_t x0,
              std::uint32_t y0,
              std::uint32_t x1,
              std::uint32_t y1,
              std::uint16_t v) {
    for (std::uint32_t j = y0; j < y1; ++j) {
        for (std::uint32_t i = x0; i < x1; ++i) {
            set_pixel(s, i, j, k, v);
        }
    }
}

std::vector<std::uint16_t> labels_on(const SliceStack& s) {
    std::vector<std::uint16_t> labels;
    for (std::uint16_t v : s.labels) {
        if (v != 0) {
            labels.push_back(v);
        }
    }
    std::sort(labels.begin(), labels.end());
    labels.erase(std::unique(labels.begin(), labels.end()), labels.end());
    return labels;
}

SliceContours trace_all(const SliceStack& s) {
    SliceContours c;
    c.width = s.width;
    c.height = s.height;
    const std::vector<std::uint16_t> labels = labels_on(s);
    for (std::uint32_t k = 0; k < s.depth; ++k) {
        c.slices.push_back(trace_slice_contours(s, k, labels));
    }
    return c;
}

// ---- Independent brute force ----------------------------------------------------------------

/// A point in doubled integer coordinates (2x, 2y), exact on the half-pixel grid.
struct Doubled {
    std::int64_t x = 0;
    std::int64_t y = 0;
};

Doubled doubled(Vec2 p) {
    return {std::llround(2 * p.x), std::llround(2 * p.y)};
}

/// Expected window of `label` on slice k: pixel box over slices k-1..k+1, grown by the margin.
struct ExpectedWindow {
    std::int64_t x0 = 0, y0 = 0, x1 = 0, y1 = 0;  // px, pixel corners
};

ExpectedWindow expected_window(const SliceStack& s,
                               std::uint32_t k,
                               std::uint16_t label,
                               double margin_px) {
    std::int64_t x0 = INT64_MAX, y0 = INT64_MAX, x1 = INT64_MIN, y1 = INT64_MIN;
    for (std::int64_t kk = std::int64_t(k) - 1; kk <= std::int64_t(k) + 1; ++kk) {
        if (kk < 0 || kk >= std::int64_t(s.depth)) {
            continue;
        }
        for (std::uint32_t j = 0; j < s.height; ++j) {
            for (std::uint32_t i = 0; i < s.width; ++i) {
                if (s.at(i, j, std::uint32_t(kk)) == label) {
                    x0 = std::min<std::int64_t>(x0, i);
                    y0 = std::min<std::int64_t>(y0, j);
                    x1 = std::max<std::int64_t>(x1, i + 1);
                    y1 = std::max<std::int64_t>(y1, j + 1);
                }
            }
        }
    }
    const auto m = static_cast<std::int64_t>(std::ceil(margin_px));
    return {x0 - m, y0 - m, x1 + m, y1 + m};
}

/// The sites as the header defines them, in (contour, point, midpoint) order.
std::vector<ContourSite> expected_sites(const SliceContourSet& set, std::uint16_t label) {
    std::vector<ContourSite> sites;
    for (std::size_t c = 0; c < set.contours.size(); ++c) {
        const Contour& contour = set.contours[c];
        if (contour.label != label) {
            continue;
        }
        const std::size_t n = contour.points.size();
        for (std::size_t i = 0; i < n; ++i) {
            sites.push_back({std::uint32_t(c), std::uint32_t(i), false});
            const Vec2 a = contour.points[i];
            const Vec2 b = contour.points[(i + 1) % n];
            if (std::hypot(b.x - a.x, b.y - a.y) == 1.0) {
                sites.push_back({std::uint32_t(c), std::uint32_t(i), true});
            }
        }
    }
    return sites;
}

/// Even-odd test of p (doubled) against the label's contours; p must not lie on one.
bool inside_even_odd(const SliceContourSet& set, std::uint16_t label, Doubled p) {
    bool inside = false;
    for (const Contour& contour : set.contours) {
        if (contour.label != label) {
            continue;
        }
        const std::size_t n = contour.points.size();
        for (std::size_t i = 0; i < n; ++i) {
            const Doubled a = doubled(contour.points[i]);
            const Doubled b = doubled(contour.points[(i + 1) % n]);
            if ((a.y > p.y) == (b.y > p.y)) {
                continue;
            }
            // crossing of the horizontal ray to +x: p.x < a.x + (p.y - a.y) (b.x - a.x) / (b.y -
            // a.y)
            const std::int64_t lhs = (p.x - a.x) * (b.y - a.y);
            const std::int64_t rhs = (p.y - a.y) * (b.x - a.x);
            if ((b.y > a.y) ? lhs < rhs : lhs > rhs) {
                inside = !inside;
            }
        }
    }
    return inside;
}

double brute_distance(const std::vector<Doubled>& sites, double x, double y) {
    double best = std::numeric_limits<double>::infinity();
    for (const Doubled& s : sites) {
        best = std::min(best, std::hypot(0.5 * s.x - x, 0.5 * s.y - y));
    }
    return best;
}

/// DistanceField::distance_row gives `at` of every node, bit for bit (the compact storage's two
/// ways of recomputing a distance from the closest site).
void expect_rows_match_at(const DistanceField& field) {
    std::vector<float> row(field.nx);
    int failures = 0;
    for (std::uint32_t j = 0; j < field.ny && failures < 5; ++j) {
        // the whole row, and its part from node 1 (unaligned for the vector path)
        for (const std::uint32_t i0 : {0u, std::min(1u, field.nx)}) {
            field.distance_row(j, i0, field.nx - i0, row.data());
            for (std::uint32_t i = i0; i < field.nx && failures < 5; ++i) {
                const float at = field.at(i, j);
                if (std::memcmp(&at, &row[i - i0], sizeof at) != 0) {
                    ADD_FAILURE() << "node (" << i << ", " << j << "): at " << at << ", row "
                                  << row[i - i0];
                    ++failures;
                }
            }
        }
    }
}

/// Compares every node of `field` with the brute force; reports the first few differences.
void check_field(const SliceStack& stack,
                 const SliceContourSet& set,
                 std::uint32_t k,
                 std::uint16_t label,
                 double margin_px,
                 const DistanceField& field,
                 std::mt19937& rng) {
    SCOPED_TRACE("slice " + std::to_string(k) + ", label " + std::to_string(label) + ", margin " +
                 std::to_string(margin_px));
    ASSERT_EQ(field.label, label);
    ASSERT_EQ(field.slice, k);
    const ExpectedWindow w = expected_window(stack, k, label, margin_px);
    ASSERT_EQ(field.origin_x, double(w.x0));
    ASSERT_EQ(field.origin_y, double(w.y0));
    ASSERT_EQ(field.nx, std::uint32_t(2 * (w.x1 - w.x0) + 1));
    ASSERT_EQ(field.ny, std::uint32_t(2 * (w.y1 - w.y0) + 1));
    ASSERT_EQ(field.node_offsets.size(), std::size_t(field.nx) * field.ny);
    ASSERT_EQ(
        field.block_bases.size(),
        (field.node_offsets.size() + DistanceField::kBlockNodes - 1) / DistanceField::kBlockNodes);
    ASSERT_EQ(field.site_nodes.size(), field.sites.size());
    ASSERT_EQ(field.sites, expected_sites(set, label));
    expect_rows_match_at(field);

    std::vector<Doubled> site_points;
    for (const ContourSite& s : field.sites) {
        site_points.push_back(doubled(site_position(set, s)));
    }
    int failures = 0;
    for (std::uint32_t j = 0; j < field.ny && failures < 5; ++j) {
        for (std::uint32_t i = 0; i < field.nx && failures < 5; ++i) {
            const Doubled p{2 * w.x0 + i, 2 * w.y0 + j};
            std::int64_t best = INT64_MAX;
            std::uint32_t argmin = 0;
            for (std::size_t s = 0; s < site_points.size(); ++s) {
                const std::int64_t dx = p.x - site_points[s].x;
                const std::int64_t dy = p.y - site_points[s].y;
                const std::int64_t d2 = dx * dx + dy * dy;
                if (d2 < best) {  // strict: the first (smallest index) among equals
                    best = d2;
                    argmin = std::uint32_t(s);
                }
            }
            const double exact = 0.5 * std::sqrt(double(best));
            const float d = field.at(i, j);
            const std::uint32_t closest = field.closest(field.node_index(i, j));
            std::ostringstream node;
            node << "node (" << i << ", " << j << ") at (" << 0.5 * p.x << ", " << 0.5 * p.y
                 << "): D " << d << ", brute " << exact << ", closest " << closest
                 << ", brute argmin " << argmin;
            const Vec2 at = field.node_position(i, j);
            EXPECT_EQ(at.x, 0.5 * p.x);
            EXPECT_EQ(at.y, 0.5 * p.y);
            bool ok = std::abs(std::abs(double(d)) - exact) <= 1e-4 && closest == argmin &&
                      closest < field.sites.size();
            if (ok) {
                const Vec2 q = site_position(set, field.sites[closest]);
                ok = std::abs(std::hypot(q.x - at.x, q.y - at.y) - std::abs(double(d))) <= 1e-4;
            }
            if (ok && best == 0) {
                ok = d == 0.0f;
            } else if (ok) {
                ok = (d < 0) == inside_even_odd(set, label, p);
            }
            if (!ok) {
                ADD_FAILURE() << node.str();
                ++failures;
            }
        }
    }
    // 1-Lipschitz between neighbouring nodes (0.5 px apart)
    for (std::uint32_t j = 0; j < field.ny; ++j) {
        for (std::uint32_t i = 0; i < field.nx; ++i) {
            if (i + 1 < field.nx) {
                ASSERT_LE(std::abs(field.at(i, j) - field.at(i + 1, j)), 0.5 + 1e-6)
                    << "nodes (" << i << ", " << j << ") and (" << i + 1 << ", " << j << ")";
            }
            if (j + 1 < field.ny) {
                ASSERT_LE(std::abs(field.at(i, j) - field.at(i, j + 1)), 0.5 + 1e-6)
                    << "nodes (" << i << ", " << j << ") and (" << i << ", " << j + 1 << ")";
            }
        }
    }
    // the bound outside the window: at least the margin, below every distance outside
    EXPECT_GE(field.outside_window_px, std::ceil(margin_px));
    const double x0 = double(w.x0), y0 = double(w.y0), x1 = double(w.x1), y1 = double(w.y1);
    for (int t = -3; t <= 2 * int(x1 - x0) + 3; ++t) {  // rings of nodes just outside
        for (int ring = 1; ring <= 3; ++ring) {
            const double x = x0 + 0.5 * t;
            for (double y : {y0 - 0.5 * ring, y1 + 0.5 * ring}) {
                ASSERT_GE(brute_distance(site_points, x, y), field.outside_window_px)
                    << "at (" << x << ", " << y << ")";
            }
        }
    }
    for (int t = -3; t <= 2 * int(y1 - y0) + 3; ++t) {
        for (int ring = 1; ring <= 3; ++ring) {
            const double y = y0 + 0.5 * t;
            for (double x : {x0 - 0.5 * ring, x1 + 0.5 * ring}) {
                ASSERT_GE(brute_distance(site_points, x, y), field.outside_window_px)
                    << "at (" << x << ", " << y << ")";
            }
        }
    }
    std::uniform_real_distribution<double> offset(1e-9, 3.0);
    for (int t = 0; t < 40; ++t) {  // random points beyond each side
        double x = std::uniform_real_distribution<double>(x0 - 3, x1 + 3)(rng);
        double y = std::uniform_real_distribution<double>(y0 - 3, y1 + 3)(rng);
        switch (t % 4) {
            case 0:
                y = y0 - offset(rng);
                break;
            case 1:
                y = y1 + offset(rng);
                break;
            case 2:
                x = x0 - offset(rng);
                break;
            default:
                x = x1 + offset(rng);
                break;
        }
        ASSERT_GE(brute_distance(site_points, x, y), field.outside_window_px)
            << "at (" << x << ", " << y << ")";
    }
}

/// Random masks: noise or a union of rectangles and discs, one or two labels.
SliceStack random_stack(std::mt19937& rng) {
    auto uniform_int = [&](int lo, int hi) {
        return std::uniform_int_distribution<int>(lo, hi)(rng);
    };
    const std::uint32_t width = std::uint32_t(uniform_int(2, 13));
    const std::uint32_t height = std::uint32_t(uniform_int(2, 13));
    const std::uint32_t depth = uniform_int(0, 2) == 0 ? 1 : 3;
    const int labels = uniform_int(1, 2);
    SliceStack s = make_stack(width, height, depth);
    for (std::uint32_t k = 0; k < depth; ++k) {
        if (uniform_int(0, 1) == 0) {
            const double density = std::uniform_real_distribution<double>(0.2, 0.8)(rng);
            for (std::uint32_t j = 0; j < height; ++j) {
                for (std::uint32_t i = 0; i < width; ++i) {
                    if (std::uniform_real_distribution<double>(0, 1)(rng) < density) {
                        set_pixel(s, i, j, k, std::uint16_t(uniform_int(1, labels)));
                    }
                }
            }
        } else {
            const int shapes = uniform_int(1, 4);
            for (int n = 0; n < shapes; ++n) {
                const std::uint16_t v = std::uint16_t(uniform_int(1, labels));
                const double cx = std::uniform_real_distribution<double>(0, width)(rng);
                const double cy = std::uniform_real_distribution<double>(0, height)(rng);
                const double r = std::uniform_real_distribution<double>(0.5, 5)(rng);
                const bool disc = uniform_int(0, 1) == 0;
                const bool erase = uniform_int(0, 4) == 0;  // holes
                for (std::uint32_t j = 0; j < height; ++j) {
                    for (std::uint32_t i = 0; i < width; ++i) {
                        const double dx = i + 0.5 - cx;
                        const double dy = j + 0.5 - cy;
                        const bool in = disc ? dx * dx + dy * dy <= r * r
                                             : std::abs(dx) <= r && std::abs(dy) <= 0.6 * r;
                        if (in) {
                            set_pixel(s, i, j, k, erase ? 0 : v);
                        }
                    }
                }
            }
        }
    }
    return s;
}

TEST(DistanceField, RandomMasksMatchBruteForce) {
    const int iterations = property_iterations(300);
    std::mt19937 seeds(42);
    const double margins[] = {0.0, 0.5, 1.0, 2.0, 2.5, 4.0};
    int fields = 0;
    for (int it = 0; it < iterations; ++it) {
        const std::uint32_t seed = seeds();
        SCOPED_TRACE("seed " + std::to_string(seed));
        std::mt19937 rng(seed);
        const SliceStack stack = random_stack(rng);
        const std::uint32_t k = stack.depth / 2;
        const SliceContourSet set = trace_slice_contours(stack, k, labels_on(stack));
        DistanceOptions options;
        options.margin_px = margins[std::uniform_int_distribution<int>(0, 5)(rng)];
        for (const SliceLabelRegions& regions : set.labels) {
            const DistanceField field =
                compute_distance_field(stack, set, k, regions.label, options);
            check_field(stack, set, k, regions.label, options.margin_px, field, rng);
            ++fields;
            if (::testing::Test::HasFailure()) {
                return;
            }
        }
    }
    EXPECT_GE(fields, iterations);  // most masks hold a label on the middle slice, many two
    std::cout << "[ checked  ] " << fields << " fields from " << iterations << " random masks\n";
}

TEST(DistanceField, TiesGoToTheSmallestSiteIndex) {
    // a 2 x 2 block: its centre corner (2, 2) is equidistant from four sites; the one-pixel gap
    // to the second block gives many exact ties between the two contours
    SliceStack stack = make_stack(7, 5, 1);
    fill_box(stack, 0, 1, 1, 3, 3, 1);
    fill_box(stack, 0, 4, 1, 6, 4, 1);
    const SliceContourSet set = trace_slice_contours(stack, 0, {1});
    std::mt19937 rng(42);
    const DistanceField field = compute_distance_field(stack, set, 0, 1, {});
    check_field(stack, set, 0, 1, 4.0, field, rng);
    // the pixel centre (3.5, 2.5) in the gap: sites (3, 2.5) and (4, 2.5) tie at 0.5 px
    const std::uint32_t i = std::uint32_t(2 * (3.5 - field.origin_x));
    const std::uint32_t j = std::uint32_t(2 * (2.5 - field.origin_y));
    EXPECT_FLOAT_EQ(field.at(i, j), 0.5f);
    const ContourSite won = field.sites[field.closest(field.node_index(i, j))];
    EXPECT_EQ(set.contours[won.contour].points[0].x, 1.0);  // the first contour's site
}

TEST(DistanceField, DeterministicForAnyThreadCount) {
    std::mt19937 rng(42);
    SliceStack stack = make_stack(48, 40, 8);
    for (std::uint32_t k = 0; k < stack.depth; ++k) {
        for (int n = 0; n < 6; ++n) {
            const std::uint16_t v = std::uint16_t(1 + n % 3);
            const double cx = std::uniform_real_distribution<double>(5, 43)(rng);
            const double cy = std::uniform_real_distribution<double>(5, 35)(rng);
            const double r = std::uniform_real_distribution<double>(2, 9)(rng);
            for (std::uint32_t j = 0; j < stack.height; ++j) {
                for (std::uint32_t i = 0; i < stack.width; ++i) {
                    if (std::hypot(i + 0.5 - cx, j + 0.5 - cy) <= r) {
                        set_pixel(stack, i, j, k, v);
                    }
                }
            }
        }
    }
    const SliceContours contours = trace_all(stack);
    DistanceOptions options;
    options.threads = 1;
    std::vector<std::size_t> progress;
    options.progress = [&](std::string_view what, std::size_t done, std::size_t total) {
        EXPECT_EQ(what, "distance slices");
        EXPECT_EQ(total, stack.depth);
        progress.push_back(done);
    };
    const std::vector<SliceDistanceFields> one = compute_distance_fields(stack, contours, options);
    ASSERT_EQ(progress.size(), stack.depth);
    for (std::size_t i = 0; i < progress.size(); ++i) {
        EXPECT_EQ(progress[i], i + 1);
    }
    options.threads = 4;
    options.progress = nullptr;
    const std::vector<SliceDistanceFields> four = compute_distance_fields(stack, contours, options);
    // the label boxes of one scan, as batches of labels share them
    const LabelBoxes boxes = compute_label_boxes(stack, contours, 2);
    options.boxes = &boxes;
    const std::vector<SliceDistanceFields> shared =
        compute_distance_fields(stack, contours, options);
    LabelBoxes other_labels = boxes;
    other_labels.labels.pop_back();
    options.boxes = &other_labels;
    EXPECT_THROW(compute_distance_fields(stack, contours, options), Error);
    ASSERT_EQ(one.size(), stack.depth);
    ASSERT_EQ(four.size(), stack.depth);
    ASSERT_EQ(shared.size(), stack.depth);
    std::size_t fields = 0;
    for (std::uint32_t k = 0; k < stack.depth; ++k) {
        SCOPED_TRACE("slice " + std::to_string(k));
        ASSERT_EQ(one[k].fields.size(), contours.slices[k].labels.size());
        ASSERT_EQ(four[k].fields.size(), one[k].fields.size());
        ASSERT_EQ(shared[k].fields.size(), one[k].fields.size());
        for (std::size_t f = 0; f < one[k].fields.size(); ++f) {
            const DistanceField& a = one[k].fields[f];
            const DistanceField& b = four[k].fields[f];
            const DistanceField c = compute_distance_field(stack, contours.slices[k], k,
                                                           contours.slices[k].labels[f].label, {});
            for (const DistanceField* other : {&b, &c, &shared[k].fields[f]}) {
                EXPECT_EQ(a.label, other->label);
                EXPECT_EQ(a.slice, other->slice);
                EXPECT_EQ(a.origin_x, other->origin_x);
                EXPECT_EQ(a.origin_y, other->origin_y);
                EXPECT_EQ(a.nx, other->nx);
                EXPECT_EQ(a.ny, other->ny);
                EXPECT_EQ(a.outside_window_px, other->outside_window_px);
                EXPECT_TRUE(a.node_offsets == other->node_offsets);
                EXPECT_TRUE(a.block_bases == other->block_bases);
                EXPECT_TRUE(a.wide_values == other->wide_values);
                EXPECT_TRUE(a.site_nodes == other->site_nodes);
                EXPECT_TRUE(a.sites == other->sites);
            }
            EXPECT_EQ(a.label, contours.slices[k].labels[f].label);
            if (f > 0) {
                EXPECT_LT(one[k].fields[f - 1].label, a.label);
            }
            ++fields;
        }
    }
    EXPECT_GT(fields, 2 * stack.depth);
}

TEST(DistanceField, LabelTouchingTheImageBorder) {
    SliceStack stack = make_stack(9, 7, 1);
    fill_box(stack, 0, 0, 0, 4, 2, 1);  // top-left corner
    fill_box(stack, 0, 0, 0, 1, 7, 1);  // the whole left column
    fill_box(stack, 0, 6, 3, 9, 7, 1);  // bottom-right corner
    const SliceContourSet set = trace_slice_contours(stack, 0, {1});
    DistanceOptions options;
    options.margin_px = 2.0;
    const DistanceField field = compute_distance_field(stack, set, 0, 1, options);
    EXPECT_EQ(field.origin_x, -2.0);  // the window reaches beyond the image
    EXPECT_EQ(field.origin_y, -2.0);
    EXPECT_EQ(field.nx, 2u * 13 + 1);
    EXPECT_EQ(field.ny, 2u * 11 + 1);
    std::mt19937 rng(42);
    check_field(stack, set, 0, 1, options.margin_px, field, rng);
    // pixel centre (-0.5, 0.5) lies outside the image: background, 0.5 px from the left edge
    EXPECT_FLOAT_EQ(field.at(3, 5), 0.5f);
    // image corner (0, 0) is on the contour; (0.5, 0.5) is the centre of a label pixel
    EXPECT_EQ(field.at(4, 4), 0.0f);
    EXPECT_FLOAT_EQ(field.at(5, 5), -0.5f);
}

TEST(DistanceField, ObjectOnASingleSliceAndWindowFromNeighbours) {
    SliceStack stack = make_stack(30, 24, 3);
    fill_box(stack, 1, 10, 10, 13, 12, 1);  // label 1 on slice 1 only
    fill_box(stack, 0, 2, 3, 27, 20, 2);    // label 2: large below ...
    fill_box(stack, 1, 14, 8, 18, 13, 2);   // ... small on slice 1 ...
    fill_box(stack, 2, 15, 9, 29, 23, 2);   // ... and wide above
    const SliceContours contours = trace_all(stack);
    DistanceOptions options;
    options.margin_px = 1.5;  // two pixels
    const DistanceField one = compute_distance_field(stack, contours.slices[1], 1, 1, options);
    EXPECT_EQ(one.origin_x, 8.0);
    EXPECT_EQ(one.origin_y, 8.0);
    EXPECT_EQ(one.nx, 2u * 7 + 1);
    EXPECT_EQ(one.ny, 2u * 6 + 1);
    EXPECT_EQ(one.outside_window_px, 2.0);
    const DistanceField two = compute_distance_field(stack, contours.slices[1], 1, 2, options);
    EXPECT_EQ(two.origin_x, 0.0);
    EXPECT_EQ(two.origin_y, 1.0);
    EXPECT_EQ(two.nx, 2u * 31 + 1);
    EXPECT_EQ(two.ny, 2u * 24 + 1);
    EXPECT_EQ(two.outside_window_px, 7.0);  // the slice's own box is 7 px from the window's top
    std::mt19937 rng(42);
    check_field(stack, contours.slices[1], 1, 1, options.margin_px, one, rng);
    check_field(stack, contours.slices[1], 1, 2, options.margin_px, two, rng);
    // the top slice: label 2's window covers slice 1 and itself only
    const DistanceField top = compute_distance_field(stack, contours.slices[2], 2, 2, options);
    check_field(stack, contours.slices[2], 2, 2, options.margin_px, top, rng);
}

TEST(DistanceField, AbsentLabelThrowsAndIsSkipped) {
    SliceStack stack = make_stack(12, 12, 2);
    fill_box(stack, 0, 2, 2, 6, 6, 1);
    fill_box(stack, 0, 7, 7, 10, 10, 2);
    fill_box(stack, 1, 3, 3, 5, 5, 1);
    const SliceContours contours = trace_all(stack);
    try {
        compute_distance_field(stack, contours.slices[1], 1, 2, {});
        FAIL() << "expected an error";
    } catch (const Error& e) {
        EXPECT_EQ(e.code(), ErrorCode::InvalidInput);
        EXPECT_NE(std::string(e.what()).find("slice 1, label 2: the label is absent"),
                  std::string::npos)
            << e.what();
    }
    const std::vector<SliceDistanceFields> fields = compute_distance_fields(stack, contours, {});
    ASSERT_EQ(fields.size(), 2u);
    ASSERT_EQ(fields[0].fields.size(), 2u);
    ASSERT_EQ(fields[1].fields.size(), 1u);
    EXPECT_EQ(fields[1].fields[0].label, 1);
    // an empty slice gets no fields
    SliceStack empty = make_stack(5, 5, 1);
    const std::vector<SliceDistanceFields> none =
        compute_distance_fields(empty, trace_all(empty), {});
    ASSERT_EQ(none.size(), 1u);
    EXPECT_TRUE(none[0].fields.empty());
}

TEST(DistanceField, DiscCentreIsMinusItsRadius) {
    SliceStack stack = make_stack(80, 80, 1);
    for (std::uint32_t j = 0; j < 80; ++j) {
        for (std::uint32_t i = 0; i < 80; ++i) {
            if (std::hypot(i + 0.5 - 40.0, j + 0.5 - 40.0) <= 30.0) {
                set_pixel(stack, i, j, 0, 1);
            }
        }
    }
    const SliceContourSet set = trace_slice_contours(stack, 0, {1});
    const DistanceField field = compute_distance_field(stack, set, 0, 1, {});
    const std::uint32_t i = std::uint32_t(2 * (40.0 - field.origin_x));
    const std::uint32_t j = std::uint32_t(2 * (40.0 - field.origin_y));
    EXPECT_NEAR(field.at(i, j), -30.0, 0.75);
    // and +4 just outside the window's margin side, along the axis
    EXPECT_NEAR(field.at(i, 0), 4.0, 0.75);
    EXPECT_GE(field.outside_window_px, 4.0);
}

/// Node (i, j) of label 1's `field` against the brute force over `sites` (doubled): its distance
/// bit for bit (the exact distance rounded once to float) and its closest site; reports a
/// difference.
bool node_matches_brute_force(const DistanceField& field,
                              const SliceContourSet& set,
                              const std::vector<Doubled>& sites,
                              std::uint32_t i,
                              std::uint32_t j) {
    const Doubled p{std::int64_t(2 * field.origin_x) + i, std::int64_t(2 * field.origin_y) + j};
    std::int64_t best = INT64_MAX;
    std::uint32_t argmin = 0;
    for (std::size_t s = 0; s < sites.size(); ++s) {
        const std::int64_t dx = p.x - sites[s].x;
        const std::int64_t dy = p.y - sites[s].y;
        if (dx * dx + dy * dy < best) {  // strict: the smallest index among equals
            best = dx * dx + dy * dy;
            argmin = std::uint32_t(s);
        }
    }
    const float r = static_cast<float>(0.5 * std::sqrt(double(best)));
    const float expected = best != 0 && inside_even_odd(set, 1, p) ? -r : r;
    const float d = field.at(i, j);
    const std::uint32_t closest = field.closest(field.node_index(i, j));
    if (std::memcmp(&d, &expected, sizeof d) != 0 || closest != argmin) {
        ADD_FAILURE() << "node (" << i << ", " << j << "): D " << d << ", expected " << expected
                      << ", closest " << closest << ", brute argmin " << argmin;
        return false;
    }
    return true;
}

TEST(DistanceField, StripsOfOverAMillionNodesAreExact) {
    // Past 2^20 nodes per side the row envelope compares by quotients instead of 64-bit
    // products, and past 2048 px the roots are taken in double instead of float: a strip of
    // 530000 px with a few pixels, both ways round, every node against the brute force and the
    // distance bit for bit (the exact distance rounded once to float).
    for (const bool tall : {false, true}) {
        SCOPED_TRACE(tall ? "tall strip" : "wide strip");
        const std::uint32_t length = 530000;
        SliceStack stack = tall ? make_stack(1, length, 1) : make_stack(length, 1, 1);
        for (const std::uint32_t t : {0u, 1000u, 1001u, 250000u, length - 1}) {
            set_pixel(stack, tall ? 0 : t, tall ? t : 0, 0, 1);
        }
        const SliceContourSet set = trace_slice_contours(stack, 0, {1});
        DistanceOptions options;
        options.margin_px = 0.0;
        const DistanceField field = compute_distance_field(stack, set, 0, 1, options);
        ASSERT_EQ(tall ? field.ny : field.nx, 2 * length + 1);
        ASSERT_EQ(field.sites, expected_sites(set, 1));
        expect_rows_match_at(field);
        std::vector<Doubled> sites;
        for (const ContourSite& s : field.sites) {
            sites.push_back(doubled(site_position(set, s)));
        }
        int failures = 0;
        for (std::uint32_t j = 0; j < field.ny && failures < 5; ++j) {
            for (std::uint32_t i = 0; i < field.nx && failures < 5; ++i) {
                failures += node_matches_brute_force(field, set, sites, i, j) ? 0 : 1;
            }
        }
    }
}

TEST(DistanceField, BlocksWhoseSitesSpanOver2To15AreExact) {
    // The nodes are packed by blocks of kBlockNodes with 15-bit offsets from a base site; a block
    // whose closest sites span 2^15 or more keeps full values. A 1 px bar of 9000 px has about
    // 36000 sites, numbered along its contour, so the blocks where the numbering starts again span
    // them all: those blocks and every 16th other one against the brute force, bit for bit.
    const std::uint32_t length = 9000;
    SliceStack stack = make_stack(length, 1, 1);
    fill_box(stack, 0, 0, 0, length, 1, 1);
    const SliceContourSet set = trace_slice_contours(stack, 0, {1});
    DistanceOptions options;
    options.margin_px = 1.0;
    const DistanceField field = compute_distance_field(stack, set, 0, 1, options);
    ASSERT_GT(field.sites.size(), std::size_t(1) << 15);
    ASSERT_EQ(field.sites, expected_sites(set, 1));
    ASSERT_FALSE(field.wide_values.empty());
    expect_rows_match_at(field);
    std::vector<Doubled> sites;
    for (const ContourSite& s : field.sites) {
        sites.push_back(doubled(site_position(set, s)));
    }
    const std::size_t nodes = std::size_t(field.nx) * field.ny;
    int failures = 0;
    std::size_t wide_nodes = 0;
    for (std::size_t n = 0; n < nodes && failures < 5; ++n) {
        const std::size_t block = n / DistanceField::kBlockNodes;
        const bool wide = (field.block_bases[block] & DistanceField::kWideBlock) != 0;
        if (!wide && block % 16 != 0) {
            continue;
        }
        wide_nodes += wide ? 1 : 0;
        const auto i = std::uint32_t(n % field.nx);
        const auto j = std::uint32_t(n / field.nx);
        failures += node_matches_brute_force(field, set, sites, i, j) ? 0 : 1;
    }
    EXPECT_GT(wide_nodes, std::size_t(0));
}

// ---- Errors -----------------------------------------------------------------------------------

template <class F>
void expect_invalid_input(F&& f, const std::string& fragment) {
    try {
        f();
        ADD_FAILURE() << "expected an error containing \"" << fragment << "\"";
    } catch (const Error& e) {
        EXPECT_EQ(e.code(), ErrorCode::InvalidInput) << e.what();
        EXPECT_NE(std::string(e.what()).find(fragment), std::string::npos) << e.what();
    }
}

TEST(DistanceField, RejectsBadArguments) {
    SliceStack stack = make_stack(10, 10, 2);
    fill_box(stack, 0, 2, 2, 6, 6, 1);
    fill_box(stack, 1, 3, 2, 7, 6, 1);
    const SliceContours contours = trace_all(stack);
    DistanceOptions options;
    expect_invalid_input([&] { compute_distance_field(stack, contours.slices[0], 2, 1, options); },
                         "slice 2, label 1: slice out of range, the stack has 2 slices");
    options.margin_px = -1.0;
    expect_invalid_input([&] { compute_distance_field(stack, contours.slices[0], 0, 1, options); },
                         "margin_px -1, expected a finite value");
    expect_invalid_input([&] { compute_distance_fields(stack, contours, options); },
                         "margin_px -1, expected a finite value");
    options.margin_px = std::numeric_limits<double>::quiet_NaN();
    expect_invalid_input([&] { compute_distance_field(stack, contours.slices[0], 0, 1, options); },
                         "margin_px nan");
    options.margin_px = 1e7;
    expect_invalid_input([&] { compute_distance_field(stack, contours.slices[0], 0, 1, options); },
                         "nodes is too large");
    SliceContours wrong = contours;
    wrong.slices.pop_back();
    expect_invalid_input([&] { compute_distance_fields(stack, wrong, {}); },
                         "with 1 slices, expected 10x10 with 2 slices");
}

TEST(DistanceField, RejectsContoursThatDoNotMatchTheMask) {
    SliceStack stack = make_stack(10, 10, 2);
    fill_box(stack, 0, 2, 2, 6, 6, 1);
    fill_box(stack, 1, 3, 2, 7, 6, 1);
    const SliceContours contours = trace_all(stack);
    // slice 0's contours against slice 1's pixels
    expect_invalid_input([&] { compute_distance_field(stack, contours.slices[0], 1, 1, {}); },
                         "slice 1, label 1: the contours do not match the label image at");
    SliceContourSet off_grid = contours.slices[0];
    off_grid.contours[0].points[1].x += 0.25;
    expect_invalid_input([&] { compute_distance_field(stack, off_grid, 0, 1, {}); },
                         "is off the half-pixel grid");
    SliceContourSet long_step = contours.slices[0];
    long_step.contours[0].points.erase(long_step.contours[0].points.begin() + 1);
    expect_invalid_input([&] { compute_distance_field(stack, long_step, 0, 1, {}); },
                         "expected 1, 0.5 or sqrt(1/2) px");
    SliceContourSet twice = contours.slices[0];
    twice.contours.push_back(twice.contours[0]);
    expect_invalid_input([&] { compute_distance_field(stack, twice, 0, 1, {}); },
                         "contours 1 and 0 meet at (");
    SliceContourSet no_contour = contours.slices[0];
    no_contour.contours.clear();
    expect_invalid_input([&] { compute_distance_field(stack, no_contour, 0, 1, {}); },
                         "the label is absent from the slice (no contour)");
}

}  // namespace
}  // namespace strata
