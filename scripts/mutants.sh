#!/usr/bin/env bash
# Mutation testing (issue 24): small deliberate bugs in core places, each applied to a scratch copy
# of the tree (a detached git worktree of HEAD), the test targets that should notice it built and
# run, and a table of caught / survived printed at the end. Not part of CI: it takes long (each
# mutant recompiles a file, relinks a few test binaries and runs their tests).
#
#   bash scripts/mutants.sh            # every mutant
#   bash scripts/mutants.sh --list     # names only
#   bash scripts/mutants.sh NAME...    # only these
#   bash scripts/mutants.sh --check    # only whether every pattern still applies (fast)
#
# Each mutant is a literal text replacement that must match exactly once in its file: when the code
# moved and the pattern no longer matches (or matches twice), the mutant is reported STALE and the
# script fails, so the list is kept in step with the code. A mutant whose tests all pass SURVIVED:
# a missing test. Exit status 0 only when every mutant was applied, built and caught.
#
# Environment: STRATA_MUTANTS_DIR (scratch directory, default build-mutants/ in the checkout; it
# holds the worktree and its build, reused between runs), CCACHE_DIR / CCACHE_BASEDIR (shared
# compiler cache: the scratch tree compiles the same files as the checkout), STRATA_MUTANTS_JOBS
# (build and test parallelism, default 2).
set -euo pipefail

# note: bash reads a script as it runs; run a copy, so editing this file meanwhile is safe
if [[ -z ${STRATA_MUTANTS_COPY:-} ]]; then
    copy=$(mktemp /tmp/strata-mutants.XXXXXX.sh)
    cp "$0" "$copy"
    STRATA_MUTANTS_COPY=$copy exec bash "$copy" "$@"
fi
trap 'rm -f "$STRATA_MUTANTS_COPY"' EXIT

root=$(git rev-parse --show-toplevel)
cd "$root"
scratch=${STRATA_MUTANTS_DIR:-$root/build-mutants}
jobs=${STRATA_MUTANTS_JOBS:-2}
tree=$scratch/tree
build=$tree/build
export CCACHE_BASEDIR=${CCACHE_BASEDIR:-$(dirname "$root")}
export CCACHE_DIR=${CCACHE_DIR:-$(dirname "$root")/.ccache}

names=()
files=()
olds=()
news=()
targets=()
tests=()

# mutant NAME FILE OLD NEW TARGETS TESTS
#   OLD/NEW: literal text (may span lines); TARGETS: cmake targets to build (space separated);
#   TESTS: ctest -R regular expression of the tests that should fail.
mutant() {
    names+=("$1")
    files+=("$2")
    olds+=("$3")
    news+=("$4")
    targets+=("$5")
    tests+=("$6")
}

# ------------------------------------------------------------------------------------------------
# input: readers (src/input)
mutant input-nifti-rank-1 src/input/read_nifti.cpp \
    'if (rank < 2 || rank > 7) {' \
    'if (rank < 1 || rank > 7) {' \
    'input_test' '^(ReadNifti|WriteNifti|ReaderLimits)'
mutant input-nifti-rank-8 src/input/read_nifti.cpp \
    'if (rank < 2 || rank > 7) {' \
    'if (rank < 2 || rank > 8) {' \
    'input_test' '^(ReadNifti|WriteNifti|ReaderLimits)'
mutant input-nifti-vox-offset-in-flag src/input/read_nifti.cpp \
    '(offset > size && offset < size + 4) || offset > 0x1p62) {' \
    'offset > 0x1p62) {' \
    'input_test' '^(ReadNifti|WriteNifti|ReaderLimits)'
mutant input-nrrd-dimension-0 src/input/read_nrrd.cpp \
    '*dimension_value < 1 ||' \
    '*dimension_value < 0 ||' \
    'input_test' '^(ReadNrrd|ReaderLimits)'
mutant input-label-65536 src/input/detail/voxel_decode.h \
    'rounded > 65535.0) {' \
    'rounded > 65536.0) {' \
    'input_test' '^(ReadNifti|WriteNifti|ReadNrrd|ReaderLimits)'
mutant input-label-fraction src/input/detail/voxel_decode.h \
    'std::abs(value - rounded) > 1e-4' \
    'std::abs(value - rounded) > 0.5' \
    'input_test' '^(ReadNifti|WriteNifti|ReadNrrd|ReaderLimits)'
mutant input-intensity-agreement src/input/label_map_check.cpp \
    'constexpr double kMaxAgreement = 0.5;' \
    'constexpr double kMaxAgreement = 0.05;' \
    'input_test' '^LabelMapCheck'

# the command line (src/cli)
mutant cli-unsnapped-object-dropped src/cli/commands.cpp \
    '            throw Error(ErrorCode::Internal, "export: " + scene[i].name + " (label " +' \
    '            continue;
            throw Error(ErrorCode::Internal, "export: " + scene[i].name + " (label " +' \
    'strata_cli cli_test' '^CliOutput\.ObjectNotOnAGrid'
mutant cli-label-map-unchecked src/cli/commands.cpp \
    '        check_is_label_map(stack);' \
    '' \
    'strata_cli cli_test' '^CliOutput\.IntensityImage'

# contours: tracing, links, Douglas-Peucker (src/contours)
mutant contours-dp-tolerance src/contours/simplify_contours.cpp \
    'if (worst.distance <= tolerance_px) {' \
    'if (worst.distance <= 2.0 * tolerance_px) {' \
    'contours_test contours_property_test' '^(SimplifyContours|SimplifyPolyline|SimplifyClosedPolyline|SimplifyProperty|CatalogueContours)'
mutant contours-saddle-point-dropped src/contours/extract_contours.cpp \
    'if (c.points.empty() || !(c.points.back() == in)) {
                    c.points.push_back(in);
                }' \
    'if (c.points.empty()) {
                    c.points.push_back(in);
                }' \
    'contours_test' '^(ExtractContours|ExtractContoursProperty|CatalogueContours)'
mutant contours-link-4-connected src/contours/extract_contours.cpp \
    'if ((dx == 0 && dy == 0) || (!fg && dx != 0 && dy != 0)) {' \
    'if ((dx == 0 && dy == 0) || (dx != 0 && dy != 0)) {' \
    'contours_test' '^(LinkSlices|LinkConnectivity|CatalogueLinks|ExtractContours)'

# distance fields (src/distance)
mutant distance-sites-inside src/distance/distance_field.cpp \
    'c[X] |= all_if(side[X] < 0) & DistanceField::kInside;' \
    'c[X] |= all_if(side[X] <= 0) & DistanceField::kInside;' \
    'distance_test' '^DistanceField'
mutant distance-saddle-outside src/distance/distance_field.cpp \
    'return -1;  // note: a saddle corner is cut off by the contour, inside' \
    'return 1;  // note: a saddle corner is cut off by the contour, inside' \
    'distance_test' '^DistanceField'

# triangulation, verification, quantize (src/triangulate, src/pipeline, src/quantize)
mutant triangulate-height-unclamped src/triangulate/surface.cpp \
    'return std::clamp(t, 0.05, 0.95);' \
    'return std::clamp(t, 0.0, 1.0);' \
    'triangulate_test' '^Catalogue/CatalogueSurface.*/(t01_sphere|t13_y_branch_1to2|t27_thin_features)( |$)'
mutant verify-self-intersection-skipped src/pipeline/reconstruct.cpp \
    'v.self_intersection_free = v.closed_manifold && !has_self_intersections(surface.mesh);' \
    'v.self_intersection_free = v.closed_manifold;' \
    'triangulate_test' '^Verify\.'
mutant verify-cavity-genus-ignored src/pipeline/reconstruct.cpp \
    'v.topology_as_reference = v.closed_manifold && genus == expected;' \
    'v.topology_as_reference = v.closed_manifold && genus.size() == expected.size();' \
    'triangulate_test' '^Verify\.'
mutant verify-rejects-multi-component src/pipeline/reconstruct.cpp \
    'v.topology_as_reference = v.closed_manifold && genus == expected;' \
    'v.topology_as_reference = v.closed_manifold && genus == expected && genus.size() == 1;' \
    'multires_property_test' '^MultiresProperty'
mutant quantize-shift-not-declared src/pipeline/reconstruct.cpp \
    'surface.grid_shift_px = snap.max_plane_shift_px;' \
    'surface.grid_shift_px = 0.0;' \
    'quantize_test' '^SnapToGrid'
mutant quantize-rounds-down src/quantize/snap_to_grid.cpp \
    'const double qx = std::nearbyint(p.x / step);' \
    'const double qx = std::floor(p.x / step);' \
    'quantize_test' '^SnapToGrid'

# simplification (src/simplify)
mutant simplify-pieces-ignored src/simplify/edge_collapse.cpp \
    'sections_known ? cost(c.u, c.v, true) : pieces_cost(c.u, *known);' \
    'sections_known ? cost(c.u, c.v, false) : known;' \
    'simplify_test' '^(SimplifyBudget|MultiresDag)'
mutant simplify-intersection-check-skipped src/simplify/edge_collapse.cpp \
    'if (creates_intersection(c.u, c.v)) {' \
    'if (false) {' \
    'simplify_test' '^(SimplifyBudget|MultiresDag)'
mutant simplify-top-plane-skipped src/simplify/slice_error.cpp \
    'const double k1 = std::floor(zmax / spacing_ + 1e-9);' \
    'const double k1 = std::floor(zmax / spacing_ + 1e-9) - 1.0;' \
    'simplify_test' '^(SimplifyBudget|MultiresDag)'
mutant simplify-schedule-jump src/simplify/multires_dag.cpp \
    'std::max(options_.error_growth * attempt.children_error, attempt.children_error + 0.5));' \
    'std::max(options_.error_growth * attempt.children_error, attempt.children_error + 4.0));' \
    'simplify_test' '^(SimplifyBudget|MultiresDag)'
mutant simplify-cut-bound-level0 src/simplify/multires_dag.cpp \
    '                                           ? mesh.full_resolution_error_px
                                           : mesh.groups[std::size_t(cluster.producer)].error_px);' \
    '                                           ? 0.0
                                           : mesh.groups[std::size_t(cluster.producer)].error_px);' \
    'simplify_test' '^(SimplifyBudget|MultiresDag)'
mutant simplify-piece-error-unrecorded src/simplify/edge_collapse.cpp \
    'error_[to] = std::max(error_[to], best);' \
    'error_[to] = error_[to];' \
    'simplify_test' '^(SimplifyBudget|MultiresDag)'
mutant simplify-piece-deviation-dropped src/simplify/slice_error.cpp \
    'const double capsule = piece.deviation_px + ends;' \
    'const double capsule = ends;' \
    'simplify_test' '^(SimplifyBudget|MultiresDag)'
mutant simplify-keep-fraction src/simplify/multires_dag.cpp \
    'collapse.target_triangles = std::size_t(double(before) * options_.keep_fraction);' \
    'collapse.target_triangles = std::size_t(double(before) * 0.6);' \
    'simplify_test' '^(SimplifyBudget|SimplifyKeepFraction|MultiresDag)'

# exporters (exporters/)
mutant export-bound-rounded-down exporters/progressive_format.cpp \
    'double r = std::strtod(text, nullptr);
    if (r >= x) {' \
    'double r = std::strtod(text, nullptr);
    if (true) {' \
    'exporters_test' '^(ProgressiveGltf|ReadProgressiveGltf|DracoChunk)'
mutant export-sphere-rounded-down exporters/progressive_gltf.cpp \
    '    radius *= 1.0 + 1e-7;
    float r = to_float(radius);
    while (double(r) < radius) {' \
    '    float r = to_float(radius);
    while (false) {' \
    'exporters_test' '^(ProgressiveGltf|ReadProgressiveGltf|DracoChunk|SphereRounding)'
mutant export-draco-range-short exporters/detail/draco_chunk.cpp \
    'return static_cast<float>(in.step * (std::ldexp(1.0, b) - 1.0));' \
    'return static_cast<float>(in.step * (std::ldexp(1.0, b) - 2.0));' \
    'exporters_test' '^(DracoChunk|ProgressiveGltf)'

# the viewer's selection (web-viewer/selection.js)
mutant viewer-sse-far-side web-viewer/selection.js \
    'const d = Math.sqrt(dx * dx + dy * dy + dz * dz) - sphere[offset + 3];' \
    'const d = Math.sqrt(dx * dx + dy * dy + dz * dz) + sphere[offset + 3];' \
    'strata_cli' '^web_viewer_selection$'
mutant viewer-closure-first-parent web-viewer/selection.js \
    'for (const p of dag.parents[g]) refined[p] = 1;' \
    'for (const p of dag.parents[g].slice(1)) refined[p] = 1;' \
    'strata_cli' '^web_viewer_selection$'
mutant viewer-budget-overshoot web-viewer/selection.js \
    'if (triangles + dag.delta[g] > budget) {' \
    'if (triangles > budget) {' \
    'strata_cli' '^web_viewer_selection$'
mutant viewer-loaded-some web-viewer/selection.js \
    'if (refined[g] && !dag.groups[g].consumed.every((c) => isLoaded(c))) {' \
    'if (refined[g] && !dag.groups[g].consumed.some((c) => isLoaded(c))) {' \
    'strata_cli' '^web_viewer_selection$'

# ------------------------------------------------------------------------------------------------

if [[ ${1:-} == --list ]]; then
    printf '%s\n' "${names[@]}"
    exit 0
fi
check_only=0
if [[ ${1:-} == --check ]]; then
    check_only=1
    shift
fi
selected=("$@")
wanted() {
    [[ ${#selected[@]} -eq 0 ]] && return 0
    local s
    for s in "${selected[@]}"; do
        [[ $s == "$1" ]] && return 0
    done
    return 1
}

# The scratch tree: a detached worktree at HEAD (reset to HEAD when it exists), configured once.
mkdir -p "$scratch"
if [[ -e $tree/.git ]]; then
    git -C "$tree" reset --quiet --hard
    git -C "$tree" checkout --quiet --detach "$(git rev-parse HEAD)"
else
    git worktree add --quiet --detach "$tree" HEAD
fi
head=$(git -C "$tree" rev-parse --short HEAD)
# the tests read shared data from ../shared beside the source tree
if [[ -d $root/../shared && ! -e $scratch/shared ]]; then
    ln -s "$(cd "$root/.." && pwd)/shared" "$scratch/shared"
fi
for dir in web-viewer tests/node; do
    if [[ -d $root/$dir/node_modules && ! -e $tree/$dir/node_modules ]]; then
        ln -s "$root/$dir/node_modules" "$tree/$dir/node_modules"
    fi
done
if [[ ! -f $build/CMakeCache.txt ]]; then
    cmake -S "$tree" -B "$build" -DSTRATA_BUILD_TESTS=ON -DSTRATA_WERROR=ON \
        -DCMAKE_BUILD_TYPE=Release -DCMAKE_CXX_COMPILER_LAUNCHER=ccache >/dev/null
fi
log=$scratch/logs
rm -rf "$log"
mkdir -p "$log"

# Replaces OLD by NEW in FILE when OLD occurs exactly once; else prints how often it occurs.
apply_mutant() {
    python3 - "$1" "$2" "$3" <<'EOF'
import sys
path, old, new = sys.argv[1:4]
text = open(path, encoding="utf-8").read()
count = text.count(old)
if count != 1:
    print(f"pattern occurs {count} times in {path}")
    sys.exit(1)
open(path, "w", encoding="utf-8").write(text.replace(old, new))
EOF
}

results=()
failed=0
for i in "${!names[@]}"; do
    name=${names[$i]}
    wanted "$name" || continue
    file=${files[$i]}
    start=$(date +%s)
    status=""
    detail=""
    git -C "$tree" checkout --quiet -- .
    if ! why=$(apply_mutant "$tree/$file" "${olds[$i]}" "${news[$i]}"); then
        status=STALE
        detail=$why
    elif [[ $check_only == 1 ]]; then
        status=applies
        detail="--check: not built"
    elif ! cmake --build "$build" -j"$jobs" --target ${targets[$i]} >"$log/$name.build" 2>&1; then
        status=BUILD-ERROR
        detail="see $log/$name.build"
    else
        # note: a test that fails, times out or crashes catches the mutant; none selected is an
        # error (the regex no longer names a test).
        if ctest --test-dir "$build" -R "${tests[$i]}" -j"$jobs" --timeout 1200 --output-on-failure \
            >"$log/$name.test" 2>&1; then
            if grep -q "No tests were found" "$log/$name.test"; then
                status=NO-TESTS
                detail="ctest -R '${tests[$i]}' selects nothing"
            else
                status=SURVIVED
                detail="$(grep -Eo '[0-9]+ tests? passed|100% tests passed, 0 tests failed out of [0-9]+' "$log/$name.test" | tail -1)"
            fi
        else
            status=caught
            detail="$(grep -Eo '[0-9]+ tests failed out of [0-9]+' "$log/$name.test" | tail -1)"
            # note: the first test that failed, not one that was skipped
            first=$(sed -n '/The following tests FAILED/,$p' "$log/$name.test" |
                grep -E '^\s+[0-9]+ - ' | grep -v '(Skipped)' | head -1 |
                sed -E 's/^\s+[0-9]+ - //; s/ \(.*//')
            [[ -n $first ]] && detail="$detail, e.g. $first"
        fi
    fi
    git -C "$tree" checkout --quiet -- .
    [[ $status == caught || $status == applies ]] || failed=1
    seconds=$(($(date +%s) - start))
    results+=("$(printf '%-38s %-12s %5ss  %s' "$name" "$status" "$seconds" "$detail")")
    echo "${results[-1]}"
done

echo
echo "mutants of $head ($(date -u +%Y-%m-%dT%H:%MZ)), logs in $log:"
printf '%-38s %-12s %6s  %s\n' mutant result time detail
printf '%s\n' "${results[@]}"
caught=$(printf '%s\n' "${results[@]}" | grep -c ' caught ' || true)
survived=$(printf '%s\n' "${results[@]}" | grep -c ' SURVIVED ' || true)
echo "caught $caught, survived $survived, of ${#results[@]} mutants"
exit $failed
