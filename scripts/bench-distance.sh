#!/usr/bin/env bash
# Distance stage against its peer, side by side in one run: tests/bench/distance_bench
# (compute_distance_field, one thread) writes its window masks to a temp folder, then
# scripts/bench_distance_peer.py times scipy.ndimage.distance_transform_edt on the same pixels and
# prints both rates and their ratio. Builds nothing: configure with -DSTRATA_BUILD_BENCHMARKS=ON
# and build distance_bench first.
#   bash scripts/bench-distance.sh [path/to/distance_bench] [benchmark flags...]
# The peer needs Debian's python3-numpy and python3-scipy (PYTHON overrides /usr/bin/python3).
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
bench="${1:-$root/build/tests/bench/distance_bench}"
shift || true
python="${PYTHON:-/usr/bin/python3}"
tmp="$(mktemp -d)"
trap 'rm -rf "$tmp"' EXIT
STRATA_BENCH_MASK_DIR="$tmp" "$bench" --benchmark_format=console \
    --benchmark_out="$tmp/ours.json" --benchmark_out_format=json "$@"
echo
"$python" "$root/scripts/bench_distance_peer.py" "$tmp" "$tmp/ours.json"
