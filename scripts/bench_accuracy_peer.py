#!/usr/bin/env python3
"""Peers of strata's surface reconstruction for scripts/bench-accuracy.sh: label stack -> meshes.

`mesh NIFTI OUT_DIR` reads a label stack written by `strata phantom NAME --format nifti` and writes
one PLY per method to OUT_DIR, vertices in patient LPS mm, plus OUT_DIR/peer_times.json (seconds
per method, mesh building only: NIfTI parsing and PLY writing are not timed):
  flying-edges.ply     vtkDiscreteFlyingEdges3D on every non-zero label, the volume padded by one
                       background voxel on each side so that surfaces close (what 3D Slicer's
                       labelmap -> closed surface conversion runs, before its smoothing).
  slicer-smoothed.ply  the same followed by Slicer's default smoothing (factor 0.5):
                       vtkWindowedSincPolyDataFilter, 20 iterations, pass band 10^(-4 * 0.5),
                       no boundary or feature-edge smoothing, non-manifold smoothing, normalised
                       coordinates, run in voxel index space like Slicer.
  shape-based.ply      shape-based interpolation: per slice the signed Euclidean distance of the
                       foreground mask (scipy.ndimage.distance_transform_edt outside minus inside,
                       each shifted by half a pixel so that the zero level sits on the pixel
                       boundary), linearly interpolated in z onto an isotropic grid (z step = one
                       in-plane pixel), then vtkFlyingEdges3D at 0. Slices without foreground,
                       and one background slice padded beyond each end of the stack, take the
                       mirrored distance |sdf| of their non-empty neighbour slices (the smaller
                       of the two), so that objects close half-way between slices as with flying
                       edges; far from any foreground they hold the slice's width + height.
`record ... ACCURACY_JSON` turns the `mesh_accuracy --json` output for one method (all of its
meshes taken as one surface) into one JSON line, or with `--missing TEXT` a line that says why the
method has no meshes.
`table RESULTS_JSONL` prints the comparison table of the JSON lines bench-accuracy.sh collected.

Frames: the file's sform (else qform, else pixdim) maps voxel index (i, j, k), voxel centres at
integer indices, to RAS mm; negating the first two rows gives LPS, the frame strata's SliceStack
uses (index_to_world) and tests/bench/mesh_accuracy expects. Meshes are built in index space and
mapped through that affine. The NIfTI is parsed with numpy + gzip (NIfTI-1, little-endian, integer
voxels), so no reader's own reorientation can shift the frame.

Needs Debian's python3-numpy, python3-scipy and python3-vtk9.
Usage: bench_accuracy_peer.py mesh NIFTI OUT_DIR
       bench_accuracy_peer.py record --phantom P --d D --method M [--seconds S | --times JSON]
                              ACCURACY_JSON
       bench_accuracy_peer.py record --phantom P --d D --method M --missing TEXT
       bench_accuracy_peer.py table RESULTS_JSONL
"""
import argparse
import gzip
import json
import pathlib
import struct
import sys
import time

import numpy as np
from scipy import ndimage
from vtkmodules.util import numpy_support
from vtkmodules.vtkCommonDataModel import vtkImageData
from vtkmodules.vtkFiltersCore import vtkFlyingEdges3D
from vtkmodules.vtkFiltersGeneral import vtkDiscreteFlyingEdges3D

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))
import bench_e2e_peer as e2e  # noqa: E402  (3D Slicer's smoothing)

NIFTI_TYPES = {2: np.uint8, 4: np.int16, 8: np.int32, 256: np.int8, 512: np.uint16,
               768: np.uint32}
SLICER_SMOOTHING_FACTOR = 0.5  # Slicer's default "smoothing factor" for closed surfaces


def quaternion_affine(header):
    """NIfTI-1 qform (method 2) as a 4x4 index -> RAS matrix."""
    b, c, d = struct.unpack_from("<3f", header, 256)
    qx, qy, qz = struct.unpack_from("<3f", header, 268)
    pixdim = struct.unpack_from("<8f", header, 76)
    a = np.sqrt(max(0.0, 1.0 - (b * b + c * c + d * d)))
    rotation = np.array([
        [a * a + b * b - c * c - d * d, 2 * (b * c - a * d), 2 * (b * d + a * c)],
        [2 * (b * c + a * d), a * a + c * c - b * b - d * d, 2 * (c * d - a * b)],
        [2 * (b * d - a * c), 2 * (c * d + a * b), a * a + d * d - c * c - b * b]])
    qfac = -1.0 if pixdim[0] < 0 else 1.0
    affine = np.eye(4)
    affine[:3, :3] = rotation * np.array([pixdim[1], pixdim[2], qfac * pixdim[3]])
    affine[:3, 3] = (qx, qy, qz)
    return affine


def read_nifti(path):
    """Labels as an array indexed [k, j, i] and the 4x4 voxel index -> LPS mm affine."""
    raw = pathlib.Path(path).read_bytes()
    if str(path).endswith(".gz"):
        raw = gzip.decompress(raw)
    if struct.unpack_from("<i", raw, 0)[0] != 348:
        sys.exit(f"{path}: not a little-endian NIfTI-1 file")
    header = raw[:348]
    dims = struct.unpack_from("<8h", header, 40)
    if dims[0] < 3 or any(n != 1 for n in dims[4:dims[0] + 1]):
        sys.exit(f"{path}: expected a 3-D volume, found dim {dims}")
    nx, ny, nz = dims[1:4]
    datatype = struct.unpack_from("<h", header, 70)[0]
    if datatype not in NIFTI_TYPES:
        sys.exit(f"{path}: unsupported datatype {datatype}, expected integer voxels")
    vox_offset = int(struct.unpack_from("<f", header, 108)[0])
    count = nx * ny * nz
    labels = np.frombuffer(raw, dtype=np.dtype(NIFTI_TYPES[datatype]).newbyteorder("<"),
                           count=count, offset=vox_offset).reshape(nz, ny, nx)
    qform_code, sform_code = struct.unpack_from("<2h", header, 252)
    if sform_code > 0:
        ras = np.eye(4)
        ras[0] = struct.unpack_from("<4f", header, 280)
        ras[1] = struct.unpack_from("<4f", header, 296)
        ras[2] = struct.unpack_from("<4f", header, 312)
    elif qform_code > 0:
        ras = quaternion_affine(header)
    else:
        ras = np.diag(list(struct.unpack_from("<3f", header, 80)) + [1.0])
    lps = np.diag([-1.0, -1.0, 1.0, 1.0]) @ ras
    return labels, lps


def image_data(volume, origin=(0.0, 0.0, 0.0)):
    """vtkImageData over a [k, j, i] array, spacing 1: points are in voxel index units."""
    image = vtkImageData()
    nz, ny, nx = volume.shape
    image.SetDimensions(nx, ny, nz)
    image.SetOrigin(*origin)
    image.SetSpacing(1.0, 1.0, 1.0)
    scalars = numpy_support.numpy_to_vtk(np.ascontiguousarray(volume).ravel(), deep=True)
    image.GetPointData().SetScalars(scalars)
    return image


def poly_arrays(poly):
    """Points (n x 3) and triangles (m x 3) of a triangle-only vtkPolyData."""
    if poly.GetNumberOfPoints() == 0:
        return np.zeros((0, 3)), np.zeros((0, 3), dtype=np.int64)
    points = numpy_support.vtk_to_numpy(poly.GetPoints().GetData()).astype(np.float64)
    cells = numpy_support.vtk_to_numpy(poly.GetPolys().GetData()).reshape(-1, 4)
    if not np.all(cells[:, 0] == 3):
        sys.exit("expected triangles only")
    return points, cells[:, 1:].astype(np.int64)


def discrete_flying_edges(labels, values):
    padded = np.pad(labels, 1)
    fe = vtkDiscreteFlyingEdges3D()
    fe.SetInputData(image_data(padded, origin=(-1.0, -1.0, -1.0)))
    for n, v in enumerate(values):
        fe.SetValue(n, float(v))
    fe.ComputeNormalsOff()
    fe.ComputeGradientsOff()
    fe.ComputeScalarsOff()
    fe.Update()
    return fe.GetOutput()


def slicer_smooth(poly, factor=SLICER_SMOOTHING_FACTOR):
    return e2e.slicer_smooth(poly, 20, factor)


def shape_based(mask, k_per_px):
    """Shape-based interpolation; returns (points in index space, triangles).

    mask is [k, j, i] bool; k_per_px is the slice index step of one in-plane pixel (1 / d)."""
    nz, ny, nx = mask.shape
    big = float(nx + ny)
    padded = np.pad(mask, ((1, 1), (1, 1), (1, 1)))  # background ring and end slices
    sdf = np.full(padded.shape, big, dtype=np.float32)
    filled = [bool(padded[k].any()) for k in range(padded.shape[0])]
    for k in range(padded.shape[0]):
        m = padded[k]
        if not filled[k]:
            continue
        outside = ndimage.distance_transform_edt(~m)
        inside = ndimage.distance_transform_edt(m)
        sdf[k] = np.where(m, 0.5 - inside, outside - 0.5)
    # an empty slice has no distance of its own: mirror its non-empty neighbours' so that the
    # surface closes half-way between the slices, where flying edges closes it too
    for k in range(padded.shape[0]):
        if filled[k]:
            continue
        for n in (k - 1, k + 1):
            if 0 <= n < padded.shape[0] and filled[n]:
                sdf[k] = np.minimum(sdf[k], np.abs(sdf[n]))
    # isotropic grid: padded slice index kp = k + 1 from 0 to nz + 1 in steps of k_per_px
    steps = int(np.floor((padded.shape[0] - 1) / k_per_px + 1e-9))
    kp = np.arange(steps + 1) * k_per_px
    lo = np.minimum(np.floor(kp).astype(np.int64), padded.shape[0] - 2)
    t = (kp - lo).astype(np.float32)[:, None, None]
    iso = (1.0 - t) * sdf[lo] + t * sdf[lo + 1]
    fe = vtkFlyingEdges3D()
    fe.SetInputData(image_data(iso, origin=(-1.0, -1.0, 0.0)))
    fe.SetValue(0, 0.0)
    fe.ComputeNormalsOff()
    fe.ComputeGradientsOff()
    fe.ComputeScalarsOff()
    fe.Update()
    points, triangles = poly_arrays(fe.GetOutput())
    # the grid's third axis counts isotropic steps from padded slice 0 (slice index -1)
    points[:, 2] = points[:, 2] * k_per_px - 1.0
    return points, triangles


def to_world(points, affine):
    return points @ affine[:3, :3].T + affine[:3, 3]


def write_ply(path, points, triangles):
    """Binary little-endian PLY: float32 x, y, z and uchar-counted int32 vertex_indices."""
    header = (f"ply\nformat binary_little_endian 1.0\ncomment strata bench_accuracy_peer\n"
              f"element vertex {len(points)}\nproperty float x\nproperty float y\n"
              f"property float z\nelement face {len(triangles)}\n"
              f"property list uchar int vertex_indices\nend_header\n")
    faces = np.zeros(len(triangles), dtype=[("n", "u1"), ("v", "<i4", (3,))])
    faces["n"] = 3
    faces["v"] = triangles
    with open(path, "wb") as out:
        out.write(header.encode("ascii"))
        out.write(np.asarray(points, dtype="<f4").tobytes())
        out.write(faces.tobytes())


def timed(fn):
    start = time.perf_counter()
    result = fn()
    return result, time.perf_counter() - start


def run_mesh(args):
    labels, affine = read_nifti(args.nifti)
    values = [int(v) for v in np.unique(labels) if v != 0]
    spacing = np.linalg.norm(affine[:3, :3], axis=0)
    if not np.isclose(spacing[0], spacing[1], rtol=1e-4):
        sys.exit(f"{args.nifti}: pixels are not square ({spacing[0]} x {spacing[1]} mm)")
    k_per_px = spacing[0] / spacing[2]
    args.out_dir.mkdir(parents=True, exist_ok=True)
    times = {}

    poly, times["flying-edges"] = timed(lambda: discrete_flying_edges(labels, values))
    points, triangles = poly_arrays(poly)
    write_ply(args.out_dir / "flying-edges.ply", to_world(points, affine), triangles)

    smoothed, seconds = timed(lambda: slicer_smooth(poly))
    times["slicer-smoothed"] = times["flying-edges"] + seconds
    points, triangles = poly_arrays(smoothed)
    write_ply(args.out_dir / "slicer-smoothed.ply", to_world(points, affine), triangles)

    (points, triangles), times["shape-based"] = timed(
        lambda: shape_based(labels != 0, k_per_px))
    write_ply(args.out_dir / "shape-based.ply", to_world(points, affine), triangles)

    (args.out_dir / "peer_times.json").write_text(json.dumps(times, indent=2) + "\n")


def volume_error(r):
    """The enclosed volume's error in % of the truth's, or '-' (rows recorded without volumes)."""
    if not r.get("truth_volume_px3"):
        return f"{'-':>6}"
    return f"{100.0 * (r['volume_px3'] / r['truth_volume_px3'] - 1.0):>+6.2f}"


def run_table(args):
    rows = [json.loads(line) for line in args.results.read_text().splitlines() if line.strip()]
    methods = ["strata", "flying-edges", "slicer-smoothed", "shape-based"]
    header = (f"{'phantom':<14} {'d':>3} {'method':<16} {'triangles':>9} {'mean px':>8}"
              f" {'rms px':>7} {'max px':>7} {'bias px':>8} {'vol %':>6} {'time s':>7}"
              f"  {'mean/FE':>7} {'rms/FE':>7} {'max/FE':>7} {'tri/FE':>7}")
    print("Surface accuracy, one-sided |distance| mesh -> analytic solid, area-weighted; px = "
          "in-plane pixel (1 mm). bias > 0: the mesh lies outside the solid on average. vol %: "
          "enclosed volume against the analytic solid's.")
    print("Ratios vs flying-edges (FE); < 1 is better for errors. Time: peers build the mesh "
          "only; strata is the whole `strata build` command (read, all stages, write).")
    print(header)
    print("-" * len(header))
    seen = []
    for r in rows:
        key = (r["phantom"], r["d"])
        if key not in seen:
            seen.append(key)
    for key in seen:
        group = {r["method"]: r for r in rows if (r["phantom"], r["d"]) == key}
        fe = group.get("flying-edges")
        for method in methods:
            r = group.get(method)
            label = f"{key[0]:<14} {key[1]:>3g} {method:<16}"
            if r is None:
                continue
            if "missing" in r:
                print(f"{label} {r['missing']}")
                continue

            def ratio(field):
                if fe is None or not fe.get(field):
                    return f"{'-':>7}"
                return f"{r[field] / fe[field]:>7.2f}"

            print(f"{label} {r['triangles']:>9} {r['mean_px']:>8.3f} {r['rms_px']:>7.3f}"
                  f" {r['max_px']:>7.3f} {r['bias_px']:>+8.3f} {volume_error(r)}"
                  f" {r['seconds']:>7.3f}"
                  f"  {ratio('mean_px')} {ratio('rms_px')} {ratio('max_px')}"
                  f" {ratio('triangles')}"
                  + ("  (clipped)" if r.get("clipped") else ""))
    notes = sorted({r["phantom"] for r in rows if r.get("clipped")})
    if notes:
        print(f"(clipped) truth = solid inside the stack's voxel extent: {', '.join(notes)} "
              "reach beyond the sampled slab")


def run_record(args):
    """One JSON line: a method's accuracy, all its meshes taken as one surface."""
    row = {"phantom": args.phantom, "d": args.d, "method": args.method}
    seconds = args.seconds
    if seconds is None and args.times is not None:
        seconds = json.loads(args.times.read_text()).get(args.method)
    if seconds is None:
        seconds = float("nan")
    if args.missing:
        row["missing"] = args.missing
    else:
        meshes = json.loads(args.accuracy.read_text())
        if not meshes:
            sys.exit(f"{args.accuracy}: no mesh measured")
        area = sum(m["area_px2"] for m in meshes)

        def weighted(field):
            return sum(m[field] * m["area_px2"] for m in meshes) / area if area > 0 else 0.0

        row.update({
            "meshes": [m["mesh"] for m in meshes],
            "triangles": sum(m["triangles"] for m in meshes),
            "area_px2": area,
            "mean_px": weighted("mean_px"),
            "rms_px": (sum(m["rms_px"] ** 2 * m["area_px2"] for m in meshes) / area) ** 0.5
            if area > 0 else 0.0,
            "max_px": max(m["max_px"] for m in meshes),
            "bias_px": weighted("bias_px"),
            "volume_px3": sum(m.get("volume_px3", 0.0) for m in meshes),
            "truth_volume_px3": sum(m.get("truth_volume_px3", 0.0) for m in meshes),
            "pixel_mm": meshes[0]["pixel_mm"],
            "centroid_px": [sum(m["centroid_px"][a] * m["area_px2"] for m in meshes) / area
                            if area > 0 else 0.0 for a in range(3)],
            "clipped": any(m["clipped"] for m in meshes),
            "exact_distance": all(m["exact_distance"] for m in meshes),
            "seconds": seconds,
        })
    print(json.dumps(row))


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = parser.add_subparsers(dest="command", required=True)
    mesh = sub.add_parser("mesh", help="label stack (.nii/.nii.gz) -> peer meshes (PLY, LPS mm)")
    mesh.add_argument("nifti", type=pathlib.Path)
    mesh.add_argument("out_dir", type=pathlib.Path)
    table = sub.add_parser("table", help="print the table of collected results (JSON lines)")
    table.add_argument("results", type=pathlib.Path)
    record = sub.add_parser("record", help="mesh_accuracy --json output -> one result line")
    record.add_argument("--phantom", required=True)
    record.add_argument("--d", type=float, required=True)
    record.add_argument("--method", required=True)
    record.add_argument("--seconds", type=float, help="the method's time")
    record.add_argument("--times", type=pathlib.Path,
                        help="or the peer_times.json of `mesh` holding it under the method's name")
    record.add_argument("--missing", help="no meshes: print this text in the method's row")
    record.add_argument("accuracy", type=pathlib.Path, nargs="?")
    args = parser.parse_args()
    if args.command == "mesh":
        run_mesh(args)
    elif args.command == "record":
        if not args.missing and args.accuracy is None:
            parser.error("record: expected ACCURACY_JSON or --missing TEXT")
        run_record(args)
    else:
        run_table(args)


if __name__ == "__main__":
    main()
