#!/usr/bin/env bash
# README command 2: install dependencies, build, and run the whole test suite through CTest.
#   bash scripts/test.sh              Release build in ./build
#   bash scripts/test.sh --sanitize   AddressSanitizer + UndefinedBehaviorSanitizer in ./build-asan
# Also installs what only the tests need: Debian's chromium (install-deps --tests) and the npm
# packages of tests/node, tests/babylon and web-viewer, as locked.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/install-deps.sh --tests
# npm packages of the node tests (the Khronos glTF validator), exactly as locked; npm ci writes
# node_modules/.package-lock.json, so reinstall when it is missing or older than the lock file.
if [ ! -f tests/node/node_modules/.package-lock.json ] ||
    [ tests/node/package-lock.json -nt tests/node/node_modules/.package-lock.json ]; then
    echo "test: npm ci in tests/node"
    (cd tests/node && npm ci --no-audit --no-fund)
fi
# the LOD file's Babylon.js test (tests/babylon: @babylonjs/core, @babylonjs/loaders, draco3d), likewise
if [ ! -f tests/babylon/node_modules/.package-lock.json ] ||
    [ tests/babylon/package-lock.json -nt tests/babylon/node_modules/.package-lock.json ]; then
    echo "test: npm ci in tests/babylon"
    (cd tests/babylon && npm ci --no-audit --no-fund)
fi
# the web viewer's npm packages (three.js, draco3d, playwright-core), likewise
if [ ! -f web-viewer/node_modules/.package-lock.json ] ||
    [ web-viewer/package-lock.json -nt web-viewer/node_modules/.package-lock.json ]; then
    echo "test: npm ci in web-viewer"
    (cd web-viewer && npm ci --no-audit --no-fund)
fi
jobs=$(nproc)
if [ "${1:-}" = "--sanitize" ]; then
    dir=build-asan
    # -g1: line tables only (the sanitizers' stack traces keep file:line and inlined frames);
    # full -g made each object 2-3 times larger and its compile about a fifth slower
    flags=(-DCMAKE_BUILD_TYPE=RelWithDebInfo -DSTRATA_SANITIZE=ON
        "-DCMAKE_CXX_FLAGS_RELWITHDEBINFO=-O2 -g1 -DNDEBUG" -DSTRATA_SLOW_TESTS=OFF)
    export ASAN_OPTIONS=detect_leaks=1:abort_on_error=1
    export UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1
    export LSAN_OPTIONS="suppressions=$PWD/tests/lsan.supp:print_suppressions=0"
    # the Release run covers the full property iterations; keep the sanitizer run short
    export STRATA_PROPERTY_ITERATIONS="${STRATA_PROPERTY_ITERATIONS:-200}"
    # label `slow` (the 188-label parcellation end to end) runs in the Release build only, and so
    # do the two longest tests under the sanitizers (3.5 min of CPU there: every shared-data input
    # through the CLI, whose readers the SharedData tests cover, and the 1-vs-2-thread comparison)
    # Label `node` (the validator, three.js, Babylon.js and the viewer in Chromium: JavaScript
    # reading the files strata writes) runs in the Release run only: the sanitized strata still
    # writes those files here (their fixture set-ups are `unit`), and the same sources write them
    # in Release, where every one is checked.
    ctest_args=(-LE "^(slow|node)$"
        -E "^(Cli\.BuildReadsEverySharedDataInput|Surface\.IdenticalForAnyThreadCount)$")
else
    dir=build
    flags=(-DCMAKE_BUILD_TYPE=Release)
    ctest_args=()
fi
# ccache (installed by install-deps) keeps compiled objects between runs and checkouts; paths are
# hashed relative to the checkout, so another clone of the same sources reuses them
export CCACHE_BASEDIR="$PWD" CCACHE_NOHASHDIR=1
cmake -S . -B "$dir" -DSTRATA_BUILD_TESTS=ON -DSTRATA_WERROR=ON -DCMAKE_CXX_COMPILER_LAUNCHER=ccache \
    "${flags[@]}" >/dev/null
cmake --build "$dir" -j"$jobs"
ctest --test-dir "$dir" --output-on-failure -j"$jobs" "${ctest_args[@]}"
