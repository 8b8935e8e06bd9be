// Distance stage throughput: compute_distance_field (one thread) on single-slice masks of 512 x 512
// and 2048 x 2048: a disc, a union of random discs, and the T06 spiral (slice 0, scaled up by
// pixel replication). Counters: Mnode/s (half-pixel grid nodes, 4x the pixels) and Mpixel/s (the
// window's pixels: the label's box plus the 4 px margin, which is what the field covers).
//
// Peer comparison: with STRATA_BENCH_MASK_DIR set, every window mask is written there as raw
// uint8 (`<name>_<width>x<height>.u8`, row-major, 1 = label) so that
// scripts/bench_distance_peer.py can time scipy.ndimage.distance_transform_edt on exactly the same
// pixels. Run both with scripts/bench-distance.sh.

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <fstream>
#include <random>
#include <string>
#include <vector>

#include <benchmark/benchmark.h>

#include "contours/extract_contours.h"
#include "distance/distance_field.h"
#include "phantom/catalogue.h"

namespace strata {
namespace {

struct BenchMask {
    std::string name;
    SliceStack stack;
    SliceContourSet contours;
};

SliceStack empty_slice(std::uint32_t size) {
    SliceStack s;
    s.width = size;
    s.height = size;
    s.depth = 1;
    s.labels.assign(s.slice_size(), 0);
    return s;
}

SliceStack disc(std::uint32_t size) {
    SliceStack s = empty_slice(size);
    const double c = 0.5 * size;
    const double r = 0.45 * size;
    for (std::uint32_t j = 0; j < size; ++j) {
        for (std::uint32_t i = 0; i < size; ++i) {
            if (std::hypot(i + 0.5 - c, j + 0.5 - c) <= r) {
                s.labels[std::size_t(j) * size + i] = 1;
            }
        }
    }
    return s;
}

SliceStack blobs(std::uint32_t size) {
    SliceStack s = empty_slice(size);
    std::mt19937 rng(42);
    std::uniform_real_distribution<double> centre(0.1 * size, 0.9 * size);
    std::uniform_real_distribution<double> radius(0.02 * size, 0.1 * size);
    for (int n = 0; n < 60; ++n) {
        const double cx = centre(rng);
        const double cy = centre(rng);
        const double r = radius(rng);
        const auto j0 = static_cast<std::uint32_t>(std::max(0.0, cy - r));
        const auto j1 = static_cast<std::uint32_t>(std::min<double>(size, cy + r + 1));
        const auto i0 = static_cast<std::uint32_t>(std::max(0.0, cx - r));
        const auto i1 = static_cast<std::uint32_t>(std::min<double>(size, cx + r + 1));
        for (std::uint32_t j = j0; j < j1; ++j) {
            for (std::uint32_t i = i0; i < i1; ++i) {
                if (std::hypot(i + 0.5 - cx, j + 0.5 - cy) <= r) {
                    s.labels[std::size_t(j) * size + i] = 1;
                }
            }
        }
    }
    return s;
}

SliceStack spiral(std::uint32_t size) {
    const Phantom t06 = make_phantom("t06_spiral");
    const SliceStack& p = t06.stack;
    SliceStack s = empty_slice(size);
    for (std::uint32_t j = 0; j < size; ++j) {
        for (std::uint32_t i = 0; i < size; ++i) {
            const std::uint32_t pi = std::uint32_t(std::uint64_t(i) * p.width / size);
            const std::uint32_t pj = std::uint32_t(std::uint64_t(j) * p.height / size);
            s.labels[std::size_t(j) * size + i] = p.at(pi, pj, 0) != 0 ? 1 : 0;
        }
    }
    return s;
}

/// Writes the field's window of the mask (pixels outside the image are 0) for the peer script.
void write_window_mask(const BenchMask& m, const DistanceField& f, const std::string& dir) {
    const std::int64_t pw = (f.nx - 1) / 2;
    const std::int64_t ph = (f.ny - 1) / 2;
    std::vector<std::uint8_t> mask(std::size_t(pw * ph), 0);
    for (std::int64_t y = 0; y < ph; ++y) {
        for (std::int64_t x = 0; x < pw; ++x) {
            const std::int64_t ix = x + std::int64_t(f.origin_x);
            const std::int64_t iy = y + std::int64_t(f.origin_y);
            if (ix >= 0 && iy >= 0 && ix < m.stack.width && iy < m.stack.height) {
                mask[std::size_t(y * pw + x)] =
                    m.stack.at(std::uint32_t(ix), std::uint32_t(iy), 0) == 1;
            }
        }
    }
    const std::string path =
        dir + "/" + m.name + "_" + std::to_string(pw) + "x" + std::to_string(ph) + ".u8";
    std::ofstream(path, std::ios::binary)
        .write(reinterpret_cast<const char*>(mask.data()), std::streamsize(mask.size()));
}

void run(benchmark::State& state, const BenchMask& m) {
    const DistanceOptions options;  // margin 4 px
    DistanceField field = compute_distance_field(m.stack, m.contours, 0, 1, options);
    if (const char* dir = std::getenv("STRATA_BENCH_MASK_DIR")) {
        write_window_mask(m, field, dir);
    }
    // the field and every signed distance decoded into one array: what scipy's call returns
    // (distances and indices), though strata stores only sites and sides (DistanceField)
    std::vector<float> distances;
    for (auto _ : state) {
        field = compute_distance_field(m.stack, m.contours, 0, 1, options);
        distances.resize(std::size_t(field.nx) * field.ny);
        for (std::uint32_t j = 0; j < field.ny; ++j) {
            field.distance_row(j, 0, field.nx, distances.data() + std::size_t(j) * field.nx);
        }
        benchmark::DoNotOptimize(distances.data());
    }
    const double nodes = double(field.nx) * field.ny;
    const double pixels = double((field.nx - 1) / 2) * ((field.ny - 1) / 2);
    const double iterations = double(state.iterations());
    state.counters["Mnode/s"] =
        benchmark::Counter(nodes * iterations / 1e6, benchmark::Counter::kIsRate);
    state.counters["Mpixel/s"] =
        benchmark::Counter(pixels * iterations / 1e6, benchmark::Counter::kIsRate);
    state.counters["pixels"] = pixels;
    state.counters["sites"] = double(field.sites.size());
}

const std::vector<BenchMask>& masks() {
    static const std::vector<BenchMask> all = [] {
        std::vector<BenchMask> list;
        for (std::uint32_t size : {512u, 2048u}) {
            const std::string suffix = "_" + std::to_string(size);
            list.push_back({"disc" + suffix, disc(size), {}});
            list.push_back({"blobs" + suffix, blobs(size), {}});
            list.push_back({"spiral" + suffix, spiral(size), {}});
        }
        for (BenchMask& m : list) {
            m.contours = trace_slice_contours(m.stack, 0, {1});
        }
        return list;
    }();
    return all;
}

}  // namespace
}  // namespace strata

int main(int argc, char** argv) {
    for (const strata::BenchMask& m : strata::masks()) {
        benchmark::RegisterBenchmark(("distance_field/" + m.name).c_str(),
                                     [&m](benchmark::State& state) { strata::run(state, m); })
            ->Unit(benchmark::kMillisecond)
            ->UseRealTime();
    }
    benchmark::Initialize(&argc, argv);
    if (benchmark::ReportUnrecognizedArguments(argc, argv)) {
        return 1;
    }
    benchmark::RunSpecifiedBenchmarks();
    benchmark::Shutdown();
    return 0;
}
