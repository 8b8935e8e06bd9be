#!/usr/bin/env bash
# Size and decode time of the LOD file (lods.glb, issue 23) beside its peers, side by side in one
# run. For each case (phantoms and files of ../shared/data, every label an object) `strata build`
# writes, from the same input:
#   progressive     model.glb, the progressive file (all levels, Draco clusters)
#   single Draco    lods.glb with one level (--lod-levels 1): every object's full resolution as
#                   one Draco mesh, the writer's settings, lossless on the grid
#   single meshopt  the same with --lod-compression meshopt (EXT_meshopt_compression + 16-bit grid
#                   positions, lossless)
#   gltfpack -cc    npm gltfpack (scripts/node-bench, as bench-size.sh) on the plain scene.glb:
#                   meshopt with filters, 14-bit positions (lossy)
#   scene.glb       strata's single-rate scene: plain floats (--scene-uncompressed, gltfpack's
#                   input), Draco (the default) and --scene-meshopt (EXT_meshopt_compression,
#                   16-bit positions per object); the last two lossy
#   lods Draco      lods.glb with --lod-levels LEVELS (default 0.5mm,2mm,8mm)
#   lods meshopt    the same with --lod-compression meshopt
# and prints bytes, gzip -9 bytes (meshopt data is meant to be served compressed), the triangles
# the file holds (every level), and the median time to decode all of its geometry in one thread
# (tests/bench/gltf_decode_time: Draco's decoder against meshoptimizer's, as a glTF loader calls
# them; a progressive file's Draco primitives are all of its clusters).
#   bash scripts/bench-lods.sh [--quick] [--levels LIST] [--build-dir DIR] [--keep DIR]
#     --quick          phantom scene and the torso only
#     --levels LIST    --lod-levels of the LOD files (default 0.5mm,2mm,8mm)
#     --build-dir DIR  build there (default: build-bench in the repository; BUILD_DIR also works)
#     --keep DIR       keep the written files in DIR (default: a temp folder, removed)
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
build="${BUILD_DIR:-$root/build-bench}"
data="$root/../shared/data"
cases=(phantom:scene
       "stack:$data/niivue_torso/torsoLabel.nii.gz"
       "stack:$data/totalsegmentator_abdomen/example_seg.nii.gz"
       "stack:$data/pyradiomics_lung_tumor/lung2_label.nrrd")
levels=0.5mm,2mm,8mm
keep=""
while [[ $# -gt 0 ]]; do
    case "$1" in
        --quick) cases=(phantom:scene "stack:$data/niivue_torso/torsoLabel.nii.gz") ;;
        --levels) levels="$2"; shift ;;
        --build-dir) build="$2"; shift ;;
        --keep) keep="$2"; shift ;;
        -h|--help) awk 'NR > 1 && !/^#/ { exit } NR > 1 { sub(/^# ?/, ""); print }' "$0"; exit 0 ;;
        *) echo "bench-lods: unknown argument $1 (see --help)" >&2; exit 2 ;;
    esac
    shift
done

node_bench="$root/scripts/node-bench"
if [[ ! -f "$node_bench/node_modules/.package-lock.json" ]] ||
    [[ "$node_bench/package-lock.json" -nt "$node_bench/node_modules/.package-lock.json" ]]; then
    echo "bench-lods: npm ci in scripts/node-bench" >&2
    (cd "$node_bench" && npm ci --no-audit --no-fund >/dev/null)
fi
gltfpack="$node_bench/node_modules/.bin/gltfpack"

configure=(-DCMAKE_BUILD_TYPE=Release -DSTRATA_BUILD_BENCHMARKS=ON)
if [[ ! -f "$build/CMakeCache.txt" ]]; then
    configure+=(-DSTRATA_BUILD_TESTS=OFF)
fi
cmake -S "$root" -B "$build" "${configure[@]}" >/dev/null
cmake --build "$build" -j2 --target strata_cli gltf_decode_time >/dev/null
strata="$build/strata"
decode="$build/tests/bench/gltf_decode_time"

if [[ -n "$keep" ]]; then
    mkdir -p "$keep"
    work="$(cd "$keep" && pwd)"
else
    work="$(mktemp -d)"
    trap 'rm -rf "$work"' EXIT
fi

echo "LOD file (--lod-levels $levels) against the progressive file, single-rate Draco and"
echo "meshopt, and gltfpack; bytes, gzip -9 bytes, triangles held, median decode time (1 thread)."
for c in "${cases[@]}"; do
    kind="${c%%:*}"
    what="${c#*:}"
    if [[ "$kind" == phantom ]]; then
        input=(--phantom "$what")
        name="$what"
    else
        input=("$what")
        name="$(basename "$(dirname "$what")")"
    fi
    dir="$work/$name"
    start=$(date +%s.%N)
    "$strata" build "${input[@]}" -o "$dir/draco" --lod-levels "$levels" --scene-uncompressed \
        --quiet
    "$strata" build "${input[@]}" -o "$dir/meshopt" --lod-levels "$levels" \
        --lod-compression meshopt --quiet
    "$strata" build "${input[@]}" -o "$dir/single_draco" --lod-levels 1 --quiet
    "$strata" build "${input[@]}" -o "$dir/single_meshopt" --lod-levels 1 \
        --lod-compression meshopt --scene-meshopt --quiet
    "$gltfpack" -i "$dir/draco/scene.glb" -o "$dir/gltfpack_cc.glb" -cc >/dev/null 2>&1 ||
        echo "bench-lods: gltfpack failed on $dir/draco/scene.glb" >&2
    rows=("progressive model.glb|$dir/draco/model.glb"
          "single Draco|$dir/single_draco/lods.glb"
          "single meshopt|$dir/single_meshopt/lods.glb"
          "gltfpack -cc|$dir/gltfpack_cc.glb"
          "scene.glb plain|$dir/draco/scene.glb"
          "scene.glb Draco|$dir/single_draco/scene.glb"
          "scene.glb meshopt|$dir/single_meshopt/scene.glb"
          "lods.glb Draco|$dir/draco/lods.glb"
          "lods.glb meshopt|$dir/meshopt/lods.glb")
    files=()
    for r in "${rows[@]}"; do
        files+=("${r#*|}")
    done
    mapfile -t timed < <("$decode" --seconds 1 "${files[@]}" 2>/dev/null || true)
    printf '\n%s (%.0f s to build 4x)\n' "$name" "$(echo "$(date +%s.%N) - $start" | bc)"
    printf '  %-22s %10s %10s %10s %10s %9s\n' file bytes gzip triangles "decode ms" "Mtri/s"
    for i in "${!rows[@]}"; do
        label="${rows[$i]%%|*}"
        file="${rows[$i]#*|}"
        if [[ ! -f "$file" ]]; then
            printf '  %-22s %10s\n' "$label" -
            continue
        fi
        gz=$(gzip -9 -c "$file" | wc -c)
        read -r _ _ bytes triangles ms rate <<<"${timed[$i]:-x x - - - -}"
        printf '  %-22s %10s %10s %10s %10s %9s\n' "$label" "$bytes" "$gz" "$triangles" "$ms" "$rate"
    done
done
