#!/usr/bin/env bash
# README command 1: install dependencies, build, and run `strata build` on the built-in phantom.
# Outputs go to ./out (override: OUT=dir bash scripts/demo.sh).
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/install-deps.sh
jobs=$(nproc)
export CCACHE_BASEDIR="$PWD"  # see scripts/test.sh
cmake -S . -B build -DCMAKE_BUILD_TYPE=Release -DCMAKE_CXX_COMPILER_LAUNCHER=ccache >/dev/null
cmake --build build --target strata_cli -j"$jobs"
./build/strata build -o "${OUT:-out}"
