#!/usr/bin/env python3
"""VTK's quadric decimation, the VTK peer of scripts/bench-simplify.sh (tests/bench/simplify_peers).

`decimate IN.ply OUT.ply --reduction R` runs vtkQuadricDecimation with VTK's default settings
(VolumePreservation off, no attribute error metric, so vertices move to the quadric optimum and
topology is not preserved) at target reduction R (0.9 = keep about 10% of the triangles) on
IN.ply and writes the result to OUT.ply (binary PLY); prints one JSON line
{"seconds": S, "triangles": T}, S the decimation only (PLY reading and writing are not timed).

`serve` does the same for requests on stdin, one per line, so that the bisection of
tests/bench/simplify_peers pays for Python and VTK start-up once:
    decimate IN.ply R OUT.ply   ->   ok SECONDS TRIANGLES   (or: error MESSAGE)
Input meshes are read once and kept (the same IN.ply is decimated at many reductions).

Needs Debian's python3-vtk9.
Usage: bench_simplify_peer.py decimate IN.ply OUT.ply --reduction R
       bench_simplify_peer.py serve
"""
import argparse
import json
import sys
import time

from vtkmodules.vtkFiltersCore import vtkQuadricDecimation
from vtkmodules.vtkIOPLY import vtkPLYReader, vtkPLYWriter


def read_ply(path):
    reader = vtkPLYReader()
    reader.SetFileName(str(path))
    reader.Update()
    poly = reader.GetOutput()
    if poly.GetNumberOfPolys() == 0:
        raise ValueError(f"{path}: no triangles read")
    return poly


def decimate(poly, reduction):
    """(vtkPolyData, seconds) of vtkQuadricDecimation at `reduction`, default settings."""
    if not 0.0 <= reduction < 1.0:
        raise ValueError(f"reduction {reduction}: expected 0 <= R < 1")
    decimation = vtkQuadricDecimation()
    decimation.SetInputData(poly)
    decimation.SetTargetReduction(reduction)
    start = time.perf_counter()
    decimation.Update()
    seconds = time.perf_counter() - start
    return decimation.GetOutput(), seconds


def write_ply(poly, path):
    writer = vtkPLYWriter()
    writer.SetFileName(str(path))
    writer.SetInputData(poly)
    writer.SetFileTypeToBinary()
    if not writer.Write():
        raise OSError(f"{path}: cannot write")


def run_decimate(args):
    poly, seconds = decimate(read_ply(args.input), args.reduction)
    write_ply(poly, args.output)
    print(json.dumps({"seconds": seconds, "triangles": poly.GetNumberOfPolys()}))


def run_serve():
    inputs = {}
    for line in sys.stdin:
        words = line.split()
        if not words:
            continue
        try:
            if words[0] != "decimate" or len(words) != 4:
                raise ValueError(f"unknown request '{line.strip()}', expected "
                                 "'decimate IN.ply R OUT.ply'")
            path, reduction, out = words[1], float(words[2]), words[3]
            if path not in inputs:
                inputs[path] = read_ply(path)
            poly, seconds = decimate(inputs[path], reduction)
            write_ply(poly, out)
            print(f"ok {seconds:.9f} {poly.GetNumberOfPolys()}", flush=True)
        except (ValueError, OSError) as e:
            print(f"error {e}", flush=True)


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    commands = parser.add_subparsers(dest="command", required=True)
    one = commands.add_parser("decimate", help="decimate one PLY")
    one.add_argument("input")
    one.add_argument("output")
    one.add_argument("--reduction", type=float, required=True)
    commands.add_parser("serve", help="decimation requests on stdin")
    args = parser.parse_args()
    if args.command == "decimate":
        run_decimate(args)
    else:
        run_serve()


if __name__ == "__main__":
    main()
