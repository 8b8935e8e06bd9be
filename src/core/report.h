#pragma once

#include <string>
#include <vector>

namespace strata {

/// One structured warning: legal but noteworthy input or a fallback a stage took.
struct Warning {
    std::string stage;    ///< pipeline stage that noticed it ("input", "contours", ...)
    std::string where;    ///< slice, label, file ... ("slice 17 (scan_017.png)")
    std::string message;  ///< what happened and what strata did about it
};

/// Warnings collected along the pipeline (tinygltf's separate `warn`, structured).
struct Report {
    std::vector<Warning> warnings;

    void warn(std::string stage, std::string where, std::string message) {
        warnings.push_back({std::move(stage), std::move(where), std::move(message)});
    }
};

}  // namespace strata
