#!/usr/bin/env bash
# Appearance benchmark (issue 17), side by side in one run, on three cases:
#   torso     ../shared/data/niivue_torso/torsoLabel.nii.gz, label 6 (liver), 0.78 x 0.78 x 5 mm
#   ts        ../shared/data/totalsegmentator_abdomen/example_seg.nii.gz, label 5 (liver), 3 mm
#   phantom   a smooth ellipsoid with per-slice boundary noise, 0.78 x 0.78 x 5 mm, known truth
#             (bench_appearance_peer.py phantom)
# and four surfaces of each: strata full resolution (`strata build`, meshes/*.ply with the
# shading normals), strata's 1 mm cut (`strata extract model.glb --max-error 1mm`, normals by the
# same definition computed in Python), the 3D Slicer pipeline (flying edges + windowed sinc,
# pass band 0.01, 20 iterations, vtkPolyDataNormals) and plain flying edges (with
# vtkPolyDataNormals). Printed per surface: share of edges folded over 90 degrees, mean
# dihedral angle, share of faces under 5 degrees, vertex-normal error against the truth
# (phantom), shading roughness (degrees between neighbouring vertex normals per mm of edge),
# slice error (sections at the slice centres against the pixel boundary, mean / max mm).
# Pictures: WORK/<case>.png, the four surfaces side by side, one camera, rendered offscreen
# with VTK under xvfb-run (Phong shading with each surface's normals).
#   bash scripts/bench-appearance.sh [--strata PATH] [--build-dir DIR] [--keep DIR]
#     --strata PATH    the strata binary (default: build strata_cli, Release, in --build-dir)
#     --build-dir DIR  build there (default: build-bench; BUILD_DIR also works)
#     --area-normals   measure strata's surfaces with area-weighted vertex normals (what
#                      scene.glb had before the shading normals), for a before/after pair
#     --keep DIR       keep the outputs, meshes, JSON and pictures in DIR (default: a temp
#                      folder; the pictures are copied to ./bench-appearance-pictures)
# Needs Debian's python3-numpy, python3-scipy, python3-vtk9 and xvfb (installed here when
# missing and running as root); PYTHON overrides /usr/bin/python3.
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
build="${BUILD_DIR:-$root/build-bench}"
python="${PYTHON:-/usr/bin/python3}"
peer="$root/scripts/bench_appearance_peer.py"
data="$root/../shared/data"
strata=""
keep=""
strata_normals=--shading-normals
while [[ $# -gt 0 ]]; do
    case "$1" in
        --strata) strata="$2"; shift ;;
        --build-dir) build="$2"; shift ;;
        --keep) keep="$2"; shift ;;
        --area-normals) strata_normals=--area-normals ;;
        -h|--help) awk 'NR > 1 && !/^#/ { exit } NR > 1 { sub(/^# ?/, ""); print }' "$0"; exit 0 ;;
        *) echo "bench-appearance: unknown argument $1 (see --help)" >&2; exit 2 ;;
    esac
    shift
done

missing=()
"$python" -c 'import numpy' 2>/dev/null || missing+=(python3-numpy)
"$python" -c 'import scipy.sparse' 2>/dev/null || missing+=(python3-scipy)
"$python" -c 'import vtkmodules' 2>/dev/null || missing+=(python3-vtk9)
command -v xvfb-run >/dev/null || missing+=(xvfb xauth)
if [[ ${#missing[@]} -gt 0 ]]; then
    if [[ $(id -u) -ne 0 ]]; then
        echo "bench-appearance: error: missing ${missing[*]} (apt-get install them as root)" >&2
        exit 2
    fi
    DEBIAN_FRONTEND=noninteractive apt-get install -y -q "${missing[@]}" >/dev/null
fi

if [[ -z "$strata" ]]; then
    cmake -S "$root" -B "$build" -DCMAKE_BUILD_TYPE=Release >/dev/null
    cmake --build "$build" -j2 --target strata_cli >/dev/null
    strata="$build/strata"
fi
if [[ -n "$keep" ]]; then
    work="$keep"
    mkdir -p "$work"
else
    work="$(mktemp -d)"
    trap 'rm -rf "$work"' EXIT
fi

"$python" "$peer" phantom "$work/phantom_input"
# name, input, label value, truth (or empty)
cases=(
    "torso|$data/niivue_torso/torsoLabel.nii.gz|6|"
    "ts|$data/totalsegmentator_abdomen/example_seg.nii.gz|5|"
    "phantom|$work/phantom_input/mask.nii.gz|1|$work/phantom_input/truth.json"
)
surfaces=(strata_full strata_1mm slicer flying_edges)
printf '[' >"$work/cases.json"
sep=""
for entry in "${cases[@]}"; do
    IFS='|' read -r name input label truth <<<"$entry"
    dir="$work/$name"
    mkdir -p "$dir"
    "$strata" build "$input" --labels "$label" -o "$dir/strata" -q
    cp "$dir"/strata/meshes/*.ply "$dir/strata_full.ply"
    "$strata" extract "$dir/strata/model.glb" --max-error 1mm -o "$dir/strata_1mm.ply" -q
    "$python" "$peer" peer "$input" "$label" "$dir"
    for s in "${surfaces[@]}"; do
        extra=()
        [[ -n "$truth" ]] && extra+=(--truth "$truth")
        [[ $s == strata_* ]] && extra+=("$strata_normals")
        "$python" "$peer" metrics "$input" "$label" "$dir/$s.ply" "${extra[@]}" --out "$dir/$s.json"
    done
    # the 1 mm cut with the normals written for it (Python, same definition) for the picture
    if [[ $strata_normals == --shading-normals ]]; then
        "$python" "$peer" normals "$dir/strata_1mm.ply" "$dir/strata_1mm_n.ply"
    else
        cp "$dir/strata_1mm.ply" "$dir/strata_1mm_n.ply"
    fi
    xvfb-run -a -s "-screen 0 3200x1000x24" "$python" "$peer" render "$work/$name.png" \
        "strata=$dir/strata_full.ply" "strata 1 mm cut=$dir/strata_1mm_n.ply" \
        "Slicer=$dir/slicer.ply" "flying edges=$dir/flying_edges.ply" 2>/dev/null
    printf '%s{"name": "%s", "surfaces": ["%s"]}' "$sep" "$name" \
        "$(IFS=,; echo "${surfaces[*]}" | sed 's/,/", "/g')" >>"$work/cases.json"
    sep=", "
done
printf ']\n' >>"$work/cases.json"
"$python" "$peer" table "$work"
if [[ -z "$keep" ]]; then
    mkdir -p bench-appearance-pictures
    cp "$work"/*.png bench-appearance-pictures/
    echo "pictures: bench-appearance-pictures/{torso,ts,phantom}.png"
else
    echo "pictures: $work/{torso,ts,phantom}.png"
fi
