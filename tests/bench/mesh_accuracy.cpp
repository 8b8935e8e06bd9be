// Surface accuracy of reconstructed meshes against a phantom's analytic solids.
//
//   mesh_accuracy --phantom NAME [--slice-spacing D] [--pixel-mm S] [--label N] [--no-clip]
//                 [--worst N] [--by-level N] [--json] MESH...
//
// Regenerates the phantom with make_phantom(NAME, {pixel_mm = S, slice_spacing_px = D}), reads
// each mesh (PLY, OBJ or STL; vertices in patient LPS mm, as `strata build` and
// scripts/bench_accuracy_peer.py write them), maps its vertices into the phantom's pixel frame and
// measures the distance from the mesh to the true surface (one-sided: mesh -> truth).
//
// Frames: the phantom's stack maps voxel index (i, j, k), pixel centres at integer indices, to LPS
// mm through index_to_world = diag(pixel_mm, pixel_mm, d * pixel_mm); the solids live in slice
// space px, where pixel (i, j) of slice k has its centre at (i + 0.5, j + 0.5, k * d). A world
// point is therefore mapped by (i, j, k) = index_to_world^-1 (p) and then (i + 0.5, j + 0.5, k d).
// Slice-space px are isotropic (1 px = pixel_mm along every axis): |d| mm = |d| px * pixel_mm.
//
// Truth: for each sample the minimum |signed_distance| over the phantom's objects with a solid;
// only over those of one label when that label is known and some object has it: --label N, else
// the triangle's label when the mesh carries per-triangle labels, else the label of the object
// the file is named after (meshes/<object-name>.ply, compared ignoring case and punctuation).
// A solid reaching beyond the stack's voxel extent ([0, W] x [0, H] x [-d/2, (K - 1) d + d/2] px:
// each voxel stands for its cell) is intersected with that extent, since nothing outside it was
// sampled (T13's trunk and arms leave the stack; --no-clip keeps the whole solid).
// signed_distance is exact for single primitives and a bound (|value| <= true distance, so errors
// can only be underestimated) for CSG results and clipped solids; the JSON says which.
//
// Sampling, deterministic: each triangle (in px) is split into n^2 congruent sub-triangles by a
// barycentric grid, n = ceil(2 sqrt(area_px2)) >= 1 (about 4 samples per px^2; n = 1: the
// centroid), and |d| is taken at the sub-triangle centroids with weight area / n^2 (mean, RMS,
// signed bias) and at those centroids plus the grid's lattice points, corners included (max).
// Where the max sits: its sample's position (px) and signed distance; --worst N also lists the N
// mesh vertices farthest from the truth (position px, slice index z / d, signed distance), to
// find what part of a surface makes the max.
// By level (--by-level N): the same statistics over the samples in N bins of their distance from
// the nearest slice plane, |z / d - round(z / d)| in [0, 1/2] (bin 0 holds the slice planes: the
// surface through the simplified contours), and over the samples beyond the first or last slice
// plane (the ends): where between the slices the error sits.
//
// Volume: the volume the mesh encloses (|signed volume| by the divergence theorem, px^3: closed
// meshes oriented either way, as marching cubes' inward winding) against the volume of the union
// of the solids it is compared with (all of them for a mesh of several labels), integrated over
// cubes of 1 px in the union's bounding box: a cube whose centre's |signed distance| exceeds its
// half-diagonal lies wholly inside or outside (the distance is a lower bound of the true one),
// others are split in 8, three times; the last cubes (1/8 px) count the fraction
// clamp(1/2 - d / side, 0, 1).

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <exception>
#include <filesystem>
#include <iomanip>
#include <iostream>
#include <limits>
#include <optional>
#include <sstream>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "core/error.h"
#include "mesh/mesh_io.h"
#include "phantom/catalogue.h"
#include "phantom/solids.h"

namespace strata {
namespace {

constexpr int kExitOk = 0;
constexpr int kExitFailure = 1;
constexpr int kExitBadInput = 2;

/// Finer grids than this per triangle edge are not needed: 1024^2 samples for one triangle.
constexpr int kMaxGridLevel = 1024;

struct Arguments {
    std::string phantom;
    std::optional<double> slice_spacing_px;
    std::optional<double> pixel_mm;
    std::optional<std::uint16_t> label;  ///< compare with this label's objects only
    bool clip = true;                    ///< intersect solids with the stack's voxel extent
    bool json = false;
    std::size_t worst = 0;   ///< list this many vertices farthest from the truth
    std::size_t levels = 0;  ///< --by-level: bins of the distance from the nearest slice plane
    std::vector<std::filesystem::path> meshes;
};

/// One object's truth: its (possibly clipped) solid.
struct TruthSolid {
    std::uint16_t label = 0;
    std::string name;
    Solid solid;
    bool clipped = false;
    bool exact = true;  ///< signed_distance is the exact Euclidean distance
};

/// Accuracy of one mesh, distances in px.
struct MeshAccuracy {
    std::string mesh;
    std::size_t vertices = 0;
    std::size_t triangles = 0;
    std::size_t samples = 0;
    double area_px2 = 0.0;
    double mean_px = 0.0;        ///< area-weighted mean of |d|
    double rms_px = 0.0;         ///< area-weighted root mean square of d
    double max_px = 0.0;         ///< largest sampled |d|
    Vec3 max_at_px;              ///< where: the sample of largest |d|
    double max_signed_px = 0.0;  ///< its signed d
    /// The vertices farthest from the truth (--worst): position px and signed d, worst first.
    std::vector<std::pair<Vec3, double>> worst;
    double bias_px = 0.0;     ///< area-weighted mean of signed d (> 0: mesh lies outside the truth)
    Vec3 centroid_px;         ///< area-weighted centroid of the surface
    double volume_px3 = 0.0;  ///< volume enclosed by the mesh
    double truth_volume_px3 = 0.0;  ///< volume of the union of the solids compared with
    bool clipped = false;           ///< some solid compared with was clipped to the stack's extent
    bool exact = true;              ///< every solid compared with has an exact distance
    /// --by-level: per bin (the last: beyond the end planes) area px^2, sum of |d| and of d
    /// times area.
    struct Level {
        double area_px2 = 0.0, sum_abs = 0.0, sum_signed = 0.0;
    };
    std::vector<Level> levels;
};

const char* usage() {
    return "usage: mesh_accuracy --phantom NAME [--slice-spacing D] [--pixel-mm S] [--label N]\n"
           "                     [--no-clip] [--worst N] [--by-level N] [--json] MESH...\n"
           "Distance from each mesh (PLY/OBJ/STL, LPS mm) to the phantom's true surface:\n"
           "triangles, area-weighted mean and RMS and the max of |d|, in px and mm.\n";
}

double parse_number(const std::string& flag, const std::string& text) {
    std::size_t used = 0;
    double value = 0.0;
    try {
        value = std::stod(text, &used);
    } catch (const std::exception&) {
        used = 0;
    }
    if (used != text.size() || text.empty() || !std::isfinite(value)) {
        throw Error(ErrorCode::InvalidInput, flag + ": '" + text + "' is not a finite number");
    }
    return value;
}

Arguments parse_arguments(int argc, char** argv) {
    Arguments a;
    for (int i = 1; i < argc; ++i) {
        const std::string arg = argv[i];
        auto value = [&]() -> std::string {
            if (i + 1 >= argc) {
                throw Error(ErrorCode::InvalidInput, arg + ": expected a value");
            }
            return argv[++i];
        };
        if (arg == "--phantom") {
            a.phantom = value();
        } else if (arg == "--slice-spacing") {
            a.slice_spacing_px = parse_number(arg, value());
        } else if (arg == "--pixel-mm") {
            a.pixel_mm = parse_number(arg, value());
        } else if (arg == "--label") {
            const double v = parse_number(arg, value());
            if (v < 1 || v > 65535 || v != std::floor(v)) {
                throw Error(
                    ErrorCode::InvalidInput,
                    "--label: expected an integer label in [1, 65535], found " + std::to_string(v));
            }
            a.label = static_cast<std::uint16_t>(v);
        } else if (arg == "--worst") {
            const double v = parse_number(arg, value());
            if (v < 0 || v > 1e6 || v != std::floor(v)) {
                throw Error(
                    ErrorCode::InvalidInput,
                    "--worst: expected a count in [0, 1000000], found " + std::to_string(v));
            }
            a.worst = static_cast<std::size_t>(v);
        } else if (arg == "--by-level") {
            const double v = parse_number(arg, value());
            if (v != std::floor(v) || v < 1 || v > 1000) {
                throw Error(
                    ErrorCode::InvalidInput,
                    "--by-level: expected a bin count in [1, 1000], found " + std::to_string(v));
            }
            a.levels = static_cast<std::size_t>(v);
        } else if (arg == "--no-clip") {
            a.clip = false;
        } else if (arg == "--json") {
            a.json = true;
        } else if (arg == "-h" || arg == "--help") {
            std::cout << usage();
            std::exit(kExitOk);
        } else if (arg.starts_with("-") && arg != "-") {
            throw Error(ErrorCode::InvalidInput, "unknown option " + arg);
        } else {
            a.meshes.emplace_back(arg);
        }
    }
    if (a.phantom.empty()) {
        throw Error(ErrorCode::InvalidInput, "--phantom NAME is required");
    }
    if (a.meshes.empty()) {
        throw Error(ErrorCode::InvalidInput, "expected at least one mesh file");
    }
    return a;
}

/// The inverse of an affine map. \throw Error{InvalidInput} when singular.
Affine3 inverse(const Affine3& a) {
    const auto& m = a.linear;
    const double det = a.determinant();
    if (!(std::abs(det) > 0.0) || !std::isfinite(det)) {
        throw Error(ErrorCode::InvalidInput, "phantom index_to_world is singular");
    }
    Affine3 r;
    for (int i = 0; i < 3; ++i) {
        for (int j = 0; j < 3; ++j) {
            // note: inverse = adjugate / det; adjugate[i][j] = cofactor[j][i]
            const int r0 = (j + 1) % 3, r1 = (j + 2) % 3;
            const int c0 = (i + 1) % 3, c1 = (i + 2) % 3;
            r.linear[i][j] = (m[r0][c0] * m[r1][c1] - m[r0][c1] * m[r1][c0]) / det;
        }
    }
    const Vec3 t = a.translation;
    for (int i = 0; i < 3; ++i) {
        r.translation[i] = -(r.linear[i][0] * t.x + r.linear[i][1] * t.y + r.linear[i][2] * t.z);
    }
    return r;
}

bool box_contains(const Bounds3& outer, const Bounds3& inner) {
    for (int a = 0; a < 3; ++a) {
        if (inner.min[a] < outer.min[a] || inner.max[a] > outer.max[a]) {
            return false;
        }
    }
    return true;
}

std::vector<TruthSolid> truth_solids(const Phantom& phantom, bool clip) {
    const SliceStack& s = phantom.stack;
    const double d = phantom.slice_spacing_px;
    const Bounds3 extent{{0.0, 0.0, -0.5 * d},
                         {double(s.width), double(s.height), (double(s.depth) - 0.5) * d}};
    std::vector<TruthSolid> out;
    for (const PhantomObject& o : phantom.objects) {
        if (!o.solid) {
            continue;
        }
        TruthSolid t{o.label, o.name, *o.solid, false, has_exact_distance(*o.solid)};
        if (clip && !box_contains(extent, bounding_box(*o.solid))) {
            t.solid = intersect({*o.solid, make_solid(Box{extent.min, extent.max})});
            t.clipped = true;
            t.exact = false;
        }
        out.push_back(std::move(t));
    }
    if (out.empty()) {
        throw Error(ErrorCode::InvalidInput, "phantom " + phantom.name +
                                                 ": no analytic solid (slice-defined case), "
                                                 "nothing to measure against");
    }
    return out;
}

/// Lower-case letters and digits, anything else as '_': "Hollow sphere" and "hollow_sphere" match.
std::string normalised_name(const std::string& name) {
    std::string out;
    for (char c : name) {
        const unsigned char u = static_cast<unsigned char>(c);
        out += std::isalnum(u) ? static_cast<char>(std::tolower(u)) : '_';
    }
    return out;
}

/// The label of the object a mesh file is named after (`strata build` writes
/// meshes/<object-name>.ply), or 0 when no object has the file's stem as its name.
std::uint16_t label_from_file_name(const std::vector<TruthSolid>& truth,
                                   const std::filesystem::path& path) {
    const std::string stem = normalised_name(path.stem().string());
    for (const TruthSolid& t : truth) {
        if (normalised_name(t.name) == stem) {
            return t.label;
        }
    }
    return 0;
}

/// Indices into `truth` to compare a triangle of `label` with (0: no label).
std::vector<std::size_t> candidates(const std::vector<TruthSolid>& truth, std::uint16_t label) {
    std::vector<std::size_t> c;
    if (label != 0) {
        for (std::size_t i = 0; i < truth.size(); ++i) {
            if (truth[i].label == label) {
                c.push_back(i);
            }
        }
    }
    if (c.empty()) {
        for (std::size_t i = 0; i < truth.size(); ++i) {
            c.push_back(i);
        }
    }
    return c;
}

/// Volume of the union of the candidate solids, px^3 (see the top comment).
double union_volume_px3(const std::vector<TruthSolid>& truth,
                        const std::vector<std::size_t>& which) {
    constexpr int kSplits = 3;
    Bounds3 box{Vec3{1e300, 1e300, 1e300}, Vec3{-1e300, -1e300, -1e300}};
    for (std::size_t i : which) {
        const Bounds3 b = bounding_box(truth[i].solid);
        for (int a = 0; a < 3; ++a) {
            box.min[a] = std::min(box.min[a], b.min[a]);
            box.max[a] = std::max(box.max[a], b.max[a]);
        }
    }
    const auto union_distance = [&](Vec3 p) {
        double best = std::numeric_limits<double>::infinity();
        for (std::size_t i : which) {
            best = std::min(best, signed_distance(truth[i].solid, p));
        }
        return best;
    };
    const auto cube = [&](const auto& self, Vec3 centre, double side, int level) -> double {
        const double dist = union_distance(centre);
        const double volume = side * side * side;
        if (std::abs(dist) > 0.5 * std::sqrt(3.0) * side) {
            return dist < 0.0 ? volume : 0.0;
        }
        if (level == kSplits) {
            return volume * std::clamp(0.5 - dist / side, 0.0, 1.0);
        }
        double sum = 0.0;
        for (int c = 0; c < 8; ++c) {
            const Vec3 offset{(c & 1) ? 0.25 : -0.25, (c & 2) ? 0.25 : -0.25,
                              (c & 4) ? 0.25 : -0.25};
            sum += self(self, centre + side * offset, 0.5 * side, level + 1);
        }
        return sum;
    };
    double total = 0.0;
    for (double z = std::floor(box.min.z) - 1.0; z < box.max.z + 1.0; z += 1.0) {
        for (double y = std::floor(box.min.y) - 1.0; y < box.max.y + 1.0; y += 1.0) {
            for (double x = std::floor(box.min.x) - 1.0; x < box.max.x + 1.0; x += 1.0) {
                total += cube(cube, Vec3{x + 0.5, y + 0.5, z + 0.5}, 1.0, 0);
            }
        }
    }
    return total;
}

/// The signed distance of smallest magnitude over the candidate solids.
double distance_px(const std::vector<TruthSolid>& truth,
                   const std::vector<std::size_t>& which,
                   Vec3 p_px) {
    double best = std::numeric_limits<double>::infinity();
    for (std::size_t i : which) {
        const double v = signed_distance(truth[i].solid, p_px);
        if (std::abs(v) < std::abs(best)) {
            best = v;
        }
    }
    return best;
}

MeshAccuracy measure(const std::filesystem::path& path,
                     const Phantom& phantom,
                     const std::vector<TruthSolid>& truth,
                     std::optional<std::uint16_t> label,
                     std::size_t worst,
                     std::size_t levels) {
    const TriMesh mesh = read_mesh(path);
    const std::uint16_t file_label = label_from_file_name(truth, path);
    const Affine3 world_to_index = inverse(phantom.stack.index_to_world);
    const double d = phantom.slice_spacing_px;
    std::vector<Vec3> px(mesh.positions.size());
    for (std::size_t v = 0; v < px.size(); ++v) {
        const Vec3 ijk = world_to_index.apply(mesh.positions[v]);
        px[v] = {ijk.x + 0.5, ijk.y + 0.5, ijk.z * d};
    }

    MeshAccuracy r;
    r.mesh = path.filename().string();
    r.vertices = mesh.positions.size();
    r.triangles = mesh.triangles.size();
    double sum_abs = 0.0, sum_sq = 0.0, sum_signed = 0.0;
    Vec3 sum_centroid;
    std::vector<bool> used(truth.size(), false);
    const double last_plane = (double(phantom.stack.depth) - 1.0) * d;
    if (levels > 0) {
        r.levels.resize(levels + 1);
    }
    for (std::size_t t = 0; t < mesh.triangles.size(); ++t) {
        const auto& tri = mesh.triangles[t];
        const Vec3 a = px[tri[0]], b = px[tri[1]], c = px[tri[2]];
        const Vec3 ab = b - a, ac = c - a;
        r.volume_px3 += dot(a, cross(b, c)) / 6.0;
        const double area = 0.5 * norm(cross(ab, ac));
        const std::uint16_t tri_label =
            label ? *label : (mesh.labels.empty() ? file_label : mesh.labels[t]);
        const std::vector<std::size_t> which = candidates(truth, tri_label);
        for (std::size_t i : which) {
            used[i] = true;
        }
        const int n =
            std::clamp(static_cast<int>(std::ceil(2.0 * std::sqrt(area))), 1, kMaxGridLevel);
        auto at = [&](double u, double v) { return a + u * ab + v * ac; };
        // max over the lattice points of the grid, corners included
        auto keep_max = [&](Vec3 p, double dist) {
            if (std::abs(dist) > r.max_px) {
                r.max_px = std::abs(dist);
                r.max_at_px = p;
                r.max_signed_px = dist;
            }
        };
        for (int i = 0; i <= n; ++i) {
            for (int j = 0; i + j <= n; ++j) {
                const Vec3 p = at(double(i) / n, double(j) / n);
                keep_max(p, distance_px(truth, which, p));
            }
        }
        // weighted statistics over the n^2 sub-triangle centroids (upward then downward ones)
        const double weight = area / (double(n) * n);
        auto sample = [&](double u, double v) {
            const Vec3 p = at(u, v);
            const double dist = distance_px(truth, which, p);
            keep_max(p, dist);
            sum_abs += weight * std::abs(dist);
            sum_sq += weight * dist * dist;
            sum_signed += weight * dist;
            sum_centroid = sum_centroid + weight * p;
            if (levels > 0) {
                const double s = std::abs(p.z / d - std::round(p.z / d));
                const std::size_t bin =
                    p.z < 0.0 || p.z > last_plane
                        ? levels
                        : std::min(levels - 1, static_cast<std::size_t>(2.0 * s * double(levels)));
                r.levels[bin].area_px2 += weight;
                r.levels[bin].sum_abs += weight * std::abs(dist);
                r.levels[bin].sum_signed += weight * dist;
            }
            ++r.samples;
        };
        for (int i = 0; i < n; ++i) {
            for (int j = 0; i + j < n; ++j) {
                sample((3.0 * i + 1) / (3.0 * n), (3.0 * j + 1) / (3.0 * n));
                if (i + j < n - 1) {
                    sample((3.0 * i + 2) / (3.0 * n), (3.0 * j + 2) / (3.0 * n));
                }
            }
        }
        r.area_px2 += area;
    }
    if (r.area_px2 > 0.0) {
        r.mean_px = sum_abs / r.area_px2;
        r.rms_px = std::sqrt(sum_sq / r.area_px2);
        r.bias_px = sum_signed / r.area_px2;
        r.centroid_px = (1.0 / r.area_px2) * sum_centroid;
    }
    if (worst > 0) {
        // each vertex against the solids of the labels of its triangles
        std::vector<double> dist(px.size(), 0.0);
        std::vector<bool> seen(px.size(), false);
        for (std::size_t t = 0; t < mesh.triangles.size(); ++t) {
            const std::uint16_t tri_label =
                label ? *label : (mesh.labels.empty() ? file_label : mesh.labels[t]);
            const std::vector<std::size_t> which = candidates(truth, tri_label);
            for (std::uint32_t v : mesh.triangles[t]) {
                const double e = distance_px(truth, which, px[v]);
                if (!seen[v] || std::abs(e) > std::abs(dist[v])) {
                    dist[v] = e;
                }
                seen[v] = true;
            }
        }
        std::vector<std::size_t> order;
        for (std::size_t v = 0; v < px.size(); ++v) {
            if (seen[v]) {
                order.push_back(v);
            }
        }
        const std::size_t n = std::min(worst, order.size());
        std::partial_sort(
            order.begin(), order.begin() + std::ptrdiff_t(n), order.end(),
            [&](std::size_t u, std::size_t v) { return std::abs(dist[u]) > std::abs(dist[v]); });
        for (std::size_t i = 0; i < n; ++i) {
            r.worst.emplace_back(px[order[i]], dist[order[i]]);
        }
    }
    std::vector<std::size_t> compared;
    for (std::size_t i = 0; i < truth.size(); ++i) {
        if (used[i]) {
            r.clipped = r.clipped || truth[i].clipped;
            r.exact = r.exact && truth[i].exact;
            compared.push_back(i);
        }
    }
    r.volume_px3 = std::abs(r.volume_px3);
    if (!compared.empty()) {
        r.truth_volume_px3 = union_volume_px3(truth, compared);
    }
    return r;
}

nlohmann::json to_json(const MeshAccuracy& r, const Phantom& phantom) {
    const double mm = phantom.pixel_mm;
    nlohmann::json j;
    j["mesh"] = r.mesh;
    j["phantom"] = phantom.name;
    j["slice_spacing_px"] = phantom.slice_spacing_px;
    j["pixel_mm"] = mm;
    j["vertices"] = r.vertices;
    j["triangles"] = r.triangles;
    j["samples"] = r.samples;
    j["area_px2"] = r.area_px2;
    j["mean_px"] = r.mean_px;
    j["rms_px"] = r.rms_px;
    j["max_px"] = r.max_px;
    j["bias_px"] = r.bias_px;
    j["mean_mm"] = r.mean_px * mm;
    j["rms_mm"] = r.rms_px * mm;
    j["max_mm"] = r.max_px * mm;
    j["max_at_px"] = {r.max_at_px.x, r.max_at_px.y, r.max_at_px.z};
    j["max_signed_px"] = r.max_signed_px;
    if (!r.worst.empty()) {
        nlohmann::json w = nlohmann::json::array();
        for (const auto& [p, dist] : r.worst) {
            w.push_back({{"at_px", {p.x, p.y, p.z}},
                         {"slice", p.z / phantom.slice_spacing_px},
                         {"signed_px", dist}});
        }
        j["worst_vertices"] = w;
    }
    if (!r.levels.empty()) {
        nlohmann::json levels = nlohmann::json::array();
        for (const MeshAccuracy::Level& l : r.levels) {
            levels.push_back({{"area_px2", l.area_px2},
                              {"mean_px", l.area_px2 > 0 ? l.sum_abs / l.area_px2 : 0.0},
                              {"bias_px", l.area_px2 > 0 ? l.sum_signed / l.area_px2 : 0.0}});
        }
        j["by_level"] = levels;
    }
    j["centroid_px"] = {r.centroid_px.x, r.centroid_px.y, r.centroid_px.z};
    j["volume_px3"] = r.volume_px3;
    j["truth_volume_px3"] = r.truth_volume_px3;
    j["clipped"] = r.clipped;
    j["exact_distance"] = r.exact;
    return j;
}

int run(int argc, char** argv) {
    if (argc < 2) {
        std::cerr << usage();
        return kExitBadInput;
    }
    const Arguments args = parse_arguments(argc, argv);
    PhantomOptions options;
    options.slice_spacing_px = args.slice_spacing_px;
    options.pixel_mm = args.pixel_mm;
    const Phantom phantom = make_phantom(args.phantom, options);
    const std::vector<TruthSolid> truth = truth_solids(phantom, args.clip);
    for (const TruthSolid& t : truth) {
        if (t.clipped) {
            std::cerr << "mesh_accuracy: note: " << phantom.name << " object '" << t.name
                      << "' leaves the stack's voxel extent; compared with its part inside it "
                         "(--no-clip: the whole solid)\n";
        } else if (!t.exact) {
            std::cerr << "mesh_accuracy: note: " << phantom.name << " object '" << t.name
                      << "': CSG solid, its signed distance is a bound (|d| may be "
                         "underestimated where operands meet)\n";
        }
    }

    // note: every mesh is read and measured before anything is printed, so that a bad file
    // leaves no partial table or JSON behind
    std::vector<MeshAccuracy> results;
    for (const std::filesystem::path& path : args.meshes) {
        results.push_back(measure(path, phantom, truth, args.label, args.worst, args.levels));
    }
    if (args.json) {
        nlohmann::json all = nlohmann::json::array();
        for (const MeshAccuracy& r : results) {
            all.push_back(to_json(r, phantom));
        }
        std::cout << all.dump(2) << '\n';
        return kExitOk;
    }
    const double mm = phantom.pixel_mm;
    std::cout << phantom.name << ", d = " << phantom.slice_spacing_px << " px, pixel = " << mm
              << " mm; |distance| mesh -> truth\n"
              << std::left << std::setw(32) << "mesh" << std::right << std::setw(10) << "triangles"
              << std::setw(10) << "mean px" << std::setw(10) << "rms px" << std::setw(10)
              << "max px" << std::setw(10) << "mean mm" << std::setw(10) << "rms mm"
              << std::setw(10) << "max mm" << '\n';
    for (const MeshAccuracy& r : results) {
        std::cout << std::left << std::setw(32) << r.mesh << std::right << std::setw(10)
                  << r.triangles << std::fixed << std::setprecision(3) << std::setw(10) << r.mean_px
                  << std::setw(10) << r.rms_px << std::setw(10) << r.max_px << std::setw(10)
                  << r.mean_px * mm << std::setw(10) << r.rms_px * mm << std::setw(10)
                  << r.max_px * mm << '\n'
                  << std::defaultfloat;
        std::cout << "  max at (" << r.max_at_px.x << ", " << r.max_at_px.y << ", " << r.max_at_px.z
                  << ") px, signed " << r.max_signed_px << " px\n";
        for (const auto& [p, dist] : r.worst) {
            std::cout << "  vertex (" << p.x << ", " << p.y << ", " << p.z << ") px, slice "
                      << p.z / phantom.slice_spacing_px << ", signed " << dist << " px\n";
        }
        const std::size_t bins = r.levels.empty() ? 0 : r.levels.size() - 1;
        for (std::size_t b = 0; b < r.levels.size(); ++b) {
            const MeshAccuracy::Level& l = r.levels[b];
            std::ostringstream where;
            if (b == bins) {
                where << "beyond the end planes";
            } else {
                where << "|z/d - round(z/d)| in [" << 0.5 * double(b) / double(bins) << ", "
                      << 0.5 * double(b + 1) / double(bins) << ")";
            }
            const double share = r.area_px2 > 0 ? l.area_px2 / r.area_px2 : 0.0;
            std::cout << "  " << std::left << std::setw(36) << where.str() << std::right
                      << std::fixed << std::setprecision(3) << " area " << share << "  mean "
                      << (l.area_px2 > 0 ? l.sum_abs / l.area_px2 : 0.0) << " px  bias "
                      << (l.area_px2 > 0 ? l.sum_signed / l.area_px2 : 0.0) << " px\n"
                      << std::defaultfloat;
        }
    }
    return kExitOk;
}

}  // namespace
}  // namespace strata

int main(int argc, char** argv) {
    try {
        return strata::run(argc, argv);
    } catch (const strata::Error& e) {
        std::cerr << "mesh_accuracy: error: " << e.what() << '\n';
        const bool bad_input = e.code() == strata::ErrorCode::InvalidInput ||
                               e.code() == strata::ErrorCode::Unsupported;
        return bad_input ? strata::kExitBadInput : strata::kExitFailure;
    } catch (const std::exception& e) {
        std::cerr << "mesh_accuracy: error: " << e.what() << '\n';
        return strata::kExitFailure;
    }
}
