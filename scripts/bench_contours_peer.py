#!/usr/bin/env python3
"""Helper of scripts/bench-contours.sh: planar contours in, against rasterise-then-mesh.

`phantom OUT_DIR [--gap MM] [--scale S]` writes OUT_DIR/phantom.json (contour JSON, schema/contours.schema.json):
a ball (radius 20 mm, centre 0) and a torus (radii 22 and 9 mm, centre x = 60 mm, axis z), every
length times SCALE (--scale, default 1; 2.5 makes them organ-sized), sliced
analytically on planes GAP mm apart (default 3, a CT's slice spacing) at z = GAP/2 + k GAP, as
polygons with vertices on the true circles every <= 0.5 mm (the torus: outer circle and hole as two
contours).

`raster OUT_DIR --pixel MM` is the rasterise-then-mesh route, what 3D Slicer does when it turns a
structure set into a labelmap and then into "Export to models" surfaces: every plane's polygons
filled (even-odd, pixel centres) on a grid of MM pixels whose slices are the planes, then per
structure vtkDiscreteFlyingEdges3D, vtkWindowedSincPolyDataFilter with Slicer's defaults (pass band
0.01, 20 iterations, boundary and feature smoothing off, non-manifold smoothing on, normalised
coordinates), index -> patient mm, vtkPolyDataNormals. Writes OUT_DIR/raster_MM.ply and .json
(seconds of rasterisation + meshing, triangles).

`error OUT_DIR MESH... --name NAME` measures meshes (PLY, mm) against the analytic surfaces:
area-weighted random samples (300k) plus every vertex, distance to the true surface (exact: ball
|p| - r, torus sqrt((rho - R)^2 + z^2) - r); "between planes" keeps the samples whose z lies
strictly between the first and the last plane of their object (the region the contours describe;
end caps and what lies beyond the end planes are guesses of either route); truth -> mesh from area-
uniform samples of the true surfaces between planes (VTK's exact point-triangle distance).
Writes OUT_DIR/error_NAME.json.

`table OUT_DIR` prints the comparison.
Needs Debian's python3-numpy and python3-vtk9.
"""
import argparse
import json
import math
import pathlib
import sys
import time

import numpy as np

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))
from bench_e2e_peer import (flying_edges, mesh_distance, read_ply, slicer_smooth,  # noqa: E402
                            triangle_array, write_ply)

BALL_R = 20.0
TORUS_C = np.array([60.0, 0.0, 0.0])
TORUS_R, TORUS_r = 22.0, 9.0


def set_scale(scale):
    """Every length of the phantom times `scale` (planes and pixels stay)."""
    global BALL_R, TORUS_C, TORUS_R, TORUS_r
    BALL_R, TORUS_C = 20.0 * scale, np.array([60.0 * scale, 0.0, 0.0])
    TORUS_R, TORUS_r = 22.0 * scale, 9.0 * scale


def load_params(out):
    params = json.loads((out / "params.json").read_text())
    set_scale(params["scale"])
    return params["gap"]


def circle(cx, cy, r):
    n = max(12, math.ceil(2 * math.pi * r / 0.5))
    a = 2 * math.pi * np.arange(n) / n
    return np.stack([cx + r * np.cos(a), cy + r * np.sin(a)], axis=1)


def planes(gap):
    k = np.arange(-40, 41)
    z = gap / 2 + k * gap
    return z[np.abs(z) < BALL_R + gap]


def structures(gap):
    """Per structure: name and the list of (z, [polygons])."""
    ball, torus = [], []
    for z in planes(gap):
        if abs(z) < BALL_R:
            ball.append((z, [circle(0.0, 0.0, math.sqrt(BALL_R ** 2 - z ** 2))]))
        if abs(z) < TORUS_r:
            h = math.sqrt(TORUS_r ** 2 - z ** 2)
            torus.append((z, [circle(TORUS_C[0], TORUS_C[1], TORUS_R + h),
                              circle(TORUS_C[0], TORUS_C[1], TORUS_R - h)]))
    return [("ball", ball), ("torus", torus)]


def run_phantom(args):
    out = pathlib.Path(args.out_dir)
    out.mkdir(parents=True, exist_ok=True)
    set_scale(args.scale)
    rois = []
    for number, (name, slices) in enumerate(structures(args.gap), start=1):
        rois.append({"number": number, "name": name,
                     "color_rgb": [200, 60, 60] if name == "ball" else [60, 60, 200],
                     "slices": [{"z": float(z), "contours": [
                         {"points": [[float(x), float(y)] for x, y in poly]} for poly in polys]}
                         for z, polys in slices]})
    doc = {"format": "planar contours v1", "frame": "LPS mm",
           "note": f"bench-contours phantom: ball and torus, planes {args.gap} mm apart",
           "rois": rois}
    (out / "phantom.json").write_text(json.dumps(doc) + "\n")
    (out / "params.json").write_text(json.dumps({"gap": args.gap, "scale": args.scale}) + "\n")


def fill_even_odd(polys, xs, ys):
    """Boolean mask [len(ys), len(xs)]: pixel centres inside the polygons by the even-odd rule."""
    mask = np.zeros((len(ys), len(xs)), dtype=bool)
    for j, y in enumerate(ys):
        crossings = []
        for p in polys:
            a, b = p, np.roll(p, -1, axis=0)
            hit = (a[:, 1] > y) != (b[:, 1] > y)
            xa, ya, xb, yb = a[hit, 0], a[hit, 1], b[hit, 0], b[hit, 1]
            crossings.extend(xa + (y - ya) * (xb - xa) / (yb - ya))
        crossings.sort()
        for x0, x1 in zip(crossings[0::2], crossings[1::2]):
            mask[j] ^= (xs >= x0) & (xs < x1)
    return mask


def run_raster(args):
    from vtkmodules.util import numpy_support
    from vtkmodules.vtkCommonCore import vtkSMPTools
    from vtkmodules.vtkCommonDataModel import vtkImageData
    from vtkmodules.vtkCommonTransforms import vtkTransform
    from vtkmodules.vtkFiltersCore import vtkAppendPolyData, vtkPolyDataNormals
    from vtkmodules.vtkFiltersGeneral import vtkTransformPolyDataFilter

    vtkSMPTools.Initialize(2)
    out = pathlib.Path(args.out_dir)
    gap = load_params(out)
    px = args.pixel
    zs = planes(gap)
    # the grid: pixel centres on multiples of px, with a border of empty slices and pixels
    x0, x1 = -BALL_R - 2 * px, TORUS_C[0] + TORUS_R + TORUS_r + 2 * px
    y0, y1 = -(TORUS_R + TORUS_r) - 2 * px, TORUS_R + TORUS_r + 2 * px
    xs = np.arange(math.floor(x0 / px), math.ceil(x1 / px) + 1) * px + px / 2
    ys = np.arange(math.floor(y0 / px), math.ceil(y1 / px) + 1) * px + px / 2
    z_all = np.concatenate([[zs[0] - gap], zs, [zs[-1] + gap]])
    start = time.perf_counter()
    labels = np.zeros((len(z_all), len(ys), len(xs)), dtype=np.uint8)
    for value, (_, slices) in enumerate(structures(gap), start=1):
        for z, polys in slices:
            k = int(np.argmin(np.abs(z_all - z)))
            labels[k][fill_even_odd(polys, xs, ys)] = value
    raster_s = time.perf_counter() - start
    image = vtkImageData()
    image.SetDimensions(len(xs), len(ys), len(z_all))
    image.SetOrigin(0.0, 0.0, 0.0)
    image.SetSpacing(1.0, 1.0, 1.0)
    image.GetPointData().SetScalars(numpy_support.numpy_to_vtk(labels.ravel(), deep=True))
    start = time.perf_counter()
    append = vtkAppendPolyData()
    for value in (1, 2):
        smoothed = slicer_smooth(flying_edges(image, value))
        transform = vtkTransform()  # index -> mm (uniform planes: an affine map)
        transform.Translate(xs[0], ys[0], z_all[0])
        transform.Scale(px, px, gap)
        to_world = vtkTransformPolyDataFilter()
        to_world.SetInputData(smoothed)
        to_world.SetTransform(transform)
        normals = vtkPolyDataNormals()
        normals.SetInputConnection(to_world.GetOutputPort())
        normals.ConsistencyOn()
        normals.SplittingOff()
        normals.Update()
        append.AddInputData(normals.GetOutput())
    append.Update()
    mesh_s = time.perf_counter() - start
    poly = append.GetOutput()
    points = numpy_support.vtk_to_numpy(poly.GetPoints().GetData()).astype(np.float64)
    tris = triangle_array(poly)
    name = f"raster_{px:g}"
    write_ply(out / f"{name}.ply", points, tris)
    (out / f"{name}.json").write_text(json.dumps(
        {"rasterise_s": raster_s, "mesh_s": mesh_s, "triangles": int(len(tris)),
         "grid": [len(xs), len(ys), len(z_all)]}) + "\n")


def truth_distance(p):
    ball = np.linalg.norm(p, axis=1) - BALL_R
    q = p - TORUS_C
    torus = np.hypot(np.hypot(q[:, 0], q[:, 1]) - TORUS_R, q[:, 2]) - TORUS_r
    near_ball = p[:, 0] < 24.5 * BALL_R / 20.0  # the ball ends at x = 20 s, the torus at 29 s
    return np.where(near_ball, ball, torus), near_ball


def truth_samples(gap, rng, spacing=0.5):
    """Area-uniform points of the true surfaces between each object's first and last plane."""
    zs = planes(gap)
    out = []
    zb = zs[np.abs(zs) < BALL_R]
    n = int(4 * math.pi * BALL_R ** 2 / spacing ** 2)
    z = rng.uniform(-BALL_R, BALL_R, n)  # Archimedes: uniform z is area-uniform on a sphere
    a = rng.uniform(0, 2 * math.pi, n)
    r = np.sqrt(BALL_R ** 2 - z ** 2)
    p = np.stack([r * np.cos(a), r * np.sin(a), z], axis=1)
    out.append(p[(z >= zb[0]) & (z <= zb[-1])])
    zt = zs[np.abs(zs) < TORUS_r]
    n = int(4 * math.pi ** 2 * TORUS_R * TORUS_r / spacing ** 2)
    u = rng.uniform(0, 2 * math.pi, 3 * n)
    v = rng.uniform(0, 2 * math.pi, 3 * n)
    keep = rng.uniform(0, 1, 3 * n) < (TORUS_R + TORUS_r * np.cos(v)) / (TORUS_R + TORUS_r)
    u, v = u[keep][:n], v[keep][:n]
    rho = TORUS_R + TORUS_r * np.cos(v)
    p = np.stack([TORUS_C[0] + rho * np.cos(u), rho * np.sin(u), TORUS_r * np.sin(v)], axis=1)
    out.append(p[(p[:, 2] >= zt[0]) & (p[:, 2] <= zt[-1])])
    return np.concatenate(out)


def run_error(args):
    out = pathlib.Path(args.out_dir)
    gap = load_params(out)
    pts_list, tri_list, base = [], [], 0
    for path in args.meshes:
        p, t = read_ply(path)
        pts_list.append(p)
        tri_list.append(t + base)
        base += len(p)
    points, tris = np.concatenate(pts_list), np.concatenate(tri_list)
    rng = np.random.default_rng(7)
    a, b, c = points[tris[:, 0]], points[tris[:, 1]], points[tris[:, 2]]
    area = 0.5 * np.linalg.norm(np.cross(b - a, c - a), axis=1)
    count = 300000
    which = rng.choice(len(tris), size=count, p=area / area.sum())
    u, v = rng.random(count), rng.random(count)
    flip = u + v > 1
    u[flip], v[flip] = 1 - u[flip], 1 - v[flip]
    samples = a[which] + u[:, None] * (b[which] - a[which]) + v[:, None] * (c[which] - a[which])
    samples = np.concatenate([samples, points])
    d, near_ball = truth_distance(samples)
    d = np.abs(d)
    zs = planes(gap)
    zb, zt = zs[np.abs(zs) < BALL_R], zs[np.abs(zs) < TORUS_r]
    z = samples[:, 2]
    eps = 1e-6  # strictly between: the end caps lie on the end planes, beyond what contours say
    between = np.where(near_ball, (z > zb[0] + eps) & (z < zb[-1] - eps),
                       (z > zt[0] + eps) & (z < zt[-1] - eps))
    back = mesh_distance(points, tris, truth_samples(gap, rng))
    result = {"triangles": int(len(tris)),
              "mean_mm": float(d.mean()), "max_mm": float(d.max()),
              "between_mean_mm": float(d[between].mean()), "between_max_mm": float(d[between].max()),
              "truth_to_mesh_between_mean_mm": float(back.mean()),
              "truth_to_mesh_between_max_mm": float(back.max())}
    (out / f"error_{args.name}.json").write_text(json.dumps(result, indent=1) + "\n")


def run_table(args):
    out = pathlib.Path(args.out_dir)
    gap = load_params(out)
    rows = []
    strata = json.loads((out / "strata_time.json").read_text())
    for name, label, seconds in [
            ("strata", "strata (contours in, full resolution)", strata["wall_s"]),
            ("raster_1", "rasterise at CT grid 1 mm + FE + sinc", None),
            ("raster_0.25", "rasterise at 0.25 mm (4x) + FE + sinc", None)]:
        e = json.loads((out / f"error_{name}.json").read_text())
        if seconds is None:
            r = json.loads((out / f"{name}.json").read_text())
            seconds = r["rasterise_s"] + r["mesh_s"]
        rows.append((label, e, seconds))
    print(f"bench-contours: ball r {BALL_R:g} mm + torus {TORUS_R:g}/{TORUS_r:g} mm, contour "
          f"planes {gap:g} mm apart "
          f"(vertices on the true circles every <= 0.5 mm)")
    print(f"{'route':42s} {'triangles':>9s} {'seconds':>8s} {'mean':>7s} {'max':>7s} "
          f"{'btw mean':>9s} {'btw max':>8s} {'truth->mesh max':>16s}")
    for label, e, s in rows:
        print(f"{label:42s} {e['triangles']:9d} {s:8.2f} {e['mean_mm']:7.3f} {e['max_mm']:7.3f} "
              f"{e['between_mean_mm']:9.3f} {e['between_max_mm']:8.3f} "
              f"{e['truth_to_mesh_between_max_mm']:16.3f}")
    ratio = rows[0][1]["between_mean_mm"] / rows[1][1]["between_mean_mm"]
    print(f"mean error between planes, strata / rasterise at the CT grid: {ratio:.2f}")
    print("errors in mm to the analytic surfaces (mesh -> truth over 300k area samples and the "
          "vertices; 'btw': samples between each object's first and last plane); seconds: strata "
          "= the whole `strata build` process (reading, pipeline, multiresolution model, glTF); "
          "rasterise routes = rasterisation (numpy) + flying edges + smoothing + normals (VTK, 2 "
          "threads)")


def main():
    parser = argparse.ArgumentParser()
    sub = parser.add_subparsers(dest="command", required=True)
    p = sub.add_parser("phantom")
    p.add_argument("out_dir")
    p.add_argument("--gap", type=float, default=3.0)
    p.add_argument("--scale", type=float, default=1.0)
    p = sub.add_parser("raster")
    p.add_argument("out_dir")
    p.add_argument("--pixel", type=float, required=True)
    p = sub.add_parser("error")
    p.add_argument("out_dir")
    p.add_argument("meshes", nargs="+")
    p.add_argument("--name", required=True)
    p = sub.add_parser("table")
    p.add_argument("out_dir")
    args = parser.parse_args()
    {"phantom": run_phantom, "raster": run_raster, "error": run_error,
     "table": run_table}[args.command](args)


if __name__ == "__main__":
    main()
