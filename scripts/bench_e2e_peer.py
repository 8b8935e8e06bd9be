#!/usr/bin/env python3
"""Helper of scripts/bench-e2e.sh: phantom, 3D Slicer's pipeline, error to the truth, the table.

`phantom OUT_DIR [--dims NX,NY,NZ] [--spacing SX,SY,SZ] [--seed N]` writes OUT_DIR/mask.nii.gz, a
union of 8 ellipsoids (label 1: five, four of them overlapping, and a separate flat disc;
label 2: two overlapping and a separate small one; random orientations from the seed) rasterised
at the voxel centres, and OUT_DIR/truth.json: the ellipsoids in the truth frame F = voxel index
times spacing (mm, origin at voxel 0) and the file's voxel index -> LPS mm affine. The NIfTI-1
file is written with numpy + gzip + struct: uint8 voxels, sform = qform = a radiological
(LPS-aligned) orientation with the origin at the volume centre, so that RAS -> LPS is exercised.
Geometry scales with the volume: sizes and positions are fractions of its extent. Ellipsoids of
different labels keep >= 8 mm apart, so the union of all ellipsoids is the disjoint union of the
per-label surfaces and errors need no label bookkeeping.

`slicer NIFTI OUT_DIR [--threads N] [--iterations N]` runs what 3D Slicer runs for
"Export to models" (vtkBinaryLabelmapToClosedSurfaceConversionRule, default parameters:
decimation 0, smoothing factor 0.5, surface normals on, no joint smoothing), once per label on the
shared labelmap: vtkDiscreteFlyingEdges3D in voxel index space (1-voxel padding only when a border
voxel is set, as Slicer), vtkWindowedSincPolyDataFilter (pass band 10^(-4 * 0.5) = 0.01,
20 iterations as Slicer's source sets, boundary and feature-edge smoothing off, non-manifold
smoothing on, normalised coordinates), vtkTransformPolyDataFilter by the image -> world matrix,
vtkPolyDataNormals (consistency on, splitting off). Writes OUT_DIR/slicer.ply (LPS mm) and
OUT_DIR/slicer.json: pipeline seconds (labelmap in memory -> surfaces with normals, as in Slicer;
python start, NIfTI parsing, vtkImageData set-up and PLY writing excluded), triangles, the
process's peak RSS (getrusage) and the affine used.

`error TRUTH_JSON AFFINE_JSON MESH... --out JSON` measures meshes (PLY, LPS mm; several files are
one surface) against the analytic union of the ellipsoids, in frame F (LPS -> index through the
affine of AFFINE_JSON: a strata summary.json or slicer.json; index * spacing):
  mesh -> truth: exact distance of each sample to the union's boundary: per ellipsoid the closest
    point by Eberly's method (bisection on the Lagrange parameter, double precision), kept when
    it lies on the union's boundary (not strictly inside another ellipsoid), plus the distance
    to the union's creases (the intersection curves of two ellipsoid surfaces outside all
    others, sampled at <= 0.02 mm, so 0.01 mm is the floor of this term). Samples: every vertex,
    every triangle centroid, 500k area-weighted random points (the mean, RMS and bias are over
    these, i.e. per unit area), then a 20 x 20 barycentric grid on the 200 worst triangles.
  truth -> mesh: exact point-to-triangle distance (vtkImplicitPolyDataDistance) from area-uniform
    random points of the true surface (mean spacing 1 mm), then 200 points within 1.5 mm around
    each of the 100 worst; the two-sided max is the larger of both maxima.
`table WORK` prints the comparison from the files bench-e2e.sh left in WORK.

`png-nifti SLICES_DIR OUT.nii.gz` writes a strata PNG stack (8-bit greyscale slices and
meta.json, as ../shared/data has them) as a NIfTI-1 label map with meta.json's affine, so that
strata and the Slicer pipeline read the same file (PNG decoded with zlib: no imaging library).

`cases-table WORK` prints the one-run table of `bench-e2e.sh --cases`: per case, strata build
at 1 and 2 threads and the Slicer pipeline, each as a whole process (/usr/bin/time -v: wall, CPU
= user + system, peak RSS), Slicer's pipeline in process, strata's stage times (summary.json:
wall per stage, and below it a line of CPU per stage), and the ratios the issue asks for.

Needs Debian's python3-numpy, python3-scipy and python3-vtk9.
Usage: bench_e2e_peer.py phantom OUT_DIR [--dims NX,NY,NZ] [--spacing SX,SY,SZ] [--seed N]
       bench_e2e_peer.py slicer NIFTI OUT_DIR [--threads N] [--iterations N]
       bench_e2e_peer.py error TRUTH_JSON AFFINE_JSON MESH... --out JSON
       bench_e2e_peer.py table WORK
       bench_e2e_peer.py png-nifti SLICES_DIR OUT.nii.gz
       bench_e2e_peer.py cases-table WORK
"""
import argparse
import gzip
import json
import pathlib
import re
import resource
import struct
import sys
import textwrap
import time
import zlib

import numpy as np

# (label, centre as a fraction of the extent, semi-axes as a fraction of the smallest extent)
ELLIPSOIDS = [
    (1, (0.42, 0.45, 0.50), (0.24, 0.17, 0.13)),   # large body
    (1, (0.60, 0.55, 0.58), (0.12, 0.08, 0.07)),   # lobe overlapping the body
    (1, (0.30, 0.33, 0.42), (0.16, 0.035, 0.04)),  # thin elongated, overlapping the body
    (1, (0.45, 0.40, 0.66), (0.06, 0.05, 0.045)),  # small bump on the body
    (1, (0.20, 0.76, 0.30), (0.07, 0.06, 0.015)),  # flat disc, separate
    (2, (0.79, 0.25, 0.35), (0.08, 0.06, 0.05)),   # second object
    (2, (0.84, 0.33, 0.42), (0.06, 0.04, 0.04)),   # overlapping it
    (2, (0.80, 0.78, 0.70), (0.03, 0.028, 0.025)),  # small, separate
]
LABEL_GAP_MM = 8.0
BORDER_VOXELS = 3


# ---------------------------------------------------------------------------------------------
# the truth: a union of ellipsoids in frame F


class Truth:
    def __init__(self, ellipsoids):
        self.c = np.array([e["center"] for e in ellipsoids], dtype=np.float64)
        self.a = np.array([e["axes"] for e in ellipsoids], dtype=np.float64)
        self.r = np.array([e["rotation"] for e in ellipsoids], dtype=np.float64)  # columns: axes
        self.labels = [e["label"] for e in ellipsoids]
        self.m = len(ellipsoids)

    def local(self, i, x):
        return (x - self.c[i]) @ self.r[i]

    def world(self, i, y):
        return y @ self.r[i].T + self.c[i]

    def g(self, i, x):
        """Normalised radius: < 1 inside ellipsoid i, 1 on its surface."""
        return np.sqrt(np.sum((self.local(i, x) / self.a[i]) ** 2, axis=1))

    def inside_other(self, x, skip, tol=1e-9):
        """Strictly inside an ellipsoid not in skip."""
        out = np.zeros(len(x), dtype=bool)
        for j in range(self.m):
            if j not in skip:
                out |= self.g(j, x) < 1.0 - tol
        return out

    def closest(self, i, x):
        """Closest points of ellipsoid i's surface to x (Eberly, bisection) and their distance."""
        y = self.local(i, x)
        z = np.maximum(np.abs(y), 1e-9)
        e = self.a[i]
        k = int(np.argmin(e))
        emin2 = e[k] ** 2
        ez = z * e
        lo = -emin2 + ez[:, k]
        hi = -emin2 + np.linalg.norm(ez, axis=1)
        e2 = e * e
        for _ in range(80):
            mid = 0.5 * (lo + hi)
            f = np.sum((ez / (mid[:, None] + e2)) ** 2, axis=1) - 1.0
            pos = f > 0
            lo = np.where(pos, mid, lo)
            hi = np.where(pos, hi, mid)
        t = 0.5 * (lo + hi)
        q = e2 * z / (t[:, None] + e2) * np.sign(y + (y == 0))
        qw = self.world(i, q)
        return qw, np.linalg.norm(qw - x, axis=1)

    def surface_point(self, i, theta, phi):
        u = np.stack([np.sin(theta) * np.cos(phi), np.sin(theta) * np.sin(phi), np.cos(theta)],
                     axis=-1)
        return self.world(i, u * self.a[i])

    def area(self, i):
        p = 1.6075  # Knud Thomsen's approximation, < 1.1 % off
        a, b, c = self.a[i] ** p
        return 4 * np.pi * ((a * b + a * c + b * c) / 3) ** (1 / p)

    def creases(self, spacing=0.02, coarse=0.5):
        """Points of the union's creases: surface i meets surface j outside every other."""
        out = []
        for i in range(self.m):
            for j in range(self.m):
                if j == i or (np.linalg.norm(self.c[i] - self.c[j])
                              >= self.a[i].max() + self.a[j].max()):
                    continue
                out.append(self._crease(i, j, spacing, coarse))
        pts = np.concatenate(out) if out else np.zeros((0, 3))
        return pts

    def _crease(self, i, j, spacing, coarse):
        amax = self.a[i].max()
        nt = int(np.ceil(np.pi * amax / coarse))
        npf = int(np.ceil(2 * np.pi * amax / coarse))
        th = np.linspace(0, np.pi, nt + 1)
        ph = np.linspace(0, 2 * np.pi, npf + 1)
        T, P = np.meshgrid(th, ph, indexing="ij")
        s = self.g(j, self.surface_point(i, T.ravel(), P.ravel())).reshape(T.shape) - 1.0
        sign = s > 0
        corners = sign[:-1, :-1].astype(int) + sign[1:, :-1] + sign[:-1, 1:] + sign[1:, 1:]
        ci, cj = np.nonzero((corners > 0) & (corners < 4))
        if len(ci) == 0:
            return np.zeros((0, 3))
        sub = int(np.ceil(coarse / spacing))
        f = np.linspace(0, 1, sub + 1)
        dt, dp = th[1] - th[0], ph[1] - ph[0]
        pts = []
        for start in range(0, len(ci), 2000):
            bi, bj = ci[start:start + 2000], cj[start:start + 2000]
            t = th[bi][:, None, None] + dt * f[None, :, None] + 0 * f[None, None, :]
            p = ph[bj][:, None, None] + 0 * f[None, :, None] + dp * f[None, None, :]
            val = self.g(j, self.surface_point(i, t.ravel(), p.ravel())).reshape(t.shape) - 1
            for axis in (1, 2):
                a0 = [slice(None)] * 3
                a1 = [slice(None)] * 3
                a0[axis] = slice(None, -1)
                a1[axis] = slice(1, None)
                cross = (val[tuple(a0)] > 0) != (val[tuple(a1)] > 0)
                t0, t1 = t[tuple(a0)][cross], t[tuple(a1)][cross]
                p0, p1 = p[tuple(a0)][cross], p[tuple(a1)][cross]
                v0 = val[tuple(a0)][cross]
                lo, hi = np.zeros(len(t0)), np.ones(len(t0))
                for _ in range(40):
                    mid = 0.5 * (lo + hi)
                    vm = self.g(j, self.surface_point(i, t0 + mid * (t1 - t0),
                                                      p0 + mid * (p1 - p0))) - 1
                    same = (vm > 0) == (v0 > 0)
                    lo = np.where(same, mid, lo)
                    hi = np.where(same, hi, mid)
                mid = 0.5 * (lo + hi)
                pts.append(self.surface_point(i, t0 + mid * (t1 - t0), p0 + mid * (p1 - p0)))
        pts = np.concatenate(pts)
        return pts[~self.inside_other(pts, (i, j))]

    def exposed_area(self, i, n=1200):
        """Area of ellipsoid i's surface outside every other (midpoint rule in theta, phi)."""
        th = (np.arange(n) + 0.5) * np.pi / n
        ph = (np.arange(2 * n) + 0.5) * np.pi / n
        total = 0.0
        for row in np.array_split(np.arange(n), 8):
            T, P = np.meshgrid(th[row], ph, indexing="ij")
            T, P = T.ravel(), P.ravel()
            st, ct, sp, cp = np.sin(T), np.cos(T), np.sin(P), np.cos(P)
            a = self.a[i]
            d_t = np.stack([ct * cp, ct * sp, -st], axis=1) * a
            d_p = np.stack([-st * sp, st * cp, np.zeros_like(T)], axis=1) * a
            element = np.linalg.norm(np.cross(d_t, d_p), axis=1) * (np.pi / n) ** 2
            outside = ~self.inside_other(self.surface_point(i, T, P), (i,))
            total += float(element[outside].sum())
        return total

    def sample_surface(self, spacing, rng):
        """Area-uniform random points of the union's boundary, mean spacing about `spacing`."""
        pts, owner = [], []
        for i in range(self.m):
            want = int(np.ceil(self.area(i) / spacing ** 2))
            got = []
            n = 0
            while n < want:
                u = rng.normal(size=(2 * want, 3))
                u /= np.linalg.norm(u, axis=1)[:, None]
                keep = rng.random(len(u)) < self.a[i].min() * np.linalg.norm(u / self.a[i], axis=1)
                got.append(u[keep])
                n += int(keep.sum())
            y = np.concatenate(got)[:want] * self.a[i]
            x = self.world(i, y)
            x = x[~self.inside_other(x, (i,))]
            pts.append(x)
            owner.append(np.full(len(x), i))
        return np.concatenate(pts), np.concatenate(owner)

    def project(self, i, x):
        """Radial projection onto ellipsoid i's surface."""
        y = self.local(i, x)
        return self.world(i, y / np.sqrt(np.sum((y / self.a[i]) ** 2, axis=1))[:, None])


class UnionDistance:
    """Exact distance to the boundary of the union (see the module doc)."""

    def __init__(self, truth, crease_spacing=0.02):
        from scipy.spatial import cKDTree
        self.truth = truth
        self.creases = truth.creases(spacing=crease_spacing)
        self.tree = cKDTree(self.creases) if len(self.creases) else None
        # beyond `near` a query of the dense set is slow; a thinned copy (one point per 0.1 mm
        # cube, gaps <= 0.2 mm) overestimates a distance d by at most 0.2^2 / (8 d) <= 0.0025 mm
        self.near = 2.0  # mm
        if self.tree is not None:
            _, first = np.unique(np.floor(self.creases / 0.1).astype(np.int64), axis=0,
                                 return_index=True)
            self.far_tree = cKDTree(self.creases[first])

    def signed(self, x, chunk=400000):
        """Signed distance (+ outside) and the true unit normal at the closest point (zero
        where that point is on a crease)."""
        if len(x) == 0:
            return np.zeros(0), np.zeros((0, 3))
        parts = [self._signed(x[s:s + chunk]) for s in range(0, len(x), chunk)]
        return np.concatenate([p[0] for p in parts]), np.concatenate([p[1] for p in parts])

    def _signed(self, x):
        t = self.truth
        n = len(x)
        G = np.stack([np.maximum(t.g(i, x), 1e-12) for i in range(t.m)])
        inside = (G < 1.0).any(axis=0)
        best = np.full(n, np.inf)
        normal = np.zeros((n, 3))
        if self.tree is not None:  # far from every crease a query is slow: bounded here, the
            best, _ = self.tree.query(x, distance_upper_bound=self.near)  # rest at the end
        # upper bound: radial projections that lie on the union's boundary
        ub = best.copy()
        for i in range(t.m):
            r = t.c[i] + (x - t.c[i]) / G[i][:, None]
            d = np.linalg.norm(x - r, axis=1)
            cand = np.nonzero(d < ub)[0]
            if len(cand):
                ok = ~t.inside_other(r[cand], (i,))
                ub[cand[ok]] = d[cand][ok]
        for i in range(t.m):
            lower = t.a[i].min() * np.abs(G[i] - 1.0)
            cand = np.nonzero(lower <= ub * (1 + 1e-9) + 1e-9)[0]
            if len(cand) == 0:
                continue
            q, d = t.closest(i, x[cand])
            ok = ~t.inside_other(q, (i,)) & (d < best[cand])
            sel = cand[ok]
            best[sel] = d[ok]
            grad = (t.local(i, q[ok]) / t.a[i] ** 2) @ t.r[i].T
            normal[sel] = grad / np.linalg.norm(grad, axis=1)[:, None]
        if self.tree is not None:
            far = np.nonzero(best > self.near)[0]
            if len(far):
                d = self.far_tree.query(x[far])[0]
                closer = d < best[far]
                best[far[closer]] = d[closer]
                normal[far[closer]] = 0.0
        missing = ~np.isfinite(best)
        if missing.any():
            sys.exit(f"error: {int(missing.sum())} points without a boundary distance")
        # a crease point nearer than every ellipsoid's exposed closest point: no normal
        crease = np.ones(n, dtype=bool)
        crease[np.linalg.norm(normal, axis=1) > 0] = False
        return np.where(inside, -best, best), normal * (~crease)[:, None]


# ---------------------------------------------------------------------------------------------
# files


def write_nifti(path, labels, affine_ras, spacing):
    """NIfTI-1, uint8, [k, j, i] array; sform and qform both set to affine_ras."""
    nz, ny, nx = labels.shape
    h = bytearray(348)
    struct.pack_into("<i", h, 0, 348)
    struct.pack_into("<8h", h, 40, 3, nx, ny, nz, 1, 1, 1, 1)
    struct.pack_into("<2h", h, 70, 2, 8)  # datatype uint8, bitpix
    struct.pack_into("<8f", h, 76, 1.0, *spacing, 1.0, 0.0, 0.0, 0.0)  # pixdim[0] = qfac
    struct.pack_into("<f", h, 108, 352.0)  # vox_offset
    struct.pack_into("<2f", h, 112, 1.0, 0.0)  # scl_slope, scl_inter
    h[123] = 2 | 8  # mm, s
    struct.pack_into("<2h", h, 252, 1, 1)  # qform_code, sform_code: scanner
    rotation = affine_ras[:3, :3] / np.asarray(spacing)
    quat = rotation_quaternion(rotation)
    struct.pack_into("<3f", h, 256, *quat[1:])
    struct.pack_into("<3f", h, 268, *affine_ras[:3, 3])
    for row in range(3):
        struct.pack_into("<4f", h, 280 + 16 * row, *affine_ras[row])
    h[344:348] = b"n+1\0"
    with open(path, "wb") as raw, gzip.GzipFile(fileobj=raw, mode="wb", compresslevel=6,
                                                mtime=0) as out:  # reproducible bytes
        out.write(bytes(h) + b"\0\0\0\0")
        out.write(np.ascontiguousarray(labels, dtype=np.uint8).tobytes())


def rotation_quaternion(m):
    """(a, b, c, d) of a proper rotation matrix, a >= 0 (NIfTI's quatern_b/c/d are b, c, d)."""
    a = 0.5 * np.sqrt(max(0.0, 1 + m[0, 0] + m[1, 1] + m[2, 2]))
    if a > 1e-6:
        b = (m[2, 1] - m[1, 2]) / (4 * a)
        c = (m[0, 2] - m[2, 0]) / (4 * a)
        d = (m[1, 0] - m[0, 1]) / (4 * a)
    else:
        b = 0.5 * np.sqrt(max(0.0, 1 + m[0, 0] - m[1, 1] - m[2, 2]))
        c = 0.5 * np.sqrt(max(0.0, 1 - m[0, 0] + m[1, 1] - m[2, 2]))
        d = 0.5 * np.sqrt(max(0.0, 1 - m[0, 0] - m[1, 1] + m[2, 2]))
        # signs from the off-diagonal terms, relative to the largest component
        if b >= c and b >= d:
            c, d = np.copysign(c, m[0, 1] + m[1, 0]), np.copysign(d, m[0, 2] + m[2, 0])
        elif c >= d:
            b, d = np.copysign(b, m[0, 1] + m[1, 0]), np.copysign(d, m[1, 2] + m[2, 1])
        else:
            b, c = np.copysign(b, m[0, 2] + m[2, 0]), np.copysign(c, m[1, 2] + m[2, 1])
    return np.array([a, b, c, d])


def read_nifti(path):
    """Labels [k, j, i] and the voxel index -> LPS mm affine (sform, else qform, else pixdim)."""
    raw = pathlib.Path(path).read_bytes()
    if str(path).endswith(".gz"):
        raw = gzip.decompress(raw)
    if struct.unpack_from("<i", raw, 0)[0] != 348:
        sys.exit(f"{path}: not a little-endian NIfTI-1 file")
    dims = struct.unpack_from("<8h", raw, 40)
    nx, ny, nz = dims[1:4]
    types = {2: np.uint8, 4: np.int16, 512: np.uint16, 8: np.int32}
    datatype = struct.unpack_from("<h", raw, 70)[0]
    if datatype not in types:
        sys.exit(f"{path}: unsupported datatype {datatype}")
    offset = int(struct.unpack_from("<f", raw, 108)[0])
    labels = np.frombuffer(raw, dtype=np.dtype(types[datatype]).newbyteorder("<"),
                           count=nx * ny * nz, offset=offset).reshape(nz, ny, nx)
    qform_code, sform_code = struct.unpack_from("<2h", raw, 252)
    ras = np.eye(4)
    if sform_code > 0:
        for row in range(3):
            ras[row] = struct.unpack_from("<4f", raw, 280 + 16 * row)
    elif qform_code > 0:
        b, c, d = struct.unpack_from("<3f", raw, 256)
        pixdim = struct.unpack_from("<8f", raw, 76)
        a = np.sqrt(max(0.0, 1.0 - (b * b + c * c + d * d)))
        rot = np.array([
            [a * a + b * b - c * c - d * d, 2 * (b * c - a * d), 2 * (b * d + a * c)],
            [2 * (b * c + a * d), a * a + c * c - b * b - d * d, 2 * (c * d - a * b)],
            [2 * (b * d - a * c), 2 * (c * d + a * b), a * a + d * d - c * c - b * b]])
        qfac = -1.0 if pixdim[0] < 0 else 1.0
        ras[:3, :3] = rot * np.array([pixdim[1], pixdim[2], qfac * pixdim[3]])
        ras[:3, 3] = struct.unpack_from("<3f", raw, 268)
    else:
        ras = np.diag(list(struct.unpack_from("<3f", raw, 80)) + [1.0])
    return labels, np.diag([-1.0, -1.0, 1.0, 1.0]) @ ras


PLY_TYPES = {"char": "i1", "uchar": "u1", "int8": "i1", "uint8": "u1", "short": "<i2",
             "ushort": "<u2", "int16": "<i2", "uint16": "<u2", "int": "<i4", "uint": "<u4",
             "int32": "<i4", "uint32": "<u4", "float": "<f4", "float32": "<f4",
             "double": "<f8", "float64": "<f8"}


def read_ply(path, with_normals=False):
    """Binary little-endian triangle PLY -> (points n x 3 float64, triangles m x 3 int64), and
    with_normals: the vertex normals too (n x 3 float64, None when the file has none)."""
    raw = pathlib.Path(path).read_bytes()
    end = raw.index(b"end_header\n") + len(b"end_header\n")
    lines = raw[:end].decode("ascii").splitlines()
    if "format binary_little_endian 1.0" not in lines:
        sys.exit(f"{path}: expected a binary little-endian PLY")
    elements = []
    for line in lines:
        w = line.split()
        if w[0] == "element":
            elements.append([w[1], int(w[2]), []])
        elif w[0] == "property":
            if w[1] == "list":
                elements[-1][2].append((w[4], ("list", PLY_TYPES[w[2]], PLY_TYPES[w[3]])))
            else:
                elements[-1][2].append((w[2], PLY_TYPES[w[1]]))
    offset = end
    points = triangles = normals = None
    for name, count, props in elements:
        fields = []
        for pname, ptype in props:
            if isinstance(ptype, tuple):
                fields += [(pname + "_n", ptype[1]), (pname, ptype[2], (3,))]
            else:
                fields.append((pname, ptype))
        dtype = np.dtype(fields)
        data = np.frombuffer(raw, dtype=dtype, count=count, offset=offset)
        offset += dtype.itemsize * count
        if name == "vertex":
            points = np.stack([data["x"], data["y"], data["z"]], axis=1).astype(np.float64)
            if "nx" in data.dtype.names:
                normals = np.stack([data["nx"], data["ny"], data["nz"]], axis=1).astype(np.float64)
        elif name == "face":
            key = [p for p, t in props if isinstance(t, tuple)][0]
            if count and not np.all(data[key + "_n"] == 3):
                sys.exit(f"{path}: expected triangles only")
            triangles = data[key].astype(np.int64)
    return (points, triangles, normals) if with_normals else (points, triangles)


def write_ply(path, points, triangles, normals=None):
    """Binary little-endian triangle PLY, with vertex normals when given."""
    normal_props = "property float nx\nproperty float ny\nproperty float nz\n"
    header = (f"ply\nformat binary_little_endian 1.0\ncomment strata benchmark peer\n"
              f"element vertex {len(points)}\nproperty float x\nproperty float y\n"
              f"property float z\n{normal_props if normals is not None else ''}"
              f"element face {len(triangles)}\n"
              f"property list uchar int vertex_indices\nend_header\n")
    faces = np.zeros(len(triangles), dtype=[("n", "u1"), ("v", "<i4", (3,))])
    faces["n"] = 3
    faces["v"] = triangles
    with open(path, "wb") as out:
        out.write(header.encode("ascii"))
        vertices = points if normals is None else np.hstack([points, normals])
        out.write(np.asarray(vertices, dtype="<f4").tobytes())
        out.write(faces.tobytes())


def affine_of(path):
    data = json.loads(pathlib.Path(path).read_text())
    if "index_to_world_lps_mm" in data:
        return np.array(data["index_to_world_lps_mm"], dtype=np.float64)
    return np.array(data["input"]["index_to_world_lps_mm"], dtype=np.float64)


# ---------------------------------------------------------------------------------------------
# phantom


def random_rotation(rng):
    q, r = np.linalg.qr(rng.normal(size=(3, 3)))
    q = q * np.sign(np.diag(r))
    if np.linalg.det(q) < 0:
        q[:, 0] = -q[:, 0]
    return q


def make_ellipsoids(extent, seed):
    """The ellipsoids in frame F; rotations redrawn until they fit and labels keep apart."""
    rng = np.random.default_rng(seed)
    size = min(extent)
    for _ in range(1000):
        ells = [{"label": label, "center": list(np.asarray(c) * extent),
                 "axes": list(np.asarray(a) * size), "rotation": random_rotation(rng).tolist()}
                for label, c, a in ELLIPSOIDS]
        if ellipsoids_ok(ells, extent, rng):
            return ells
    sys.exit("phantom: no arrangement found")


def ellipsoids_ok(ells, extent, rng):
    truth = Truth(ells)
    for i in range(truth.m):
        half = np.sqrt(np.sum((truth.r[i] * truth.a[i]) ** 2, axis=1))
        if np.any(truth.c[i] - half < BORDER_VOXELS * 2) or \
                np.any(truth.c[i] + half > extent - BORDER_VOXELS * 2):
            return False
    pts, owner = truth.sample_surface(2.0, rng)
    for i in range(truth.m):
        mine = pts[owner == i]
        for j in range(truth.m):
            if truth.labels[j] != truth.labels[i]:
                inside = truth.g(j, mine) < 1
                _, d = truth.closest(j, mine)
                if inside.any() or d.min() < LABEL_GAP_MM:
                    return False
    return True


def run_phantom(args):
    dims = np.array([int(v) for v in args.dims.split(",")])
    spacing = np.array([float(v) for v in args.spacing.split(",")])
    extent = dims * spacing
    ells = make_ellipsoids(extent, args.seed)
    truth = Truth(ells)
    labels = np.zeros((dims[2], dims[1], dims[0]), dtype=np.uint8)
    for i, e in enumerate(ells):
        half = np.sqrt(np.sum((truth.r[i] * truth.a[i]) ** 2, axis=1))
        lo = np.maximum(np.floor((truth.c[i] - half) / spacing).astype(int), 0)
        hi = np.minimum(np.ceil((truth.c[i] + half) / spacing).astype(int) + 1, dims)
        for k in range(lo[2], hi[2]):
            jj, ii = np.mgrid[lo[1]:hi[1], lo[0]:hi[0]]
            x = np.stack([ii.ravel() * spacing[0], jj.ravel() * spacing[1],
                          np.full(ii.size, k * spacing[2])], axis=1)
            inside = (truth.g(i, x) < 1.0).reshape(ii.shape)
            labels[k, lo[1]:hi[1], lo[0]:hi[0]][inside] = e["label"]
    # radiological storage: i -> left, j -> posterior (RAS x = -i, y = -j), origin at the centre
    centre = (dims - 1) / 2 * spacing
    ras = np.array([[-spacing[0], 0, 0, centre[0]], [0, -spacing[1], 0, centre[1]],
                    [0, 0, spacing[2], -centre[2]], [0, 0, 0, 1]])
    out = pathlib.Path(args.out_dir)
    out.mkdir(parents=True, exist_ok=True)
    write_nifti(out / "mask.nii.gz", labels, ras, spacing)
    lps = np.diag([-1.0, -1.0, 1.0, 1.0]) @ ras
    area = sum(truth.exposed_area(i) for i in range(truth.m))
    info = {"dims": dims.tolist(), "spacing_mm": spacing.tolist(), "seed": args.seed,
            "true_area_mm2": area, "index_to_world_lps_mm": lps.tolist(), "ellipsoids": ells,
            "voxels": {str(v): int((labels == v).sum()) for v in (1, 2)}}
    (out / "truth.json").write_text(json.dumps(info, indent=1) + "\n")
    print(f"phantom: {dims.tolist()} voxels of {spacing.tolist()} mm, {len(ells)} ellipsoids, "
          f"labels {info['voxels']} voxels", file=sys.stderr)


# ---------------------------------------------------------------------------------------------
# Slicer's pipeline


def flying_edges(image, value):
    """The surface of one label of a vtkImageData: discrete flying edges, as Slicer's closed
    surface representation makes it."""
    from vtkmodules.vtkFiltersGeneral import vtkDiscreteFlyingEdges3D

    fe = vtkDiscreteFlyingEdges3D()
    fe.SetInputData(image)
    fe.ComputeGradientsOff()
    fe.ComputeNormalsOff()
    fe.SetValue(0, value)
    fe.Update()
    return fe.GetOutput()


def slicer_smooth(poly, iterations=20, factor=0.5):
    """3D Slicer's smoothing of a closed surface: windowed sinc, pass band 10^(-4 factor)
    (Slicer's default smoothing factor 0.5: pass band 0.01), coordinates normalised."""
    from vtkmodules.vtkFiltersCore import vtkWindowedSincPolyDataFilter

    smoother = vtkWindowedSincPolyDataFilter()
    smoother.SetInputData(poly)
    smoother.SetNumberOfIterations(iterations)
    smoother.SetPassBand(10.0 ** (-4.0 * factor))
    smoother.BoundarySmoothingOff()
    smoother.FeatureEdgeSmoothingOff()
    smoother.NonManifoldSmoothingOn()
    smoother.NormalizeCoordinatesOn()
    smoother.Update()
    return smoother.GetOutput()


def run_slicer(args):
    from vtkmodules.util import numpy_support
    from vtkmodules.vtkCommonCore import vtkSMPTools
    from vtkmodules.vtkCommonDataModel import vtkImageData
    from vtkmodules.vtkCommonMath import vtkMatrix4x4
    from vtkmodules.vtkCommonTransforms import vtkTransform
    from vtkmodules.vtkFiltersCore import vtkAppendPolyData, vtkPolyDataNormals
    from vtkmodules.vtkFiltersGeneral import vtkTransformPolyDataFilter

    vtkSMPTools.Initialize(args.threads)
    labels, lps = read_nifti(args.nifti)
    values = [int(v) for v in np.unique(labels) if v != 0]  # Slicer's segment list
    image = vtkImageData()
    nz, ny, nx = labels.shape
    image.SetDimensions(nx, ny, nz)
    image.SetOrigin(0.0, 0.0, 0.0)
    image.SetSpacing(1.0, 1.0, 1.0)
    image.GetPointData().SetScalars(
        numpy_support.numpy_to_vtk(np.ascontiguousarray(labels).ravel(), deep=True))
    matrix = vtkMatrix4x4()
    for r in range(4):
        for c in range(4):
            matrix.SetElement(r, c, lps[r, c])

    start = time.perf_counter()
    # Slicer pads by one voxel only when a border voxel is set (IsLabelmapPaddingNecessary)
    border = (labels[0].any() or labels[-1].any() or labels[:, 0].any() or labels[:, -1].any()
              or labels[:, :, 0].any() or labels[:, :, -1].any())
    source = image
    if border:
        from vtkmodules.vtkImagingCore import vtkImageConstantPad
        pad = vtkImageConstantPad()
        pad.SetInputData(image)
        pad.SetOutputWholeExtent(-1, nx, -1, ny, -1, nz)
        pad.Update()
        source = pad.GetOutput()
    surfaces = []
    for value in values:
        smoothed = slicer_smooth(flying_edges(source, value), args.iterations)
        transform = vtkTransform()
        transform.SetMatrix(matrix)
        to_world = vtkTransformPolyDataFilter()
        to_world.SetInputData(smoothed)
        to_world.SetTransform(transform)
        normals = vtkPolyDataNormals()
        normals.SetInputConnection(to_world.GetOutputPort())
        normals.ConsistencyOn()
        normals.SplittingOff()
        normals.Update()
        surfaces.append((value, normals.GetOutput()))
    seconds = time.perf_counter() - start

    append = vtkAppendPolyData()
    for _, poly in surfaces:
        append.AddInputData(poly)
    append.Update()
    poly = append.GetOutput()
    points = numpy_support.vtk_to_numpy(poly.GetPoints().GetData()).astype(np.float64)
    triangles = triangle_array(poly)
    out = pathlib.Path(args.out_dir)
    out.mkdir(parents=True, exist_ok=True)
    write_ply(out / "slicer.ply", points, triangles)
    info = {"pipeline_s": seconds, "threads": args.threads, "iterations": args.iterations,
            "padded": bool(border), "smp_backend": vtkSMPTools.GetBackend(),
            "triangles": int(len(triangles)),
            "per_label_triangles": {str(v): int(p.GetNumberOfPolys()) for v, p in surfaces},
            "ru_maxrss_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0,
            "index_to_world_lps_mm": lps.tolist()}
    (out / "slicer.json").write_text(json.dumps(info, indent=1) + "\n")


def triangle_array(poly):
    from vtkmodules.util import numpy_support
    polys = poly.GetPolys()
    offsets = numpy_support.vtk_to_numpy(polys.GetOffsetsArray())
    conn = numpy_support.vtk_to_numpy(polys.GetConnectivityArray())
    if not np.all(np.diff(offsets) == 3):
        sys.exit("slicer: expected triangles only")
    return conn.reshape(-1, 3).astype(np.int64)


# ---------------------------------------------------------------------------------------------
# error to the truth


def triangle_samples(points, tris, rng, count):
    a, b, c = points[tris[:, 0]], points[tris[:, 1]], points[tris[:, 2]]
    area = 0.5 * np.linalg.norm(np.cross(b - a, c - a), axis=1)
    which = rng.choice(len(tris), size=count, p=area / area.sum())
    u, v = rng.random(count), rng.random(count)
    flip = u + v > 1
    u[flip], v[flip] = 1 - u[flip], 1 - v[flip]
    x = a[which] + u[:, None] * (b[which] - a[which]) + v[:, None] * (c[which] - a[which])
    return x, which, area


def barycentric_grid(points, tris, n):
    i, j = np.meshgrid(np.arange(n + 1), np.arange(n + 1), indexing="ij")
    keep = i + j <= n
    u, v = (i[keep] / n), (j[keep] / n)
    a, b, c = points[tris[:, 0]], points[tris[:, 1]], points[tris[:, 2]]
    x = (a[:, None] + u[None, :, None] * (b - a)[:, None] + v[None, :, None] * (c - a)[:, None])
    return x.reshape(-1, 3)


def mesh_distance(points, tris, queries):
    """Exact unsigned distance from queries to the triangle mesh (VTK's cell locator)."""
    from vtkmodules.util import numpy_support
    from vtkmodules.vtkCommonCore import vtkDoubleArray, vtkPoints
    from vtkmodules.vtkCommonDataModel import vtkCellArray, vtkPolyData
    from vtkmodules.vtkFiltersCore import vtkImplicitPolyDataDistance
    poly = vtkPolyData()
    pts = vtkPoints()
    pts.SetData(numpy_support.numpy_to_vtk(np.ascontiguousarray(points), deep=True))
    poly.SetPoints(pts)
    cells = vtkCellArray()
    offsets = numpy_support.numpy_to_vtkIdTypeArray(
        np.arange(0, 3 * len(tris) + 1, 3, dtype=np.int64), deep=True)
    conn = numpy_support.numpy_to_vtkIdTypeArray(
        np.ascontiguousarray(tris.ravel(), dtype=np.int64), deep=True)
    cells.SetData(offsets, conn)
    poly.SetPolys(cells)
    dist = vtkImplicitPolyDataDistance()
    dist.SetInput(poly)
    out = vtkDoubleArray()
    dist.FunctionValue(numpy_support.numpy_to_vtk(np.ascontiguousarray(queries), deep=True), out)
    return np.abs(numpy_support.vtk_to_numpy(out))


def run_error(args):
    info = json.loads(pathlib.Path(args.truth).read_text())
    truth = Truth(info["ellipsoids"])
    spacing = np.array(info["spacing_mm"])
    affine = affine_of(args.affine)
    to_index = np.linalg.inv(affine)
    pts_list, tri_list, base = [], [], 0
    for path in args.meshes:
        p, t = read_ply(path)
        pts_list.append(p)
        tri_list.append(t + base)
        base += len(p)
    lps = np.concatenate(pts_list)
    tris = np.concatenate(tri_list)
    points = (lps @ to_index[:3, :3].T + to_index[:3, 3]) * spacing  # frame F
    rng = np.random.default_rng(12345)
    start = time.perf_counter()
    union = UnionDistance(truth, crease_spacing=args.crease_spacing)

    # mesh -> truth
    randoms, which, area = triangle_samples(points, tris, rng, args.random_samples)
    d_rand, n_true = union.signed(randoms)
    a, b, c = points[tris[:, 0]], points[tris[:, 1]], points[tris[:, 2]]
    face = np.cross(b - a, c - a)
    face /= np.maximum(np.linalg.norm(face, axis=1), 1e-300)[:, None]
    has_normal = np.linalg.norm(n_true, axis=1) > 0
    cos = np.abs(np.sum(face[which] * n_true, axis=1))[has_normal]
    normal_deg = np.degrees(np.arccos(np.clip(cos, 0.0, 1.0)))
    centroids = points[tris].mean(axis=1)
    d_cent = np.abs(union.signed(centroids)[0])
    d_vert = np.abs(union.signed(points)[0])
    worst = np.concatenate([np.argsort(-d_cent)[:args.refine],
                            which[np.argsort(-np.abs(d_rand))[:args.refine]]])
    worst_v = np.argsort(-d_vert)[:args.refine]
    worst = np.unique(np.concatenate([worst, np.nonzero(np.isin(tris, worst_v).any(axis=1))[0]]))
    grid = barycentric_grid(points, tris[worst], 20)
    d_grid = np.abs(union.signed(grid)[0])
    max_m2t = float(max(d_vert.max(), d_cent.max(), np.abs(d_rand).max(), d_grid.max()))
    worst_point = grid[np.argmax(d_grid)] if d_grid.max() >= max_m2t else \
        np.concatenate([points, centroids, randoms])[
            np.argmax(np.concatenate([d_vert, d_cent, np.abs(d_rand)]))]

    # truth -> mesh
    truth_pts, owner = truth.sample_surface(args.truth_spacing, rng)
    d_t = mesh_distance(points, tris, truth_pts)
    top = np.argsort(-d_t)[:args.refine // 2]
    local = []
    for k in top:
        i = owner[k]
        jitter = rng.normal(size=(200, 3))
        jitter *= (rng.random(200) ** 0.5 * 1.5 / np.linalg.norm(jitter, axis=1))[:, None]
        x = truth.project(i, truth_pts[k] + jitter)
        local.append(x[~truth.inside_other(x, (i,))])
    local = np.concatenate(local) if local else np.zeros((0, 3))
    d_local = mesh_distance(points, tris, local) if len(local) else np.zeros(0)
    max_t2m = float(max(d_t.max(), d_local.max() if len(d_local) else 0.0))
    worst_truth = local[np.argmax(d_local)] if len(d_local) and d_local.max() >= d_t.max() \
        else truth_pts[np.argmax(d_t)]

    result = {
        "meshes": [str(m) for m in args.meshes], "triangles": int(len(tris)),
        "vertices": int(len(points)), "area_mm2": float(area.sum()),
        "mean_mm": float(np.abs(d_rand).mean()),
        "rms_mm": float(np.sqrt(np.mean(d_rand ** 2))), "bias_mm": float(d_rand.mean()),
        "max_mesh_to_truth_mm": max_m2t, "mean_truth_to_mesh_mm": float(d_t.mean()),
        "max_truth_to_mesh_mm": max_t2m, "max_mm": max(max_m2t, max_t2m),
        "normal_mean_deg": float(normal_deg.mean()),
        "normal_p95_deg": float(np.percentile(normal_deg, 95)),
        "worst_mesh_point_frame_mm": worst_point.tolist(),
        "worst_truth_point_frame_mm": worst_truth.tolist(),
        "samples": {"vertices": int(len(points)), "centroids": int(len(centroids)),
                    "random": int(len(randoms)), "grid": int(len(d_grid)),
                    "truth": int(len(truth_pts)), "truth_local": int(len(local)),
                    "crease_points": int(len(union.creases))},
        "crease_spacing_mm": args.crease_spacing, "truth_spacing_mm": args.truth_spacing,
        "seconds": time.perf_counter() - start}
    pathlib.Path(args.out).write_text(json.dumps(result, indent=1) + "\n")
    print(f"error: {' '.join(pathlib.Path(m).name for m in args.meshes[:3])}"
          f"{' ...' if len(args.meshes) > 3 else ''}: mean {result['mean_mm']:.3f} mm, "
          f"max {result['max_mm']:.3f} mm ({result['seconds']:.0f} s)", file=sys.stderr)


# ---------------------------------------------------------------------------------------------
# table


def gnu_time(path):
    """(wall seconds, max RSS MB) of a `/usr/bin/time -v` log."""
    text = pathlib.Path(path).read_text()
    wall = re.search(r"Elapsed \(wall clock\) time \(h:mm:ss or m:ss\): ([\d:.]+)", text).group(1)
    seconds = 0.0
    for part in wall.split(":"):
        seconds = seconds * 60 + float(part)
    rss = int(re.search(r"Maximum resident set size \(kbytes\): (\d+)", text).group(1))
    return seconds, rss / 1024.0


def run_table(args):
    work = pathlib.Path(args.work)
    runs = sorted(work.glob("runs/strata_*.time"))
    strata = [gnu_time(p) for p in runs]
    slicer = [gnu_time(p) for p in sorted(work.glob("runs/slicer_*.time"))]
    slicer_json = [json.loads(p.read_text()) for p in sorted(work.glob("runs/slicer_*.json"))]
    summary = json.loads((work / "strata" / "summary.json").read_text())
    truth = json.loads((work / "truth.json").read_text())
    med = lambda v: float(np.median(v))  # noqa: E731
    s_wall, s_rss = med([w for w, _ in strata]), med([r for _, r in strata])
    v_wall, v_rss = med([w for w, _ in slicer]), med([r for _, r in slicer])
    v_pipe = med([j["pipeline_s"] for j in slicer_json])
    v_inrss = med([j["ru_maxrss_mb"] for j in slicer_json])

    def err(name):
        path = work / f"error_{name}.json"
        return json.loads(path.read_text()) if path.exists() else None

    objects = summary["objects"]
    levels = max(len(o["surface"]["levels"]) for o in objects)
    full_tris = sum(o["surface"]["triangles"] for o in objects)
    root_tris = sum(o["surface"]["levels"][-1]["triangles"] for o in objects)
    full_bound = max(o["surface"]["levels"][0]["error_mm"] for o in objects)

    rows = []
    e = err("strata_full")
    rows.append((f"strata build (full resolution + multires, {levels} levels)", s_wall, s_rss,
                 full_tris, full_bound, e))
    for eps in args.levels + ["base"]:
        ext = json.loads((work / f"extract_{eps}.json").read_text())
        tris = sum(o["triangles"] for o in ext["objects"])
        bound = max(o["error_mm"] for o in ext["objects"])
        name = f"strata level <= {eps} mm (cut of the same model)"
        if eps == "base":
            name = "strata base (root of every object)"
            if tris != root_tris:
                name += f" [summary: {root_tris} triangles]"
        rows.append((name, None, None, tris, bound, err(f"strata_{eps}")))
    rows.append(("Slicer pipeline (VTK FE + sinc + normals)", v_pipe, v_rss,
                 slicer_json[0]["triangles"], None, err("slicer")))

    dims = truth["dims"]
    sp = truth["spacing_mm"]
    print()
    voxels = ", ".join(f"{k}: {v} voxels" for k, v in truth["voxels"].items())
    print(textwrap.fill(
        f"End-to-end: {dims[0]}x{dims[1]}x{dims[2]} label map, {sp[0]:g} x {sp[1]:g} x "
        f"{sp[2]:g} mm, {len(truth['ellipsoids'])} ellipsoids, labels {voxels}, seed "
        f"{truth['seed']}; median of {len(strata)} run(s) each, strata --threads "
        f"{args.threads}, VTK SMP {slicer_json[0]['smp_backend']} {args.threads} threads.",
        width=100, subsequent_indent="  "))
    header = (f"{'tool':<56} {'wall s':>7} {'peak MB':>8} {'triangles':>10} {'bound mm':>8}"
              f" {'mean err':>8} {'bias':>7} {'max err':>8} {'max m>t':>8} {'max t>m':>8}"
              f" {'area':>7} {'normal':>7}")
    print(header)
    print("-" * len(header))
    for name, wall, rss, tris, bound, e in rows:
        wall_s = f"{wall:>7.2f}" if wall is not None else f"{'-':>7}"
        rss_s = f"{rss:>8.0f}" if rss is not None else f"{'-':>8}"
        bound_s = f"{bound:>8.3f}" if bound is not None else f"{'-':>8}"
        if e is None:
            errs = f"{'(not measured)':>60}"
        else:
            errs = (f" {e['mean_mm']:>8.3f} {e['bias_mm']:>+7.3f} {e['max_mm']:>8.3f}"
                    f" {e['max_mesh_to_truth_mm']:>8.3f} {e['max_truth_to_mesh_mm']:>8.3f}"
                    f" {100 * (e['area_mm2'] / truth['true_area_mm2'] - 1):>+6.1f}%"
                    f" {e['normal_mean_deg']:>7.1f}")
        print(f"{name:<56} {wall_s} {rss_s} {tris:>10} {bound_s}{errs}")
    print("-" * len(header))
    print(textwrap.fill(
        f"strata / Slicer: time {s_wall / v_pipe:.2f} (against the pipeline alone), "
        f"{s_wall / v_wall:.2f} (against the whole peer process, {v_wall:.2f} s); "
        f"peak memory {s_rss / v_rss:.2f}; triangles (full resolution) "
        f"{full_tris / slicer_json[0]['triangles']:.2f}", width=100, subsequent_indent="  "))
    ef = err("strata_full")
    es = err("slicer")
    if ef and es:
        print(f"strata full / Slicer: mean error {ef['mean_mm'] / es['mean_mm']:.2f}, "
              f"max error {ef['max_mm'] / es['max_mm']:.2f}")
    stages = [json.loads(p.read_text())["timings_s"]
              for p in sorted(work.glob("runs/strata_*.summary.json"))] or [summary["timings_s"]]
    median_stage = {k: med([st[k] for st in stages]) for k in stages[0]}
    notes = [
        "wall s: strata = the whole `strata build` process (/usr/bin/time -v: NIfTI read, every "
        "stage, writing meshes/*.ply, scene.glb, summary.json); Slicer = its pipeline in process "
        "(labelmap in memory -> surfaces with normals, what Slicer runs on \"Export to models\"; "
        "python start, NIfTI parsing and PLY writing excluded). Level rows are cuts of the model "
        "the build made, written by `strata extract --max-error` (not timed). Runs, wall s: "
        "strata " + " ".join(f"{w:.2f}" for w, _ in strata) + "; Slicer pipeline "
        + " ".join(f"{j['pipeline_s']:.2f}" for j in slicer_json) + ", its whole process "
        + " ".join(f"{w:.2f}" for w, _ in slicer) + ".",
        f"peak MB: max RSS of each process (/usr/bin/time -v); the python peer's own getrusage "
        f"says {v_inrss:.0f} MB (python, numpy, the VTK libraries and the labelmap included).",
        "bound mm: strata's declared bound, largest over the objects: the contour tolerance at "
        "full resolution, the cut's error bound otherwise (both directions between the surface "
        "and the input contours: slice sections to contours, contour points to the surface; "
        "not against the true surface, which is unknown between slices).",
    ]
    if es:
        notes.append(
            f"errors, mm, to the analytic union of ellipsoids in one frame (voxel index x "
            f"spacing): mean err = area-weighted mean |distance| mesh -> truth "
            f"({es['samples']['random']} random points), bias = signed mean (+ outside), max "
            f"err = two-sided (Hausdorff) = max(max m>t, max t>m). m>t is exact at each sample "
            f"(Eberly point-to-ellipsoid; union creases sampled at {es['crease_spacing_mm']:g} "
            f"mm, floor {es['crease_spacing_mm'] / 2:g} mm) over vertices, centroids, random "
            f"points and a 20x20 grid on the worst triangles; t>m is exact point-to-triangle "
            f"from true-surface points at {es['truth_spacing_mm']:g} mm mean spacing, refined "
            f"within 1.5 mm of the worst 100 (peaks narrower than that may be missed).")
    notes += [
        f"area: the mesh's surface area against the true surface's "
        f"({truth['true_area_mm2']:.0f} mm^2); normal: area-weighted mean angle in degrees "
        f"between the mesh's face normals and the true normal at the closest point. An area "
        f"excess or a large normal angle with small distances means a rippled surface (shading "
        f"shows it).",
        f"timings_s of strata build (summary.json, median of {len(stages)} runs): " + ", ".join(
            f"{k} {v:.2f}" for k, v in median_stage.items())
        + f" (sum {sum(median_stage.values()):.2f} s).",
    ]
    print()
    for note in notes:
        print(textwrap.fill(note, width=100, subsequent_indent="  "))


# ---------------------------------------------------------------------------------------------
# benchmark cases (bench-e2e.sh --cases)


def read_png_grey8(path):
    """An 8-bit greyscale, non-interlaced PNG as a [row, column] uint8 array."""
    raw = pathlib.Path(path).read_bytes()
    if raw[:8] != b"\x89PNG\r\n\x1a\n":
        sys.exit(f"{path}: not a PNG file")
    pos, idat, header = 8, [], None
    while pos < len(raw):
        length, kind = struct.unpack_from(">I4s", raw, pos)
        data = raw[pos + 8:pos + 8 + length]
        if kind == b"IHDR":
            header = struct.unpack(">IIBBBBB", data)
        elif kind == b"IDAT":
            idat.append(data)
        pos += 12 + length
    width, height, depth, colour, _, _, interlace = header
    if depth != 8 or colour != 0 or interlace != 0:
        sys.exit(f"{path}: expected 8-bit greyscale without interlacing")
    data = np.frombuffer(zlib.decompress(b"".join(idat)), dtype=np.uint8)
    rows = data.reshape(height, width + 1)
    out = np.zeros((height, width), dtype=np.int32)
    for y in range(height):
        kind, line = rows[y, 0], rows[y, 1:].astype(np.int32)
        up = out[y - 1] if y > 0 else np.zeros(width, dtype=np.int32)
        if kind == 0:
            out[y] = line
        elif kind == 2:
            out[y] = (line + up) & 255
        else:  # sub, average, Paeth: they depend on the reconstructed left neighbour
            row = np.zeros(width, dtype=np.int32)
            for x in range(width):
                left = row[x - 1] if x > 0 else 0
                corner = up[x - 1] if x > 0 else 0
                if kind == 1:
                    pred = left
                elif kind == 3:
                    pred = (left + up[x]) // 2
                else:
                    p = left + up[x] - corner
                    pa, pb, pc = abs(p - left), abs(p - up[x]), abs(p - corner)
                    pred = left if pa <= pb and pa <= pc else (up[x] if pb <= pc else corner)
                row[x] = (line[x] + pred) & 255
            out[y] = row
    return out.astype(np.uint8)


def run_png_nifti(args):
    folder = pathlib.Path(args.slices)
    meta = json.loads((folder.parent / "meta.json").read_text()
                      if not (folder / "meta.json").exists() else (folder / "meta.json").read_text())
    files = sorted(folder.glob("slice_*.png"))
    # PNG column = i, row = j: a [j, i] image per slice, stacked along k
    labels = np.stack([read_png_grey8(f) for f in files])
    nx, ny, nz = meta["dims"]
    if labels.shape != (nz, ny, nx):
        sys.exit(f"{folder}: slices make {labels.shape[::-1]}, meta.json says {meta['dims']}")
    affine = np.asarray(meta["index_to_world_mm"], dtype=np.float64)
    if meta.get("frame", "RAS") != "RAS":
        affine = np.diag([-1.0, -1.0, 1.0, 1.0]) @ affine  # LPS -> RAS
    write_nifti(args.out, labels, affine, meta["spacing_mm"])


def gnu_time_cpu(path):
    """(wall s, CPU s = user + system, max RSS MB) of a `/usr/bin/time -v` log."""
    text = pathlib.Path(path).read_text()
    wall, rss = gnu_time(path)
    user = float(re.search(r"User time \(seconds\): ([\d.]+)", text).group(1))
    system = float(re.search(r"System time \(seconds\): ([\d.]+)", text).group(1))
    return wall, user + system, rss


def finished(paths):
    """The `/usr/bin/time -v` logs of runs that ended (a run still going has an empty log)."""
    return [p for p in paths if "Elapsed" in p.read_text()]


def run_cases_table(args):
    work = pathlib.Path(args.work)
    med = lambda v: float(np.median(v)) if v else float("nan")  # noqa: E731
    cases = [d for d in sorted(work.iterdir()) if d.is_dir() and (d / "case.json").exists()]
    header = (f"{'case':<12} {'tool':<24} {'wall s':>8} {'CPU s':>8} {'peak MB':>8} "
              f"{'/Slicer wall':>12} {'/Slicer CPU':>11} {'/Slicer RSS':>11}  stages (s)")
    print()
    print(header)
    print("-" * len(header))
    notes = []
    for d in cases:
        case = json.loads((d / "case.json").read_text())
        slicer = [gnu_time_cpu(p) for p in finished(sorted(d.glob("slicer_*.time")))]
        slicer_json = [json.loads(p.read_text()) for p in sorted(d.glob("slicer_*.json"))]
        v_wall = med([w for w, _, _ in slicer])
        v_rss = med([r for _, _, r in slicer])
        v_cpu = med([c for _, c, _ in slicer])
        rows = []
        walls = {}
        for t in case["threads"]:
            runs = [gnu_time_cpu(p) for p in finished(sorted(d.glob(f"strata_t{t}_*.time")))]
            if not runs:
                continue
            summaries = [json.loads(p.read_text())
                         for p in sorted(d.glob(f"strata_t{t}_*.summary.json"))]

            def stage_text(field):
                stages = [s.get(field, {}) for s in summaries]
                keys = list(stages[0]) if stages else []
                return " ".join(f"{k} {med([st.get(k, 0.0) for st in stages]):.2f}"
                                for k in keys)

            wall, cpu, rss = (med([r[i] for r in runs]) for i in range(3))
            walls[t] = wall
            rows.append((f"strata --threads {t}", wall, cpu, rss, stage_text("timings_s"),
                         stage_text("cpu_timings_s")))
        if slicer:
            rows.append((f"Slicer pipeline ({case['slicer_threads']} thr)", v_wall,
                         med([c for _, c, _ in slicer]), v_rss,
                         f"in process {med([j['pipeline_s'] for j in slicer_json]):.2f}", ""))
        for tool, wall, cpu, rss, stages, cpu_stages in rows:
            ratio_wall = f"{wall / v_wall:>12.2f}" if slicer else f"{'-':>12}"
            ratio_cpu = f"{cpu / v_cpu:>11.2f}" if slicer else f"{'-':>11}"
            ratio_rss = f"{rss / v_rss:>11.2f}" if slicer else f"{'-':>11}"
            print(f"{case['name']:<12} {tool:<24} {wall:>8.2f} {cpu:>8.2f} {rss:>8.0f} "
                  f"{ratio_wall} {ratio_cpu} {ratio_rss}  {stages}")
            if cpu_stages:  # summaries before cpu_timings_s have none
                print(f"{'':<12} {'  CPU stages (s)':<24} {'':>8} {'':>8} {'':>8} "
                      f"{'':>12} {'':>11} {'':>11}  {cpu_stages}")
        if 1 in walls and 2 in walls:
            notes.append(f"{case['name']}: strata 1 thread / 2 threads = "
                         f"{walls[1] / walls[2]:.2f}x")
        notes.append(f"{case['name']}: {case['input']} ({case['what']}); "
                     f"median of {case['runs']} run(s) each, runs alternated")
    print("-" * len(header))
    notes.append("wall, CPU, peak MB: the whole process under /usr/bin/time -v (strata build: "
                 "reading, every stage, every output; Slicer pipeline: python start, NIfTI "
                 "parsing, VTK flying edges + windowed sinc + normals per label, PLY writing). "
                 "/Slicer: against the Slicer pipeline's whole process (CPU: on a loaded machine the "
                 "steadier measure). stages: strata's "
                 "summary.json timings_s (wall per stage); CPU stages: its cpu_timings_s "
                 "(process CPU, user + system of every thread, per stage); Slicer's in-process "
                 "time excludes python start, parsing and writing.")
    for note in notes:
        print(textwrap.fill(note, width=100, subsequent_indent="  "))


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = parser.add_subparsers(dest="command", required=True)
    p = sub.add_parser("phantom", help="write mask.nii.gz and truth.json")
    p.add_argument("out_dir")
    p.add_argument("--dims", default="512,512,256")
    p.add_argument("--spacing", default="1,1,2")
    p.add_argument("--seed", type=int, default=7)
    s = sub.add_parser("slicer", help="Slicer's labelmap -> closed surface pipeline")
    s.add_argument("nifti")
    s.add_argument("out_dir")
    s.add_argument("--threads", type=int, default=2)
    s.add_argument("--iterations", type=int, default=20)
    e = sub.add_parser("error", help="error of meshes to the truth")
    e.add_argument("truth")
    e.add_argument("affine")
    e.add_argument("meshes", nargs="+")
    e.add_argument("--out", required=True)
    e.add_argument("--random-samples", type=int, default=500000)
    e.add_argument("--refine", type=int, default=200)
    e.add_argument("--truth-spacing", type=float, default=1.0)
    e.add_argument("--crease-spacing", type=float, default=0.02)
    t = sub.add_parser("table", help="print the table")
    t.add_argument("work")
    t.add_argument("--threads", type=int, default=2)
    t.add_argument("--levels", nargs="*", default=["1", "2"])
    n = sub.add_parser("png-nifti", help="a strata PNG stack as a NIfTI-1 label map")
    n.add_argument("slices")
    n.add_argument("out")
    c = sub.add_parser("cases-table", help="print the table of bench-e2e.sh --cases")
    c.add_argument("work")
    args = parser.parse_args()
    {"phantom": run_phantom, "slicer": run_slicer, "error": run_error,
     "table": run_table, "png-nifti": run_png_nifti,
     "cases-table": run_cases_table}[args.command](args)


if __name__ == "__main__":
    main()
