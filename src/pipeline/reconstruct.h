#pragma once

#include <string>
#include <vector>

#include "contours/extract_contours.h"
#include "contours/slice_contours.h"
#include "core/progress.h"
#include "core/report.h"
#include "core/slice_frame.h"
#include "distance/distance_field.h"
#include "input/slice_stack.h"
#include "medial/medial_axis.h"
#include "pipeline/repair_record.h"
#include "quantize/snap_to_grid.h"
#include "simplify/multires_dag.h"
#include "triangulate/reference_topology.h"
#include "triangulate/surface.h"

namespace strata {

/// Options of the whole reconstruction, one struct per stage.
struct ReconstructOptions {
    ContourOptions contours;
    DistanceOptions distance;
    MedialOptions medial;
    TriangulateOptions triangulate;  ///< slice spacing is taken from the stack
    /// Snap every surface to a dyadic grid (before verification, so the checks see the snapped
    /// surface); its full-resolution error bound grows by the largest in-plane move.
    QuantizeOptions quantize;
    /// Check every surface after triangulation: manifold, outward, no self-intersection (exact),
    /// components and genus of the reference volume R. Failures become warnings.
    bool verify = true;
    /// Build the multiresolution model of every surface (error-bounded simplification). A surface
    /// that failed verification is kept at full resolution (one level) and a warning says so.
    bool simplify = true;
    MultiresOptions multires;
    /// Keep every distance field in the result. False: a label's fields are released as soon
    /// as its multiresolution model is built (nothing after needs them but debug pictures), so
    /// the memory of the labels done goes to the export.
    bool keep_fields = true;
    /// Labels taken through the stages after the contours together (distance fields, medial
    /// axes, triangulation, verification, simplification), the labels with the most contour
    /// points first (so that one large label does not leave the other threads idle while its
    /// batch waits for it); each batch's fields and axes are freed before the next starts, so
    /// memory holds one batch's work. 0 or keep_fields: all labels in one batch. The output is
    /// the same, in label order, for any size.
    std::size_t batch_labels = 8;
    /// Keep every slice pair's medial axes in the result. False: each batch's axes are counted
    /// (Reconstruction::medial_counts) and freed with its fields, so they do not add up over the
    /// labels (FreeSurfer: about 970k medial points, 75 MB).
    bool keep_medial_axes = true;
    unsigned threads = 0;  ///< worker threads of every stage, 0 = all cores
    ProgressFn progress;   ///< stage progress (may be empty)
};

/// Wall time and process CPU time (every thread, user + system) of one stage.
struct StageTiming {
    std::string stage;
    double seconds = 0.0;
    double cpu_seconds = 0.0;
};

/// Slice spacing in in-plane pixels: the length of the affine's k column over the i column's.
double slice_spacing_px(const SliceStack& stack);

/// Maps a slice-space point (x, y px on the contour grid, z = k d px) to patient LPS mm.
Vec3 slice_to_world(const SliceStack& stack, double slice_spacing_px, Vec3 p);

/// Millimetres per slice-space pixel for error bounds: the larger in-plane spacing, so an in-plane
/// distance of e px is at most e times this in mm.
double error_mm_per_px(const SliceStack& stack);

/// The frame of slice space (spacing d = `slice_spacing_px`) in patient LPS mm, as
/// slice_to_world maps it, with the error scale of error_mm_per_px.
SliceFrame slice_frame(const SliceStack& stack, double slice_spacing_px);

/// A slice-space surface in patient LPS mm: every position through slice_to_world, triangles
/// reversed when the affine mirrors (negative determinant) so they still face outwards.
TriMesh surface_to_world(const SliceStack& stack, double slice_spacing_px, const TriMesh& mesh);

/// Fills `surface.verification` (see ObjectSurface::Verification) against `stack`'s label.
void verify_surface(const SliceStack& stack, ObjectSurface& surface);

/// The same against the label's reference topology, already computed (reference_topology).
void verify_surface(const ReferenceTopology& reference, ObjectSurface& surface);

/// Everything the pipeline produced, stage by stage.
struct Reconstruction {
    SliceContours contours;
    std::vector<SliceDistanceFields> fields;  ///< one per slice (emptied unless keep_fields)
    std::vector<MedialAxis> medial_axes;      ///< one per consecutive slice pair (if kept)
    std::vector<MedialCounts> medial_counts;  ///< per label with medial axes, sorted by label
    std::vector<ObjectSurface> surfaces;      ///< one closed surface per label, slice space
    std::vector<RepairRecord> repairs;        ///< per surface: the repair steps taken on it
    std::vector<MultiresMesh> models;         ///< per surface (when simplified), slice space
    double slice_spacing_px = 1.0;            ///< d of the slice-space surfaces
    std::vector<StageTiming> timings;
};

/// Runs the pipeline stages in order on `stack` (the only code that knows the stage order).
/// Notes degenerate input in `report`. Throws strata::Error from the stages.
Reconstruction reconstruct(const SliceStack& stack,
                           const ReconstructOptions& options,
                           Report& report);

}  // namespace strata
