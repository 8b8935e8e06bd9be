// The test-catalogue phantoms (docs/test-catalogue.md), rasterised from analytic solids.
//
// - numpy's default_rng: M. E. O'Neill, "PCG: A Family of Simple Fast Space-Efficient
//   Statistically Good Algorithms for Random Number Generation" (HMC-CS-2014-0905), the
//   XSL-RR 128/64 generator numpy calls PCG64, seeded through numpy's SeedSequence (after
//   M. E. O'Neill's randutils seed_seq_fe hash mixing), exactly as numpy 1.17+ does.
// - T36's acceptance test evaluates the catalogue's reference volume R (slices interleaved
//   with the AND of neighbours): foreground components (26-connected, which in R equals 8 in
//   plane + faces in z), background components (6-connected), and the Euler characteristic of
//   the closed foreground cubes counted per grid vertex.
//
// One file: the catalogue is a table of cases (docs/test-catalogue.md), each written in the
// solid shorthands above it, with the seeded draws of T33, T35 and T36 and the reference-volume
// topology T36 accepts its draws with; a case reads top to bottom in one place. The sections:
// shorthands, a case before rasterisation, rasterisation, reference-volume topology, draws, the
// cases, numpy's default_rng.
#include "phantom/catalogue.h"

#include <algorithm>
#include <cmath>
#include <functional>
#include <numbers>
#include <sstream>
#include <utility>

#include "core/error.h"
#include "phantom/whole_body.h"

namespace strata {

namespace {

constexpr double kPi = std::numbers::pi;
constexpr double kDeg = kPi / 180.0;

// ---------------------------------------------------------------------------------------------
// Solid shorthands (px)

Solid ball(Vec3 c, double r) {
    return make_solid(Ball{c, r});
}

Solid cylinder(Vec2 c, double r, double z_min, double z_max, Vec2 slope = {}) {
    return make_solid(Cylinder{c, r, z_min, z_max, slope});
}

Solid half_open_box(Vec3 min, Vec3 max) {
    // note: [min, max) in x and y, closed in z (the catalogue's convention)
    return make_solid(Box{min, max, {true, true, false}});
}

Solid capsule(Vec3 a, Vec3 b, double r) {
    return make_solid(Capsule{a, b, r});
}

Solid half_space(Vec3 normal, double offset) {
    return make_solid(HalfSpace{normal, offset});
}

ExpectedTopology topology(std::uint32_t surfaces,
                          std::vector<std::uint32_t> genus,
                          std::uint32_t solids) {
    std::sort(genus.begin(), genus.end(), std::greater<>());
    return {surfaces, std::move(genus), solids};
}

ExpectedTopology genus_zero(std::uint32_t count) {
    return topology(count, std::vector<std::uint32_t>(count, 0), count);
}

// ---------------------------------------------------------------------------------------------
// A case before rasterisation.

struct Paint {
    std::uint16_t label = 1;
    Solid solid;
};

struct Spec {
    std::string id;
    std::string description;
    std::uint32_t width = 0;
    std::uint32_t height = 0;
    std::uint32_t depth = 0;
    double d = 1.0;
    double pixel_mm = 1.0;
    bool slice_defined = false;
    std::vector<PhantomObject> objects;
    std::vector<std::pair<std::uint16_t, std::string>> label_names;
    std::vector<Paint> paint;  // solids drawn in order; empty: the objects' solids
    // slice-defined pixel edits after painting; updates the draws of seeded cases
    std::function<void(SliceStack&, std::optional<PhantomDraws>&)> edit;
    std::optional<ExpectedTopology> expected;
    std::optional<PhantomDraws> draws;
    bool expected_needs_catalogue_seed = false;  // the expectation holds for the default seed only
};

Spec base(std::string id,
          std::string description,
          std::uint32_t width,
          std::uint32_t height,
          std::uint32_t depth,
          double d) {
    Spec s;
    s.id = std::move(id);
    s.description = std::move(description);
    s.width = width;
    s.height = height;
    s.depth = depth;
    s.d = d;
    return s;
}

Spec single(std::string id,
            std::string description,
            std::uint32_t width,
            std::uint32_t height,
            std::uint32_t depth,
            double d,
            std::string object,
            Solid solid,
            ExpectedTopology expected) {
    Spec s = base(std::move(id), std::move(description), width, height, depth, d);
    s.label_names = {{1, object}};
    s.objects.push_back({1, std::move(object), std::move(solid), true});
    s.expected = std::move(expected);
    return s;
}

// ---------------------------------------------------------------------------------------------
// Rasterisation

void paint(SliceStack& stack, const std::vector<Paint>& paints, double d) {
    // note: a solid is empty on the planes outside its (conservative) bounds in z; skipping them
    // leaves the stack unchanged and keeps a 1000-slice map of small solids fast
    std::vector<Bounds3> bounds;
    for (const Paint& p : paints) {
        bounds.push_back(bounding_box(p.solid));
    }
    for (std::uint32_t k = 0; k < stack.depth; ++k) {
        auto slice = stack.slice(k);
        for (std::size_t n = 0; n < paints.size(); ++n) {
            const Paint& p = paints[n];
            if (k * d < bounds[n].min.z || k * d > bounds[n].max.z) {
                continue;
            }
            const std::vector<std::uint8_t> mask =
                rasterize_solid_slice(p.solid, k * d, stack.width, stack.height);
            for (std::size_t i = 0; i < mask.size(); ++i) {
                if (mask[i]) {
                    slice[i] = p.label;
                }
            }
        }
    }
}

std::vector<std::uint8_t> binary_slices(
    const Solid& solid, std::uint32_t width, std::uint32_t height, std::uint32_t depth, double d) {
    std::vector<std::uint8_t> out;
    out.reserve(std::size_t(width) * height * depth);
    for (std::uint32_t k = 0; k < depth; ++k) {
        const std::vector<std::uint8_t> mask = rasterize_solid_slice(solid, k * d, width, height);
        out.insert(out.end(), mask.begin(), mask.end());
    }
    return out;
}

// ---------------------------------------------------------------------------------------------
// Topology of the reference volume R (used by T36's acceptance test).

struct Run {
    std::int32_t x0;
    std::int32_t x1;  // [x0, x1)
};

struct UnionFind {
    std::vector<std::uint32_t> parent;
    std::uint32_t add() {
        parent.push_back(static_cast<std::uint32_t>(parent.size()));
        return parent.back();
    }
    std::uint32_t find(std::uint32_t a) {
        while (parent[a] != a) {
            parent[a] = parent[parent[a]];
            a = parent[a];
        }
        return a;
    }
    bool unite(std::uint32_t a, std::uint32_t b) {
        a = find(a);
        b = find(b);
        if (a == b) {
            return false;
        }
        parent[std::max(a, b)] = std::min(a, b);
        return true;
    }
};

struct RTopology {
    std::uint64_t foreground_components = 0;
    std::uint64_t background_components = 0;
    std::int64_t euler = 0;  // of the closed foreground cubes
};

// A padded binary volume, x fastest.
struct Volume {
    std::int64_t nx = 0, ny = 0, nz = 0;
    std::vector<std::uint8_t> v;
    std::uint8_t at(std::int64_t x, std::int64_t y, std::int64_t z) const {
        return v[static_cast<std::size_t>((z * ny + y) * nx + x)];
    }
};

// R of `depth` binary slices (width x height, slice-major), padded by one voxel all round.
Volume reference_volume(const std::vector<std::uint8_t>& slices,
                        std::uint32_t width,
                        std::uint32_t height,
                        std::uint32_t depth) {
    Volume r;
    r.nx = width + 2;
    r.ny = height + 2;
    r.nz = 2 * std::int64_t(depth) - 1 + 2;
    r.v.assign(static_cast<std::size_t>(r.nx * r.ny * r.nz), 0);
    const std::size_t plane = std::size_t(width) * height;
    for (std::int64_t l = 0; l + 2 < r.nz; ++l) {
        const std::uint8_t* a = slices.data() + static_cast<std::size_t>(l / 2) * plane;
        const std::uint8_t* b = (l % 2 == 1) ? a + plane : a;
        for (std::uint32_t j = 0; j < height; ++j) {
            std::uint8_t* out =
                r.v.data() + static_cast<std::size_t>(((l + 1) * r.ny + j + 1) * r.nx + 1);
            for (std::uint32_t i = 0; i < width; ++i) {
                out[i] = a[std::size_t(j) * width + i] & b[std::size_t(j) * width + i];
            }
        }
    }
    return r;
}

// Components of the voxels equal to `value`; 26-connected if `full`, else 6-connected.
std::uint64_t count_components(const Volume& vol, std::uint8_t value, bool full) {
    const std::int64_t rows = vol.ny * vol.nz;
    std::vector<std::uint32_t> row_start(static_cast<std::size_t>(rows) + 1, 0);
    std::vector<Run> runs;
    for (std::int64_t r = 0; r < rows; ++r) {
        row_start[static_cast<std::size_t>(r)] = static_cast<std::uint32_t>(runs.size());
        const std::uint8_t* row = vol.v.data() + static_cast<std::size_t>(r * vol.nx);
        std::int64_t x = 0;
        while (x < vol.nx) {
            if (row[x] != value) {
                ++x;
                continue;
            }
            const std::int64_t x0 = x;
            while (x < vol.nx && row[x] == value) {
                ++x;
            }
            runs.push_back({static_cast<std::int32_t>(x0), static_cast<std::int32_t>(x)});
        }
    }
    row_start[static_cast<std::size_t>(rows)] = static_cast<std::uint32_t>(runs.size());
    UnionFind uf;
    uf.parent.reserve(runs.size());
    for (std::size_t i = 0; i < runs.size(); ++i) {
        uf.add();
    }
    std::uint64_t components = runs.size();
    // note: forward neighbour rows only; 26-connectivity adds the diagonal rows and lets runs
    // touch at a corner (slack 1), 6-connectivity needs a shared x.
    const int slack = full ? 1 : 0;
    std::vector<std::pair<int, int>> offsets = {{1, 0}, {0, 1}};
    if (full) {
        offsets.push_back({1, 1});
        offsets.push_back({-1, 1});
    }
    for (std::int64_t z = 0; z < vol.nz; ++z) {
        for (std::int64_t y = 0; y < vol.ny; ++y) {
            const std::int64_t r = z * vol.ny + y;
            for (auto [dy, dz] : offsets) {
                const std::int64_t y2 = y + dy;
                const std::int64_t z2 = z + dz;
                if (y2 < 0 || y2 >= vol.ny || z2 >= vol.nz) {
                    continue;
                }
                const std::int64_t r2 = z2 * vol.ny + y2;
                std::uint32_t a = row_start[static_cast<std::size_t>(r)];
                const std::uint32_t a_end = row_start[static_cast<std::size_t>(r) + 1];
                std::uint32_t b = row_start[static_cast<std::size_t>(r2)];
                const std::uint32_t b_end = row_start[static_cast<std::size_t>(r2) + 1];
                while (a < a_end && b < b_end) {
                    if (runs[a].x0 < runs[b].x1 + slack && runs[b].x0 < runs[a].x1 + slack) {
                        if (uf.unite(a, b)) {
                            --components;
                        }
                    }
                    if (runs[a].x1 < runs[b].x1) {
                        ++a;
                    } else {
                        ++b;
                    }
                }
            }
        }
    }
    return components;
}

// Euler characteristic of the union of closed foreground cubes: every vertex, edge, face and
// cube is counted once, at its lowest corner.
std::int64_t euler_characteristic(const Volume& vol) {
    static const std::array<std::int8_t, 256> kLut = [] {
        std::array<std::int8_t, 256> lut{};
        for (int c = 0; c < 256; ++c) {
            // bit (dz * 4 + dy * 2 + dx): voxel at vertex - 1 + (dx, dy, dz)
            auto any = [c](int mx, int my, int mz) {
                for (int b = 0; b < 8; ++b) {
                    const int dx = b & 1, dy = (b >> 1) & 1, dz = (b >> 2) & 1;
                    if ((c >> b & 1) && (mx < 0 || dx == mx) && (my < 0 || dy == my) &&
                        (mz < 0 || dz == mz)) {
                        return 1;
                    }
                }
                return 0;
            };
            lut[c] = static_cast<std::int8_t>(any(-1, -1, -1) - any(1, -1, -1) - any(-1, 1, -1) -
                                              any(-1, -1, 1) + any(1, 1, -1) + any(1, -1, 1) +
                                              any(-1, 1, 1) - any(1, 1, 1));
        }
        return lut;
    }();
    // note: vertex rows whose four voxel rows are all background contribute nothing
    std::vector<std::uint8_t> row_any(static_cast<std::size_t>(vol.ny * vol.nz), 0);
    for (std::size_t r = 0; r < row_any.size(); ++r) {
        const std::uint8_t* row = vol.v.data() + r * static_cast<std::size_t>(vol.nx);
        row_any[r] = std::any_of(row, row + vol.nx, [](std::uint8_t v) { return v != 0; });
    }
    std::int64_t chi = 0;
    for (std::int64_t z = 1; z < vol.nz; ++z) {
        for (std::int64_t y = 1; y < vol.ny; ++y) {
            const auto r = static_cast<std::size_t>((z - 1) * vol.ny + y - 1);
            const auto r_up = r + static_cast<std::size_t>(vol.ny);
            if (!(row_any[r] | row_any[r + 1] | row_any[r_up] | row_any[r_up + 1])) {
                continue;
            }
            const std::uint8_t* r00 =
                vol.v.data() + static_cast<std::size_t>(((z - 1) * vol.ny + y - 1) * vol.nx);
            const std::uint8_t* r01 = r00 + vol.nx;
            const std::uint8_t* r10 = r00 + vol.nx * vol.ny;
            const std::uint8_t* r11 = r10 + vol.nx;
            for (std::int64_t x = 1; x < vol.nx; ++x) {
                const int c = r00[x - 1] | r00[x] << 1 | r01[x - 1] << 2 | r01[x] << 3 |
                              r10[x - 1] << 4 | r10[x] << 5 | r11[x - 1] << 6 | r11[x] << 7;
                chi += kLut[static_cast<std::size_t>(c)];
            }
        }
    }
    return chi;
}

RTopology analyse_reference_volume(const std::vector<std::uint8_t>& slices,
                                   std::uint32_t width,
                                   std::uint32_t height,
                                   std::uint32_t depth) {
    const Volume r = reference_volume(slices, width, height, depth);
    RTopology t;
    t.foreground_components = count_components(r, 1, true);
    t.background_components = count_components(r, 0, false);
    t.euler = euler_characteristic(r);
    return t;
}

// One closed surface of genus 0: one foreground component, no cavity, chi = 1 - genus = 1.
bool is_single_sphere(const RTopology& t) {
    return t.foreground_components == 1 && t.background_components == 1 && t.euler == 1;
}

// 8-connected regions of a width x height mask.
std::uint32_t count_regions_8(const std::uint8_t* mask, std::uint32_t width, std::uint32_t height) {
    std::vector<std::uint8_t> seen(std::size_t(width) * height, 0);
    std::vector<std::uint32_t> stack;
    std::uint32_t regions = 0;
    for (std::uint32_t start = 0; start < width * height; ++start) {
        if (!mask[start] || seen[start]) {
            continue;
        }
        ++regions;
        seen[start] = 1;
        stack.push_back(start);
        while (!stack.empty()) {
            const std::uint32_t p = stack.back();
            stack.pop_back();
            const std::int64_t x = p % width;
            const std::int64_t y = p / width;
            for (std::int64_t dy = -1; dy <= 1; ++dy) {
                for (std::int64_t dx = -1; dx <= 1; ++dx) {
                    const std::int64_t nx = x + dx;
                    const std::int64_t ny = y + dy;
                    if (nx < 0 || ny < 0 || nx >= width || ny >= height) {
                        continue;
                    }
                    const auto q = static_cast<std::uint32_t>(ny * width + nx);
                    if (mask[q] && !seen[q]) {
                        seen[q] = 1;
                        stack.push_back(q);
                    }
                }
            }
        }
    }
    return regions;
}

// ---------------------------------------------------------------------------------------------
// T33, T35, T36 draws

Spec make_t01_sphere_spec();

Spec many_components(std::uint64_t seed) {
    constexpr std::uint32_t kW = 512, kH = 512, kK = 40;
    constexpr double kD = 2.0;
    NumpyRandom rng(seed);
    std::vector<Ball> balls;
    std::uint64_t drawn = 0;
    while (balls.size() < 300) {
        Ball b;
        b.centre.x = rng.uniform(0.0, 512.0);
        b.centre.y = rng.uniform(0.0, 512.0);
        b.centre.z = rng.uniform(0.0, 78.0);
        b.radius = rng.uniform(3.0, 8.0);
        ++drawn;
        const bool too_close = std::any_of(balls.begin(), balls.end(), [&](const Ball& o) {
            return norm(b.centre - o.centre) < b.radius + o.radius + 3.0;
        });
        if (too_close) {
            continue;
        }
        // Slices with an in-image pixel centre inside: the nearest in-image centre decides.
        const Solid solid = make_solid(b);
        const double px = std::clamp(std::floor(b.centre.x), 0.0, kW - 1.0) + 0.5;
        const double py = std::clamp(std::floor(b.centre.y), 0.0, kH - 1.0) + 0.5;
        std::uint32_t covered = 0;
        for (std::uint32_t k = 0; k < kK; ++k) {
            if (contains(solid, {px, py, k * kD})) {
                ++covered;
            }
        }
        if (covered < 2) {
            continue;
        }
        balls.push_back(b);
    }
    std::vector<Solid> solids;
    solids.reserve(balls.size());
    for (const Ball& b : balls) {
        solids.push_back(make_solid(b));
    }
    Spec s = single("T33", "300 separated balls of radius 3-8 px drawn with numpy default_rng", kW,
                    kH, kK, kD, "balls", unite(std::move(solids)), genus_zero(300));
    s.draws = PhantomDraws{seed, drawn, balls.size()};
    return s;
}

Spec speckle_noise(std::uint64_t seed) {
    Spec s = make_t01_sphere_spec();
    s.id = "T35";
    s.description = "the T01 sphere with pixels flipped independently with p = 0.5 %";
    s.slice_defined = true;
    s.paint = {{1, *s.objects[0].solid}};
    s.objects = {{1, "speckled sphere", std::nullopt, false}};
    s.label_names = {{1, "speckled sphere"}};
    s.expected = topology(
        1609,
        [] {
            std::vector<std::uint32_t> g(1609, 0);
            g[0] = 1;
            return g;
        }(),
        1367);
    s.expected_needs_catalogue_seed = true;
    s.draws = PhantomDraws{seed, 0, 0};
    s.edit = [seed](SliceStack& stack, std::optional<PhantomDraws>& draws) {
        // rng.random((22, 128, 128)) < 0.005 in C order [k, j, i]: the label layout
        NumpyRandom rng(seed);
        for (std::uint16_t& v : stack.labels) {
            if (rng.random() < 0.005) {
                v ^= 1;
                ++draws->accepted;
            }
        }
        draws->drawn = stack.labels.size();
    };
    return s;
}

double gaussian_factor(double delta, double inv_two_sigma2) {
    return std::exp(-(delta * delta) * inv_two_sigma2);
}

// The catalogue's fine check: R of 0.5 px slices over z in [0, 150) and x, y within 12 px of
// the sampled slices' bounding box is one component of genus 0.
bool fine_voxelisation_is_sphere(const GaussianLevelSet& g,
                                 std::int64_t i_min,
                                 std::int64_t i_max,
                                 std::int64_t j_min,
                                 std::int64_t j_max) {
    auto index_range = [](double lo, double hi) {
        // fine centres 0.25 + 0.5 m within [lo, hi]
        const auto m0 = static_cast<std::int64_t>(std::ceil((lo - 0.25) / 0.5));
        const auto m1 = static_cast<std::int64_t>(std::floor((hi - 0.25) / 0.5));
        return std::pair{m0, m1};
    };
    const auto [mx0, mx1] = index_range(double(i_min) - 12.0, double(i_max + 1) + 12.0);
    const auto [my0, my1] = index_range(double(j_min) - 12.0, double(j_max + 1) + 12.0);
    const auto nx = static_cast<std::uint32_t>(mx1 - mx0 + 1);
    const auto ny = static_cast<std::uint32_t>(my1 - my0 + 1);
    constexpr std::uint32_t nz = 300;
    const std::size_t n = g.blobs.size();
    std::vector<double> gx(n * nx), gy(n * ny), wz(n * nz);
    for (std::size_t b = 0; b < n; ++b) {
        const GaussianBlob& blob = g.blobs[b];
        const double inv = 1.0 / (2.0 * blob.sigma * blob.sigma);
        for (std::uint32_t m = 0; m < nx; ++m) {
            gx[b * nx + m] = gaussian_factor(0.25 + 0.5 * double(mx0 + m) - blob.centre.x, inv);
        }
        for (std::uint32_t m = 0; m < ny; ++m) {
            gy[b * ny + m] = gaussian_factor(0.25 + 0.5 * double(my0 + m) - blob.centre.y, inv);
        }
        for (std::uint32_t m = 0; m < nz; ++m) {
            wz[b * nz + m] = blob.weight * gaussian_factor(0.25 + 0.5 * m - blob.centre.z, inv);
        }
    }
    std::vector<std::uint8_t> fine(std::size_t(nx) * ny * nz, 0);
    std::vector<double> row(n);
    std::vector<double> f(nx);
    for (std::uint32_t z = 0; z < nz; ++z) {
        for (std::uint32_t y = 0; y < ny; ++y) {
            double row_max = 0.0;  // note: gx <= 1, so the sum of row[] bounds every f below
            for (std::size_t b = 0; b < n; ++b) {
                row[b] = wz[b * nz + z] * gy[b * ny + y];
                row_max += row[b];
            }
            if (row_max < g.level) {
                continue;
            }
            std::fill(f.begin(), f.end(), 0.0);
            for (std::size_t b = 0; b < n; ++b) {
                const double* gxb = gx.data() + b * nx;
                for (std::uint32_t x = 0; x < nx; ++x) {
                    f[x] += row[b] * gxb[x];
                }
            }
            std::uint8_t* out = fine.data() + (std::size_t(z) * ny + y) * nx;
            for (std::uint32_t x = 0; x < nx; ++x) {
                out[x] = f[x] >= g.level ? 1 : 0;
            }
        }
    }
    return is_single_sphere(analyse_reference_volume(fine, nx, ny, nz));
}

// T36's acceptance test on the 24 sampled slices, then the fine check.
bool accept_organ(const Solid& solid, const GaussianLevelSet& g) {
    constexpr std::uint32_t kW = 256, kH = 256, kK = 24;
    constexpr double kD = 6.25;
    const std::vector<std::uint8_t> slices = binary_slices(solid, kW, kH, kK, kD);
    const std::size_t plane = std::size_t(kW) * kH;
    auto slice_empty = [&](std::uint32_t k) {
        return std::none_of(slices.begin() + std::ptrdiff_t(k * plane),
                            slices.begin() + std::ptrdiff_t((k + 1) * plane),
                            [](std::uint8_t v) { return v != 0; });
    };
    if (!slice_empty(0) || !slice_empty(kK - 1)) {
        return false;
    }
    std::int64_t i_min = kW, i_max = -1, j_min = kH, j_max = -1;
    for (std::uint32_t k = 0; k < kK; ++k) {
        for (std::uint32_t j = 0; j < kH; ++j) {
            for (std::uint32_t i = 0; i < kW; ++i) {
                if (!slices[k * plane + std::size_t(j) * kW + i]) {
                    continue;
                }
                if (i == 0 || j == 0 || i == kW - 1 || j == kH - 1) {
                    return false;
                }
                i_min = std::min<std::int64_t>(i_min, i);
                i_max = std::max<std::int64_t>(i_max, i);
                j_min = std::min<std::int64_t>(j_min, j);
                j_max = std::max<std::int64_t>(j_max, j);
            }
        }
    }
    if (i_max < 0) {
        return false;
    }
    if (!is_single_sphere(analyse_reference_volume(slices, kW, kH, kK))) {
        return false;
    }
    bool branches = false;
    for (std::uint32_t k = 0; k < kK && !branches; ++k) {
        branches = count_regions_8(slices.data() + k * plane, kW, kH) >= 2;
    }
    if (!branches) {
        return false;
    }
    return fine_voxelisation_is_sphere(g, i_min, i_max, j_min, j_max);
}

Spec organ_like(std::uint64_t seed) {
    constexpr int kMaxAttempts = 1000;
    NumpyRandom rng(seed);
    const Vec3 lo{51.2, 51.2, 30.0};
    const Vec3 hi{204.8, 204.8, 120.0};
    auto uniform3 = [&] {
        Vec3 c;
        for (int a = 0; a < 3; ++a) {
            c[a] = rng.uniform(lo[a], hi[a]);
        }
        return c;
    };
    for (int attempt = 1; attempt <= kMaxAttempts; ++attempt) {
        GaussianLevelSet g;
        g.level = 0.5;
        for (int b = 0; b < 5; ++b) {
            GaussianBlob blob;
            blob.centre = uniform3();
            blob.sigma = rng.uniform(15.0, 35.0);
            blob.weight = rng.uniform(0.6, 1.2);
            g.blobs.push_back(blob);
        }
        Vec3 top = g.blobs[0].centre;
        for (const GaussianBlob& b : g.blobs) {
            if (b.centre.z > top.z) {
                top = b.centre;
            }
        }
        const double phi = rng.uniform(0.0, 2.0 * kPi);
        const double a = rng.uniform(25.0, 40.0);
        const double h = rng.uniform(20.0, 35.0);
        for (double s : {1.0, -1.0}) {
            GaussianBlob blob;
            blob.centre = top + Vec3{s * a * std::cos(phi), s * a * std::sin(phi), h};
            for (int ax = 0; ax < 3; ++ax) {
                blob.centre[ax] = std::clamp(blob.centre[ax], lo[ax], hi[ax]);
            }
            blob.sigma = rng.uniform(15.0, 22.0);
            blob.weight = rng.uniform(0.8, 1.2);
            g.blobs.push_back(blob);
        }
        Solid solid = make_solid(g);
        if (!accept_organ(solid, g)) {
            continue;
        }
        Spec s = single("T36",
                        "organ-like blob: level set 0.5 of 7 Gaussians (5 body, 2 lobes "
                        "branching 1->2), drawn with numpy default_rng until accepted",
                        256, 256, 24, 6.25, "organ", std::move(solid), genus_zero(1));
        s.pixel_mm = 0.8;
        s.draws = PhantomDraws{seed, static_cast<std::uint64_t>(attempt), 1};
        return s;
    }
    throw Error(ErrorCode::InvalidInput, "phantom t36_organ_like: seed " + std::to_string(seed) +
                                             ": no attempt accepted within " +
                                             std::to_string(kMaxAttempts) + " attempts");
}

// ---------------------------------------------------------------------------------------------
// The cases

Spec make_t01_sphere_spec() {
    return single("T01", "ball centre (64, 64, 42) radius 40", 128, 128, 22, 4.0, "sphere",
                  ball({64, 64, 42}, 40), genus_zero(1));
}

Spec ellipsoid_tilted() {
    const double cx = std::cos(30 * kDeg), sx = std::sin(30 * kDeg);
    const double cy = std::cos(20 * kDeg), sy = std::sin(20 * kDeg);
    // R_y(20) * R_x(30)
    const std::array<std::array<double, 3>, 3> rx{{{1, 0, 0}, {0, cx, -sx}, {0, sx, cx}}};
    const std::array<std::array<double, 3>, 3> ry{{{cy, 0, sy}, {0, 1, 0}, {-sy, 0, cy}}};
    std::array<std::array<double, 3>, 3> r{};
    for (int i = 0; i < 3; ++i) {
        for (int j = 0; j < 3; ++j) {
            for (int k = 0; k < 3; ++k) {
                r[i][j] += ry[i][k] * rx[k][j];
            }
        }
    }
    return single("T02",
                  "ellipsoid semi-axes (60, 35, 25) rotated R_y(20 deg) R_x(30 deg), centre "
                  "(80, 80, 45)",
                  160, 160, 31, 3.0, "ellipsoid",
                  make_solid(Ellipsoid{{80, 80, 45}, {60, 35, 25}, r}), genus_zero(1));
}

Solid y_branch(bool mirrored) {
    auto z = [mirrored](double v) { return mirrored ? 60.0 - v : v; };
    return unite({capsule({64, 64, z(-20)}, {64, 64, z(30)}, 12),
                  capsule({64, 64, z(30)}, {34, 64, z(60)}, 12),
                  capsule({64, 64, z(30)}, {94, 64, z(60)}, 12)});
}

Spec y_branch_case() {
    return single("T13", "union of three capsules radius 12: a trunk and two 45 deg arms", 128, 128,
                  31, 2.0, "y_branch", y_branch(false), genus_zero(1));
}

Solid trident() {
    std::vector<Solid> parts;
    parts.push_back(capsule({80, 80, -20}, {80, 80, 28}, 12));
    for (double azimuth : {0.0, 120.0, 240.0}) {
        const double t = 40 * kDeg;
        const Vec3 dir{std::sin(t) * std::cos(azimuth * kDeg),
                       std::sin(t) * std::sin(azimuth * kDeg), std::cos(t)};
        parts.push_back(capsule({80, 80, 28}, Vec3{80, 80, 28} + 45.0 * dir, 10));
    }
    return unite(std::move(parts));
}

Spec torus_case() {
    return single("T18", "torus R 30 r 10 with its centre-line circle in the x-z plane", 128, 128,
                  51, 2.0, "torus", make_solid(Torus{{64, 64, 50}, {0, 1, 0}, 30, 10}),
                  topology(1, {1}, 1));
}

Solid comb() {
    std::vector<Solid> parts;
    parts.push_back(half_open_box({24, 80, 0}, {168, 100, 33}));
    // tooth i: x in [x_i, x_i + 4), y in [80 - L(z), 80), L(z) = 48 (1 - z / 24), i.e.
    // y >= 32 + 2 z: the half-space -y + 2 z <= -32
    for (int i = 0; i < 6; ++i) {
        const double x = 30.0 + 20.0 * i;
        parts.push_back(
            intersect({half_open_box({x, 32, 0}, {x + 4, 80, 33}), half_space({0, -1, 2}, -32.0)}));
    }
    return unite(std::move(parts));
}

Solid annulus(Vec2 c, double inner, double outer, double z_min, double z_max) {
    return subtract(cylinder(c, outer, z_min, z_max), cylinder(c, inner, z_min, z_max));
}

Spec touching_discs(double gap) {
    std::ostringstream desc;
    desc << "two discs radius 20 at (34, 32) and (" << 74 + gap << ", 32), gap " << gap << " px";
    Spec s = base("T25", desc.str(), 128, 64, 6, 4.0);
    s.label_names = {{1, "discs"}};
    s.objects.push_back({1, "left disc", cylinder({34, 32}, 20, 0, 20), true});
    s.objects.push_back({1, "right disc", cylinder({74 + gap, 32}, 20, 0, 20), true});
    s.expected = gap <= 0 ? genus_zero(1) : genus_zero(2);
    return s;
}

Spec shifted(double step, bool gt) {
    Spec s =
        base("T29", "disc radius 15 at (20 + " + std::to_string(int(step)) + " k, 32) on slice k",
             256, 64, 5, 4.0);
    s.label_names = {{1, "disc"}};
    s.objects.push_back({1, "shifted disc", cylinder({20, 32}, 15, 0, 16, {step / 4.0, 0}), gt});
    s.expected = gt ? genus_zero(1) : genus_zero(5);
    return s;
}

Spec empty_slices(bool variant_b) {
    Spec s = base("T22",
                  variant_b ? "disc radius 30 on slices 0-7 and 9-16 (slice 8 empty)"
                            : "disc radius 30 on slices 0-6 and 10-16 (slices 7-9 empty)",
                  128, 128, 17, 4.0);
    s.label_names = {{1, "disc"}};
    s.objects.push_back({1, "lower", cylinder({64, 64}, 30, 0, variant_b ? 28 : 24), true});
    s.objects.push_back({1, "upper", cylinder({64, 64}, 30, variant_b ? 36 : 40, 64), true});
    s.expected = genus_zero(2);
    return s;
}

Spec border_touch(bool variant_b) {
    if (!variant_b) {
        return single("T34", "ball centre (10, 64, 64) radius 60, clipped by the image edge", 128,
                      128, 33, 4.0, "ball", ball({10, 64, 64}, 60), genus_zero(1));
    }
    return single("T34", "ball centre (64, 64, 64) radius 50 with slices 10-12 fully foreground",
                  128, 128, 33, 4.0, "ball",
                  unite({ball({64, 64, 64}, 50), half_open_box({0, 0, 40}, {128, 128, 48})}),
                  genus_zero(1));
}

Spec n_to_m_tree() {
    Spec s = base("T16", "discs A, B on slices 0-5, discs 1, 2, 3 on slices 6-11 (tree overlap)",
                  128, 128, 12, 4.0);
    s.slice_defined = true;
    s.label_names = {{1, "discs"}};
    s.objects.push_back({1, "discs", std::nullopt, false});
    s.paint.push_back({1, unite({cylinder({40, 64}, 14, 0, 20), cylinder({88, 64}, 14, 0, 20),
                                 cylinder({28, 64}, 10, 24, 44), cylinder({64, 64}, 16, 24, 44),
                                 cylinder({100, 64}, 10, 24, 44)})});
    s.expected = genus_zero(1);
    return s;
}

Spec tiny_objects() {
    Spec s =
        base("T24", "1-9 px objects on slice 6 and a 1 px needle on slices 2-9", 64, 64, 12, 3.0);
    s.slice_defined = true;
    s.label_names = {{1, "tiny objects"}};
    s.objects.push_back({1, "tiny objects", std::nullopt, false});
    s.edit = [](SliceStack& stack, std::optional<PhantomDraws>&) {
        auto set = [&](std::uint32_t i, std::uint32_t j, std::uint32_t k) {
            stack.labels[(std::size_t(k) * stack.height + j) * stack.width + i] = 1;
        };
        const std::pair<int, int> on_slice_6[] = {
            {8, 8},  {20, 8},  {21, 8},  {32, 8},  {33, 8},  {32, 9},  {33, 9},
            {8, 24}, {9, 24},  {10, 24}, {8, 25},  {9, 25},  {10, 25}, {8, 26},
            {9, 26}, {10, 26}, {20, 24}, {21, 24}, {20, 25}, {32, 24}, {33, 25}};
        for (auto [i, j] : on_slice_6) {
            set(std::uint32_t(i), std::uint32_t(j), 6);
        }
        for (std::uint32_t k = 2; k <= 9; ++k) {
            set(50, 50, k);
        }
    };
    s.expected = genus_zero(7);
    return s;
}

Spec thin_features() {
    Spec s = base("T27", "1 px L-shape, 2 px ring 39 < r <= 41, 1 px line moving 1 px per slice",
                  128, 128, 6, 3.0);
    s.label_names = {{1, "thin features"}};
    s.objects.push_back({1, "l_shape",
                         unite({half_open_box({10, 20, 0}, {70, 21, 15}),
                                half_open_box({10, 20, 0}, {11, 80, 15})}),
                         true});
    s.objects.push_back({1, "ring", annulus({84, 84}, 39, 41, 0, 15), true});
    // column i = 10 + k on slice k: 10 <= x - z / 3 <= 11 (pixel centres never on a bound)
    s.objects.push_back(
        {1, "moving_line",
         intersect({half_open_box({0, 96, 0}, {128, 124, 15}),
                    half_space({-1, 0, 1.0 / 3.0}, -10.0), half_space({1, 0, -1.0 / 3.0}, 11.0)}),
         false});
    s.expected = topology(8, {0, 1, 0, 0, 0, 0, 0, 0}, 8);
    return s;
}

Spec huge_contour() {
    RadialWave w;
    w.centre = {2048, 2048};
    w.base_radius = 1500;
    // note: 15 sin(173 theta + 0.3 k) with k = z / d, d = 4
    w.terms = {{40, 60, 0, 0}, {15, 173, 0, 0.3 / 4.0}};
    w.z_min = 0;
    w.z_max = 36;
    return single("T32", "radial wave r = 1500 + 40 sin(60 t) + 15 sin(173 t + 0.3 k) px", 4096,
                  4096, 10, 4.0, "huge contour", make_solid(w), genus_zero(1));
}

Spec hollow_sphere() {
    Spec s = single("", "ball radius 40 minus ball radius 20, centre (64, 64, 42)", 128, 128, 22,
                    4.0, "hollow sphere", subtract(ball({64, 64, 42}, 40), ball({64, 64, 42}, 20)),
                    topology(2, {0, 0}, 1));
    return s;
}

Spec scene() {
    Spec s = base("", "demo scene: a sphere, a tilted torus, a branching vessel, an ellipsoid", 128,
                  128, 40, 2.0);
    s.label_names = {{1, "sphere"}, {2, "torus"}, {3, "vessel"}, {4, "ellipsoid"}};
    s.objects.push_back({1, "sphere", ball({36, 36, 40}, 20), true});
    s.objects.push_back({2, "torus", make_solid(Torus{{92, 36, 40}, {0, 0.6, 0.8}, 18, 6}), true});
    s.objects.push_back(
        {3, "vessel",
         unite({capsule({64, 96, 2}, {64, 96, 36}, 7), capsule({64, 96, 36}, {44, 96, 74}, 6),
                capsule({64, 96, 36}, {84, 96, 74}, 6)}),
         true});
    const double c = std::cos(25 * kDeg), sn = std::sin(25 * kDeg);
    s.objects.push_back({4, "ellipsoid",
                         make_solid(Ellipsoid{
                             {104, 100, 24}, {14, 10, 12}, {{{c, -sn, 0}, {sn, c, 0}, {0, 0, 1}}}}),
                         true});
    s.expected = topology(4, {1, 0, 0, 0}, 4);
    return s;
}

Spec whole_body() {
    Spec s = base("",
                  "whole-body-like map: the 117 TotalSegmentator classes as organ-like solids, "
                  "1 mm pixels, 1.5 mm slices",
                  kWholeBodyWidth, kWholeBodyHeight, kWholeBodyDepth, kWholeBodySliceSpacingPx);
    for (LabelledSolid& c : whole_body_solids()) {
        s.label_names.push_back({c.label, c.name});
        s.objects.push_back({c.label, c.name, c.solid, false});
        s.paint.push_back({c.label, std::move(c.solid)});
    }
    std::sort(s.label_names.begin(), s.label_names.end());
    return s;
}

struct CaseEntry {
    std::string name;
    std::function<Spec(std::optional<std::uint64_t> seed)> build;
};

/// Phantoms for the benchmarks only: too large for the catalogue's tests, which build every
/// phantom_names() case.
const std::vector<CaseEntry>& benchmark_cases() {
    static const std::vector<CaseEntry> kCases = {
        {"whole_body", [](std::optional<std::uint64_t>) { return whole_body(); }}};
    return kCases;
}

/// Adds a case built without a seed.
void add_case(std::vector<CaseEntry>& c, std::string name, std::function<Spec()> f) {
    c.push_back({std::move(name), [f](std::optional<std::uint64_t>) { return f(); }});
}

/// T01-T19: one shape each, its topology changing along the stack or not.
void add_shape_cases(std::vector<CaseEntry>& c) {
    add_case(c, "t01_sphere", make_t01_sphere_spec);
    add_case(c, "t02_ellipsoid_tilted", ellipsoid_tilted);
    add_case(c, "t03_box_sharp", [] {
        return single("T03", "box x in [34, 94), y in [44, 84), z in [0, 40]", 128, 128, 11, 4.0,
                      "box", half_open_box({34, 44, 0}, {94, 84, 40}), genus_zero(1));
    });
    add_case(c, "t04_cylinder_aniso10", [] {
        return single("T04", "cylinder centre (64, 64) radius 30 along z", 128, 128, 8, 10.0,
                      "cylinder", cylinder({64, 64}, 30, 0, 70), genus_zero(1));
    });
    add_case(c, "t05_c_shape_twist", [] {
        return single(
            "T05", "annulus 30 < r <= 50 minus the wedge |theta - 6 deg k| < 35 deg", 160, 160, 20,
            3.0, "c_shape",
            make_solid(TwistedSector{{80, 80}, 30, 50, 35 * kDeg, 0.0, 6 * kDeg / 3.0, 0, 57}),
            genus_zero(1));
    });
    add_case(c, "t06_spiral", [] {
        return single("T06",
                      "6 px band along r = 8 + 12 t / (2 pi), t in [0, 6 pi], rotated 2 deg "
                      "per slice",
                      256, 256, 10, 3.0, "spiral",
                      make_solid(SpiralBand{
                          {128, 128}, 8, 12 / (2 * kPi), 6 * kPi, 3, 0.0, 2 * kDeg / 3.0, 0, 27}),
                      genus_zero(1));
    });
    add_case(c, "t07_star_to_circle", [] {
        return single("T07", "5-point star (55 / 22) morphing linearly into a circle of 35", 160,
                      160, 13, 3.0, "star", make_solid(StarMorph{{80, 80}, 5, 55, 22, 35, 0, 36}),
                      genus_zero(1));
    });
    add_case(c, "t08_comb_retracting", [] {
        return single("T08", "bar with six 4 px teeth shrinking by 6 px per slice", 192, 128, 12,
                      3.0, "comb", comb(), genus_zero(1));
    });
    add_case(c, "t09_annulus_tube", [] {
        return single("T09", "annulus 25 < r <= 50 on all slices", 128, 128, 16, 4.0, "tube",
                      annulus({64, 64}, 25, 50, 0, 60), topology(1, {1}, 1));
    });
    add_case(c, "t10_internal_cavity", [] {
        return single("T10", "disc radius 50 with a hole of radius 15 on slices 7-12", 128, 128, 20,
                      4.0, "disc with cavity",
                      subtract(cylinder({64, 64}, 50, 0, 76), cylinder({64, 64}, 15, 28, 48)),
                      topology(2, {0, 0}, 1));
    });
    add_case(c, "t11_island_in_hole", [] {
        Spec s = base("T11", "ring 40 < r <= 60 on all slices, island disc 20 on slices 3-8", 128,
                      128, 12, 4.0);
        s.label_names = {{1, "ring and island"}};
        s.objects.push_back({1, "ring", annulus({64, 64}, 40, 60, 0, 44), true});
        s.objects.push_back({1, "island", cylinder({64, 64}, 20, 12, 32), true});
        s.expected = topology(2, {1, 0}, 2);
        return s;
    });
    add_case(c, "t13_y_branch_1to2", y_branch_case);
    add_case(c, "t14_merge_2to1", [] {
        return single("T14", "T13 mirrored in z (z -> 60 - z)", 128, 128, 31, 2.0, "merge",
                      y_branch(true), genus_zero(1));
    });
    add_case(c, "t15_trident_1to3", [] {
        return single("T15", "trunk capsule radius 12 and three arms radius 10 tilted 40 deg", 160,
                      160, 31, 2.0, "trident", trident(), genus_zero(1));
    });
    add_case(c, "t16_n_to_m_tree", n_to_m_tree);
    add_case(c, "t18_torus_on_side", torus_case);
    add_case(c, "t19_plate_two_holes", [] {
        return single(
            "T19", "plate x in [20, 236), y in [40, 88) minus two discs radius 14", 256, 128, 8,
            4.0, "plate",
            subtract(half_open_box({20, 40, 0}, {236, 88, 28}),
                     unite({cylinder({88, 64}, 14, 0, 28), cylinder({168, 64}, 14, 0, 28)})),
            topology(1, {2}, 1));
    });
}

/// T21-T36: objects appearing and vanishing, degenerate slices, scale, noise; then the demos.
void add_stack_cases(std::vector<CaseEntry>& c) {
    add_case(c, "t21_appear_midstack", [] {
        Spec s = base("T21", "cylinder radius 30 on all slices and a ball radius 8 on 8-11", 128,
                      128, 20, 4.0);
        s.label_names = {{1, "cylinder and ball"}};
        s.objects.push_back({1, "cylinder", cylinder({40, 64}, 30, 0, 76), true});
        s.objects.push_back({1, "ball", ball({100, 64, 38}, 8), true});
        s.expected = genus_zero(2);
        return s;
    });
    add_case(c, "t22_empty_slices_inside", [] { return empty_slices(false); });
    add_case(c, "t22_empty_slices_inside_b", [] { return empty_slices(true); });
    add_case(c, "t23_single_slice_object", [] {
        Spec s = single("T23", "disc centre (32, 32) radius 20 on slice 5 only", 64, 64, 11, 4.0,
                        "disc", cylinder({32, 32}, 20, 20, 20), genus_zero(1));
        s.objects[0].gt_applies = false;
        return s;
    });
    add_case(c, "t24_tiny_objects_and_needle", tiny_objects);
    add_case(c, "t25_touching_discs_gm2", [] { return touching_discs(-2); });
    add_case(c, "t25_touching_discs_g0", [] { return touching_discs(0); });
    add_case(c, "t25_touching_discs_g1", [] { return touching_discs(1); });
    add_case(c, "t25_touching_discs_g2", [] { return touching_discs(2); });
    add_case(c, "t27_thin_features", thin_features);
    add_case(c, "t29_shifted_nonoverlap_a", [] { return shifted(40, false); });
    add_case(c, "t29_shifted_nonoverlap_b", [] { return shifted(20, true); });
    add_case(c, "t31_aniso_branch_d10", [] {
        return single("T31", "the T13 solid sampled with d = 10", 128, 128, 7, 10.0, "y_branch",
                      y_branch(false), genus_zero(1));
    });
    add_case(c, "t32_huge_contour", huge_contour);
    c.push_back({"t33_many_components", [](std::optional<std::uint64_t> seed) {
                     return many_components(seed.value_or(1234));
                 }});
    add_case(c, "t34_border_touch", [] { return border_touch(false); });
    add_case(c, "t34_border_touch_b", [] { return border_touch(true); });
    c.push_back({"t35_speckle_noise", [](std::optional<std::uint64_t> seed) {
                     return speckle_noise(seed.value_or(7));
                 }});
    c.push_back({"t36_organ_like",
                 [](std::optional<std::uint64_t> seed) { return organ_like(seed.value_or(36)); }});
    // Demos (CLI names).
    add_case(c, "sphere", make_t01_sphere_spec);
    add_case(c, "ellipsoid", ellipsoid_tilted);
    add_case(c, "torus", torus_case);
    add_case(c, "branching", y_branch_case);
    add_case(c, "hollow_sphere", hollow_sphere);
    add_case(c, "scene", scene);
}

const std::vector<CaseEntry>& cases() {
    static const std::vector<CaseEntry> kCases = [] {
        std::vector<CaseEntry> c;
        add_shape_cases(c);
        add_stack_cases(c);
        return c;
    }();
    return kCases;
}

std::string joined_names() {
    std::string s;
    for (const auto* list : {&cases(), &benchmark_cases()}) {
        for (const CaseEntry& c : *list) {
            if (!s.empty()) {
                s += ", ";
            }
            s += c.name;
        }
    }
    return s;
}

std::uint64_t default_seed(std::string_view name) {
    if (name == "t33_many_components") {
        return 1234;
    }
    if (name == "t35_speckle_noise") {
        return 7;
    }
    if (name == "t36_organ_like") {
        return 36;
    }
    return 0;
}

}  // namespace

std::vector<std::string> phantom_names() {
    std::vector<std::string> names;
    for (const CaseEntry& c : cases()) {
        names.push_back(c.name);
    }
    return names;
}

std::vector<std::string> benchmark_phantom_names() {
    std::vector<std::string> names;
    for (const CaseEntry& c : benchmark_cases()) {
        names.push_back(c.name);
    }
    return names;
}

Phantom make_phantom(std::string_view name, const PhantomOptions& options) {
    const CaseEntry* entry = nullptr;
    for (const auto* list : {&cases(), &benchmark_cases()}) {
        for (const CaseEntry& c : *list) {
            if (c.name == name && entry == nullptr) {
                entry = &c;
            }
        }
    }
    if (entry == nullptr) {
        throw Error(ErrorCode::InvalidInput, "unknown phantom '" + std::string(name) +
                                                 "', expected one of: " + joined_names());
    }
    const std::string where = "phantom " + std::string(name);
    if (options.pixel_mm && !(std::isfinite(*options.pixel_mm) && *options.pixel_mm > 0.0)) {
        std::ostringstream s;
        s << where << ": pixel size " << *options.pixel_mm << " mm, expected finite and > 0";
        throw Error(ErrorCode::InvalidInput, s.str());
    }
    if (options.slice_spacing_px &&
        !(std::isfinite(*options.slice_spacing_px) && *options.slice_spacing_px > 0.0)) {
        std::ostringstream s;
        s << where << ": slice spacing " << *options.slice_spacing_px
          << " px, expected finite and > 0";
        throw Error(ErrorCode::InvalidInput, s.str());
    }
    Spec spec = entry->build(options.seed);

    double d = spec.d;
    std::uint32_t depth = spec.depth;
    bool resampled = false;
    if (options.slice_spacing_px && *options.slice_spacing_px != spec.d) {
        if (spec.slice_defined) {
            throw Error(ErrorCode::InvalidInput,
                        where +
                            " is slice-defined (its masks are given per slice): it cannot "
                            "be resampled at another slice spacing");
        }
        d = *options.slice_spacing_px;
        const double extent = (spec.depth - 1) * spec.d;
        const double count = std::floor(extent / d + 1e-9) + 1.0;
        if (count > 1e6) {
            std::ostringstream s;
            s << where << ": slice spacing " << d << " px gives " << count << " slices over "
              << extent << " px, more than 1000000";
            throw Error(ErrorCode::InvalidInput, s.str());
        }
        depth = static_cast<std::uint32_t>(count);
        resampled = true;
    }
    check_stack_dimensions(spec.width, spec.height, depth, where);

    Phantom p;
    p.name = std::string(name);
    p.catalogue_id = spec.id;
    p.description = spec.description;
    p.slice_spacing_px = d;
    p.pixel_mm = options.pixel_mm.value_or(spec.pixel_mm);
    p.slice_defined = spec.slice_defined;
    p.draws = spec.draws;
    const bool other_seed = options.seed && *options.seed != default_seed(name);
    if (!resampled && !(spec.expected_needs_catalogue_seed && other_seed)) {
        p.expected = spec.expected;
    }

    SliceStack& stack = p.stack;
    stack.width = spec.width;
    stack.height = spec.height;
    stack.depth = depth;
    stack.labels.assign(std::size_t(spec.width) * spec.height * depth, 0);
    stack.index_to_world = Affine3{};
    stack.index_to_world.linear = {
        {{p.pixel_mm, 0, 0}, {0, p.pixel_mm, 0}, {0, 0, d * p.pixel_mm}}};
    stack.source = "phantom " + std::string(name);
    stack.source_frame = "none";
    for (const auto& [value, label_name] : spec.label_names) {
        stack.label_table.push_back({value, label_name, palette_color(value)});
    }

    if (spec.paint.empty()) {
        for (const PhantomObject& o : spec.objects) {
            if (o.solid) {
                spec.paint.push_back({o.label, *o.solid});
            }
        }
    }
    paint(stack, spec.paint, d);
    if (spec.edit) {
        spec.edit(stack, p.draws);
    }
    p.objects = std::move(spec.objects);
    return p;
}

// ---------------------------------------------------------------------------------------------
// numpy default_rng

namespace {

__extension__ using U128 = unsigned __int128;

U128 make_u128(std::uint64_t high, std::uint64_t low) {
    return (U128(high) << 64) | low;
}

constexpr std::uint64_t kPcgMultHigh = 2549297995355413924ULL;
constexpr std::uint64_t kPcgMultLow = 4865540595714422341ULL;

// numpy/random/bit_generator.pyx: SeedSequence constants.
constexpr std::uint32_t kInitA = 0x43b0d7e5;
constexpr std::uint32_t kMultA = 0x931e8875;
constexpr std::uint32_t kInitB = 0x8b51f9dd;
constexpr std::uint32_t kMultB = 0x58f38ded;
constexpr std::uint32_t kMixMultL = 0xca01f9dd;
constexpr std::uint32_t kMixMultR = 0x4973f715;
constexpr int kXShift = 16;
constexpr std::size_t kPoolSize = 4;

std::uint32_t hashmix(std::uint32_t value, std::uint32_t& hash_const) {
    value ^= hash_const;
    hash_const *= kMultA;
    value *= hash_const;
    value ^= value >> kXShift;
    return value;
}

std::uint32_t mix(std::uint32_t x, std::uint32_t y) {
    std::uint32_t result = kMixMultL * x - kMixMultR * y;
    result ^= result >> kXShift;
    return result;
}

// SeedSequence(seed).generate_state(4, uint64).
std::array<std::uint64_t, 4> seed_sequence_state(std::uint64_t seed) {
    std::vector<std::uint32_t> entropy;
    if (seed == 0) {
        entropy.push_back(0);
    }
    for (std::uint64_t s = seed; s > 0; s >>= 32) {
        entropy.push_back(static_cast<std::uint32_t>(s & 0xFFFFFFFFu));
    }
    std::array<std::uint32_t, kPoolSize> pool{};
    std::uint32_t hash_const = kInitA;
    for (std::size_t i = 0; i < kPoolSize; ++i) {
        pool[i] = hashmix(i < entropy.size() ? entropy[i] : 0u, hash_const);
    }
    for (std::size_t src = 0; src < kPoolSize; ++src) {
        for (std::size_t dst = 0; dst < kPoolSize; ++dst) {
            if (src != dst) {
                pool[dst] = mix(pool[dst], hashmix(pool[src], hash_const));
            }
        }
    }
    for (std::size_t src = kPoolSize; src < entropy.size(); ++src) {
        for (std::size_t dst = 0; dst < kPoolSize; ++dst) {
            pool[dst] = mix(pool[dst], hashmix(entropy[src], hash_const));
        }
    }
    std::array<std::uint32_t, 8> words{};
    std::uint32_t hash_b = kInitB;
    for (std::size_t i = 0; i < words.size(); ++i) {
        std::uint32_t v = pool[i % kPoolSize];
        v ^= hash_b;
        hash_b *= kMultB;
        v *= hash_b;
        v ^= v >> kXShift;
        words[i] = v;
    }
    std::array<std::uint64_t, 4> out{};
    for (std::size_t i = 0; i < 4; ++i) {
        out[i] = std::uint64_t(words[2 * i]) | (std::uint64_t(words[2 * i + 1]) << 32);
    }
    return out;
}

}  // namespace

NumpyRandom::NumpyRandom(std::uint64_t seed) {
    const std::array<std::uint64_t, 4> v = seed_sequence_state(seed);
    const U128 init_state = make_u128(v[0], v[1]);
    const U128 init_seq = make_u128(v[2], v[3]);
    const U128 mult = make_u128(kPcgMultHigh, kPcgMultLow);
    const U128 inc = (init_seq << 1) | 1u;
    U128 state = 0;
    state = state * mult + inc;
    state += init_state;
    state = state * mult + inc;
    state_ = {static_cast<std::uint64_t>(state >> 64), static_cast<std::uint64_t>(state)};
    increment_ = {static_cast<std::uint64_t>(inc >> 64), static_cast<std::uint64_t>(inc)};
}

std::uint64_t NumpyRandom::next_uint64() {
    const U128 mult = make_u128(kPcgMultHigh, kPcgMultLow);
    U128 state = make_u128(state_[0], state_[1]);
    state = state * mult + make_u128(increment_[0], increment_[1]);
    state_ = {static_cast<std::uint64_t>(state >> 64), static_cast<std::uint64_t>(state)};
    // XSL-RR: xor the halves, rotate right by the top 6 bits
    const std::uint64_t x = state_[0] ^ state_[1];
    const unsigned rot = static_cast<unsigned>(state_[0] >> 58);
    return (x >> rot) | (x << ((64u - rot) & 63u));
}

double NumpyRandom::random() {
    return static_cast<double>(next_uint64() >> 11) * (1.0 / 9007199254740992.0);
}

double NumpyRandom::uniform(double low, double high) {
    return low + (high - low) * random();
}

}  // namespace strata
