#!/usr/bin/env bash
# Size of the progressive glTF (STRATA_progressive_mesh version 3) against its peers (issue 16),
# side by side in one run. For each case (every label an object, as `strata build` does)
# tests/bench/progressive_size reconstructs the surfaces, writes the progressive model.glb and
# reports its total bytes (= bytes to full resolution), its base (GLB header + JSON + DAG tables +
# base meshes: a first frame's bytes) and share, and its JSON per object, against
#   Draco PN  single-rate Draco .glb of each object's full-resolution mesh, POSITION + NORMAL, with
#             the encoder settings and the lossless grid quantization of our chunks;
#   Draco P   the same without NORMAL (our chunks carry none: the viewer computes them);
#   gltfpack  npm gltfpack -cc (meshoptimizer, WASM) on the plain full-resolution scene.glb;
# then a sweep of the multiresolution parameters (keep fraction x cluster triangles: total /
# Draco PN, base share, chunk count and size, triangles over all levels / level 0).
# Cases: the torso, the TotalSegmentator example, the FreeSurfer aparc (../shared/data) and the
# bench-e2e volume (scripts/bench_e2e_peer.py phantom, 512 x 512 x 256, seed 7, as
# scripts/bench-e2e.sh makes it).
#   bash scripts/bench-size.sh [--quick] [--build-dir DIR] [--keep DIR]
#     --quick          one case (torus), sweep of 0.25 and 0.35 x 1024 on it
#     --build-dir DIR  build there (default: build-bench in the repository; BUILD_DIR also works)
#     --keep DIR       keep the written files (model.glb, scene.glb, draco.glb, draco_p.glb,
#                      gltfpack output) in DIR (default: a temp folder, removed)
# Needs Node.js with npm and the npm package gltfpack (installed exactly as locked into
# scripts/node-bench, npm ci, when missing), and python3-numpy for the bench-e2e volume (both
# installed from Debian when missing and running as root).
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
build="${BUILD_DIR:-$root/build-bench}"
data="$root/../shared/data"
python="${PYTHON:-/usr/bin/python3}"
cases=("stack:$data/niivue_torso/torsoLabel.nii.gz"
       "stack:$data/totalsegmentator_abdomen/example_seg.nii.gz"
       "stack:$data/freesurfer_aparc_aseg/slices"
       e2e)
sweep_cases=("stack:$data/niivue_torso/torsoLabel.nii.gz"
             "stack:$data/totalsegmentator_abdomen/example_seg.nii.gz")
sweep_keep=0.2,0.25,0.35
sweep_clusters=2048,4096
keep=""
while [[ $# -gt 0 ]]; do
    case "$1" in
        --quick) cases=(phantom:torus); sweep_cases=(phantom:torus); sweep_keep=0.25,0.35
                 sweep_clusters=1024 ;;
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

args=(--work "$work" --gltfpack "$gltfpack" --sweep-keep "$sweep_keep"
      --sweep-clusters "$sweep_clusters")
for c in "${cases[@]}"; do
    if [[ "$c" == e2e ]]; then
        # the bench-e2e volume, made as scripts/bench-e2e.sh makes it
        if ! "$python" -c 'import numpy' 2>/dev/null; then
            if [[ $(id -u) -eq 0 ]] && command -v apt-get >/dev/null; then
                DEBIAN_FRONTEND=noninteractive apt-get install -y -qq python3-numpy >/dev/null
            else
                echo "bench-size: missing python3-numpy for the bench-e2e volume" >&2
                exit 1
            fi
        fi
        mkdir -p "$work/e2e"
        "$python" "$root/scripts/bench_e2e_peer.py" phantom "$work/e2e" --dims 512,512,256 \
            --seed 7 >/dev/null
        c="stack:$work/e2e/mask.nii.gz"
    fi
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
