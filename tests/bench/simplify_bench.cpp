// Douglas-Peucker on worst-case spirals: the Hershberger-Snoeyink path hull (simplify_polyline,
// O(n log n)) next to the textbook recursion (O(n^2) when every split peels a few points off
// the end, as on a spiral sampled with few points per turn).
//
//   simplify_bench --benchmark_counters_tabular=true
#include <cmath>
#include <cstdint>
#include <numbers>
#include <span>
#include <utility>
#include <vector>

#include <benchmark/benchmark.h>

#include "contours/simplify_contours.h"

namespace {

using strata::Vec2;

constexpr double kTolerancePx = 0.5;

/// Archimedean spiral with pitch 1 px and 8 points per turn, from the centre outwards: almost
/// every point is kept, and the farthest point from any chord to the outer end lies a quarter
/// turn before that end, so the textbook recursion peels two points per level.
std::vector<Vec2> coarse_spiral(std::size_t n) {
    std::vector<Vec2> points(n);
    for (std::size_t k = 0; k < n; ++k) {
        const double angle = static_cast<double>(k) * std::numbers::pi / 4.0;
        const double radius = 1.0 + static_cast<double>(k) / 8.0;
        points[k] = {radius * std::cos(angle), radius * std::sin(angle)};
    }
    return points;
}

/// Archimedean spiral with pitch 2 px sampled every 0.25 px of arc: a contour-like input where
/// most points go; each split peels about a quarter turn.
std::vector<Vec2> dense_spiral(std::size_t n) {
    std::vector<Vec2> points(n);
    double angle = 0.0;
    for (std::size_t k = 0; k < n; ++k) {
        const double radius = 2.0 + angle / std::numbers::pi;
        points[k] = {radius * std::cos(angle), radius * std::sin(angle)};
        angle += 0.25 / radius;
    }
    return points;
}

/// Textbook Douglas-Peucker (line distance, explicit stack): O(n^2) worst case.
std::vector<std::uint32_t> naive_douglas_peucker(std::span<const Vec2> points, double tolerance) {
    std::vector<std::uint32_t> kept{0};
    std::vector<std::pair<std::uint32_t, std::uint32_t>> stack{
        {0, static_cast<std::uint32_t>(points.size() - 1)}};
    while (!stack.empty()) {
        const auto [i, j] = stack.back();
        stack.pop_back();
        const Vec2 a = points[i];
        const Vec2 d = points[j] - a;
        const double length = strata::norm(d);
        double worst = -1.0;
        std::uint32_t at = i;
        for (std::uint32_t k = i + 1; k < j; ++k) {
            const double distance = std::abs(strata::cross(d, points[k] - a));
            if (distance > worst) {
                worst = distance;
                at = k;
            }
        }
        if (j > i + 1 && worst > tolerance * length) {
            stack.push_back({at, j});
            stack.push_back({i, at});
        } else {
            kept.push_back(j);
        }
    }
    return kept;
}

template <std::vector<Vec2> (*Make)(std::size_t), bool kNaive>
void simplify_spiral(benchmark::State& state) {
    const std::vector<Vec2> points = Make(static_cast<std::size_t>(state.range(0)));
    std::size_t kept = 0;
    for (auto _ : state) {
        const std::vector<std::uint32_t> result =
            kNaive ? naive_douglas_peucker(points, kTolerancePx)
                   : strata::simplify_polyline(points, kTolerancePx);
        kept = result.size();
        benchmark::DoNotOptimize(result.data());
    }
    state.counters["points/s"] = benchmark::Counter(static_cast<double>(points.size()),
                                                    benchmark::Counter::kIsIterationInvariantRate);
    state.counters["kept"] = static_cast<double>(kept);
}

BENCHMARK(simplify_spiral<coarse_spiral, false>)
    ->Name("path_hull/coarse_spiral")
    ->RangeMultiplier(10)
    ->Range(1000, 1000000)
    ->Unit(benchmark::kMillisecond);
BENCHMARK(simplify_spiral<coarse_spiral, true>)
    ->Name("naive/coarse_spiral")
    ->RangeMultiplier(10)
    ->Range(1000, 100000)
    ->Unit(benchmark::kMillisecond);
BENCHMARK(simplify_spiral<dense_spiral, false>)
    ->Name("path_hull/dense_spiral")
    ->RangeMultiplier(10)
    ->Range(1000, 1000000)
    ->Unit(benchmark::kMillisecond);
BENCHMARK(simplify_spiral<dense_spiral, true>)
    ->Name("naive/dense_spiral")
    ->RangeMultiplier(10)
    ->Range(1000, 100000)
    ->Unit(benchmark::kMillisecond);

}  // namespace

BENCHMARK_MAIN();
