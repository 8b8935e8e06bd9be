#!/usr/bin/env bash
# Simplification of strata against its peers at equal measured error (issue 6), side by side in
# one run. For each case (phantoms and labels of ../shared/data) tests/bench/simplify_peers
# reconstructs the full-resolution surface and, for each bound eps of 0.5, 1 and 2 px, compares
# the triangles and time of
#   ours     the cut of our multiresolution model with declared bound <= eps;
#   meshopt  meshoptimizer's meshopt_simplify (Debian 0.18), target count bisected;
#   vtk      vtkQuadricDecimation (python3-vtk9, default settings) through
#            scripts/bench_simplify_peer.py, target reduction bisected;
# each peer driven to the fewest triangles whose error, measured by the same independent oracle
# (tests/support/cut_error.h: slice-plane sections against the original contours), is <= eps.
# Prints one table: triangles, declared / measured error, time, closed manifold + genus, and
# the triangle and time ratios.
#   bash scripts/bench-simplify.sh [--quick] [--build-dir DIR] [--keep DIR]
#     --quick          one case (torus) instead of all
#     --build-dir DIR  build there (default: build-bench in the repository; BUILD_DIR also works)
#     --keep DIR       keep the full meshes handed to VTK and VTK's last output in DIR
#                      (default: a temp folder, removed)
# Needs Debian's libmeshoptimizer-dev, python3-vtk9 and python3-numpy (installed here when
# missing and running as root); PYTHON overrides /usr/bin/python3.
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
build="${BUILD_DIR:-$root/build-bench}"
python="${PYTHON:-/usr/bin/python3}"
torso="$root/../shared/data/niivue_torso/torsoLabel.nii.gz"
# torso labels 3 and 7: mid-sized organs (60k and 122k pixels on 23 and 29 slices)
cases=(phantom:sphere phantom:torus phantom:hollow_sphere phantom:branching
       phantom:t36_organ_like "stack:$torso@3" "stack:$torso@7")
keep=""
while [[ $# -gt 0 ]]; do
    case "$1" in
        --quick) cases=(phantom:torus) ;;
        --build-dir) build="$2"; shift ;;
        --keep) keep="$2"; shift ;;
        -h|--help) awk 'NR > 1 && !/^#/ { exit } NR > 1 { sub(/^# ?/, ""); print }' "$0"; exit 0 ;;
        *) echo "bench-simplify: unknown argument $1 (see --help)" >&2; exit 2 ;;
    esac
    shift
done

missing=()
[[ -f /usr/include/meshoptimizer.h ]] || missing+=(libmeshoptimizer-dev)
"$python" -c 'import numpy' 2>/dev/null || missing+=(python3-numpy)
"$python" -c 'import vtkmodules' 2>/dev/null || missing+=(python3-vtk9)
if [[ ${#missing[@]} -gt 0 ]]; then
    if [[ $(id -u) -eq 0 ]] && command -v apt-get >/dev/null; then
        echo "bench-simplify: installing ${missing[*]}" >&2
        DEBIAN_FRONTEND=noninteractive apt-get install -y -qq "${missing[@]}" >/dev/null
    else
        echo "bench-simplify: missing ${missing[*]}: apt-get install ${missing[*]}" >&2
        exit 1
    fi
fi

configure=(-DCMAKE_BUILD_TYPE=Release -DSTRATA_BUILD_BENCHMARKS=ON)
if [[ ! -f "$build/CMakeCache.txt" ]]; then
    # a fresh bench build needs no test suite: tests/bench/CMakeLists.txt then builds the error
    # oracle from tests/support itself
    configure+=(-DSTRATA_BUILD_TESTS=OFF)
fi
cmake -S "$root" -B "$build" "${configure[@]}" >/dev/null
cmake --build "$build" -j2 --target simplify_peers >/dev/null

if [[ -n "$keep" ]]; then
    mkdir -p "$keep"
    work="$(cd "$keep" && pwd)"
else
    work="$(mktemp -d)"
    trap 'rm -rf "$work"' EXIT
fi

args=(--work "$work" --vtk-python "$python" --vtk-script "$root/scripts/bench_simplify_peer.py")
for c in "${cases[@]}"; do
    args+=(--case "$c")
done
echo
"$build/tests/bench/simplify_peers" "${args[@]}" 2>"$work/progress.txt" || {
    status=$?
    tail -n 20 "$work/progress.txt" >&2
    exit "$status"
}
grep -v '^simplify_peers: ' "$work/progress.txt" | sort -u | sed 's/^/  /' || true
