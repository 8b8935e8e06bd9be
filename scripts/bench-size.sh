#!/usr/bin/env bash
# Size of the progressive glTF against its peers (issue 7), side by side in one run, and the
# cluster-size sweep of DESIGN.md section 4. For each case (phantoms and files of
# ../shared/data, every label an object, as `strata build` does) tests/bench/progressive_size
# reconstructs the surfaces, writes the progressive model.glb and reports its total bytes (= bytes
# to full resolution), base bytes and level-0 chunk bytes against
#   Draco     single-rate Draco of each object's full-resolution mesh, with the encoder settings
#             and the lossless grid quantization of our chunks (raw bytes, POSITION + NORMAL and
#             POSITION only, and a minimal .glb of them);
#   gltfpack  npm gltfpack (meshoptimizer, WASM) on the plain full-resolution scene.glb, -cc and
#             -cc -vp B with B bits matching our grid's in-plane resolution;
# then where our bytes go (positions, normals, _COARSE_POSITION, JSON, base) and the sweep of
# cluster sizes (total bytes, bytes to full resolution, ratio to single-rate Draco, chunk size).
#   bash scripts/bench-size.sh [--quick] [--build-dir DIR] [--keep DIR]
#     --quick          one case (torus), sweep of 512 and 1024 on it
#     --build-dir DIR  build there (default: build-bench in the repository; BUILD_DIR also works)
#     --keep DIR       keep the written files (model.glb, scene.glb, draco.glb, gltfpack output
#                      and the sweep's models) in DIR (default: a temp folder, removed)
# Needs Node.js with npm (installed from Debian when missing and running as root) and the npm
# package gltfpack, installed exactly as locked into scripts/node-bench (npm ci) when missing.
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
build="${BUILD_DIR:-$root/build-bench}"
data="$root/../shared/data"
cases=(phantom:sphere phantom:torus phantom:t36_organ_like phantom:scene
       "stack:$data/niivue_torso/torsoLabel.nii.gz"
       "stack:$data/totalsegmentator_abdomen/example_seg.nii.gz"
       "stack:$data/pyradiomics_lung_tumor/lung2_label.nrrd"
       "stack:$data/freesurfer_aparc_aseg/slices")
sweep_cases=(phantom:t36_organ_like "stack:$data/niivue_torso/torsoLabel.nii.gz"
             "stack:$data/totalsegmentator_abdomen/example_seg.nii.gz")
sweep=256,512,1024,2048,4096
keep=""
while [[ $# -gt 0 ]]; do
    case "$1" in
        --quick) cases=(phantom:torus); sweep_cases=(phantom:torus); sweep=512,1024 ;;
        --build-dir) build="$2"; shift ;;
        --keep) keep="$2"; shift ;;
        -h|--help) awk 'NR > 1 && !/^#/ { exit } NR > 1 { sub(/^# ?/, ""); print }' "$0"; exit 0 ;;
        *) echo "bench-size: unknown argument $1 (see --help)" >&2; exit 2 ;;
    esac
    shift
done

if ! command -v npm >/dev/null; then
    if [[ $(id -u) -eq 0 ]] && command -v apt-get >/dev/null; then
        echo "bench-size: installing nodejs npm" >&2
        DEBIAN_FRONTEND=noninteractive apt-get install -y -qq nodejs npm >/dev/null
    else
        echo "bench-size: missing npm: apt-get install nodejs npm" >&2
        exit 1
    fi
fi
# npm ci writes node_modules/.package-lock.json: reinstall when missing or older than the lock
node_bench="$root/scripts/node-bench"
if [[ ! -f "$node_bench/node_modules/.package-lock.json" ]] ||
    [[ "$node_bench/package-lock.json" -nt "$node_bench/node_modules/.package-lock.json" ]]; then
    echo "bench-size: npm ci in scripts/node-bench" >&2
    (cd "$node_bench" && npm ci --no-audit --no-fund >/dev/null)
fi
gltfpack="$node_bench/node_modules/.bin/gltfpack"

configure=(-DCMAKE_BUILD_TYPE=Release -DSTRATA_BUILD_BENCHMARKS=ON)
if [[ ! -f "$build/CMakeCache.txt" ]]; then
    configure+=(-DSTRATA_BUILD_TESTS=OFF)  # a fresh bench build needs no test suite
fi
cmake -S "$root" -B "$build" "${configure[@]}" >/dev/null
cmake --build "$build" -j2 --target progressive_size >/dev/null

if [[ -n "$keep" ]]; then
    mkdir -p "$keep"
    work="$(cd "$keep" && pwd)"
else
    work="$(mktemp -d)"
    trap 'rm -rf "$work"' EXIT
fi

args=(--work "$work" --gltfpack "$gltfpack" --sweep "$sweep")
for c in "${cases[@]}"; do
    args+=(--case "$c")
done
for c in "${sweep_cases[@]}"; do
    args+=(--sweep-case "$c")
done
echo
"$build/tests/bench/progressive_size" "${args[@]}" 2>"$work/progress.txt" || {
    status=$?
    tail -n 20 "$work/progress.txt" >&2
    exit "$status"
}
