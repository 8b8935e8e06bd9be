// libFuzzer target: the progressive glTF reader (STRATA_progressive_mesh version 3) on arbitrary
// bytes (as a .glb; external buffers are refused). Only crashes, sanitizer reports, timeouts and
// memory beyond libFuzzer's limit are findings: every exception is caught here (that the reader
// throws nothing but strata::Error with a JSON pointer is checked by read_progressive_gltf_test).
// Seeds: tests/fuzz/corpus/read_progressive, made structure-aware by ReadProgressiveGltfSeeds
// (a valid file and one variant per class of damage; STRATA_FUZZ_SEED_DIR=DIR exporters_test
// --gtest_filter=ReadProgressiveGltfSeeds.*).
//   fuzz:   cmake -B build-fuzz -DCMAKE_CXX_COMPILER=clang++ -DSTRATA_BUILD_FUZZERS=ON && cmake
//   --build
//           build-fuzz --target read_progressive_fuzz && build-fuzz/tests/read_progressive_fuzz
//           tests/fuzz/corpus/read_progressive
//   replay: read_progressive_fuzz_replay FILE|DIR... (built with the tests, run by CTest on the
//           saved corpus)
#include <cstddef>
#include <cstdint>
#include <exception>
#include <string>
#include <string_view>

#include "core/error.h"
#include "exporters/read_progressive_gltf.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    try {
        const strata::ProgressiveFile file = strata::read_progressive_gltf(
            std::string_view(reinterpret_cast<const char*>(data), size), "fuzz.glb",
            [](const std::string& uri) -> std::string {
                throw strata::Error(strata::ErrorCode::Io, "external buffer " + uri + " refused");
            });
        // use what was read: every level cut of every object
        for (const strata::ProgressiveFileObject& object : file.objects) {
            for (std::uint32_t level = 0; level < strata::level_count(object.model); ++level) {
                (void)strata::cut_mesh(object.model,
                                       strata::select_cut_at_level(object.model, level));
            }
        }
    } catch (const std::exception&) {
        // rejected (strata::Error, with a message): fine
    }
    return 0;
}
