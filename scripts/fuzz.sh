#!/usr/bin/env bash
# Runs every libFuzzer target under AddressSanitizer + UndefinedBehaviorSanitizer for SECONDS
# each: the progressive glTF reader and the input readers (NIfTI, NIfTI gzip, NRRD, TIFF, PNG).
# Each starts from its saved corpus (tests/fuzz/corpus/<target>, copied; new inputs stay in
# build-fuzz/corpus/<target>) and ends with a line "target: N executions, M findings"; crash
# inputs are kept in build-fuzz/findings/<target>/. Needs clang (Debian's clang package).
#   bash scripts/fuzz.sh SECONDS [TARGET...]   (default: 60 s, every target)
# CI does not fuzz; CTest replays every target's saved corpus (read_*_fuzz_corpus).
set -euo pipefail
cd "$(dirname "$0")/.."
seconds="${1:-60}"
shift || true
all_targets=(read_progressive read_nii read_nii_gz read_nrrd read_tif read_png)
targets=("${@:-${all_targets[@]}}")
if ! command -v clang++ >/dev/null; then
    echo "fuzz.sh: clang++ not found (apt-get install clang)" >&2
    exit 2
fi
export CCACHE_BASEDIR="${CCACHE_BASEDIR:-$PWD/..}"
launcher=()
if command -v ccache >/dev/null; then
    launcher=(-DCMAKE_CXX_COMPILER_LAUNCHER=ccache)
fi
cmake -S . -B build-fuzz -DCMAKE_BUILD_TYPE=RelWithDebInfo -DCMAKE_CXX_COMPILER=clang++ \
    -DSTRATA_BUILD_TESTS=ON -DSTRATA_BUILD_FUZZERS=ON "${launcher[@]}" >/dev/null
cmake --build build-fuzz -j"$(nproc)" --target "${targets[@]/%/_fuzz}"
export ASAN_OPTIONS="${ASAN_OPTIONS:-detect_leaks=1:allocator_may_return_null=1}"
export UBSAN_OPTIONS="${UBSAN_OPTIONS:-print_stacktrace=1:halt_on_error=1}"
# note: OpenImageIO's known leak of its PNG error string (third-party code only), as CTest does
export LSAN_OPTIONS="${LSAN_OPTIONS:-suppressions=$PWD/tests/lsan.supp:print_suppressions=0}"
summary=()
status=0
for target in "${targets[@]}"; do
    corpus="build-fuzz/corpus/$target"
    findings="build-fuzz/findings/$target"
    mkdir -p "$corpus" "$findings"
    cp -n "tests/fuzz/corpus/$target"/* "$corpus"/ 2>/dev/null || true
    log="build-fuzz/fuzz-$target.log"
    set +e
    # note: -rss_limit_mb 4096 as the issue's 4 GB bound; -timeout 20 s per input
    "build-fuzz/tests/${target}_fuzz" "$corpus" -max_total_time="$seconds" -rss_limit_mb=4096 \
        -timeout=20 -artifact_prefix="$findings/" -print_final_stats=1 >"$log" 2>&1
    code=$?
    set -e
    runs=$(grep -o 'stat::number_of_executed_units: *[0-9]*' "$log" | grep -o '[0-9]*$' || echo "?")
    found=$(find "$findings" -type f | wc -l)
    line="$target: $runs executions in ${seconds} s, $found findings (exit $code, log $log)"
    echo "$line"
    summary+=("$line")
    if [ "$found" -ne 0 ] || [ "$code" -ne 0 ]; then
        status=1
    fi
done
printf '%s\n' "${summary[@]}" >build-fuzz/summary.txt
exit "$status"
