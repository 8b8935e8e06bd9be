// Groups reach the keep fraction (issue 24): MultiresOptions::keep_fraction is where a group's
// simplification stops when its error budget does not stop it first. The budget and reference
// tests (budget_test.cpp) hold the errors and the triangles at a bound, which a group stopping at
// 60 % instead of 20 % of its triangles still fits after re-measured references; here, with a
// budget too large to bind, the triangles each group produces are counted against the triangles
// it consumes, for two keep fractions.
#include <algorithm>
#include <cstdint>
#include <iostream>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "core/report.h"
#include "phantom/catalogue.h"
#include "pipeline/reconstruct.h"
#include "simplify/multires_dag.h"

namespace strata {
namespace {

std::size_t triangles_of(const MultiresMesh& m, const std::vector<std::uint32_t>& clusters) {
    std::size_t n = 0;
    for (const std::uint32_t c : clusters) {
        n += m.clusters[c].triangles.size();
    }
    return n;
}

/// Per group: triangles produced / triangles consumed, every model of `name` built with
/// `keep_fraction` and an error schedule that does not bind.
std::vector<double> group_ratios(const std::string& name, double keep_fraction) {
    ReconstructOptions options;
    options.multires.cluster_triangles = 256;
    options.multires.root_triangles = 32;
    options.multires.keep_fraction = keep_fraction;
    // note: each level may grow the error a millionfold: the fraction, not the budget, stops
    options.multires.error_growth = 1e6;
    Report report;
    const Reconstruction r = reconstruct(make_phantom(name).stack, options, report);
    std::vector<double> ratios;
    for (const MultiresMesh& m : r.models) {
        for (const MultiresGroup& g : m.groups) {
            ratios.push_back(double(triangles_of(m, g.produced)) /
                             double(triangles_of(m, g.consumed)));
        }
    }
    return ratios;
}

TEST(SimplifyKeepFraction, GroupsReachTheKeepFractionWhenTheBudgetAllows) {
    for (const std::string name : {"sphere", "torus"}) {
        for (const double keep : {0.2, 0.5}) {
            SCOPED_TRACE(name + ", keep_fraction " + std::to_string(keep));
            std::vector<double> ratios = group_ratios(name, keep);
            ASSERT_GE(ratios.size(), 4u);
            std::sort(ratios.begin(), ratios.end());
            const double median = ratios[ratios.size() / 2];
            std::cout << name << " keep " << keep << ": " << ratios.size()
                      << " groups, produced / consumed triangles min " << ratios.front()
                      << ", median " << median << ", max " << ratios.back() << "\n";
            // a collapse removes two triangles, so a group stops within two of its target;
            // borders locked against neighbouring groups may stop a few groups early, not most
            EXPECT_LE(median, keep + 0.05);
            EXPECT_GE(median, keep - 0.05);
        }
    }
}

}  // namespace
}  // namespace strata
