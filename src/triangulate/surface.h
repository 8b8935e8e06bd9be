#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "contours/slice_contours.h"
#include "core/progress.h"
#include "distance/distance_field.h"
#include "input/slice_stack.h"
#include "medial/medial_axis.h"
#include "mesh/tri_mesh.h"
#include "triangulate/relax_heights.h"

namespace strata {

/// Options of the triangulation stage.
struct TriangulateOptions {
    double slice_spacing_px = 1.0;  ///< d: slice k lies at z = k * d px
    /// Medial-axis points closer than this along their curve are thinned before they become
    /// surface vertices (px).
    double medial_step_px = 1.0;
    /// Medial points are also thinned where their curve is straight: kept are the points of a
    /// Douglas-Peucker simplification of each curve with this tolerance (px), plus one at least
    /// every `medial_max_step_px` along it; 0 keeps every point (one per `medial_step_px`).
    /// Along parallel strips every pixel's medial point made a fan of slivers from each contour
    /// vertex.
    double medial_tolerance_px = 0.25;
    double medial_max_step_px = 6.0;
    /// End caps are domed, reaching at most this fraction of the slice spacing beyond their
    /// slice (the object goes on past its last slice by less than d); 0: planar caps in the
    /// end slices, as before.
    double cap_reach = 0.75;
    /// The quantize grid the surface will be stored on (QuantizeOptions::step, px in x, y and
    /// slices in z, and its `grid_halvings` finer steps): at the stack's first and last slice the
    /// walls of a region extended by d/2 lean as the object does (caps.cpp end_lean), and each
    /// lean is checked at the snapped positions of every such step (settle_end_leans), so that a
    /// lean the grid cannot store is not made. 0: checked as triangulated only (quantize off).
    double grid_step = 1.0 / 16.0;
    unsigned grid_halvings = 3;
    /// Steiner heights from a monotone cubic (Catmull-Rom) interpolation in z of the signed
    /// distance fields of slices k-1 .. k+2 instead of the linear D_k / (D_k - D_k+1). Where
    /// the region of the nearest contour ends at slice k (k+1), the slope there is at least its
    /// end dome's (caps.cpp, dome_rim_slope): the slab next to a pole bends as the dome does.
    bool cubic_height = true;
    /// With the cubic height: where it is farther than this (px in z) from the straight faces
    /// between a medial point and a contour, a vertex is added half way; 0: medial points only.
    double curvature_tolerance_px = 0.1;
    /// Rounds of local refinement (Steiner points) that remove flat chords and split
    /// correspondence jumps before a slab is declared failed.
    unsigned refine_rounds = 12;
    /// Steiner heights moved within their slab to unfold the surface (relax_heights.h).
    RelaxHeightsOptions relax;
    /// Threads over one label's slabs (0: all cores; core/parallel.h: inside a parallel_for
    /// over labels, the threads with no label left help). The surface is the same for any count.
    unsigned threads = 1;
};

/// Something the triangulation could not do as the semantics ask, for one slab of one label.
struct SlabIssue {
    std::uint32_t lower_slice = 0;
    std::string what;
};

/// The closed surface of one label, in slice space: x, y in px (contour frame), z = k * d.
struct ObjectSurface {
    std::uint16_t label = 0;
    TriMesh mesh;
    std::uint32_t slabs = 0;           ///< slice pairs joined by the surface
    std::uint32_t caps = 0;            ///< end caps (a single-slice slab counts two)
    std::uint32_t steiner_points = 0;  ///< vertices between slices (medial axis + refinement)
    /// Slabs where the contours overlap in another pattern than the pixels do (the surface
    /// follows the polygons there, so its topology can differ from the reference). The
    /// pipeline's repair policy (pipeline/repair.h) records in its own RepairRecord what it did
    /// about them.
    std::uint32_t topology_mismatches = 0;
    /// The largest deviation (px) of the simplified contours the surface was built from from
    /// the original contour points: its full-resolution bound.
    double contour_deviation_px = 0.0;
    std::uint32_t failed_slabs = 0;  ///< slabs refinement could not make valid
    std::vector<SlabIssue> issues;   ///< one per mismatch or failure, sorted by slice

    /// Independent checks of the finished surface (pipeline/reconstruct.h: verify_surface).
    struct Verification {
        bool done = false;
        bool closed_manifold = false;  ///< closed, edge- and vertex-manifold, oriented
        bool outward = false;          ///< encloses positive volume
        bool self_intersection_free = false;
        bool topology_as_reference = false;  ///< components and genus of the reference volume R
        std::string reference;               ///< R's topology, one line
        std::string problem;                 ///< first failed check, empty when all pass
        bool ok() const { return done && problem.empty(); }
    } verification;

    /// Set by the quantize stage (quantize/snap_to_grid.h): the grid step the positions lie on
    /// (0: not snapped) and the largest in-plane move of a slice-plane vertex it caused.
    double grid_step = 0.0;
    double grid_shift_px = 0.0;
};

/// One label's triangulation: its surface, and the slabs it could not build as the pixels ask.
struct LabelTriangulation {
    ObjectSurface surface;
    /// Slabs (their lower slice, increasing) whose contours overlap in another pattern than the
    /// pixels do: the surface follows the polygons there, so its topology can differ from the
    /// reference. The pipeline's repair policy (pipeline/repair.h) decides what to do.
    std::vector<std::uint32_t> mismatched_slabs;
};

/// How much of a label triangulate_label builds. A slab's mismatch is decided from its contour
/// rings alone, before any of its Steiner points, so the mismatched slabs are the same in every
/// mode; a surface with a mismatched slab is one the repair policy (pipeline/repair.h) replaces.
enum class TriangulateMode {
    kSurface,           ///< the surface, and its mismatched slabs
    kSurfaceIfMatched,  ///< the surface when no slab mismatches; else only the mismatched slabs
    kMismatchesOnly,    ///< only the mismatched slabs (the surface is left unfinished)
};

namespace detail {
class LabelSurface;
struct SlabCheckMemo;
}  // namespace detail

/// What one build of a label leaves for the next build of the same label with some of its
/// slices' contours changed (the repair attempts, pipeline/repair.cpp): every slab's contour
/// rings and whether it mismatched. A slab's mismatch is decided from its two slices' rings
/// alone, so a kMismatchesOnly build does not check again a slab whose rings are unchanged.
class SlabChecks {
public:
    SlabChecks();
    ~SlabChecks();
    SlabChecks(const SlabChecks&) = delete;
    SlabChecks& operator=(const SlabChecks&) = delete;

private:
    friend class detail::LabelSurface;
    std::unique_ptr<detail::SlabCheckMemo> memo_;
};

/// Triangulates one label of the stack (paper section 5) into one closed surface.
///
/// Between slices k and k+1 the surface is the graph, over the symmetric difference of the two
/// slices' simplified regions (only regions linked across the slab), of the shape-based
/// interpolation height t (TriangulateOptions::cubic_height; linear: t = D_k / (D_k - D_k+1);
/// moved half way to the same ratio of the distances to the simplified contours, see height_t):
/// it runs from the contour of slice k (t = 0)
/// through the medial axis (t = 1/2, the paper's correspondence curve, inserted as vertices) to
/// the contour of slice k+1 (t = 1). The planar domain is an exact constrained Delaunay
/// triangulation of both contour sets (CGAL, exact constructions), so the lifted surface is
/// embedded; where contours cross, the crossing point gets a vertical edge; where they coincide,
/// a vertical wall. Regions without a partner on the next (previous) slice are closed by a dome
/// beyond their plane (TriangulateOptions::cap_reach; at the stack's ends, a region that does not
/// close visibly is extended by d/2 instead); a region alone on its slice becomes a slab of
/// thickness d/2.
/// Contour edges are shared exactly between the slabs and caps on both sides of a slice.
/// Last, the Steiner points move in z inside their slab to unfold the surface
/// (TriangulateOptions::relax, relax_fold_heights): each slab stays a graph over its planar
/// triangulation, so the surface stays embedded and its slice-plane sections do not change.
/// Output: vertices without duplicates, triangles outward CCW;
/// `surface.contour_deviation_px` is that of `contours`. Modes other than kSurface leave the
/// surface unfinished whenever `mismatched_slabs` is not empty (kMismatchesOnly: always).
/// `checks` (if given) receives every slab's rings and mismatch; in kMismatchesOnly, the slabs
/// whose rings are those it holds take its mismatch instead of being checked again.
LabelTriangulation triangulate_label(const SliceContours& contours,
                                     const std::vector<SliceDistanceFields>& fields,
                                     const std::vector<MedialAxis>& medial_axes,
                                     const TriangulateOptions& options,
                                     std::uint16_t label,
                                     TriangulateMode mode = TriangulateMode::kSurface,
                                     SlabChecks* checks = nullptr);

/// The same with every slab k where `split[k]` split at the pixels' AND layer: a level half way
/// between the slices whose contours are those of the pixels of `label` in both slices of
/// `stack` (the reference volume's own middle layer), so the surface meets it as R does. Issues
/// and mismatched slabs name the slices of `stack`.
LabelTriangulation triangulate_label_split(const SliceStack& stack,
                                           const SliceContours& contours,
                                           const std::vector<SliceDistanceFields>& fields,
                                           const std::vector<MedialAxis>& medial_axes,
                                           const TriangulateOptions& options,
                                           std::uint16_t label,
                                           const std::vector<bool>& split);

/// Whether the simplified contours of `label` on one slice are simple and pairwise disjoint
/// (exact predicates), as the triangulation needs them.
bool contours_clean(const SliceContourSet& set, std::uint16_t label);

}  // namespace strata
