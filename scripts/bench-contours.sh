#!/usr/bin/env bash
# Planar contours in (issue 21), side by side in one run: `strata build` on a contour JSON of a
# ball and a torus sliced analytically on planes 3 mm apart (a CT's spacing), against the
# rasterise-then-mesh route (the contours filled on a grid of the CT's 1 mm pixels, and 4x finer,
# then per structure VTK flying edges + Slicer's windowed-sinc smoothing + normals; see
# scripts/bench_contours_peer.py). strata scan-converts at 0.25 mm (a quarter of the CT pixel, its
# default with a reference CT). Prints triangles, seconds, and the error to the analytic surfaces
# in mm (mean, max; between planes; truth -> mesh).
#   bash scripts/bench-contours.sh [--strata PATH] [--gap MM] [--scale S] [--pitch MM] [--keep DIR]
#     --strata PATH  the strata binary (default: build/strata in the repository)
#     --pitch MM     strata's scan-conversion pitch (default 0.25; finer shows what the
#                    rasterisation of the polygons still costs)
#     --gap MM       plane spacing (default 3)
#     --scale S      every length of the solids times S (default 1: ball r 20 mm, torus tube 9 mm)
#     --keep DIR     keep the phantom, outputs and results in DIR (default: a temp folder, removed)
# Needs Debian's python3-numpy and python3-vtk9.
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
python="${PYTHON:-/usr/bin/python3}"
peer="$root/scripts/bench_contours_peer.py"
strata="$root/build/strata"
gap=3
scale=1
pitch=0.25
keep=""
while [[ $# -gt 0 ]]; do
    case "$1" in
        --strata) strata="$2"; shift ;;
        --gap) gap="$2"; shift ;;
        --scale) scale="$2"; shift ;;
        --pitch) pitch="$2"; shift ;;
        --keep) keep="$2"; shift ;;
        -h|--help) awk 'NR > 1 && !/^#/ { exit } NR > 1 { sub(/^# ?/, ""); print }' "$0"; exit 0 ;;
        *) echo "bench-contours: unknown argument $1 (see --help)" >&2; exit 2 ;;
    esac
    shift
done
"$python" -c 'import numpy, vtkmodules' 2>/dev/null ||
    { echo "bench-contours: needs python3-numpy and python3-vtk9 (apt-get install)" >&2; exit 1; }
[[ -x "$strata" ]] || { echo "bench-contours: no strata binary at $strata" >&2; exit 1; }
work="${keep:-$(mktemp -d)}"
mkdir -p "$work"
[[ -n "$keep" ]] || trap 'rm -rf "$work"' EXIT

"$python" "$peer" phantom "$work" --gap "$gap" --scale "$scale"
start=$(date +%s.%N)
"$strata" build "$work/phantom.json" --contour-pitch "$pitch" --threads 2 -o "$work/strata" --quiet
end=$(date +%s.%N)
echo "{\"wall_s\": $(echo "$end - $start" | bc)}" > "$work/strata_time.json"
"$python" "$peer" raster "$work" --pixel 1
"$python" "$peer" raster "$work" --pixel 0.25
"$python" "$peer" error "$work" "$work"/strata/meshes/*.ply --name strata
"$python" "$peer" error "$work" "$work/raster_1.ply" --name raster_1
"$python" "$peer" error "$work" "$work/raster_0.25.ply" --name raster_0.25
"$python" "$peer" table "$work"
