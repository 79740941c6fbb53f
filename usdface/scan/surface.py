"""Depth map -> 3-D points -> a scan surface mesh in real units (seed 001, section 2).

Three ways to make the surface (:data:`SURFACE_METHODS`):

- ``"grid"`` (default): the depth map's own pixel grid, two triangles per 2x2 block of valid
  pixels, skipping blocks that straddle a depth discontinuity (an edge longer than
  ``max_stretch`` times the pixel footprint); faithful, fast, keeps holes (eyes, occlusions);
- ``"poisson"``: pymeshlab's screened Poisson reconstruction from the points and their normals,
  then trimmed back to the data (faces farther than a few pixel footprints from any point are
  removed, since Poisson closes every hole);
- ``"ball-pivoting"``: pymeshlab's ball pivoting over the points.

Each result is cleaned with pymeshlab: duplicate and unreferenced vertices, zero-area faces, and
connected pieces smaller than ``min_component`` of the largest are removed.
"""
from __future__ import annotations

import numpy as np

from ..errors import ComputeError, OptionError, UsdFaceError

__all__ = ["SURFACE_METHODS", "ScanSurface", "grid_mesh", "clean_mesh", "reconstruct_surface",
           "camera_to_scan", "scan_to_camera"]

from .methods import SURFACES as SURFACE_METHODS  # named once


def camera_to_scan(points) -> np.ndarray:
    """Camera frame (x right, y down, z forward) -> scan frame (x right, y up, z toward the camera).

    A rotation by 180 degrees about x. The scan layer is Y-up like every usdface layer; the face
    looks along +Z at the camera, which sits at the origin.
    """
    p = np.asarray(points, dtype=np.float64)
    return p * np.array([1.0, -1.0, -1.0])


scan_to_camera = camera_to_scan  # the map is its own inverse


class ScanSurface:
    """A scan surface: vertices (scan frame, calibration units), triangles, and the pixel of each
    vertex in the first rectified image (NaN for vertices not from a pixel)."""

    def __init__(self, points, triangles, pixels=None):
        self.points = np.asarray(points, dtype=np.float64)
        self.triangles = np.asarray(triangles, dtype=np.int64)
        self.pixels = None if pixels is None else np.asarray(pixels, dtype=np.float64)

    @property
    def n_points(self) -> int:
        return self.points.shape[0]


def grid_mesh(points, valid, *, step: int = 1, max_stretch: float = 4.0):
    """Triangulate a structured point grid.

    Parameters
    ----------
    points : ndarray, shape (H, W, 3)
        A point per pixel (camera frame; depth = z).
    valid : ndarray, shape (H, W), bool
    step : int
        Use every ``step``-th pixel in each direction.
    max_stretch : float
        A triangle is dropped when one of its edges is longer than ``max_stretch`` times the
        footprint of ``step`` pixels at its depth (``step * z / f``, estimated from the grid).

    Returns
    -------
    vertices : ndarray, shape (V, 3)
    triangles : ndarray, shape (T, 3), int64
        Counter-clockwise as seen from the camera (normals toward it) in the scan frame.
    pixels : ndarray, shape (V, 2)
        (x, y) pixel of each vertex.
    """
    if step < 1:
        raise OptionError(f"step must be >= 1; got {step}")
    P = np.asarray(points, dtype=np.float64)[::step, ::step]
    ok = np.asarray(valid, bool)[::step, ::step] & np.isfinite(P).all(axis=2)
    h, w = ok.shape
    idx = np.full((h, w), -1, dtype=np.int64)
    idx[ok] = np.arange(int(ok.sum()))
    verts = P[ok]
    ys, xs = np.nonzero(ok)
    pixels = np.stack([xs * step, ys * step], axis=1).astype(np.float64)
    a, b = idx[:-1, :-1], idx[:-1, 1:]
    c, d = idx[1:, :-1], idx[1:, 1:]
    # footprint of one grid step at each vertex: |p(x+1) - p(x)| for a flat frontal surface = z step / f
    if verts.shape[0] == 0:
        return verts, np.zeros((0, 3), np.int64), pixels
    dx = np.abs(np.diff(P[..., 0], axis=1))
    fz = np.nanmedian(dx[np.isfinite(dx) & ok[:, 1:] & ok[:, :-1]] / P[:, 1:, 2][np.isfinite(dx) & ok[:, 1:] & ok[:, :-1]]) \
        if (ok[:, 1:] & ok[:, :-1]).any() else 1.0
    tris = []
    for t in ((a, c, b), (b, c, d)):
        t = np.stack([x.ravel() for x in t], axis=1)
        t = t[(t >= 0).all(axis=1)]
        tris.append(t)
    tris = np.concatenate(tris)
    if tris.size:
        p0, p1, p2 = verts[tris[:, 0]], verts[tris[:, 1]], verts[tris[:, 2]]
        longest = np.max(np.stack([np.linalg.norm(p1 - p0, axis=1), np.linalg.norm(p2 - p1, axis=1),
                                   np.linalg.norm(p0 - p2, axis=1)]), axis=0)
        zmean = (p0[:, 2] + p1[:, 2] + p2[:, 2]) / 3.0
        tris = tris[longest <= max_stretch * fz * zmean * np.sqrt(2.0)]
    # (a, c, b) has the normal (c - a) x (b - a) along -z of the camera frame: toward the camera;
    # camera_to_scan is a rotation (180 degrees about x), so the winding keeps facing the camera
    used = np.unique(tris)
    remap = np.full(verts.shape[0], -1, dtype=np.int64)
    remap[used] = np.arange(used.size)
    return verts[used], remap[tris], pixels[used]


def _pymeshlab():
    try:
        import pymeshlab
    except ImportError as exc:  # pragma: no cover - a dependency of usdface
        raise UsdFaceError("scan surfaces need pymeshlab: pip install pymeshlab") from exc
    return pymeshlab


def clean_mesh(vertices, triangles, *, min_component: float = 0.02, keep_vertex_order: bool = False):
    """Remove duplicate/unreferenced vertices, null faces and small pieces (pymeshlab).

    Parameters
    ----------
    min_component : float
        Pieces with fewer faces than this fraction of the largest piece are removed.

    Returns
    -------
    vertices, triangles, kept : ndarray
        ``kept`` (V',) maps each output vertex to its input index.
    """
    pymeshlab = _pymeshlab()
    v = np.asarray(vertices, dtype=np.float64)
    t = np.asarray(triangles, dtype=np.int32)
    if t.shape[0] == 0:
        raise ComputeError("the scan has no surface: no valid depth (check the disparity range and calibration)")
    # vertex quality carries the original index through pymeshlab's filters
    m = pymeshlab.Mesh(vertex_matrix=v, face_matrix=t, v_scalar_array=np.arange(v.shape[0], dtype=np.float64))
    ms = pymeshlab.MeshSet()
    ms.add_mesh(m)
    ms.meshing_remove_duplicate_faces()
    ms.meshing_remove_null_faces()
    ms.meshing_remove_unreferenced_vertices()
    nf = ms.current_mesh().face_number()
    if min_component > 0 and nf:
        ms.generate_splitting_by_connected_components(delete_source_mesh=False)
        sizes = {i: ms.mesh(i).face_number() for i in range(1, ms.mesh_number())}
        ms.set_current_mesh(0)
        if sizes:
            largest = max(sizes.values())
            ms.meshing_remove_connected_component_by_face_number(mincomponentsize=max(1, int(min_component * largest)))
        ms.meshing_remove_unreferenced_vertices()
    cm = ms.mesh(0)
    kept = np.round(cm.vertex_scalar_array()).astype(np.int64)
    return cm.vertex_matrix().astype(np.float64), cm.face_matrix().astype(np.int64), kept


def reconstruct_surface(points, valid, *, method: str = "grid", step: int = 2, max_stretch: float = 4.0,
                        min_component: float = 0.02, poisson_depth: int = 9) -> ScanSurface:
    """Scan surface from a per-pixel point map (camera frame), in the scan frame.

    Parameters
    ----------
    points : ndarray, shape (H, W, 3)
        Camera-frame points (calibration units) of the first rectified image's pixels.
    valid : ndarray, shape (H, W), bool
    method : str
        ``"grid"``, ``"poisson"`` or ``"ball-pivoting"``.
    step : int
        Pixel subsampling (2: a quarter of the pixels).
    max_stretch, min_component :
        See :func:`grid_mesh` and :func:`clean_mesh`.
    poisson_depth : int
        Octree depth of the screened Poisson reconstruction.

    Returns
    -------
    ScanSurface
        Points in the scan frame (:func:`camera_to_scan`), counter-clockwise triangles facing the
        camera.
    """
    if method not in SURFACE_METHODS:
        raise OptionError(f"surface method must be one of {', '.join(SURFACE_METHODS)}; got {method!r}")
    verts, tris, pixels = grid_mesh(points, valid, step=step, max_stretch=max_stretch)
    if verts.shape[0] < 3 or tris.shape[0] == 0:
        raise ComputeError(f"the scan has no surface: {int(np.asarray(valid).sum())} valid pixels and no "
                           "triangle between them (check the disparity range, the calibration and the images)")
    if method == "grid":
        v, t, kept = clean_mesh(verts, tris, min_component=min_component)
        v = camera_to_scan(v)
        return ScanSurface(v, t, pixels[kept])
    pymeshlab = _pymeshlab()
    ms = pymeshlab.MeshSet()
    ms.add_mesh(pymeshlab.Mesh(vertex_matrix=camera_to_scan(verts)))
    ms.compute_normal_for_point_clouds(k=10, viewpos=np.zeros(3), flipflag=True)
    step_len = float(np.median(np.linalg.norm(verts[tris[:, 1]] - verts[tris[:, 0]], axis=1)))
    if method == "poisson":
        ms.generate_surface_reconstruction_screened_poisson(depth=poisson_depth, preclean=True)
        out = ms.current_mesh()
        v, t = out.vertex_matrix(), out.face_matrix()
        from scipy.spatial import cKDTree

        dist, _ = cKDTree(camera_to_scan(verts)).query((v[t[:, 0]] + v[t[:, 1]] + v[t[:, 2]]) / 3.0)
        t = t[dist <= 3.0 * step_len]
    else:
        ms.generate_surface_reconstruction_ball_pivoting(ballradius=pymeshlab.PureValue(2.0 * step_len))
        out = ms.current_mesh()
        v, t = out.vertex_matrix(), out.face_matrix()
    v, t, _ = clean_mesh(v, t, min_component=min_component)
    # orient toward the camera (at the origin, looking along -z in the scan frame)
    n = np.cross(v[t[:, 1]] - v[t[:, 0]], v[t[:, 2]] - v[t[:, 0]])
    if np.median(n[:, 2]) < 0:
        t = t[:, ::-1]
    return ScanSurface(v, t, None)
