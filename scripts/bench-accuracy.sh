#!/usr/bin/env bash
# Surface accuracy of strata against its peers, side by side in one run. For each phantom (sphere,
# torus, branching, hollow_sphere) at slice spacings 2, 4 and 8 px (pixel 1 mm):
#   1. `strata phantom NAME --slice-spacing D --format nifti` writes the label stack;
#   2. scripts/bench_accuracy_peer.py meshes it with VTK's discrete flying edges (what 3D Slicer
#      runs), the same with Slicer's default smoothing, and shape-based interpolation (per-slice
#      signed distance, linear in z, marching cubes);
#   3. `strata build STACK -o OURS --quiet` writes one mesh per object to OURS/meshes/*.ply (while
#      triangulation is not built, the strata row says so);
#   4. tests/bench/mesh_accuracy measures every mesh against the phantom's analytic solids;
# then prints one table: triangles, mean / RMS / max error in px, bias, the enclosed volume's
# error against the analytic solid's in %, time, and ratios vs flying edges.
#   bash scripts/bench-accuracy.sh [--quick] [--build-dir DIR] [--keep DIR]
#     --quick          one slice spacing (4 px) instead of 2, 4, 8
#     --build-dir DIR  build there (default: build-bench in the repository; BUILD_DIR also works)
#     --keep DIR       keep stacks, meshes and results in DIR (default: a temp folder, removed)
# Needs Debian's python3-numpy, python3-scipy and python3-vtk9 (installed here when missing and
# running as root); PYTHON overrides /usr/bin/python3.
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
build="${BUILD_DIR:-$root/build-bench}"
python="${PYTHON:-/usr/bin/python3}"
spacings=(2 4 8)
phantoms=(sphere torus branching hollow_sphere)
keep=""
while [[ $# -gt 0 ]]; do
    case "$1" in
        --quick) spacings=(4) ;;
        --build-dir) build="$2"; shift ;;
        --keep) keep="$2"; shift ;;
        -h|--help) awk 'NR > 1 && !/^#/ { exit } NR > 1 { sub(/^# ?/, ""); print }' "$0"; exit 0 ;;
        *) echo "bench-accuracy: unknown argument $1 (see --help)" >&2; exit 2 ;;
    esac
    shift
done

if ! "$python" -c 'import numpy, scipy, vtkmodules' 2>/dev/null; then
    if [[ $(id -u) -eq 0 ]] && command -v apt-get >/dev/null; then
        echo "bench-accuracy: installing python3-vtk9 python3-scipy python3-numpy" >&2
        DEBIAN_FRONTEND=noninteractive apt-get install -y -qq \
            python3-vtk9 python3-scipy python3-numpy >/dev/null
    else
        echo "bench-accuracy: $python needs numpy, scipy and vtk:" \
             "apt-get install python3-vtk9 python3-scipy python3-numpy" >&2
        exit 1
    fi
fi

configure=(-DCMAKE_BUILD_TYPE=Release -DSTRATA_BUILD_BENCHMARKS=ON)
if [[ ! -f "$build/CMakeCache.txt" ]]; then
    configure+=(-DSTRATA_BUILD_TESTS=OFF)  # a fresh bench build needs no test suite
fi
cmake -S "$root" -B "$build" "${configure[@]}" >/dev/null
cmake --build "$build" -j2 --target strata_cli mesh_accuracy >/dev/null
strata="$build/strata"
accuracy="$build/tests/bench/mesh_accuracy"
peer="$root/scripts/bench_accuracy_peer.py"

if [[ -n "$keep" ]]; then
    mkdir -p "$keep"
    work="$(cd "$keep" && pwd)"
else
    work="$(mktemp -d)"
    trap 'rm -rf "$work"' EXIT
fi
results="$work/results.jsonl"
: >"$results"

now() { date +%s.%N; }
elapsed() { awk -v a="$1" -v b="$2" 'BEGIN { printf "%.6f", b - a }'; }

for name in "${phantoms[@]}"; do
    for d in "${spacings[@]}"; do
        dir="$work/${name}_d$d"
        rm -rf "$dir"
        mkdir -p "$dir"
        stack="$dir/stack.nii.gz"
        echo "bench-accuracy: $name d=$d" >&2
        "$strata" phantom "$name" -o "$stack" --slice-spacing "$d" --format nifti --quiet
        measure=("$accuracy" --phantom "$name" --slice-spacing "$d" --json)

        "$python" "$peer" mesh "$stack" "$dir/peer"
        for method in flying-edges slicer-smoothed shape-based; do
            "${measure[@]}" "$dir/peer/$method.ply" >"$dir/$method.json" 2>>"$dir/notes.txt"
            "$python" "$peer" record --phantom "$name" --d "$d" --method "$method" \
                --times "$dir/peer/peer_times.json" "$dir/$method.json" >>"$results"
        done

        start="$(now)"
        status=0
        # note: through an inner shell, whose crash report (if any) lands in strata.err
        bash -c '"$@"; exit $?' _ "$strata" build "$stack" -o "$dir/ours" --quiet \
            2>"$dir/strata.err" || status=$?
        seconds="$(elapsed "$start" "$(now)")"
        meshes=()
        if [[ -d "$dir/ours/meshes" ]]; then
            mapfile -t meshes < <(find "$dir/ours/meshes" -maxdepth 1 -type f \
                \( -iname '*.ply' -o -iname '*.obj' -o -iname '*.stl' \) | sort)
        fi
        if [[ $status -ne 0 ]]; then
            why="strata: build failed (exit $status"
            if [[ $status -gt 128 ]]; then
                why+=", killed by SIG$(kill -l $((status - 128)) 2>/dev/null || echo '?'))"
            elif [[ -s "$dir/strata.err" ]]; then
                why+="): $(head -n 1 "$dir/strata.err")"
            else
                why+=")"
            fi
            "$python" "$peer" record --phantom "$name" --d "$d" --method strata \
                --missing "$why" >>"$results"
        elif [[ ${#meshes[@]} -eq 0 ]]; then
            "$python" "$peer" record --phantom "$name" --d "$d" --method strata \
                --missing "strata: no meshes (triangulation not built)" >>"$results"
        else
            "${measure[@]}" "${meshes[@]}" >"$dir/strata.json" 2>>"$dir/notes.txt"
            "$python" "$peer" record --phantom "$name" --d "$d" --method strata \
                --seconds "$seconds" "$dir/strata.json" >>"$results"
        fi
    done
done

echo
"$python" "$peer" table "$results"
sort -u "$work"/*/notes.txt 2>/dev/null | sed 's/^/  /' || true
