// libFuzzer targets: the input readers (NIfTI, NRRD, TIFF and PNG slices) on arbitrary bytes,
// written to a file named for the format (the readers take paths). Every input must end in a
// stack or a strata::Error; a crash, a sanitizer report, a hang or another exception escaping is a
// finding. STRATA_FUZZ_FORMAT picks the file name at compile time: nii, nii.gz, nrrd, tif, png.
//   fuzz:   scripts/fuzz.sh SECONDS (every target, ASan + UBSan)
//   replay: read_input_fuzz_replay_<format> FILE|DIR... (built with the tests; CTest replays
//           tests/fuzz/corpus/read_<format>)
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <string>
#include <unistd.h>

#include "core/error.h"
#include "input/read_slice_stack.h"

#ifndef STRATA_FUZZ_FORMAT
#error "define STRATA_FUZZ_FORMAT (nii, nii.gz, nrrd, tif or png)"
#endif

namespace {

/// A per-process file for the inputs (in /dev/shm when there is one: no disk writes).
const std::filesystem::path& input_file() {
    static const std::filesystem::path file = [] {
        const std::filesystem::path dir =
            std::filesystem::is_directory("/dev/shm") ? "/dev/shm" : "/tmp";
        return dir / ("strata-fuzz-" + std::to_string(::getpid()) + "." STRATA_FUZZ_FORMAT);
    }();
    return file;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    const std::filesystem::path& file = input_file();
    {
        std::ofstream out(file, std::ios::binary | std::ios::trunc);
        out.write(reinterpret_cast<const char*>(data), static_cast<std::streamsize>(size));
    }
    strata::ReadOptions options;
    // note: stacks up to 64 MiB of labels; larger claims are refused like the 8 GiB default
    options.max_bytes = std::uint64_t(64) << 20;
    strata::Report report;
    try {
        const strata::SliceStack stack = strata::read_slice_stack(file, options, report);
        // use what was read
        volatile std::size_t labelled = 0;
        for (const std::uint16_t v : stack.labels) {
            labelled = labelled + (v != 0 ? 1 : 0);
        }
    } catch (const strata::Error&) {
        // rejected with a message: fine
    }
    return 0;
}
