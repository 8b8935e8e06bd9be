#pragma once

#include <cstdint>
#include <vector>

namespace strata {

/// The repair steps (pipeline/repair.h: kRepairPolicy) taken on one label's surface, and where.
/// Written by the repair policy alone; read by the summary and the report.
struct RepairRecord {
    std::uint16_t label = 0;
    /// kCornerVertices: slices whose contours of the label were simplified again with vertices
    /// at pixel corners only, and then overlapped their neighbours like the pixels (or went on
    /// to the next step); increasing, none of them in `original_slices`.
    std::vector<std::uint32_t> corner_slices;
    /// kOriginalNearNeighbours: slices where only the simplified edges near a neighbouring
    /// slice's contours went back to their original points; increasing, none of them in
    /// `original_slices` (all of them in `corner_slices`: that was done first).
    std::vector<std::uint32_t> near_neighbour_slices;
    /// kOriginalContours: slices whose contours of the label were used unsimplified;
    /// increasing.
    std::vector<std::uint32_t> original_slices;
    /// kSplitAtAndLayer: slabs split at the pixels' AND layer because even the original
    /// contours overlapped unlike the pixels.
    std::uint32_t split_slabs = 0;
    /// kLabelAtCorners: the label did not snap to a grid with edge-midpoint contours and was
    /// built again from contours with vertices at pixel corners on every slice (the steps
    /// above are those of that rebuild).
    bool rebuilt_at_corners = false;
};

}  // namespace strata
