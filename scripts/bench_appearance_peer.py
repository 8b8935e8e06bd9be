#!/usr/bin/env python3
"""Helper of scripts/bench-appearance.sh (issue 17): the peers, the metrics, the pictures.

`phantom OUT_DIR [--seed N]` writes OUT_DIR/mask.nii.gz, a smooth phantom at 0.78 x 0.78 x 5 mm
(an ellipsoid, semi-axes 62, 46 and 38 mm, turned 25 degrees about z and 20 degrees about x so
the slices cut it obliquely) whose boundary carries per-slice noise as a segmentation would:
every slice's section is shifted by a random in-plane offset (sigma 0.35 px) and scaled by a
random factor (sigma 1 %); OUT_DIR/truth.json keeps the smooth ellipsoid (frame F = voxel
index times spacing, and the index -> LPS mm affine) for the normals' error.

`peer NIFTI LABEL OUT_DIR [--iterations N]` makes the peers' surfaces of one label (LABEL a
value) in LPS mm, with their vertex normals: OUT_DIR/flying_edges.ply (vtkDiscreteFlyingEdges3D,
then vtkPolyDataNormals as a viewer would) and OUT_DIR/slicer.ply (3D Slicer's "Export to models"
as in bench_e2e_peer.py: flying edges, vtkWindowedSincPolyDataFilter pass band 0.01, N = 20
iterations, vtkPolyDataNormals consistency on, splitting off).

`metrics NIFTI LABEL MESH.ply [--truth truth.json] --out JSON` measures one surface (LPS mm):
  folded: share of edges whose two faces' normals differ by more than 90 degrees;
  dihedral: mean angle between the normals of the two faces of an edge (degrees);
  slivers: share of faces whose smallest angle is under 5 degrees;
  roughness: shading roughness, the sum over edges of the angle between the two end vertices'
    normals divided by the sum of the edges' lengths (degrees per mm); the vertex normals are
    the file's (nx, ny, nz) when it has them, else area-weighted, or with --shading-normals
    strata's shading normals computed here by the header's definition (when the file has normals
    too, both must agree within 0.01 degrees: a check of the two implementations);
  normal_error: with --truth, the mean angle between a vertex's normal and the smooth truth's
    normal at the nearest point (degrees; area-weighted over the vertices' one-ring areas);
  slice error: the surface's sections with the planes through the slice centres (index z = k)
    against the label's pixel boundary on that slice (edges between pixels in and out): mean
    and max distance (mm) of points every 0.1 px along the sections to that boundary.
`folds NIFTI MESH.ply [--list N]` finds the edges folded over 90 degrees: their count per slab
(index k for k <= z < k + 1 of the edge's midpoint, voxel index frame), by kind (each end and
the two opposite corners: C on a slice plane, S between slices; short = under 0.35 px in plane)
and the N sharpest with their ends in voxel indices.
`normals MESH.ply OUT.ply` writes the mesh again with strata's shading normals computed here.
`render OUT.png TITLE=MESH.ply...` draws the meshes side by side, one camera for all (the
first mesh's bounds), offscreen (VTK; run it under xvfb-run), Phong-shaded with the files'
normals, the slices' direction vertical.
`table WORK` prints the comparison from the JSON files bench-appearance.sh left in WORK.

Needs Debian's python3-numpy, python3-scipy, python3-vtk9 (and xvfb for `render`).
"""
import argparse
import json
import pathlib
import sys

import numpy as np

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))
import bench_e2e_peer as e2e  # noqa: E402  (NIfTI and PLY files, triangle arrays)

SPACING = (0.78, 0.78, 5.0)
DIMS = (224, 224, 24)  # x, y, slices
SEMI_AXES = (62.0, 46.0, 38.0)


# ---------------------------------------------------------------------------------------------
# phantom


def rotation():
    a, b = np.radians(25.0), np.radians(20.0)
    rz = np.array([[np.cos(a), -np.sin(a), 0], [np.sin(a), np.cos(a), 0], [0, 0, 1]])
    rx = np.array([[1, 0, 0], [0, np.cos(b), -np.sin(b)], [0, np.sin(b), np.cos(b)]])
    return rz @ rx


def ellipsoid_value(points_f, centre, rot):
    """(x R)^T D (x R) - 1 and its gradient, points in frame F (mm)."""
    local = (points_f - centre) @ rot  # columns of rot are the ellipsoid's axes
    d = 1.0 / np.square(SEMI_AXES)
    value = np.sum(local * local * d, axis=1) - 1.0
    grad = (2.0 * local * d) @ rot.T
    return value, grad


def run_phantom(args):
    rng = np.random.default_rng(args.seed)
    nx, ny, nz = DIMS
    centre = np.array([nx * SPACING[0] / 2, ny * SPACING[1] / 2, nz * SPACING[2] / 2])
    rot = rotation()
    labels = np.zeros((nz, ny, nx), dtype=np.uint8)
    jj, ii = np.meshgrid(np.arange(ny), np.arange(nx), indexing="ij")
    for k in range(nz):
        shift = rng.normal(0.0, 0.35, 2)
        scale = 1.0 + rng.normal(0.0, 0.01)
        # the section of a scaled, shifted copy: voxel centres of this slice
        x = (ii - shift[0]) * SPACING[0]
        y = (jj - shift[1]) * SPACING[1]
        pts = np.stack([x.ravel(), y.ravel(), np.full(x.size, k * SPACING[2])], axis=1)
        pts = centre + (pts - centre) / scale
        value, _ = ellipsoid_value(pts, centre, rot)
        labels[k] = (value <= 0).reshape(ny, nx)
    affine_ras = np.diag([-SPACING[0], -SPACING[1], SPACING[2], 1.0])  # LPS-aligned
    out = pathlib.Path(args.out_dir)
    out.mkdir(parents=True, exist_ok=True)
    e2e.write_nifti(out / "mask.nii.gz", labels, affine_ras, SPACING)
    lps = np.diag([-1.0, -1.0, 1.0, 1.0]) @ affine_ras
    truth = {"centre_f_mm": centre.tolist(), "rotation": rot.tolist(),
             "semi_axes_mm": list(SEMI_AXES), "spacing_mm": list(SPACING),
             "index_to_world_lps_mm": lps.tolist()}
    (out / "truth.json").write_text(json.dumps(truth, indent=1) + "\n")


# ---------------------------------------------------------------------------------------------
# peers


def to_polydata(points, triangles):
    from vtkmodules.util import numpy_support
    from vtkmodules.vtkCommonCore import vtkPoints
    from vtkmodules.vtkCommonDataModel import vtkCellArray, vtkPolyData
    pd = vtkPolyData()
    pts = vtkPoints()
    pts.SetData(numpy_support.numpy_to_vtk(points, deep=True))
    pd.SetPoints(pts)
    cells = vtkCellArray()
    offsets = np.arange(0, 3 * len(triangles) + 1, 3, dtype=np.int64)
    cells.SetData(numpy_support.numpy_to_vtk(offsets, deep=True),
                  numpy_support.numpy_to_vtk(triangles.ravel().astype(np.int64), deep=True))
    pd.SetPolys(cells)
    return pd


def run_peer(args):
    from vtkmodules.util import numpy_support
    from vtkmodules.vtkCommonDataModel import vtkImageData
    from vtkmodules.vtkFiltersCore import vtkPolyDataNormals
    from vtkmodules.vtkImagingCore import vtkImageConstantPad

    labels, lps = e2e.read_nifti(args.nifti)
    mask = (labels == args.label).astype(np.uint8)
    nz, ny, nx = mask.shape
    image = vtkImageData()
    image.SetDimensions(nx, ny, nz)
    image.GetPointData().SetScalars(numpy_support.numpy_to_vtk(mask.ravel(), deep=True))
    pad = vtkImageConstantPad()  # a closed surface also where the label touches the border
    pad.SetInputData(image)
    pad.SetOutputWholeExtent(-1, nx, -1, ny, -1, nz)
    pad.Update()
    surface = e2e.flying_edges(pad.GetOutput(), 1)
    smoothed = e2e.slicer_smooth(surface, args.iterations)
    out = pathlib.Path(args.out_dir)
    out.mkdir(parents=True, exist_ok=True)
    for name, poly in (("flying_edges", surface), ("slicer", smoothed)):
        index_points = numpy_support.vtk_to_numpy(poly.GetPoints().GetData()).astype(np.float64)
        world = index_points @ lps[:3, :3].T + lps[:3, 3]
        triangles = e2e.triangle_array(poly)
        if np.linalg.det(lps[:3, :3]) < 0:
            triangles = triangles[:, [0, 2, 1]]
        # normals after the transform, as Slicer: consistency on, splitting off
        pd = to_polydata(world, triangles)
        normals = vtkPolyDataNormals()
        normals.SetInputData(pd)
        normals.ConsistencyOn()
        normals.SplittingOff()
        normals.Update()
        res = normals.GetOutput()
        n = numpy_support.vtk_to_numpy(res.GetPointData().GetNormals()).astype(np.float64)
        p = numpy_support.vtk_to_numpy(res.GetPoints().GetData()).astype(np.float64)
        e2e.write_ply(out / f"{name}.ply", p, e2e.triangle_array(res), n)


# ---------------------------------------------------------------------------------------------
# metrics


def unit(v):
    n = np.linalg.norm(v, axis=-1, keepdims=True)
    return np.divide(v, n, out=np.zeros_like(v), where=n > 0)


def angle_deg(a, b):
    return np.degrees(np.arctan2(np.linalg.norm(np.cross(a, b), axis=-1),
                                 np.sum(a * b, axis=-1)))


def edges_with_faces(triangles):
    """Unique undirected edges (e x 2) and, for manifold edges, their two faces (e x 2)."""
    m = len(triangles)
    half = np.concatenate([triangles[:, [0, 1]], triangles[:, [1, 2]], triangles[:, [2, 0]]])
    face = np.concatenate([np.arange(m)] * 3)
    key = np.sort(half, axis=1)
    order = np.lexsort((key[:, 1], key[:, 0]))
    key, face = key[order], face[order]
    same = np.all(key[1:] == key[:-1], axis=1)
    first = np.flatnonzero(np.concatenate([[True], ~same]))
    counts = np.diff(np.concatenate([first, [len(key)]]))
    two = first[counts == 2]
    return key[two], np.stack([face[two], face[two + 1]], axis=1)


def surface_metrics(points, triangles, normals):
    p = points[triangles]
    cross = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
    face_n = unit(cross)
    edges, faces = edges_with_faces(triangles)
    dihedral = angle_deg(face_n[faces[:, 0]], face_n[faces[:, 1]])
    angles = []
    for i in range(3):
        a = unit(p[:, (i + 1) % 3] - p[:, i])
        b = unit(p[:, (i + 2) % 3] - p[:, i])
        angles.append(angle_deg(a, b))
    min_angle = np.min(np.stack(angles, axis=1), axis=1)
    if normals is None:
        normals = np.zeros_like(points)
        for i in range(3):
            np.add.at(normals, triangles[:, i], cross)
        normals = unit(normals)
    lengths = np.linalg.norm(points[edges[:, 0]] - points[edges[:, 1]], axis=1)
    shading = angle_deg(normals[edges[:, 0]], normals[edges[:, 1]])
    return {
        "triangles": int(len(triangles)),
        "edges": int(len(edges)),
        "folded_share": float(np.mean(dihedral > 90.0)),
        "folded_edges": int(np.sum(dihedral > 90.0)),
        "mean_dihedral_deg": float(np.mean(dihedral)),
        "sliver_share": float(np.mean(min_angle < 5.0)),
        "roughness_deg_per_mm": float(np.sum(shading) / np.sum(lengths)),
    }, normals


def shading_normals(points, triangles, rings=3):
    """src/mesh/shading_normals.h, written again here: unit face normals, angle-weighted vertex
    normals normalised, summed over each vertex's `rings`-ring (vertex sets),
    each weighted clamp((a(u) . a(v) + 1/2) / 0.1, 0, 1), and normalised."""
    from scipy import sparse
    p = points[triangles]
    face_n = unit(np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]))
    a = np.zeros_like(points)
    for i in range(3):
        e1 = unit(p[:, (i + 1) % 3] - p[:, i])
        e2 = unit(p[:, (i + 2) % 3] - p[:, i])
        angle = np.arccos(np.clip(np.sum(e1 * e2, axis=1), -1.0, 1.0))
        angle[(np.linalg.norm(e1, axis=1) == 0) | (np.linalg.norm(e2, axis=1) == 0)] = 0.0
        np.add.at(a, triangles[:, i], angle[:, None] * face_n)
    a = unit(a)
    n = len(points)
    rows = np.concatenate([triangles[:, i] for i in (0, 0, 1, 1, 2, 2)] + [np.arange(n)])
    cols = np.concatenate([triangles[:, j] for j in (1, 2, 0, 2, 0, 1)] + [np.arange(n)])
    step = sparse.csr_matrix((np.ones(len(rows)), (rows, cols)), shape=(n, n))
    step.data[:] = 1.0
    ring = step
    for _ in range(rings - 1):
        ring = ring @ step
        ring.data[:] = 1.0
    # sum over the ring of the a(u) weighted clamp((a(u) . a(v) + 1/2) / 0.1, 0, 1), per vertex v (row)
    coo = ring.tocoo()
    weight = np.clip((np.sum(a[coo.row] * a[coo.col], axis=1) + 0.5) / 0.1, 0.0, 1.0)
    weighted = sparse.csr_matrix((weight, (coo.row, coo.col)), shape=(n, n))
    out = unit(weighted @ a)
    out[np.linalg.norm(out, axis=1) == 0] = a[np.linalg.norm(out, axis=1) == 0]
    out[np.linalg.norm(out, axis=1) == 0] = (0.0, 0.0, 1.0)
    return out


def normal_error(points, triangles, normals, truth):
    """Mean angle (area-weighted per vertex) to the smooth ellipsoid's normal at the nearest point."""
    lps = np.array(truth["index_to_world_lps_mm"])
    spacing = np.array(truth["spacing_mm"])
    centre = np.array(truth["centre_f_mm"])
    rot = np.array(truth["rotation"])
    inv = np.linalg.inv(lps)
    index = points @ inv[:3, :3].T + inv[:3, 3]
    f = index * spacing
    # nearest point of the ellipsoid: Newton-free projection by a few gradient steps
    x = f.copy()
    for _ in range(30):
        value, grad = ellipsoid_value(x, centre, rot)
        g2 = np.sum(grad * grad, axis=1)
        x = x - (value / np.maximum(g2, 1e-30))[:, None] * grad
    _, grad = ellipsoid_value(x, centre, rot)
    # truth normal in frame F -> LPS (directions: through the linear part, normals by the
    # inverse transpose of F -> LPS)
    f_to_lps = lps[:3, :3] @ np.diag(1.0 / spacing)
    n_lps = unit(grad @ np.linalg.inv(f_to_lps))
    area = np.zeros(len(points))
    p = points[triangles]
    a = 0.5 * np.linalg.norm(np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]), axis=1)
    for i in range(3):
        np.add.at(area, triangles[:, i], a / 3.0)
    err = angle_deg(normals, n_lps)
    return float(np.sum(err * area) / np.sum(area))


def slice_error(points, triangles, labels, lps, label):
    """Mean and max distance (mm) of the sections at z = k to the label's pixel boundary."""
    from scipy.spatial import cKDTree
    inv = np.linalg.inv(lps)
    index = points @ inv[:3, :3].T + inv[:3, 3]
    spacing = np.linalg.norm(lps[:3, :3], axis=0)
    distances = []
    for k in range(labels.shape[0]):
        mask = labels[k] == label
        if not mask.any():
            continue
        z = k + 1e-7
        tz = index[triangles, 2] - z
        below = tz < 0
        cut = np.any(below, axis=1) & np.any(~below, axis=1)
        if not cut.any():
            continue
        seg = []
        for t, d in zip(index[triangles[cut]], tz[cut]):
            pts = []
            for i in range(3):
                j = (i + 1) % 3
                if (d[i] < 0) != (d[j] < 0):
                    s = d[i] / (d[i] - d[j])
                    pts.append(t[i][:2] + s * (t[j][:2] - t[i][:2]))
            if len(pts) == 2:
                seg.append(pts)
        seg = np.array(seg)
        # boundary of the pixels: unit edges between in and out, pixel centres at integers
        m = np.pad(mask, 1)
        b = []
        dy, dx = np.nonzero(m[:, 1:] != m[:, :-1])  # vertical edges at x = dx - 0.5
        for s in np.linspace(0, 1, 11):
            b.append(np.stack([dx - 1 + 0.5, dy - 1 - 0.5 + s], axis=1))
        dy, dx = np.nonzero(m[1:, :] != m[:-1, :])
        for s in np.linspace(0, 1, 11):
            b.append(np.stack([dx - 1 - 0.5 + s, dy - 1 + 0.5], axis=1))
        tree = cKDTree(np.concatenate(b) * spacing[:2])
        samples = []
        for a, c in seg:
            n = max(2, int(np.ceil(np.linalg.norm(c - a) / 0.1)) + 1)
            samples.append(a + np.linspace(0, 1, n)[:, None] * (c - a))
        d, _ = tree.query(np.concatenate(samples) * spacing[:2])
        distances.append(d)
    d = np.concatenate(distances)
    # sampling floor of the boundary: 0.05 px
    return float(np.mean(d)), float(np.max(d))


def run_metrics(args):
    points, triangles, normals = e2e.read_ply(args.mesh, with_normals=True)
    if args.area_normals:
        normals = None
    if args.shading_normals:
        computed = shading_normals(points, triangles)
        if normals is not None:  # a check of both implementations of the definition
            result_check = float(np.max(angle_deg(normals, computed)))
            if result_check > 0.01:
                sys.exit(f"{args.mesh}: the file's normals differ from shading_normals() by "
                         f"{result_check:.4f} degrees")
        normals = computed
    result, normals = surface_metrics(points, triangles, normals)
    labels, lps = e2e.read_nifti(args.nifti)
    result["slice_error_mean_mm"], result["slice_error_max_mm"] = slice_error(
        points, triangles, labels, lps, args.label)
    if args.truth:
        truth = json.loads(pathlib.Path(args.truth).read_text())
        result["normal_error_deg"] = normal_error(points, triangles, normals, truth)
    pathlib.Path(args.out).write_text(json.dumps(result, indent=1) + "\n")


def run_folds(args):
    import collections
    points, triangles = e2e.read_ply(args.mesh)
    _, lps = e2e.read_nifti(args.nifti)
    inv = np.linalg.inv(lps)
    index = points @ inv[:3, :3].T + inv[:3, 3]
    p = points[triangles]
    face_n = unit(np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]))
    edges, faces = edges_with_faces(triangles)
    dihedral = angle_deg(face_n[faces[:, 0]], face_n[faces[:, 1]])
    fold = dihedral > 90.0
    print(f"{args.mesh}: {int(fold.sum())} of {len(edges)} edges folded over 90 degrees "
          f"({100.0 * fold.mean():.3f} %)")
    ends = index[edges[fold]]
    slab = np.floor(0.5 * (ends[:, 0, 2] + ends[:, 1, 2]) + 1e-6).astype(int)
    print("per slab:", " ".join(f"{k}:{n}" for k, n in sorted(collections.Counter(
        slab.tolist()).items(), key=lambda kn: -kn[1])))

    def kind(v):
        z = index[v, 2]
        return "C" if abs(z - round(z)) < 1e-4 else "S"
    kinds = collections.Counter()
    for (a, b), (f, g) in zip(edges[fold], faces[fold]):
        oa = next(v for v in triangles[f] if v not in (a, b))
        ob = next(v for v in triangles[g] if v not in (a, b))
        short = np.linalg.norm(index[a, :2] - index[b, :2]) < 0.35
        kinds["".join(sorted(kind(a) + kind(b))) + "/" + "".join(sorted(kind(oa) + kind(ob))) +
              (" short" if short else "")] += 1
    print("edge/opposite:", " ".join(f"{k}:{n}" for k, n in kinds.most_common()))
    for o in np.argsort(-dihedral[fold])[:args.list]:
        a, b = ends[o]
        print(f"{dihedral[fold][o]:6.1f} deg  ({a[0]:.2f}, {a[1]:.2f}, {a[2]:.3f}) -> "
              f"({b[0]:.2f}, {b[1]:.2f}, {b[2]:.3f})")


def run_normals(args):
    points, triangles, _ = e2e.read_ply(args.mesh, with_normals=True)
    e2e.write_ply(args.out, points, triangles, shading_normals(points, triangles))


# ---------------------------------------------------------------------------------------------
# pictures


def run_render(args):
    import vtkmodules.vtkRenderingFreeType  # noqa: F401  (text)
    import vtkmodules.vtkRenderingOpenGL2  # noqa: F401  (the OpenGL back end)
    from vtkmodules.util import numpy_support
    from vtkmodules.vtkIOImage import vtkPNGWriter
    from vtkmodules.vtkRenderingCore import (vtkActor, vtkPolyDataMapper, vtkRenderer,
                                             vtkRenderWindow, vtkTextActor,
                                             vtkWindowToImageFilter)

    panels = [item.split("=", 1) for item in args.meshes]
    width = args.size
    window = vtkRenderWindow()
    window.SetOffScreenRendering(1)
    window.SetSize(width * len(panels), width)
    camera = None
    for i, (title, path) in enumerate(panels):
        points, triangles, normals = e2e.read_ply(path, with_normals=True)
        if normals is None:
            _, normals = surface_metrics(points, triangles, None)
        pd = to_polydata(points, triangles)
        pd.GetPointData().SetNormals(numpy_support.numpy_to_vtk(normals, deep=True))
        mapper = vtkPolyDataMapper()
        mapper.SetInputData(pd)
        actor = vtkActor()
        actor.SetMapper(mapper)
        prop = actor.GetProperty()
        prop.SetColor(0.80, 0.45, 0.40)
        prop.SetInterpolationToPhong()
        prop.SetSpecular(0.3)
        prop.SetSpecularPower(30)
        renderer = vtkRenderer()
        renderer.SetViewport(i / len(panels), 0.0, (i + 1) / len(panels), 1.0)
        renderer.SetBackground(1.0, 1.0, 1.0)
        renderer.AddActor(actor)
        text = vtkTextActor()
        text.SetInput(title)
        text.GetTextProperty().SetColor(0, 0, 0)
        text.GetTextProperty().SetFontSize(max(12, width // 28))
        text.GetPositionCoordinate().SetCoordinateSystemToNormalizedViewport()
        text.SetPosition(0.03, 0.03)
        renderer.AddActor2D(text)
        if camera is None:
            renderer.ResetCamera(pd.GetBounds())
            camera = renderer.GetActiveCamera()
            # LPS: look from the anterior-left (-y, +x), superior (+z) up
            centre = np.median(points, axis=0)
            camera.SetFocalPoint(*centre)
            camera.SetPosition(*(centre + np.array(args.view) * 1000.0))
            camera.SetViewUp(0, 0, 1)
            # frame the largest component's bounds: the points within the 1st-99th percentiles
            lo = np.percentile(points, 1, axis=0)
            hi = np.percentile(points, 99, axis=0)
            renderer.ResetCamera(lo[0], hi[0], lo[1], hi[1], lo[2], hi[2])
            camera.Zoom(args.zoom)
        else:
            renderer.SetActiveCamera(camera)
        window.AddRenderer(renderer)
    window.Render()
    grab = vtkWindowToImageFilter()
    grab.SetInput(window)
    grab.Update()
    writer = vtkPNGWriter()
    writer.SetFileName(args.out)
    writer.SetInputConnection(grab.GetOutputPort())
    writer.Write()


# ---------------------------------------------------------------------------------------------
# table


def run_table(args):
    work = pathlib.Path(args.work)
    cases = json.loads((work / "cases.json").read_text())
    columns = [("folded > 90 %", "folded_share", 100.0, "{:.2f}"),
               ("mean dihedral", "mean_dihedral_deg", 1.0, "{:.1f}"),
               ("faces < 5 deg %", "sliver_share", 100.0, "{:.2f}"),
               ("normal err deg", "normal_error_deg", 1.0, "{:.2f}"),
               ("roughness deg/mm", "roughness_deg_per_mm", 1.0, "{:.2f}"),
               ("slice err mean/max mm", None, 1.0, None),
               ("triangles", "triangles", 1.0, "{:.0f}")]
    header = f"{'case':<22}{'surface':<20}" + "".join(f"{c[0]:>23}" for c in columns)
    print(header)
    for case in cases:
        for name in case["surfaces"]:
            path = work / case["name"] / f"{name}.json"
            if not path.exists():
                continue
            r = json.loads(path.read_text())
            row = f"{case['name']:<22}{name:<20}"
            for title, key, scale, fmt in columns:
                if key is None:
                    cell = f"{r['slice_error_mean_mm']:.3f}/{r['slice_error_max_mm']:.2f}"
                elif key in r:
                    cell = fmt.format(r[key] * scale)
                else:
                    cell = "-"
                row += f"{cell:>23}"
            print(row)


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = parser.add_subparsers(dest="command", required=True)
    p = sub.add_parser("phantom")
    p.add_argument("out_dir")
    p.add_argument("--seed", type=int, default=17)
    p.set_defaults(run=run_phantom)
    p = sub.add_parser("peer")
    p.add_argument("nifti")
    p.add_argument("label", type=int)
    p.add_argument("out_dir")
    p.add_argument("--iterations", type=int, default=20)
    p.set_defaults(run=run_peer)
    p = sub.add_parser("metrics")
    p.add_argument("nifti")
    p.add_argument("label", type=int)
    p.add_argument("mesh")
    p.add_argument("--truth")
    p.add_argument("--area-normals", action="store_true",
                   help="ignore the file's normals, use area-weighted ones")
    p.add_argument("--shading-normals", action="store_true",
                   help="compute strata's shading normals here (checked against the file's)")
    p.add_argument("--out", required=True)
    p.set_defaults(run=run_metrics)
    p = sub.add_parser("folds")
    p.add_argument("nifti")
    p.add_argument("mesh")
    p.add_argument("--list", type=int, default=20)
    p.set_defaults(run=run_folds)
    p = sub.add_parser("normals")
    p.add_argument("mesh")
    p.add_argument("out")
    p.set_defaults(run=run_normals)
    p = sub.add_parser("render")
    p.add_argument("out")
    p.add_argument("meshes", nargs="+")
    p.add_argument("--size", type=int, default=700)
    p.add_argument("--view", type=lambda s: [float(v) for v in s.split(",")], default=[0, -1, 0])
    p.add_argument("--zoom", type=float, default=1.2)
    p.set_defaults(run=run_render)
    p = sub.add_parser("table")
    p.add_argument("work")
    p.set_defaults(run=run_table)
    args = parser.parse_args()
    args.run(args)


if __name__ == "__main__":
    main()
