// Reference topology of a slice stack via the reference volume R (docs/test-catalogue.md).
//
// Fast labeller: run-based connected-component labelling with union-find (Rosenfeld & Pfaltz,
// "Sequential operations in digital picture processing", JACM 1966), streamed layer by layer,
// with Euler characteristics counted from 2x2x2 blocks (the local-count method of Lee, Poston &
// Rosenfeld, "Winding and Euler numbers for 2D and 3D digital images", CVGIP 1991; a stretch of
// identical blocks along a run is counted once) and surfaces obtained from the component
// adjacency tree with chi(dM) = 2 chi(M) (see the header).
//
// Brute force: explicit boundary quad mesh of R made a closed 2-manifold by splitting edges and
// vertices as the connectivity rule says, then V - E + F per mesh component.
#include "triangulate/reference_topology.h"

#include <algorithm>
#include <array>
#include <bit>
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <deque>
#include <limits>
#include <ostream>
#include <sstream>
#include <tuple>
#include <utility>

#include "core/error.h"

namespace strata {
namespace {

// Bit b of a 2x2x2 block mask is the voxel (dx, dy, dz) = (b & 1, (b >> 1) & 1, b >> 2) of the
// block whose corner (x, y, z) is shared by voxels x-1..x, y-1..y, z-1..z; bit set = foreground.

/// chi contribution of the closed foreground cubes: the cells whose lowest corner is the block's
/// corner (1 vertex, 3 edges, 3 faces, 1 cube), each counted if any incident voxel is foreground.
int foreground_block_chi(unsigned m) {
    // Incident voxels of each cell (as block bits) and its sign (-1)^dimension.
    constexpr std::array<std::pair<unsigned, int>, 8> kCells{{
        {0xFFu, +1},  // vertex at the corner
        {0xAAu, -1},  // edge +x: voxels with dx = 1
        {0xCCu, -1},  // edge +y: dy = 1
        {0xF0u, -1},  // edge +z: dz = 1
        {0x88u, +1},  // face spanning +x,+y: dx = dy = 1
        {0xA0u, +1},  // face spanning +x,+z: dx = dz = 1
        {0xC0u, +1},  // face spanning +y,+z: dy = dz = 1
        {0x80u, -1},  // cube with this lowest corner: voxel (1, 1, 1)
    }};
    int chi = 0;
    for (const auto& [cell, sign] : kCells) {
        if ((m & cell) != 0) {
            chi += sign;
        }
    }
    return chi;
}

/// chi contribution of the background voxel-centre complex: the cells whose highest voxel is the
/// block's voxel (1, 1, 1), each counted if all its voxels are background.
int background_block_chi(unsigned m) {
    constexpr std::array<std::pair<unsigned, int>, 8> kCells{{
        {0x80u, +1},  // vertex: voxel (1, 1, 1)
        {0xC0u, -1},  // edge to (0, 1, 1)
        {0xA0u, -1},  // edge to (1, 0, 1)
        {0x88u, -1},  // edge to (1, 1, 0)
        {0xF0u, +1},  // square in the upper layer
        {0xCCu, +1},  // square spanning x and z
        {0xAAu, +1},  // square spanning y and z
        {0xFFu, -1},  // cube: the whole block
    }};
    int chi = 0;
    for (const auto& [cell, sign] : kCells) {
        if ((m & cell) == 0) {
            chi += sign;
        }
    }
    return chi;
}

struct BlockTables {
    std::array<std::int8_t, 256> foreground{};
    std::array<std::int8_t, 256> background{};
};

const BlockTables& block_tables() {
    static const BlockTables tables = [] {
        BlockTables t;
        for (unsigned m = 0; m < 256; ++m) {
            t.foreground[m] = static_cast<std::int8_t>(foreground_block_chi(m));
            t.background[m] = static_cast<std::int8_t>(background_block_chi(m));
        }
        return t;
    }();
    return tables;
}

void check_inputs_impl(
    const std::vector<std::uint8_t>& mask, int width, int height, int depth, const char* who) {
    if (width < 0 || height < 0 || depth < 0) {
        std::ostringstream msg;
        msg << who << ": dimensions " << width << "x" << height << "x" << depth
            << ", expected non-negative";
        throw Error{ErrorCode::InvalidInput, msg.str()};
    }
    constexpr int kMaxDim = std::numeric_limits<int>::max() - 2;
    if (width > kMaxDim || height > kMaxDim || depth > kMaxDim / 2) {
        std::ostringstream msg;
        msg << who << ": dimensions " << width << "x" << height << "x" << depth << " too large";
        throw Error{ErrorCode::Unsupported, msg.str()};
    }
    const std::size_t expected = std::size_t(width) * std::size_t(height) * std::size_t(depth);
    if (mask.size() != expected) {
        std::ostringstream msg;
        msg << who << ": mask has " << mask.size() << " values, expected " << width << "x" << height
            << "x" << depth << " = " << expected;
        throw Error{ErrorCode::InvalidInput, msg.str()};
    }
}

void check_stack(const SliceStack& stack, const char* who) {
    const std::size_t size = std::size_t(stack.width) * stack.height * stack.depth;
    if (stack.labels.size() != size) {
        std::ostringstream msg;
        msg << who << ": stack has " << stack.labels.size() << " labels, expected " << stack.width
            << "x" << stack.height << "x" << stack.depth << " = " << size;
        throw Error{ErrorCode::InvalidInput, msg.str()};
    }
    constexpr auto kMaxDim = std::uint32_t(std::numeric_limits<int>::max() - 2);
    if (stack.width > kMaxDim || stack.height > kMaxDim || stack.depth > kMaxDim / 2) {
        std::ostringstream msg;
        msg << who << ": stack " << stack.width << "x" << stack.height << "x" << stack.depth
            << " is too large";
        throw Error{ErrorCode::Unsupported, msg.str()};
    }
}

std::vector<std::uint8_t> mask_of_impl(const SliceStack& stack,
                                       std::uint16_t label,
                                       const char* who) {
    check_stack(stack, who);
    std::vector<std::uint8_t> mask(stack.labels.size());
    for (std::size_t i = 0; i < mask.size(); ++i) {
        mask[i] = stack.labels[i] == label ? 1 : 0;
    }
    return mask;
}

/// Union-find whose set representative is always the smallest member.
class MinUnionFind {
public:
    std::int32_t add() {
        if (parent_.size() >= std::size_t(std::numeric_limits<std::int32_t>::max())) {
            throw Error{ErrorCode::Unsupported, "reference_topology: too many provisional labels"};
        }
        const auto id = static_cast<std::int32_t>(parent_.size());
        parent_.push_back(id);
        return id;
    }
    std::int32_t find(std::int32_t a) {
        while (parent_[a] != a) {
            parent_[a] = parent_[parent_[a]];
            a = parent_[a];
        }
        return a;
    }
    void unite(std::int32_t a, std::int32_t b) {
        a = find(a);
        b = find(b);
        if (a < b) {
            parent_[b] = a;
        } else if (b < a) {
            parent_[a] = b;
        }
    }
    std::size_t size() const { return parent_.size(); }

private:
    std::vector<std::int32_t> parent_;
};

/// The component tree and the surfaces on its edges, from per-component chi.
/// Nodes 0..solids-1 are foreground components, the rest background; `root` is the outer
/// background. `edges` are (foreground node, background node) pairs, sorted and unique.
ReferenceTopology surfaces_from_tree(int solids,
                                     int node_count,
                                     int root,
                                     const std::vector<std::pair<int, int>>& edges,
                                     const std::vector<std::int64_t>& chi) {
    if (std::size_t(node_count) != edges.size() + 1) {
        std::ostringstream msg;
        msg << "reference_topology: " << node_count << " components but " << edges.size()
            << " adjacent pairs, expected a tree";
        throw Error{ErrorCode::Internal, msg.str()};
    }
    std::vector<int> start(std::size_t(node_count) + 1, 0);
    for (const auto& [f, b] : edges) {
        ++start[f + 1];
        ++start[b + 1];
    }
    for (int n = 0; n < node_count; ++n) {
        start[n + 1] += start[n];
    }
    std::vector<int> neighbours(start.back());
    std::vector<int> fill(start.begin(), start.end() - 1);
    for (const auto& [f, b] : edges) {
        neighbours[fill[f]++] = b;
        neighbours[fill[b]++] = f;
    }
    std::vector<int> parent(node_count, -2);
    std::vector<int> order;
    order.reserve(node_count);
    parent[root] = -1;
    order.push_back(root);
    for (std::size_t head = 0; head < order.size(); ++head) {
        const int n = order[head];
        for (int e = start[n]; e < start[n + 1]; ++e) {
            const int m = neighbours[e];
            if (m != parent[n]) {
                if (parent[m] != -2) {
                    throw Error{ErrorCode::Internal,
                                "reference_topology: component adjacency has a cycle"};
                }
                parent[m] = n;
                order.push_back(m);
            }
        }
    }
    if (order.size() != std::size_t(node_count)) {
        throw Error{ErrorCode::Internal, "reference_topology: component adjacency is disconnected"};
    }
    // chi(S(Z)) = 2 chi(Z) - sum of chi(S(C)) over the children C, leaves first.
    std::vector<std::int64_t> surface_chi(node_count, 0);
    std::vector<std::int64_t> children_chi(node_count, 0);
    ReferenceTopology result;
    result.solid_components = solids;
    for (auto it = order.rbegin(); it != order.rend(); ++it) {
        const int n = *it;
        if (n == root) {
            continue;
        }
        surface_chi[n] = 2 * chi[n] - children_chi[n];
        children_chi[parent[n]] += surface_chi[n];
        const std::int64_t twice_genus = 2 - surface_chi[n];
        if (twice_genus < 0 || twice_genus % 2 != 0) {
            std::ostringstream msg;
            msg << "reference_topology: surface with Euler characteristic " << surface_chi[n];
            throw Error{ErrorCode::Internal, msg.str()};
        }
        const bool is_cavity = n >= solids;
        result.surfaces.push_back(
            {static_cast<int>(twice_genus / 2), is_cavity, is_cavity ? parent[n] : n});
    }
    return result;
}

void sort_surfaces_impl(ReferenceTopology& topology) {
    std::sort(topology.surfaces.begin(), topology.surfaces.end(),
              [](const ReferenceSurface& a, const ReferenceSurface& b) {
                  return std::tuple(a.solid_component, a.is_cavity, a.genus) <
                         std::tuple(b.solid_component, b.is_cavity, b.genus);
              });
}

}  // namespace

std::string describe(const ReferenceTopology& topology) {
    std::ostringstream out;
    out << topology.solid_components << " solids, " << topology.surface_count() << " surfaces:";
    for (const ReferenceSurface& s : topology.surfaces) {
        out << " [" << s.solid_component << (s.is_cavity ? " cavity g" : " outer g") << s.genus
            << "]";
    }
    return out.str();
}

void PrintTo(const ReferenceTopology& topology, std::ostream* os) {
    *os << describe(topology);
}

namespace {

/// A layer of the padded R as runs: row y (0 .. height+1) is split at its toggles, the sorted
/// padded columns (1 .. width+1) where the value flips. Run r of a row with n toggles covers
/// columns [toggle r-1, toggle r) (from 0, up to width+2), is background for even r (every row
/// starts and ends in padding) and foreground for odd r.
struct RunRows {
    std::vector<std::int32_t> toggles;
    std::vector<std::size_t> start;  ///< row y's toggles: toggles[start[y] .. start[y+1])

    std::size_t rows() const { return start.size() - 1; }
    const std::int32_t* row(std::size_t y) const { return toggles.data() + start[y]; }
    int toggle_count(std::size_t y) const { return int(start[y + 1] - start[y]); }
};

/// Runs of one slice; `is_foreground(i, j)` reads pixel (i, j).
template <class IsForeground>
void slice_runs(int width, int height, IsForeground&& is_foreground, RunRows& out) {
    out.toggles.clear();
    out.start.assign(1, 0);
    out.start.push_back(0);  // padding row
    for (int j = 0; j < height; ++j) {
        bool value = false;
        for (int i = 0; i < width; ++i) {
            if (is_foreground(i, j) != value) {
                value = !value;
                out.toggles.push_back(i + 1);
            }
        }
        if (value) {
            out.toggles.push_back(width + 1);
        }
        out.start.push_back(out.toggles.size());
    }
    out.start.push_back(out.toggles.size());  // padding row
}

/// Runs of a AND b, row by row (intersection of the foreground intervals).
void and_runs(const RunRows& a, const RunRows& b, RunRows& out) {
    out.toggles.clear();
    out.start.assign(1, 0);
    for (std::size_t y = 0; y < a.rows(); ++y) {
        const std::int32_t* ta = a.row(y);
        const std::int32_t* tb = b.row(y);
        const int na = a.toggle_count(y);
        const int nb = b.toggle_count(y);
        int i = 0;
        int k = 0;
        while (i < na && k < nb) {
            const std::int32_t lo = std::max(ta[i], tb[k]);
            const std::int32_t hi = std::min(ta[i + 1], tb[k + 1]);
            if (lo < hi) {
                out.toggles.push_back(lo);
                out.toggles.push_back(hi);
            }
            if (ta[i + 1] < tb[k + 1]) {
                i += 2;
            } else {
                k += 2;
            }
        }
        out.start.push_back(out.toggles.size());
    }
}

/// Runs of a padding layer (all background).
void empty_runs(std::size_t rows, RunRows& out) {
    out.toggles.clear();
    out.start.assign(rows + 1, 0);
}

/// A layer of R with a provisional label per run.
struct LabelledLayer {
    RunRows runs;
    std::vector<std::int32_t> labels;  ///< run r of row y: labels[runs.start[y] + y + r]

    const std::int32_t* row_labels(std::size_t y) const {
        return labels.data() + runs.start[y] + y;
    }
};

/// The streaming labeller: provisional labels with their phase and chi, and the
/// foreground/background pairs that share a face.
class RunLabeller {
public:
    explicit RunLabeller(std::size_t padded_width) : xp_(std::int32_t(padded_width)) {}

    /// Labels `layer` in-plane (foreground 8-connected, background 4-connected); then, if
    /// `below` is given, joins it to `below` face to face and counts the 2x2x2 blocks between.
    void add_layer(LabelledLayer& layer, const LabelledLayer* below) {
        label_in_plane(layer);
        if (below != nullptr) {
            join_in_z(*below, layer);
            count_blocks(*below, layer);
        }
    }

    ReferenceTopology finish();

private:
    std::int32_t new_label(bool foreground) {
        is_foreground_.push_back(foreground ? 1 : 0);
        chi_.push_back(0);
        return sets_.add();
    }

    // Columns [lo, hi) of run r of a row with toggles t (n of them).
    std::pair<std::int32_t, std::int32_t> bounds(const std::int32_t* t, int n, int r) const {
        return {r == 0 ? 0 : t[r - 1], r == n ? xp_ : t[r]};
    }

    void label_in_plane(LabelledLayer& layer) {
        const RunRows& runs = layer.runs;
        layer.labels.resize(runs.toggles.size() + runs.rows());
        for (std::size_t y = 0; y < runs.rows(); ++y) {
            const std::int32_t* t = runs.row(y);
            const int n = runs.toggle_count(y);
            std::int32_t* labels = layer.labels.data() + runs.start[y] + y;
            if (y == 0) {
                for (int r = 0; r <= n; ++r) {
                    labels[r] = new_label(r % 2 == 1);
                }
                continue;
            }
            const std::int32_t* pt = runs.row(y - 1);
            const int pn = runs.toggle_count(y - 1);
            const std::int32_t* plabels = layer.row_labels(y - 1);
            int q = 0;  // first run of the row above ending at or after this run's start
            for (int r = 0; r <= n; ++r) {
                const auto [lo, hi] = bounds(t, n, r);
                const bool foreground = r % 2 == 1;
                while (bounds(pt, pn, q).second < lo) {
                    ++q;
                }
                std::int32_t label = -1;
                for (int k = q; k <= pn; ++k) {
                    const auto [plo, phi] = bounds(pt, pn, k);
                    if (plo > hi) {
                        break;
                    }
                    // Foreground: columns at most 1 apart (8-connected); background: shared.
                    const bool touches =
                        foreground ? (plo <= hi && lo <= phi) : (plo < hi && lo < phi);
                    if (k % 2 == r % 2 && touches) {
                        if (label < 0) {
                            label = plabels[k];
                        } else {
                            sets_.unite(label, plabels[k]);
                        }
                    }
                }
                labels[r] = label >= 0 ? label : new_label(foreground);
            }
        }
    }

    // Runs of the same phase sharing a column in consecutive layers are face-connected.
    void join_in_z(const LabelledLayer& below, const LabelledLayer& above) {
        for (std::size_t y = 0; y < above.runs.rows(); ++y) {
            const std::int32_t* tb = below.runs.row(y);
            const std::int32_t* ta = above.runs.row(y);
            const int nb = below.runs.toggle_count(y);
            const int na = above.runs.toggle_count(y);
            const std::int32_t* lb = below.row_labels(y);
            const std::int32_t* la = above.row_labels(y);
            int i = 0;
            int k = 0;
            while (i <= nb && k <= na) {
                if (i % 2 == k % 2) {
                    sets_.unite(lb[i], la[k]);
                }
                const std::int32_t end_b = bounds(tb, nb, i).second;
                const std::int32_t end_a = bounds(ta, na, k).second;
                i += end_b <= end_a ? 1 : 0;
                k += end_a <= end_b ? 1 : 0;
            }
        }
    }

    // The mixed 2x2x2 blocks between two layers. Rows q = 0..3 of a block are (below, y-1),
    // (below, y), (above, y-1), (above, y): block bits 2q (column x-1) and 2q+1 (column x).
    // Between toggles a stretch of corners sees the same block with the same labels: it is
    // counted once, times its length.
    void count_blocks(const LabelledLayer& below, const LabelledLayer& above) {
        const BlockTables& tables = block_tables();
        std::uint64_t last_pair = std::numeric_limits<std::uint64_t>::max();
        for (std::size_t y = 1; y < above.runs.rows(); ++y) {
            const std::array<const LabelledLayer*, 4> layer{&below, &below, &above, &above};
            std::array<const std::int32_t*, 4> t{};
            std::array<const std::int32_t*, 4> labels{};
            std::array<int, 4> n{};
            for (int q = 0; q < 4; ++q) {
                const std::size_t row = y - 1 + (q % 2);
                t[q] = layer[q]->runs.row(row);
                n[q] = layer[q]->runs.toggle_count(row);
                labels[q] = layer[q]->row_labels(row);
            }
            if (n[0] + n[1] + n[2] + n[3] == 0) {
                continue;  // all background
            }
            std::array<int, 4> run{0, 0, 0, 0};   // run of column x-1, per row
            std::array<int, 4> next{0, 0, 0, 0};  // run of column x, per row
            auto block = [&](unsigned m, std::int64_t count) {
                if (m == 0 || m == 0xFF) {
                    return;
                }
                auto label_of = [&](unsigned bit) {
                    const unsigned q = bit >> 1;
                    return labels[q][(bit & 1) != 0 ? next[q] : run[q]];
                };
                // All foreground voxels of a block are in one component (see the header).
                const std::int32_t foreground = label_of(unsigned(std::countr_zero(m)));
                chi_[foreground] += count * tables.foreground[m];
                if ((m & 0x80u) == 0) {
                    chi_[label_of(7)] += count * tables.background[m];
                }
                // Faces between voxel (1,1,1) and its neighbours at bits 6 (-x), 5 (-y), 3 (-z).
                for (unsigned bit : {6u, 5u, 3u}) {
                    const bool a = ((m >> 7) & 1u) != 0;
                    if (a != (((m >> bit) & 1u) != 0)) {
                        const std::int32_t background = a ? label_of(bit) : label_of(7);
                        const std::uint64_t key =
                            (std::uint64_t(foreground) << 32) | std::uint32_t(background);
                        if (key != last_pair) {
                            layer_pairs_.push_back(key);
                            last_pair = key;
                        }
                    }
                }
            };
            std::int32_t x = 1;  // corner x lies between columns x-1 and x
            while (x < xp_) {
                std::int32_t toggle = xp_;
                for (int q = 0; q < 4; ++q) {
                    if (run[q] < n[q]) {
                        toggle = std::min(toggle, t[q][run[q]]);
                    }
                }
                unsigned m = 0;
                for (int q = 0; q < 4; ++q) {
                    next[q] = run[q];
                    m |= unsigned(run[q] & 1) * (3u << (2 * q));
                }
                block(m, toggle - x);  // corners x .. toggle-1: no row changes value
                if (toggle >= xp_) {
                    break;
                }
                m = 0;
                for (int q = 0; q < 4; ++q) {
                    next[q] = run[q] + ((run[q] < n[q] && t[q][run[q]] == toggle) ? 1 : 0);
                    m |= (unsigned(run[q] & 1) << (2 * q)) | (unsigned(next[q] & 1) << (2 * q + 1));
                }
                block(m, 1);  // corner `toggle`: some rows change value there
                run = next;
                x = toggle + 1;
            }
        }
        for (std::uint64_t& key : layer_pairs_) {
            key = (std::uint64_t(sets_.find(std::int32_t(key >> 32))) << 32) |
                  std::uint32_t(sets_.find(std::int32_t(key & 0xFFFFFFFFu)));
        }
        std::sort(layer_pairs_.begin(), layer_pairs_.end());
        layer_pairs_.erase(std::unique(layer_pairs_.begin(), layer_pairs_.end()),
                           layer_pairs_.end());
        pairs_.insert(pairs_.end(), layer_pairs_.begin(), layer_pairs_.end());
        layer_pairs_.clear();
    }

    std::int32_t xp_;
    MinUnionFind sets_;
    std::vector<std::uint8_t> is_foreground_;  // per provisional label
    std::vector<std::int64_t> chi_;            // per provisional label, from its blocks
    std::vector<std::uint64_t> pairs_;         // (foreground << 32 | background) provisional labels
    std::vector<std::uint64_t> layer_pairs_;
};

ReferenceTopology RunLabeller::finish() {
    // Number components by their smallest provisional label, which is their first voxel in
    // raster order: foreground 0..F-1, then background F..F+B-1.
    const std::size_t label_count = sets_.size();
    std::vector<std::int32_t> component(label_count, -1);
    std::int32_t foreground_count = 0;
    std::int32_t background_count = 0;
    for (std::size_t i = 0; i < label_count; ++i) {
        const std::int32_t r = sets_.find(std::int32_t(i));
        if (component[r] < 0) {
            component[r] = is_foreground_[r] != 0 ? foreground_count++ : background_count++;
        }
        component[i] = component[r];
    }
    auto node_of = [&](std::int32_t label) {
        return is_foreground_[label] != 0 ? component[label] : foreground_count + component[label];
    };
    const int node_count = foreground_count + background_count;
    std::vector<std::int64_t> node_chi(node_count, 0);
    for (std::size_t i = 0; i < label_count; ++i) {
        node_chi[node_of(std::int32_t(i))] += chi_[i];
    }
    std::vector<std::pair<int, int>> edges;
    edges.reserve(pairs_.size());
    for (std::uint64_t key : pairs_) {
        edges.emplace_back(node_of(std::int32_t(key >> 32)),
                           node_of(std::int32_t(key & 0xFFFFFFFFu)));
    }
    std::sort(edges.begin(), edges.end());
    edges.erase(std::unique(edges.begin(), edges.end()), edges.end());

    // Provisional label 0 is the first padding run: the outer background.
    ReferenceTopology result =
        surfaces_from_tree(foreground_count, node_count, node_of(0), edges, node_chi);
    sort_surfaces_impl(result);
    return result;
}

/// The fast labeller over any pixel source: `is_foreground(i, j, k)`.
template <class IsForeground>
ReferenceTopology label_reference_volume(int width,
                                         int height,
                                         int depth,
                                         IsForeground&& is_foreground) {
    if (width == 0 || height == 0 || depth == 0) {
        return {};
    }
    const std::size_t rows = std::size_t(height) + 2;
    RunLabeller labeller(std::size_t(width) + 2);

    // Slice runs, at most two alive: slice k for layer 2k, slices k and k+1 for layer 2k+1.
    std::array<RunRows, 2> slices;
    std::array<int, 2> slice_index{-1, -1};
    auto runs_of_slice = [&](int k) -> const RunRows& {
        const int slot = k % 2;
        if (slice_index[slot] != k) {
            slice_runs(
                width, height, [&](int i, int j) { return is_foreground(i, j, k); }, slices[slot]);
            slice_index[slot] = k;
        }
        return slices[slot];
    };

    LabelledLayer below;
    LabelledLayer above;
    empty_runs(rows, below.runs);
    labeller.add_layer(below, nullptr);
    for (int l = 0; l <= 2 * depth - 1; ++l) {  // R's layers 0 .. 2K-2, then padding
        if (l == 2 * depth - 1) {
            empty_runs(rows, above.runs);
        } else if (l % 2 == 0) {
            above.runs = runs_of_slice(l / 2);
        } else {
            const RunRows& a = runs_of_slice(l / 2);
            and_runs(a, runs_of_slice(l / 2 + 1), above.runs);
        }
        labeller.add_layer(above, &below);
        std::swap(below, above);
    }
    return labeller.finish();
}

}  // namespace

ReferenceTopology reference_topology(const std::vector<std::uint8_t>& mask,
                                     int width,
                                     int height,
                                     int depth) {
    check_inputs_impl(mask, width, height, depth, "reference_topology");
    return label_reference_volume(width, height, depth, [&](int i, int j, int k) {
        return mask[(std::size_t(k) * height + j) * width + i] != 0;
    });
}

ReferenceTopology reference_topology(const SliceStack& stack, std::uint16_t label) {
    check_stack(stack, "reference_topology");
    const std::size_t width = stack.width;
    const std::size_t height = stack.height;
    // note: R is the same up to a shift on the label's bounding box (outside it every layer is
    // background, which joins the padding either way), and the raster order of its voxels, which
    // numbers the solids, is kept: so only the box is labelled, not every slice of the stack.
    std::size_t i0 = width, i1 = 0, j0 = height, j1 = 0, k0 = stack.depth, k1 = 0;
    for (std::size_t k = 0; k < stack.depth; ++k) {
        for (std::size_t j = 0; j < height; ++j) {
            const std::uint16_t* row = stack.labels.data() + (k * height + j) * width;
            const std::uint16_t* first = std::find(row, row + width, label);
            if (first == row + width) {
                continue;
            }
            std::size_t last = width - 1;
            while (row[last] != label) {
                --last;
            }
            i0 = std::min(i0, std::size_t(first - row));
            i1 = std::max(i1, last + 1);
            j0 = std::min(j0, j);
            j1 = std::max(j1, j + 1);
            k0 = std::min(k0, k);
            k1 = k + 1;
        }
    }
    if (k1 <= k0) {
        return {};
    }
    return label_reference_volume(
        int(i1 - i0), int(j1 - j0), int(k1 - k0), [&](int i, int j, int k) {
            return stack.labels[((k0 + std::size_t(k)) * height + j0 + std::size_t(j)) * width +
                                i0 + std::size_t(i)] == label;
        });
}

namespace detail {

void check_topology_inputs(
    const std::vector<std::uint8_t>& mask, int width, int height, int depth, const char* who) {
    check_inputs_impl(mask, width, height, depth, who);
}

std::vector<std::uint8_t> label_mask(const SliceStack& stack,
                                     std::uint16_t label,
                                     const char* who) {
    return mask_of_impl(stack, label, who);
}

void sort_surfaces(ReferenceTopology& topology) {
    sort_surfaces_impl(topology);
}

}  // namespace detail

}  // namespace strata
