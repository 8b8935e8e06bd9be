#include "input/label_map_check.h"

#include <cstdint>
#include <cstdio>
#include <vector>

#include "core/error.h"

namespace strata {

LabelMapStatistics label_map_statistics(const SliceStack& stack) {
    LabelMapStatistics s;
    std::vector<std::uint64_t> pixels(65536, 0);
    std::vector<std::uint64_t> isolated(65536, 0);
    std::uint64_t pairs = 0;
    std::uint64_t agreeing = 0;
    const std::uint32_t w = stack.width;
    const std::uint32_t h = stack.height;
    for (std::uint32_t k = 0; k < stack.depth; ++k) {
        const auto slice = stack.slice(k);
        for (std::uint32_t j = 0; j < h; ++j) {
            const std::uint16_t* row = slice.data() + std::size_t(j) * w;
            const std::uint16_t* above = j > 0 ? row - w : nullptr;
            const std::uint16_t* below = j + 1 < h ? row + w : nullptr;
            for (std::uint32_t i = 0; i < w; ++i) {
                const std::uint16_t v = row[i];
                // note: each pair counted once, from its left or upper pixel
                if (i + 1 < w && (v != 0 || row[i + 1] != 0)) {
                    ++pairs;
                    agreeing += v == row[i + 1];
                }
                if (below != nullptr && (v != 0 || below[i] != 0)) {
                    ++pairs;
                    agreeing += v == below[i];
                }
                if (v == 0) {
                    continue;
                }
                ++pixels[v];
                const bool alone = (i == 0 || row[i - 1] != v) && (i + 1 == w || row[i + 1] != v) &&
                                   (above == nullptr || above[i] != v) &&
                                   (below == nullptr || below[i] != v);
                isolated[v] += alone;
            }
        }
    }
    std::uint64_t all_isolated = 0;
    std::size_t speckled = 0;
    for (std::size_t v = 1; v < pixels.size(); ++v) {
        if (pixels[v] == 0) {
            continue;
        }
        ++s.labels;
        s.foreground_pixels += pixels[v];
        all_isolated += isolated[v];
        speckled += 2 * isolated[v] > pixels[v];
    }
    if (pairs > 0) {
        s.neighbour_agreement = double(agreeing) / double(pairs);
    }
    if (s.foreground_pixels > 0) {
        s.isolated_share = double(all_isolated) / double(s.foreground_pixels);
    }
    if (s.labels > 0) {
        s.speckled_label_share = double(speckled) / double(s.labels);
    }
    return s;
}

namespace {

// note: the thresholds leave wide margins on both sides (measured by label_map_check_test): the
// shared data's label maps have neighbour agreement 0.81 (FreeSurfer, 188 labels) to 0.96 and at
// most 2.4 % speckled labels; greyscale pictures of 96 x 96 x 8 with noise of +-4..40 grey
// levels have 206..255 labels, agreement 0.09..0.01 and every label speckled
constexpr std::size_t kManyLabels = 64;
constexpr double kMaxAgreement = 0.5;
constexpr double kMinSpeckledLabels = 0.5;

}  // namespace

std::optional<std::string> intensity_image_evidence(const LabelMapStatistics& s) {
    if (s.labels < kManyLabels || s.neighbour_agreement >= kMaxAgreement ||
        s.speckled_label_share < kMinSpeckledLabels) {
        return std::nullopt;
    }
    char text[256];
    std::snprintf(text, sizeof(text),
                  "%zu labels, %.0f %% of them speckled (most of their pixels share the value "
                  "with no neighbour), and only %.0f %% of neighbouring pixels agree (a label map "
                  "has over %.0f %%)",
                  s.labels, 100.0 * s.speckled_label_share, 100.0 * s.neighbour_agreement,
                  100.0 * kMaxAgreement);
    return std::string(text);
}

void check_is_label_map(const SliceStack& stack) {
    const std::optional<std::string> evidence =
        intensity_image_evidence(label_map_statistics(stack));
    if (evidence) {
        throw Error(ErrorCode::InvalidInput,
                    stack.source +
                        ": looks like an intensity image, not a label map: " + *evidence +
                        "; expected one value per object. Give the objects' values with --labels "
                        "(e.g. --labels 1,2), segment or threshold the image first, or give "
                        "--force-label-map to build every value as an object");
    }
}

}  // namespace strata
