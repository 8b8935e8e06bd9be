#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <limits>
#include <vector>

#include "core/progress.h"
#include "core/types.h"
#include "mesh/tri_mesh.h"
#include "simplify/slice_error.h"

namespace strata {

/// A ball: the bounding volume of clusters and groups.
struct Sphere {
    Vec3 center;
    double radius = 0.0;
};

/// A patch of the surface at one level of detail: an ordinary indexed triangle list over a few
/// of the model's vertices.
struct MultiresCluster {
    std::uint32_t level = 0;              ///< 0: full resolution
    std::int32_t producer = -1;           ///< group that made it, -1 at full resolution
    std::int32_t consumer = -1;           ///< group that replaces it by coarser clusters, -1: root
    std::vector<std::uint32_t> vertices;  ///< ids into MultiresMesh::positions, increasing
    std::vector<std::array<std::uint32_t, 3>> triangles;  ///< indices into `vertices`, CCW out
    /// Per entry of `vertices`: the vertex (id into positions) it collapses to in the consumer's
    /// coarse clusters (itself when it survives); empty for roots. Moving every vertex there
    /// turns the consumer's fine clusters into its coarse ones (geomorphing).
    std::vector<std::uint32_t> coarse_vertices;
    Sphere bounds;  ///< contains the cluster's vertices
};

/// A refinement step: its coarse clusters (`produced`) replace its fine ones (`consumed`).
struct MultiresGroup {
    std::uint32_t level = 0;              ///< level of the produced clusters (>= 1)
    std::vector<std::uint32_t> consumed;  ///< finer clusters, ids into MultiresMesh::clusters
    std::vector<std::uint32_t> produced;  ///< coarser clusters
    /// Error bound (px, slice space) of the produced clusters against the original contours, in
    /// both directions (their slice sections to the contours, and the contour pieces attached to
    /// them to their triangles), and of the full-resolution vertices attached to them (domes
    /// included) to their triangles, made monotone: never below the error of any group that
    /// produced a consumed cluster.
    double error_px = 0.0;
    /// Bound (px, slice space) on the distance of every full-resolution vertex from a cut in which
    /// this group is the coarsest unrefined producer: every vertex attached (as a piece or a piece
    /// end) to a produced cluster lies within it of the triangle it is attached to. Made monotone
    /// like error_px and never above it; what a viewer needs to know how much the rest of the
    /// refinement would still change on screen.
    double fine_error_px = 0.0;
    /// Contains the produced and consumed clusters and the bounds of every group below, so a
    /// projected error (error / distance to the sphere) is monotone along the DAG too.
    Sphere bounds;
};

/// The multiresolution model of one closed surface (docs/architecture.md section 4): clusters of
/// triangles at several levels and the groups (splits) between them, a DAG from the full-resolution
/// clusters (level 0) to the roots (clusters no group consumes: the base mesh).
///
/// Cuts: choosing for every group whether it is refined, such that every group above a refined
/// one (consuming a cluster it produced) is refined too, and drawing each cluster whose producer is
/// not refined (or absent) and whose consumer is refined (or absent, for roots), gives a closed,
/// manifold, outward surface with the topology of the full-resolution one and no self-intersection;
/// its error bound is the largest error_px among the producers of the drawn clusters
/// (`full_resolution_error_px` for level 0).
struct MultiresMesh {
    std::vector<Vec3> positions;  ///< every vertex (the full-resolution surface's), slice space
    std::vector<MultiresCluster> clusters;
    std::vector<MultiresGroup> groups;      ///< in creation order: a group's children come first
    double full_resolution_error_px = 0.0;  ///< bound of the level-0 clusters
    /// Positions lie on the grid of this step (x, y multiples of it in px, z of it times the slice
    /// spacing; quantize/snap_to_grid.h), 0: not snapped. Collapses keep positions, so every level
    /// lies on the surface's grid.
    double grid_step = 0.0;

    std::vector<std::uint32_t> roots() const {
        std::vector<std::uint32_t> result;
        for (std::uint32_t c = 0; c < clusters.size(); ++c) {
            if (clusters[c].consumer < 0) {
                result.push_back(c);
            }
        }
        return result;
    }
};

/// Options of `build_multires_mesh`.
struct MultiresOptions {
    /// Target triangles per cluster. 4096: the size benchmark (scripts/bench-size.sh, progressive
    /// format version 2, one Draco chunk per group) measured 3-5 % fewer bytes than 2048 on the
    /// torso and TotalSegmentator (torso 1.55 -> 1.47x single-rate Draco at keep 0.2), chunks of
    /// about 5 kB on average (level-0 chunks up to about 20 kB: a few ms at 20 Mbit/s).
    std::size_t cluster_triangles = 4096;
    std::size_t group_clusters = 4;  ///< clusters simplified together (a power of two)
    /// Levels are added until the coarsest is one cluster of at most this many triangles (or no
    /// group can shrink any more): the base mesh every viewer shows.
    std::size_t root_triangles = 128;
    /// A group is simplified until `keep_fraction` of its triangles remain or the next collapse
    /// would raise its error above max(error_growth * e, e + 0.5 px), e being the error of the
    /// clusters it consumes: each level may at most double the error, so the levels form an even
    /// ladder.
    double error_growth = 2.0;
    /// 0.2 rather than Nanite's 0.5: with version 2 of the progressive format the size benchmark
    /// (scripts/bench-size.sh sweep) measured, at 4096 triangles per cluster, total bytes over
    /// single-rate Draco of 1.80 (0.35), 1.58 (0.25), 1.47 (0.2) on the torso and 1.54 (0.25),
    /// 1.47 (0.2) on TotalSegmentator; triangles over all levels / level 0: 1.58, 1.38, 1.28.
    /// The error schedule (error_growth) binds from the second level on, so a lower fraction
    /// mostly thins the first, free step of each group.
    double keep_fraction = 0.2;
    /// Collapses above this bound (px) are never made. The coarsest level is reached when no
    /// group can shrink by `min_reduction`.
    double max_error_px = std::numeric_limits<double>::infinity();
    /// The first level's bound against full resolution (px; infinity: the rule above only): a
    /// group of level 0 clusters keeps every full-resolution vertex its result would leave
    /// farther than this from its triangles (a few rounds), unless it then cannot shrink. A
    /// viewer that refines on the bound against full resolution can then stop short of level 0.
    double first_level_px = std::numeric_limits<double>::infinity();
    double min_reduction = 0.15;  ///< least fraction of triangles a group must lose
    std::uint32_t max_levels = 24;
    /// The surface's grid step (quantize/snap_to_grid.h; 0: not snapped). Intersections and
    /// degenerate triangles are then ruled out in the grid frame (grid_frame_positions), where
    /// the coordinates files store are exact; in slice space, z = slice * spacing is rounded, and
    /// a vertex lying exactly on another triangle's edge there can look a hair apart.
    double grid_step = 0.0;
    unsigned threads = 0;  ///< worker threads, 0 = all cores; output identical for any count
    ProgressFn progress;   ///< called per level ("simplify levels")
};

/// Builds the multiresolution model of `surface` (a closed, oriented, self-intersection-free
/// surface in slice space, the triangulation stage's output for one label). Clusters are made by
/// recursive bisection of triangle centroids; groups by greedy matching of adjacent clusters,
/// preferring clusters of different parents so that old group borders end up inside; each group
/// is simplified by `collapse_edges` with its outer border locked, against every existing
/// triangle it could be drawn with. `full_resolution_error_px` is the bound the caller declares
/// for the surface itself (the contour simplification tolerance achieved, e.g. 0.5 px); it is
/// raised to the distance of the contour pieces (SliceErrorMeter::contour_pieces) from the
/// full-resolution triangles they are attached to, where that is larger. Every other vertex of
/// the surface is attached like a piece of length 0, so every cut lies within its bound of every
/// full-resolution vertex (a dome beyond the end slices, which no slice section sees, is not
/// flattened by more than the bound).
/// Deterministic. \throw Error{InvalidInput} when the surface is not an oriented manifold.
MultiresMesh build_multires_mesh(const TriMesh& surface,
                                 const SliceErrorMeter& meter,
                                 double full_resolution_error_px,
                                 const MultiresOptions& options);

/// One cut of the model: the clusters to draw and the error bound they guarantee.
struct MultiresCut {
    std::vector<std::uint32_t> clusters;  ///< increasing cluster ids
    double error_px = 0.0;                ///< largest producer error among them
    /// Largest fine_error_px among their producers (0 when every cluster is of level 0): every
    /// full-resolution vertex lies within it of the cut.
    double fine_error_px = 0.0;
};

/// The cut that refines every group for which `refine(group)` is true, and every group above a
/// refined one (so any predicate gives a valid cut). Examples: uniform error, `error_px > tau`;
/// region of interest, `error_px > (intersects(bounds, roi) ? tau_inside : tau)`.
MultiresCut select_cut(const MultiresMesh& mesh,
                       const std::function<bool(const MultiresGroup&)>& refine);

/// The cut with error bound at most `max_error_px` and the fewest levels of refinement: every
/// group whose error exceeds the bound is refined.
MultiresCut select_cut_by_error(const MultiresMesh& mesh, double max_error_px);

/// The cut of level `level`: every group above that level refined, none at or below it, so each
/// part of the surface is shown by its coarsest cluster of level <= `level`.
MultiresCut select_cut_at_level(const MultiresMesh& mesh, std::uint32_t level);

/// Number of levels: 1 + the largest group level (1 when nothing was simplified).
std::uint32_t level_count(const MultiresMesh& mesh);

/// A pinhole camera in the model's units (slice space for models from the pipeline).
struct ScreenCamera {
    Vec3 position;
    double fovy_rad = 0.8;               ///< vertical field of view
    double viewport_height_px = 1080.0;  ///< screen pixels
};

/// The projected size (screen px) of error `error` seen from `camera` at the nearest point of
/// `bounds` (3D Tiles' screen-space error: error * height / (distance * 2 tan(fovy / 2)));
/// infinite inside the sphere.
double screen_space_error_px(const ScreenCamera& camera, const Sphere& bounds, double error);

/// The cut whose every cluster projects to at most `max_screen_error_px`: refines every group
/// whose error, projected from its bounding sphere, exceeds it.
MultiresCut select_cut_for_camera(const MultiresMesh& mesh,
                                  const ScreenCamera& camera,
                                  double max_screen_error_px);

/// Region of interest: bound `inside_error_px` for groups whose sphere meets `region`,
/// `outside_error_px` elsewhere.
MultiresCut select_cut_in_region(const MultiresMesh& mesh,
                                 const Sphere& region,
                                 double inside_error_px,
                                 double outside_error_px);

/// The triangles of a cut as one mesh (vertices shared between clusters merged by id).
TriMesh cut_mesh(const MultiresMesh& mesh, const MultiresCut& cut);

}  // namespace strata
