#pragma once

#include <array>
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "input/slice_stack.h"
#include "phantom/solids.h"

namespace strata {

// The synthetic test stacks of docs/test-catalogue.md (T01 ... T36), plus a few
// friendly demos for the CLI. Every case is generated from its description alone: solids are
// rasterised at pixel centres (pixel (i, j) of slice k is foreground iff (i + 0.5, j + 0.5,
// k * d) is inside), seeded cases replay numpy's default_rng draws exactly.

/// Topology the catalogue states for a case (hand-computed; the reference labeller of the
/// volume R must agree). Counts are for all non-zero labels taken together.
struct ExpectedTopology {
    std::uint32_t surfaces = 0;          ///< number of surface components
    std::vector<std::uint32_t> genus;    ///< genus of each surface, sorted in decreasing order
    std::uint32_t solid_components = 0;  ///< number of foreground components of R
};

/// One object of a phantom: which label it is drawn with and its analytic ground truth.
struct PhantomObject {
    std::uint16_t label = 1;     ///< label value in the stack (several objects may share one)
    std::string name;            ///< "sphere", "island", ...
    std::optional<Solid> solid;  ///< the analytic solid S (px); nullopt for slice-defined cases
    bool gt_applies = true;      ///< false where the catalogue excludes the `gt` metric
};

/// What a seeded case drew.
struct PhantomDraws {
    std::uint64_t seed = 0;
    std::uint64_t drawn = 0;     ///< T33: candidate balls; T35: pixels drawn; T36: attempts
    std::uint64_t accepted = 0;  ///< T33: balls kept; T35: pixels flipped; T36: 1
};

/// A generated test stack with its ground truth.
struct Phantom {
    std::string name;          ///< the name it was made from ("t01_sphere", "scene")
    std::string catalogue_id;  ///< "T01" ...; empty for the demos that are not catalogue cases
    std::string description;   ///< one line: what the generator draws
    SliceStack stack;          ///< labels; index_to_world = diag(pixel_mm, pixel_mm, d * pixel_mm)
    double slice_spacing_px = 1.0;  ///< d: slice k lies at z = k * d px
    double pixel_mm = 1.0;          ///< in-plane pixel size, mm
    bool slice_defined = false;     ///< masks given directly (T16, T24, T35): no analytic S
    std::vector<PhantomObject> objects;
    /// The catalogue's expectation; nullopt when resampled at another slice spacing or drawn
    /// with another seed where the catalogue does not say what to expect.
    std::optional<ExpectedTopology> expected;
    std::optional<PhantomDraws> draws;  ///< seeded cases only
};

/// How to generate a phantom.
struct PhantomOptions {
    /// In-plane pixel size in mm; unset: the catalogue's (0.8 mm for T36, else 1.0 mm).
    std::optional<double> pixel_mm;
    /// Slice spacing d in px; unset: the catalogue's. With another value the same solid is
    /// resampled over the same z extent [0, (K - 1) d]: K' = floor((K - 1) d / d') + 1 slices
    /// at z = k d'. Slice-defined cases (T16, T24, T35) refuse it.
    std::optional<double> slice_spacing_px;
    /// Seed of the cases that draw (T33, T35, T36); unset: the catalogue's (1234, 7, 36).
    std::optional<std::uint64_t> seed;
};

/// All phantom names: the catalogue cases in order ("t01_sphere" ... "t36_organ_like", variants
/// as separate names), then the demos ("sphere", "ellipsoid", "torus", "branching",
/// "hollow_sphere", "scene").
std::vector<std::string> phantom_names();

/// Phantoms for the benchmarks, not in phantom_names(): "whole_body" (phantom/whole_body.h,
/// 512 x 512 x 1000, 117 labels; a few seconds to generate, 250 MiB of labels).
std::vector<std::string> benchmark_phantom_names();

/// Generates the named phantom. T32 (4096 x 4096 x 10, 320 MiB of labels) and T36 (runs the
/// catalogue's acceptance test on each attempt) take about a second; the others milliseconds.
/// \throw Error{InvalidInput} for an unknown name (listing the valid ones), a non-positive or
///        non-finite pixel size or spacing, a spacing override on a slice-defined case, a
///        resampled stack too large for memory, or a seed for which T36 accepts no attempt.
Phantom make_phantom(std::string_view name, const PhantomOptions& options = {});

/// numpy.random.default_rng(seed), reimplemented: PCG64 (XSL-RR 128/64) seeded through
/// numpy's SeedSequence, doubles as (next_uint64 >> 11) * 2^-53. Used by the seeded cases so
/// that every draw matches the catalogue's Python description exactly.
class NumpyRandom {
public:
    explicit NumpyRandom(std::uint64_t seed);

    /// The next raw 64-bit output (numpy's bit_generator.random_raw()).
    std::uint64_t next_uint64();
    /// Uniform double in [0, 1) (Generator.random()).
    double random();
    /// low + (high - low) * random() (Generator.uniform).
    double uniform(double low, double high);

private:
    std::array<std::uint64_t, 2> state_{};      ///< 128-bit state, {high, low}
    std::array<std::uint64_t, 2> increment_{};  ///< 128-bit odd increment, {high, low}
};

}  // namespace strata
