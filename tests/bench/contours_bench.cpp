// Contour extraction throughput on a 512 x 512 x 300 label map (five labelled ellipsoids).
// Run: build with -DSTRATA_BUILD_BENCHMARKS=ON, then ./build/tests/bench/contours_bench

#include <cmath>

#include <benchmark/benchmark.h>

#include "contours/extract_contours.h"

namespace strata {
namespace {

const SliceStack& label_map() {
    static const SliceStack stack = [] {
        SliceStack s;
        s.width = 512;
        s.height = 512;
        s.depth = 300;
        s.labels.assign(s.slice_size() * s.depth, 0);
        struct Blob {
            double cx, cy, cz, rx, ry, rz;
            std::uint16_t label;
        };
        const Blob blobs[] = {{256, 256, 150, 200, 150, 140, 1},
                              {180, 200, 120, 60, 80, 90, 2},
                              {330, 300, 170, 70, 50, 100, 3},
                              {256, 120, 60, 40, 40, 50, 4},
                              {256, 400, 240, 90, 30, 50, 5}};
        for (std::uint32_t k = 0; k < s.depth; ++k) {
            for (std::uint32_t j = 0; j < s.height; ++j) {
                for (std::uint32_t i = 0; i < s.width; ++i) {
                    for (const Blob& b : blobs) {
                        const double x = (i + 0.5 - b.cx) / b.rx;
                        const double y = (j + 0.5 - b.cy) / b.ry;
                        const double z = (k - b.cz) / b.rz;
                        // wobbly surfaces so that contours are not all smooth conics
                        if (x * x + y * y + z * z <= 1.0 + 0.05 * std::sin(7 * x + 5 * y + 3 * z)) {
                            s.labels[(std::size_t(k) * s.height + j) * s.width + i] = b.label;
                        }
                    }
                }
            }
        }
        complete_label_table(s);
        return s;
    }();
    return stack;
}

void BM_TraceSlices(benchmark::State& state) {
    const SliceStack& s = label_map();
    const std::vector<std::uint16_t> labels = {1, 2, 3, 4, 5};
    for (auto _ : state) {
        std::size_t contours = 0;
        for (std::uint32_t k = 0; k < s.depth; ++k) {
            contours += trace_slice_contours(s, k, labels).contours.size();
        }
        benchmark::DoNotOptimize(contours);
    }
    state.counters["Mpixel/s"] =
        benchmark::Counter(static_cast<double>(s.labels.size()) * state.iterations() / 1e6,
                           benchmark::Counter::kIsRate);
}
BENCHMARK(BM_TraceSlices)->Unit(benchmark::kMillisecond)->UseRealTime();

void BM_ExtractContours(benchmark::State& state) {
    const SliceStack& s = label_map();
    ContourOptions options;
    options.threads = static_cast<unsigned>(state.range(0));
    for (auto _ : state) {
        benchmark::DoNotOptimize(extract_contours(s, options));
    }
    state.counters["Mpixel/s"] =
        benchmark::Counter(static_cast<double>(s.labels.size()) * state.iterations() / 1e6,
                           benchmark::Counter::kIsRate);
}
BENCHMARK(BM_ExtractContours)->Arg(1)->Arg(2)->Unit(benchmark::kMillisecond)->UseRealTime();

}  // namespace
}  // namespace strata

BENCHMARK_MAIN();
