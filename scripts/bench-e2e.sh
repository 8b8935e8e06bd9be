#!/usr/bin/env bash
# End-to-end benchmark (issue 7), side by side in one run: `strata build` on a 512x512x256 label
# map (1 x 1 x 2 mm; 8 ellipsoids of two labels, some overlapping, random orientations from a
# fixed seed) against 3D Slicer's default "Export to models" pipeline reproduced with VTK
# (vtkDiscreteFlyingEdges3D per label, vtkWindowedSincPolyDataFilter pass band 0.01, 20
# iterations, vtkPolyDataNormals; see scripts/bench_e2e_peer.py) on the same NIfTI file:
#   1. bench_e2e_peer.py phantom writes mask.nii.gz and the analytic truth (truth.json);
#   2. alternating, RUNS times each: `strata build mask.nii.gz --threads T` and the Slicer
#      pipeline, each under /usr/bin/time -v (wall time, max RSS);
#   3. `strata extract --max-error` 1 mm, 2 mm and the largest root bound: cuts of the model;
#   4. bench_e2e_peer.py error measures every mesh against the analytic union of ellipsoids;
# then prints one table: wall time and peak memory (medians), triangles, strata's declared
# bound, mean / max error in mm to the true surface, and the strata / Slicer ratios.
#   bash scripts/bench-e2e.sh [--quick] [--strata PATH] [--build-dir DIR] [--runs N]
#                             [--threads N] [--seed N] [--sinc-iterations N] [--keep DIR]
#                             [--cases LIST]
#     --quick              256x256x128 volume (same geometry, half the size), one run
#     --strata PATH        the strata binary to measure (default: build strata_cli, Release, in
#                          --build-dir)
#     --build-dir DIR      build there (default: build-bench in the repository; BUILD_DIR also
#                          works)
#     --runs N             runs of each tool, the median is reported (default 3)
#     --threads N          strata --threads and VTK's SMP threads (default 2)
#     --seed N             seed of the ellipsoid orientations (default 7)
#     --sinc-iterations N  smoothing iterations of the Slicer pipeline (default 20, what
#                          Slicer's vtkBinaryLabelmapToClosedSurfaceConversionRule sets)
#     --keep DIR           keep the mask, outputs, meshes and results in DIR (default: a temp
#                          folder, removed)
#     --cases LIST         instead of the above, the speed table (issue 19): comma-separated
#                          cases among e2e (this volume), freesurfer (the FreeSurfer aparc of
#                          ../shared/data, its PNG stack written as NIfTI), totalseg (the
#                          TotalSegmentator example), wholebody (`strata phantom whole_body`:
#                          512x512x1000, 117 organ-like labels, as NIfTI), wholebody4 (the
#                          same solids on every 4th slice: 250 slices of 6 mm), or all (e2e,
#                          freesurfer, totalseg, wholebody); per case, alternating, RUNS times
#                          (default 1 here): strata build --threads 1, --threads 2 and the
#                          Slicer pipeline (--threads N), each a whole process under
#                          /usr/bin/time -v; one table of wall, CPU, peak RSS, strata's stage
#                          times (wall and CPU) and the ratios to Slicer's whole process
# Needs Debian's python3-numpy, python3-scipy, python3-vtk9 and time (installed here when
# missing and running as root); PYTHON overrides /usr/bin/python3.
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
build="${BUILD_DIR:-$root/build-bench}"
python="${PYTHON:-/usr/bin/python3}"
peer="$root/scripts/bench_e2e_peer.py"
dims=512,512,256
runs=3
threads=2
seed=7
iterations=20
strata=""
keep=""
cases=""
runs_given=""
while [[ $# -gt 0 ]]; do
    case "$1" in
        --quick) dims=256,256,128; runs=1 ;;
        --strata) strata="$2"; shift ;;
        --build-dir) build="$2"; shift ;;
        --runs) runs="$2"; runs_given=1; shift ;;
        --cases) cases="$2"; shift ;;
        --threads) threads="$2"; shift ;;
        --seed) seed="$2"; shift ;;
        --sinc-iterations) iterations="$2"; shift ;;
        --keep) keep="$2"; shift ;;
        -h|--help) awk 'NR > 1 && !/^#/ { exit } NR > 1 { sub(/^# ?/, ""); print }' "$0"; exit 0 ;;
        *) echo "bench-e2e: unknown argument $1 (see --help)" >&2; exit 2 ;;
    esac
    shift
done

missing=()
"$python" -c 'import numpy' 2>/dev/null || missing+=(python3-numpy)
"$python" -c 'import scipy.spatial' 2>/dev/null || missing+=(python3-scipy)
"$python" -c 'import vtkmodules' 2>/dev/null || missing+=(python3-vtk9)
[[ -x /usr/bin/time ]] || missing+=(time)
if [[ ${#missing[@]} -gt 0 ]]; then
    if [[ $(id -u) -eq 0 ]] && command -v apt-get >/dev/null; then
        echo "bench-e2e: installing ${missing[*]}" >&2
        DEBIAN_FRONTEND=noninteractive apt-get install -y -qq "${missing[@]}" >/dev/null
    else
        echo "bench-e2e: missing ${missing[*]}: apt-get install ${missing[*]}" >&2
        exit 1
    fi
fi

if [[ -z "$strata" ]]; then
    configure=(-DCMAKE_BUILD_TYPE=Release)
    if [[ ! -f "$build/CMakeCache.txt" ]]; then
        configure+=(-DSTRATA_BUILD_TESTS=OFF)  # a fresh bench build needs no test suite
    fi
    cmake -S "$root" -B "$build" "${configure[@]}" >/dev/null
    cmake --build "$build" -j2 --target strata_cli >/dev/null
    strata="$build/strata"
fi
strata="$(cd "$(dirname "$strata")" && pwd)/$(basename "$strata")"
[[ -x "$strata" ]] || { echo "bench-e2e: $strata is not an executable" >&2; exit 1; }

if [[ -n "$keep" ]]; then
    mkdir -p "$keep"
    work="$(cd "$keep" && pwd)"
else
    work="$(mktemp -d)"
    trap 'rm -rf "$work"' EXIT
fi
rm -rf "$work/runs" "$work/strata" "$work/slicer" "$work"/error_*.json "$work"/extract_*
mkdir -p "$work/runs"

if [[ -n "$cases" ]]; then
    [[ $cases == all ]] && cases=e2e,freesurfer,totalseg,wholebody
    [[ -n $runs_given ]] || runs=1
    data="$root/../shared/data"
    for case in ${cases//,/ }; do
        dir="$work/cases/$case"
        rm -rf "$dir"
        mkdir -p "$dir"
        case "$case" in
            e2e)
                "$python" "$peer" phantom "$dir" --dims "$dims" --seed "$seed"
                input="$dir/mask.nii.gz"
                what="bench-e2e phantom, $dims voxels, 2 labels" ;;
            freesurfer)
                input="$dir/aparc.nii.gz"
                "$python" "$peer" png-nifti "$data/freesurfer_aparc_aseg/slices" "$input"
                what="FreeSurfer aparc.a2009s+aseg, 128x172x133, 188 labels" ;;
            totalseg)
                input="$data/totalsegmentator_abdomen/example_seg.nii.gz"
                what="TotalSegmentator example, 122x101x30, 41 labels" ;;
            wholebody|wholebody4)
                input="$dir/whole_body.nii.gz"
                spacing=()
                [[ $case == wholebody4 ]] && spacing=(--slice-spacing 6)
                "$strata" phantom whole_body --format nifti -o "$input" "${spacing[@]}" --quiet
                what="strata phantom whole_body ${spacing[*]}, 117 labels" ;;
            *) echo "bench-e2e: unknown case $case (e2e, freesurfer, totalseg, wholebody," \
                    "wholebody4, all)" >&2; exit 2 ;;
        esac
        "$python" -c 'import json, sys
json.dump({"name": sys.argv[1], "input": sys.argv[2], "what": sys.argv[3],
           "runs": int(sys.argv[4]), "threads": [1, 2], "slicer_threads": int(sys.argv[5])},
          open(sys.argv[6], "w"))' "$case" "$input" "$what" "$runs" "$threads" "$dir/case.json"
        for ((r = 1; r <= runs; r++)); do
            for t in 1 2; do
                echo "bench-e2e: $case run $r of $runs: strata build --threads $t" >&2
                rm -rf "$dir/out"
                /usr/bin/time -v -o "$dir/strata_t${t}_$r.time" \
                    "$strata" build "$input" -o "$dir/out" --threads "$t" --quiet
                cp "$dir/out/summary.json" "$dir/strata_t${t}_$r.summary.json"
            done
            echo "bench-e2e: $case run $r of $runs: Slicer pipeline" >&2
            /usr/bin/time -v -o "$dir/slicer_$r.time" \
                "$python" "$peer" slicer "$input" "$dir/slicer_out" --threads "$threads" \
                --iterations "$iterations"
            mv "$dir/slicer_out/slicer.json" "$dir/slicer_$r.json"
            rm -rf "$dir/out" "$dir/slicer_out"
        done
    done
    "$python" "$peer" cases-table "$work/cases"
    exit 0
fi

"$python" "$peer" phantom "$work" --dims "$dims" --seed "$seed"
mask="$work/mask.nii.gz"

# alternate the two tools so that load from elsewhere on the machine hits both alike
for ((r = 1; r <= runs; r++)); do
    echo "bench-e2e: run $r of $runs: strata build" >&2
    out="$work/runs/strata_out"
    rm -rf "$out"
    /usr/bin/time -v -o "$work/runs/strata_$r.time" \
        "$strata" build "$mask" -o "$out" --threads "$threads" --quiet
    cp "$out/summary.json" "$work/runs/strata_$r.summary.json"
    if [[ $r -eq 1 ]]; then
        mv "$out" "$work/strata"
    fi
    echo "bench-e2e: run $r of $runs: Slicer pipeline" >&2
    /usr/bin/time -v -o "$work/runs/slicer_$r.time" \
        "$python" "$peer" slicer "$mask" "$work/runs/slicer_out" --threads "$threads" \
        --iterations "$iterations"
    mv "$work/runs/slicer_out/slicer.json" "$work/runs/slicer_$r.json"
    if [[ $r -eq 1 ]]; then
        mv "$work/runs/slicer_out" "$work/slicer"
    fi
done
rm -rf "$work/runs/strata_out" "$work/runs/slicer_out"
cp "$work/runs/slicer_1.json" "$work/slicer/slicer.json"

# cuts of the multiresolution model: 1 mm, 2 mm and every object's root (its largest bound)
root_bound="$("$python" -c '
import json, sys
s = json.load(open(sys.argv[1]))
print(max(o["surface"]["levels"][-1]["error_mm"] for o in s["objects"]) * 1.0001 + 1e-6)
' "$work/strata/summary.json")"
for level in 1 2 base; do
    bound="${level}mm"
    [[ $level == base ]] && bound="${root_bound}mm"
    echo "bench-e2e: strata extract --max-error $bound" >&2
    "$strata" extract "$mask" --max-error "$bound" -o "$work/extract_$level.ply" \
        --threads "$threads" --quiet --json >"$work/extract_$level.json"
done

summary="$work/strata/summary.json"
"$python" "$peer" error "$work/truth.json" "$summary" "$work"/strata/meshes/*.ply \
    --out "$work/error_strata_full.json"
for level in 1 2 base; do
    "$python" "$peer" error "$work/truth.json" "$summary" "$work/extract_$level.ply" \
        --out "$work/error_strata_$level.json"
done
"$python" "$peer" error "$work/truth.json" "$work/slicer/slicer.json" "$work/slicer/slicer.ply" \
    --out "$work/error_slicer.json"

"$python" "$peer" table "$work" --threads "$threads"
