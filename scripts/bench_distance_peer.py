#!/usr/bin/env python3
"""Peer of tests/bench/distance_bench.cpp: scipy.ndimage.distance_transform_edt on the same masks.

Reads the window masks the benchmark wrote (<name>_<width>x<height>.u8, row-major uint8, 1 = label)
and its JSON results, times scipy on each mask at the pixel grid (one thread, mean over runs like
Google Benchmark), and prints input pixels per second for both with their ratio. Two scipy rows:
`edt` is the call the brief names, distance_transform_edt(mask, return_indices=True): unsigned,
inside only, to the nearest background pixel centre; `edt x2` adds the call on ~mask, which a
signed field with closest points would need. strata computes a signed field with closest contour
sites on the half-pixel grid, 4x the nodes of the pixel grid (Mnode/s column).

Usage: bench_distance_peer.py MASK_DIR OURS_JSON [--min-time SECONDS]
"""
import argparse
import json
import pathlib
import re
import time

import numpy as np
from scipy import ndimage


def mean_time(fn, min_time):
    """Mean wall time of fn() over at least 3 runs and min_time seconds, after one warm-up."""
    fn()
    runs = 0
    start = time.perf_counter()
    while runs < 3 or time.perf_counter() - start < min_time:
        fn()
        runs += 1
    return (time.perf_counter() - start) / runs


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("mask_dir", type=pathlib.Path)
    parser.add_argument("ours_json", type=pathlib.Path)
    parser.add_argument("--min-time", type=float, default=0.5)
    args = parser.parse_args()

    ours = {}
    for b in json.loads(args.ours_json.read_text())["benchmarks"]:
        if b.get("run_type", "iteration") != "iteration":
            continue
        name = b["name"].split("/")[1]  # distance_field/<mask>/real_time
        ours[name] = b

    header = (f"{'mask':<12} {'window px':>11} {'strata ms':>10} {'Mpixel/s':>9} {'Mnode/s':>8}"
              f" {'scipy edt ms':>13} {'Mpixel/s':>9} {'ratio':>6}"
              f" {'edt x2 ms':>10} {'Mpixel/s':>9} {'ratio':>6}")
    print("strata compute_distance_field vs scipy.ndimage.distance_transform_edt"
          "(mask, return_indices=True), one thread, same window masks; ratio = strata / scipy"
          " in Mpixel/s")
    print(header)
    print("-" * len(header))
    for path in sorted(args.mask_dir.glob("*.u8")):
        match = re.fullmatch(r"(.+)_(\d+)x(\d+)", path.stem)
        if not match or match.group(1) not in ours:
            continue
        name, width, height = match.group(1), int(match.group(2)), int(match.group(3))
        mask = np.fromfile(path, dtype=np.uint8).reshape(height, width).astype(bool)
        pixels = width * height
        one = mean_time(lambda: ndimage.distance_transform_edt(mask, return_indices=True),
                        args.min_time)
        inverse = ~mask
        two = mean_time(lambda: (ndimage.distance_transform_edt(mask, return_indices=True),
                                 ndimage.distance_transform_edt(inverse, return_indices=True)),
                        args.min_time)
        b = ours[name]
        ms = b["real_time"] * {"ns": 1e-6, "us": 1e-3, "ms": 1.0, "s": 1e3}[b["time_unit"]]
        ours_rate = b["Mpixel/s"]
        one_rate = pixels / one / 1e6
        two_rate = pixels / two / 1e6
        print(f"{name:<12} {pixels:>11} {ms:>10.2f} {ours_rate:>9.2f} {b['Mnode/s']:>8.2f}"
              f" {one * 1e3:>13.2f} {one_rate:>9.2f} {ours_rate / one_rate:>6.2f}"
              f" {two * 1e3:>10.2f} {two_rate:>9.2f} {ours_rate / two_rate:>6.2f}")


if __name__ == "__main__":
    main()
