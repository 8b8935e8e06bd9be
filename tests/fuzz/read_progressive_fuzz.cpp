// libFuzzer target: the progressive glTF reader on arbitrary bytes (as a .glb; external buffers
// are refused). Every input must end in a result or strata::Error; anything else (a crash, a
// sanitizer report, another exception escaping) is a bug.
//   fuzz:   cmake -B build-fuzz -DCMAKE_CXX_COMPILER=clang++ -DSTRATA_BUILD_FUZZERS=ON && cmake
//   --build
//           build-fuzz --target read_progressive_fuzz && build-fuzz/tests/read_progressive_fuzz
//           tests/fuzz/corpus/read_progressive
//   replay: read_progressive_fuzz_replay FILE|DIR... (built with the tests, run by CTest on the
//           saved corpus)
#include <cstddef>
#include <cstdint>
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
    } catch (const strata::Error&) {
        // rejected with a message: fine
    }
    return 0;
}
