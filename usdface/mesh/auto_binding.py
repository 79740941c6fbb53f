"""Automatic binding: align a capture's neutral marker cloud to a face surface with a similarity
(robust ICP on exact closest surface points, started from the clouds' mirror planes), then project
each aligned marker. The marker set of a capture rarely matches a character's features, so an auto
binding is a starting point for a layout, not a final one."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..capture.rigid import to_matrix
from ..errors import OptionError
from ..model.capture import Capture
from ..model.mesh import Binding, FaceMesh
from .binding import bound_at, check_retarget, neutral_markers, unit_scale_for
from .closest import SurfaceLocator
from .surface_points import locator_for, project_to_surface
from .symmetry import (
    mirror_plane,
    rotation_about_x,
    rotation_about_y,
    rotation_between,
    rotation_from_vector,
)
from .topology import boundary_edges

__all__ = ["SurfaceAlignment", "align_to_surface", "bind_auto"]


@dataclass(frozen=True)
class SurfaceAlignment:
    """Result of :func:`align_to_surface`: ``aligned = s * R @ cloud + t``.

    Attributes
    ----------
    rotation : ndarray, shape (3, 3)
    scale : float
    translation : ndarray, shape (3,)
    distances : ndarray, shape (M,)
        Distance from each aligned point to the surface.
    on_boundary : ndarray, shape (M,), bool
        True where the closest surface point lies on a mesh boundary (outer border or a hole's
        rim): such points were given zero weight in the last iteration.
    iterations : int
        ICP iterations of the best start.
    start_angle : float
        Start rotation (degrees; about X in symmetric mode, about Y otherwise) that won.
    symmetric : bool
        Whether the mirror planes of cloud and mesh were kept together.
    """

    rotation: np.ndarray
    scale: float
    translation: np.ndarray
    distances: np.ndarray
    on_boundary: np.ndarray
    iterations: int
    start_angle: float
    symmetric: bool = False

    @property
    def matrix(self) -> np.ndarray:
        """(4, 4) similarity matrix (column vectors)."""
        return to_matrix(self.rotation, self.scale, self.translation)

    def apply(self, points) -> np.ndarray:
        """(M, 3) ``s R p + t`` for points (M, 3)."""
        return self.scale * np.asarray(points, dtype=np.float64) @ self.rotation.T + self.translation


def _boundary_flags(n_points: int, tri_vertices: np.ndarray, bary: np.ndarray, bkeys: np.ndarray,
                    bverts: np.ndarray) -> np.ndarray:
    """True where a closest point (triangle vertices + barycentrics) lies on a boundary edge/vertex."""
    n = np.int64(n_points)
    zero = bary <= 1e-9
    flag = np.zeros(bary.shape[0], dtype=bool)
    for k in range(3):
        a = tri_vertices[:, (k + 1) % 3]
        b = tri_vertices[:, (k + 2) % 3]
        key = np.minimum(a, b) * n + np.maximum(a, b)
        flag |= zero[:, k] & np.isin(key, bkeys)
    at_vertex = zero.sum(axis=1) >= 2
    if at_vertex.any():
        v = tri_vertices[np.arange(bary.shape[0]), np.argmax(bary, axis=1)]
        flag |= at_vertex & np.isin(v, bverts)
    return flag


class _SurfaceICP:
    """Robust point-to-surface similarity ICP (Gauss-Newton on the distances)."""

    def __init__(self, mesh: FaceMesh, loc: SurfaceLocator) -> None:
        self.loc = loc
        self.n_points = mesh.n_points
        p = mesh.points
        self.size = float(np.linalg.norm(np.ptp(p, axis=0)))
        be = boundary_edges(mesh)
        n = np.int64(mesh.n_points)
        self.bkeys = np.unique(np.minimum(be[:, 0], be[:, 1]) * n + np.maximum(be[:, 0], be[:, 1]))
        self.bverts = np.unique(be)
        tri = loc.triangles
        fn = np.cross(p[tri[:, 1]] - p[tri[:, 0]], p[tri[:, 2]] - p[tri[:, 0]])
        self.tri_normals = fn / np.maximum(np.linalg.norm(fn, axis=1, keepdims=True), 1e-300)

    def query(self, y):
        tri, bary, cp, d = self.loc.closest(y)
        onb = _boundary_flags(self.n_points, self.loc.triangles[tri], bary, self.bkeys, self.bverts)
        return tri, cp, d, onb

    def weights(self, d, onb):
        inner = d[~onb] if (~onb).sum() >= 3 else d
        sigma = max(2.5 * float(np.median(inner)), 2e-3 * self.size)
        w = 1.0 / (1.0 + (d / sigma) ** 2)
        if (~onb).sum() >= 7:
            w = np.where(onb, 0.0, w)
        return w

    def cost(self, d):
        tau = 0.05 * self.size
        return float(np.mean(np.minimum(d, tau) ** 2))

    def run(self, x, rot, s, t, *, free, plane_x=None, max_iterations=100, tolerance=1e-6):
        """Refine ``y = s rot x + t``; ``free`` masks (wx, wy, wz, log-scale, tx, ty, tz)."""
        free = np.asarray(free, dtype=bool)
        it = 0
        for it in range(1, max_iterations + 1):
            y = s * x @ rot.T + t
            tri, cp, d, onb = self.query(y)
            w = self.weights(d, onb)
            diff = y - cp
            nrm = np.where(
                (d > 1e-12 * self.size)[:, None], diff / np.maximum(d, 1e-300)[:, None], self.tri_normals[tri]
            )
            c = np.average(y, axis=0, weights=w) if w.sum() > 0 else y.mean(axis=0)
            if plane_x is not None:
                c[0] = plane_x  # rotations about X and scaling about c keep the plane x = plane_x
            q = y - c
            jac = np.concatenate([np.cross(q, nrm), np.einsum("ij,ij->i", nrm, q)[:, None], nrm], axis=1)[:, free]
            r = np.einsum("ij,ij->i", nrm, diff)
            jw = jac * w[:, None]
            h = jac.T @ jw
            g = jw.T @ r
            h += 1e-9 * np.trace(h) * np.eye(h.shape[0]) / h.shape[0]
            try:
                step = np.linalg.solve(h, -g)
            except np.linalg.LinAlgError:
                break
            full = np.zeros(7)
            full[free] = step
            dr = rotation_from_vector(full[:3])
            ds = float(np.exp(np.clip(full[3], -0.5, 0.5)))
            rot = dr @ rot
            t = c + ds * dr @ (t - c) + full[4:]
            s = s * ds
            moved = float(np.abs(s * x @ rot.T + t - y).max())
            if moved < tolerance * self.size:
                break
        y = s * x @ rot.T + t
        _, _, d, onb = self.query(y)
        return rot, s, t, d, onb, it


def align_to_surface(
    mesh: FaceMesh,
    cloud,
    *,
    locator: SurfaceLocator | None = None,
    angles=(-15.0, 0.0, 15.0),
    symmetric: bool | None = None,
    max_iterations: int = 50,
    tolerance: float = 1e-5,
) -> SurfaceAlignment:
    """Similarity-align a point cloud to a mesh surface (robust point-to-surface ICP).

    Both are taken to be faces with +Y up looking toward +Z (the performer's left toward +X).

    1. Symmetry. The cloud's left-right mirror plane is estimated (:func:`mirror_plane`) and
       the cloud rotated so that plane faces +X. If the mesh is mirror-symmetric about its mid
       plane ``x = (min x + max x) / 2`` and the cloud about its own plane (median mismatch under
       2% of the mesh size and 5% of the cloud size), the fit keeps the two planes together: only pitch (about X), scale
       and y/z translation are fitted. This removes the sliding yaw/x-shift valley a curved face
       leaves to plain ICP. Otherwise all 7 parameters are fitted.
    2. Starts: for each of ``angles`` (pitch about X in symmetric mode, yaw about Y otherwise,
       degrees), the cloud is scaled so its x/y extent matches the mesh's, centred in x/y, and its
       front-most point put at the mesh's front-most z.
    3. ICP: Gauss-Newton on the point-to-surface distances (exact closest points from
       :class:`SurfaceLocator`), robust weights ``w = 1 / (1 + (d / sigma)^2)`` with ``sigma`` =
       2.5 x the median distance (at least 0.2% of the mesh size), and weight 0 for points whose
       closest point lies on the mesh boundary (outer border, eye or mouth rims), which would
       otherwise drag the cloud toward the rims. The start with the smallest final cost
       ``mean(min(d, 5% of mesh size)^2)`` wins.

    Parameters
    ----------
    mesh : FaceMesh
    cloud : ndarray, shape (M, 3)
        Points (M >= 3) in units roughly proportional to the mesh's.
    locator : SurfaceLocator, optional
    angles : sequence of float
        Start rotations (degrees), see above.
    symmetric : bool, optional
        Force (True) or forbid (False) the symmetric mode; default: decided from the data.
    max_iterations : int
    tolerance : float
        Stop when the aligned points move less than ``tolerance`` x mesh size in an iteration.

    Returns
    -------
    SurfaceAlignment
    """
    x = np.asarray(cloud, dtype=np.float64)
    if x.ndim != 2 or x.shape[1] != 3 or x.shape[0] < 3 or not np.isfinite(x).all():
        raise OptionError(f"align_to_surface: cloud must be (M >= 3, 3) finite points; got {x.shape}")
    loc = locator_for(mesh, locator)
    icp = _SurfaceICP(mesh, loc)
    p = mesh.points
    mid_x = 0.5 * (p[:, 0].min() + p[:, 0].max())
    # mirror planes
    n_c, c_c, res_c = mirror_plane(x)
    r_sym = rotation_between(n_c, np.array([1.0, 0.0, 0.0]))
    cloud_size = float(np.linalg.norm(np.ptp(x, axis=0)))
    if symmetric is None:
        sample = p[:: max(1, p.shape[0] // 2000)]
        mirrored = sample * np.array([-1.0, 1.0, 1.0]) + np.array([2.0 * mid_x, 0.0, 0.0])
        mesh_res = float(np.median(loc.closest(mirrored)[3]))
        symmetric = mesh_res < 0.02 * icp.size and res_c < 0.05 * cloud_size
    if symmetric:
        x0 = (x - c_c) @ r_sym.T  # mirror plane -> x = 0
        free = (True, False, False, True, False, True, True)
        make_start = rotation_about_x
    else:
        x0 = x - x.mean(axis=0)
        r_sym = np.eye(3)
        c_c = x.mean(axis=0)
        free = (True,) * 7
        make_start = rotation_about_y
    ext_mesh = np.ptp(p[:, :2], axis=0)
    c_mesh = 0.5 * (p[:, :2].min(axis=0) + p[:, :2].max(axis=0))
    best = None
    for ang in angles:
        r0 = make_start(float(ang))
        xr = x0 @ r0.T
        s0 = float(np.sqrt(np.prod(ext_mesh) / max(np.prod(np.ptp(xr[:, :2], axis=0)), 1e-300)))
        t0 = np.empty(3)
        t0[:2] = c_mesh - s0 * 0.5 * (xr[:, :2].min(axis=0) + xr[:, :2].max(axis=0))
        t0[2] = p[:, 2].max() - s0 * xr[:, 2].max()
        if symmetric:
            t0[0] = mid_x
        rot, s, t, d, onb, it = icp.run(
            x0, r0, s0, t0, free=free, plane_x=mid_x if symmetric else None,
            max_iterations=max_iterations, tolerance=tolerance,
        )
        cost = icp.cost(d)
        if best is None or cost < best[0]:
            best = (cost, rot, s, t, d, onb, it, float(ang))
    _, rot, s, t, d, onb, it, ang = best
    # fold the pre-alignment into the result: y = s rot (r_sym (x - c_c)) + t
    rot_total = rot @ r_sym
    t_total = t - s * rot_total @ c_c
    return SurfaceAlignment(rot_total, float(s), t_total, d, onb, it, ang, bool(symmetric))


def bind_auto(
    mesh: FaceMesh,
    capture: Capture,
    *,
    retarget: str = "displacement",
    locator: SurfaceLocator | None = None,
    angles=(-15.0, 0.0, 15.0),
    symmetric: bool | None = None,
    max_iterations: int = 50,
) -> Binding:
    """Bind a capture's markers to a mesh automatically (similarity ICP, then projection).

    Parameters
    ----------
    mesh : FaceMesh
        A face looking toward +Z with +Y up.
    capture : Capture
        Markers on a face with the same axes; its neutral frame is aligned.
    retarget : {"displacement", "similarity"}
    locator : SurfaceLocator, optional
    angles : sequence of float
        Start rotations tried (degrees), see :func:`align_to_surface`.
    symmetric : bool, optional
        Symmetric mode of :func:`align_to_surface` (default: decided from the data).
    max_iterations : int

    Returns
    -------
    Binding
        ``method="auto"``; ``capture_to_mesh`` = the fitted similarity (with the unit conversion);
        ``residuals`` = distance (mesh units) from each aligned marker to its bound point.

    Raises
    ------
    MarkerError
        A marker has no valid neutral position; units missing where needed.
    OptionError
        Unknown ``retarget``.
    """
    check_retarget(retarget)
    neutral = neutral_markers(capture)
    unit_scale = unit_scale_for(capture, mesh, retarget)
    loc = locator_for(mesh, locator)
    al = align_to_surface(
        mesh, neutral * unit_scale, locator=loc, angles=angles, symmetric=symmetric, max_iterations=max_iterations
    )
    sp = project_to_surface(mesh, al.apply(neutral * unit_scale), locator=loc)
    return bound_at(capture, sp, retarget=retarget,
                    capture_to_mesh=to_matrix(al.rotation, al.scale * unit_scale, al.translation),
                    unit_scale=unit_scale, method="auto")
