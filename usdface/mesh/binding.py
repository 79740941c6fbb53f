"""Bind capture markers to points on a face mesh surface.

Two ways:

- :func:`bind_layout`: from a :class:`~usdface.mesh.layout.Layout` (a vertex or a point per
  marker, made for this mesh); the points are projected onto the surface, and the capture-to-mesh
  similarity is fitted from the capture's neutral markers to the bound points (Umeyama).
- :func:`bind_auto`: align the capture's neutral marker cloud to the surface with a similarity
  (robust ICP on exact closest surface points), then project each aligned marker. The marker set
  of a capture rarely matches a character's features (the AnimFace mouth-corner markers sit about
  7.3 cm apart, the sample meshes' lip corners about 5 cm), so an auto binding is a starting
  point for a layout, not a final one.

Each marker is bound to a polygon, the triangle of :meth:`FaceMesh.triangles` holding the point
(its 3 vertices and barycentric weights) and the nearest vertex of that polygon (the nearest
vertex of the surface patch, never one across a hole such as the mouth slit).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..model.capture import Capture
from ..capture.rigid import fit_rigid, to_matrix
from ..errors import ComputeError, MarkerError, OptionError, list_names
from ..units import scale_between
from .closest import SurfaceLocator
from .layout import Layout
from ..model.mesh import Binding, FaceMesh
from .topology import boundary_edges

__all__ = [
    "RETARGET_MODES",
    "SurfacePoints",
    "SurfaceAlignment",
    "project_to_surface",
    "align_to_surface",
    "bind_layout",
    "bind_auto",
    "alignment_residuals",
    "mirror_plane",
]

#: values of the ``retarget`` option (see :class:`~usdface.model.mesh.Binding`)
RETARGET_MODES = ("displacement", "similarity")


@dataclass(frozen=True)
class SurfacePoints:
    """Points projected onto a mesh surface.

    Attributes
    ----------
    face_indices : ndarray, shape (M,), int64
        Polygon holding each projected point.
    triangle_vertices : ndarray, shape (M, 3), int64
        Vertices of the triangle (of :meth:`FaceMesh.triangles`) holding it.
    barycentrics : ndarray, shape (M, 3), float64
        Barycentric weights in that triangle.
    nearest_vertices : ndarray, shape (M,), int64
        Vertex of the holding polygon nearest to the projected point.
    points : ndarray, shape (M, 3), float64
        The projected points (mesh units).
    distances : ndarray, shape (M,), float64
        Distance from each input point to its projection (mesh units).
    """

    face_indices: np.ndarray
    triangle_vertices: np.ndarray
    barycentrics: np.ndarray
    nearest_vertices: np.ndarray
    points: np.ndarray
    distances: np.ndarray


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


def _locator_for(mesh: FaceMesh, locator: SurfaceLocator | None) -> SurfaceLocator:
    if locator is None:
        return SurfaceLocator(mesh.points, mesh.triangles())
    if locator.triangles.shape != mesh.triangles().shape or locator.points.shape != mesh.points.shape:
        raise OptionError("locator was built for another mesh (triangle count differs)")
    return locator


def project_to_surface(mesh: FaceMesh, points, *, locator: SurfaceLocator | None = None) -> SurfacePoints:
    """Project points onto the closest point of the mesh surface.

    Parameters
    ----------
    mesh : FaceMesh
    points : ndarray, shape (M, 3)
        Points in the mesh's space and units.
    locator : SurfaceLocator, optional
        Reuse a locator built on ``mesh.points`` and ``mesh.triangles()``.

    Returns
    -------
    SurfacePoints
    """
    loc = _locator_for(mesh, locator)
    tri, bary, cp, dist = loc.closest(np.asarray(points, dtype=np.float64).reshape(-1, 3))
    tv = loc.triangles[tri]
    faces = mesh.triangle_faces()[tri]
    # nearest vertex among the holding polygon's vertices
    counts, starts, idx = mesh.face_vertex_counts, mesh.face_starts, mesh.face_vertex_indices
    width = int(counts[faces].max()) if faces.size else 3
    k = np.arange(width)
    cols = starts[faces][:, None] + np.minimum(k[None, :], counts[faces][:, None] - 1)
    cand = idx[cols]  # (M, width), short polygons repeat their last vertex
    d2 = np.sum((mesh.points[cand] - cp[:, None, :]) ** 2, axis=2)
    nearest = cand[np.arange(cand.shape[0]), np.argmin(d2, axis=1)]
    return SurfacePoints(faces, tv, bary, nearest, cp, dist)


# -- checks -------------------------------------------------------------------------------------
def _check_retarget(retarget: str) -> None:
    if retarget not in RETARGET_MODES:
        raise OptionError(f"retarget: {retarget!r} is not one of {', '.join(RETARGET_MODES)}")


def _capture_where(capture: Capture) -> str:
    return f" {capture.source}" if capture.source else ""


def _neutral(capture: Capture) -> np.ndarray:
    neutral = capture.neutral
    bad = ~np.isfinite(neutral).all(axis=1)
    if bad.any():
        names = [n for n, b in zip(capture.names, bad) if b]
        raise MarkerError(
            f"capture{_capture_where(capture)}: {capture.describe_neutral()} {'has' if capture.neutral_frames[1] - capture.neutral_frames[0] == 1 else 'have'} "
            f"no valid position for marker(s) {list_names(names)}; choose other neutral frames or fill the gaps first"
        )
    return neutral


def _unit_scale(capture: Capture, mesh: FaceMesh, retarget: str) -> float:
    """Capture units -> mesh units (1.0 when both unknown, or unknown and not needed)."""
    if capture.units is not None and mesh.units is not None:
        return scale_between(capture.units, mesh.units)
    if retarget == "displacement" and (capture.units is None) != (mesh.units is None):
        missing = f"capture{_capture_where(capture)}" if capture.units is None else f"mesh {mesh.source or mesh.name}"
        raise MarkerError(
            f"{missing} has no units: retarget='displacement' moves the mesh by the capture's displacements "
            f"converted to mesh units, so both units are needed (capture: {capture.units}, mesh: {mesh.units}); "
            "give the units or use retarget='similarity'"
        )
    return 1.0


def _check_names(layout: Layout, capture: Capture) -> None:
    cap = set(capture.names)
    lay = set(layout.names)
    extra = [n for n in layout.names if n not in cap]
    missing = [n for n in capture.names if n not in lay]
    lw = f" {layout.source}" if layout.source else ""
    if extra:
        raise MarkerError(
            f"layout{lw} names marker(s) the capture{_capture_where(capture)} lacks: {list_names(extra)}; "
            f"capture has {capture.n_markers} markers: {list_names(capture.names)}"
        )
    if missing:
        raise MarkerError(
            f"layout{lw} has no entry for capture marker(s) {list_names(missing)}; "
            f"layout has {layout.n_markers} markers: {list_names(layout.names)}"
        )


# -- layout binding -------------------------------------------------------------------------------
def bind_layout(
    mesh: FaceMesh,
    layout: Layout,
    capture: Capture,
    *,
    retarget: str = "displacement",
    locator: SurfaceLocator | None = None,
) -> Binding:
    """Bind a capture's markers to a mesh through a marker layout.

    Parameters
    ----------
    mesh : FaceMesh
    layout : Layout
        One entry per capture marker (same names; order may differ).
    capture : Capture
        Its neutral frame gives the capture side of the capture-to-mesh similarity.
    retarget : {"displacement", "similarity"}
        Recorded on the binding (how capture displacements become mesh displacements).
    locator : SurfaceLocator, optional
        Reuse a locator built on this mesh.

    Returns
    -------
    Binding
        In the capture's marker order, ``method="layout"``. ``residuals`` = distance (mesh units)
        from each layout position to its bound surface point (0 for vertices and points on the
        surface). ``capture_to_mesh`` = similarity (Umeyama) fitted from the neutral markers (capture
        units) to the bound points, setting aside markers more than 25% of the face's extent off
        (:func:`usdface.mesh.judgement.robust_similarity`); :func:`alignment_residuals` gives how
        well it fits.

    Raises
    ------
    MarkerError
        Layout and capture marker sets differ; a marker has no valid neutral position; units
        missing where needed.
    MeshError
        A vertex entry is out of range.
    OptionError
        Unknown ``retarget``.
    """
    _check_retarget(retarget)
    _check_names(layout, capture)
    neutral = _neutral(capture)
    unit_scale = _unit_scale(capture, mesh, retarget)
    target = layout.positions(mesh, capture.names)
    sp = project_to_surface(mesh, target, locator=locator)
    # robust: a marker far from its layout point (judged by usdface.mesh.judgement) is set aside so
    # that it does not drag the placement of the others
    from .judgement import FIT_MARKER_FRACTION, extent, robust_similarity

    try:
        rot, s, t, _, _ = robust_similarity(neutral * unit_scale, sp.points,
                                            limit=FIT_MARKER_FRACTION * extent(sp.points))
    except ComputeError as e:
        raise ComputeError(f"layout binding: {e}") from None
    return Binding(
        names=capture.names,
        face_indices=sp.face_indices,
        triangle_vertices=sp.triangle_vertices,
        barycentrics=sp.barycentrics,
        nearest_vertices=sp.nearest_vertices,
        residuals=sp.distances,
        retarget=retarget,
        capture_to_mesh=to_matrix(rot, s * unit_scale, t),
        unit_scale=unit_scale,
        method="layout",
    )


def alignment_residuals(binding: Binding, capture: Capture, mesh: FaceMesh) -> np.ndarray:
    """Distance from each neutral marker mapped by ``binding.capture_to_mesh`` to its bound point.

    Parameters
    ----------
    binding : Binding
    capture : Capture
        With the binding's markers (any order).
    mesh : FaceMesh
        The bound mesh (its current points are used).

    Returns
    -------
    ndarray, shape (M,), float64
        Mesh units, in the binding's marker order.
    """
    idx = [capture.index(n) for n in binding.names]
    src = capture.neutral[idx]
    m = binding.capture_to_mesh
    mapped = src @ m[:3, :3].T + m[:3, 3]
    return np.linalg.norm(mapped - binding.surface_points(mesh.points), axis=1)


# -- automatic binding ----------------------------------------------------------------------------
def _rotation_x(deg: float) -> np.ndarray:
    a = np.radians(deg)
    c, s = np.cos(a), np.sin(a)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def _rotation_y(deg: float) -> np.ndarray:
    a = np.radians(deg)
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def _rodrigues(w: np.ndarray) -> np.ndarray:
    th = float(np.linalg.norm(w))
    if th < 1e-15:
        return np.eye(3)
    k = w / th
    kx = np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])
    return np.eye(3) + np.sin(th) * kx + (1.0 - np.cos(th)) * kx @ kx


def _rotation_between(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Smallest rotation taking unit vector a to unit vector b."""
    v = np.cross(a, b)
    c = float(np.dot(a, b))
    if np.linalg.norm(v) < 1e-12:
        return np.eye(3) if c > 0 else _rodrigues(np.pi * _any_perpendicular(a))
    return _rodrigues(v / np.linalg.norm(v) * np.arctan2(np.linalg.norm(v), c))


def _any_perpendicular(a: np.ndarray) -> np.ndarray:
    v = np.cross(a, [1.0, 0.0, 0.0] if abs(a[0]) < 0.9 else [0.0, 1.0, 0.0])
    return v / np.linalg.norm(v)


def mirror_plane(cloud, *, normal=(1.0, 0.0, 0.0), iterations: int = 30):
    """Estimate the left-right symmetry plane of a point cloud without correspondences.

    Reflects the cloud in the current plane, matches each reflected point to its nearest original
    point, fits the rigid motion taking the reflection onto the matches (robustly weighted), and
    reads the improved plane off the resulting improper isometry; repeats until stable.

    Parameters
    ----------
    cloud : ndarray, shape (M, 3)
    normal : sequence of 3 float
        Initial plane normal (default +X, the lateral axis of a face looking toward +Z).
    iterations : int

    Returns
    -------
    normal : ndarray, shape (3,)
        Unit normal, sign chosen along the initial ``normal``.
    point : ndarray, shape (3,)
        A point on the plane.
    residual : float
        Median distance from a reflected point to its nearest original point (cloud units): small
        (a few % of the cloud size) for a symmetric cloud.
    """
    from scipy.spatial import cKDTree

    x = np.asarray(cloud, dtype=np.float64)
    n0 = np.asarray(normal, dtype=np.float64)
    n = n0 / np.linalg.norm(n0)
    c = x.mean(axis=0)
    tree = cKDTree(x)
    res = np.inf
    for _ in range(iterations):
        refl = x - 2.0 * ((x - c) @ n)[:, None] * n
        d, j = tree.query(refl)
        sigma = max(2.5 * float(np.median(d)), 1e-9)
        w = 1.0 / (1.0 + (d / sigma) ** 2)
        rot, _, t = fit_rigid(refl, x[j], weights=w)
        # composite x -> rot (x - 2((x - c).n) n) + t = A x + b, A = rot (I - 2 n n^T)
        a = rot @ (np.eye(3) - 2.0 * np.outer(n, n))
        b = rot @ (2.0 * np.dot(c, n) * n) + t
        evals, evecs = np.linalg.eigh(0.5 * (a + a.T))
        n_new = evecs[:, 0]
        if np.dot(n_new, n0) < 0:
            n_new = -n_new
        c_new = 0.5 * (x.mean(axis=0) + (a @ x.mean(axis=0) + b))
        moved = float(np.linalg.norm(n_new - n)) + float(abs(np.dot(c_new - c, n_new)))
        n, c = n_new, c_new
        res = float(np.median(d))
        if moved < 1e-10:
            break
    refl = x - 2.0 * ((x - c) @ n)[:, None] * n
    res = float(np.median(tree.query(refl)[0]))
    return n, c, res


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
            dr = _rodrigues(full[:3])
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
    loc = _locator_for(mesh, locator)
    icp = _SurfaceICP(mesh, loc)
    p = mesh.points
    mid_x = 0.5 * (p[:, 0].min() + p[:, 0].max())
    # mirror planes
    n_c, c_c, res_c = mirror_plane(x)
    r_sym = _rotation_between(n_c, np.array([1.0, 0.0, 0.0]))
    cloud_size = float(np.linalg.norm(np.ptp(x, axis=0)))
    if symmetric is None:
        sample = p[:: max(1, p.shape[0] // 2000)]
        mirrored = sample * np.array([-1.0, 1.0, 1.0]) + np.array([2.0 * mid_x, 0.0, 0.0])
        mesh_res = float(np.median(loc.closest(mirrored)[3]))
        symmetric = mesh_res < 0.02 * icp.size and res_c < 0.05 * cloud_size
    if symmetric:
        x0 = (x - c_c) @ r_sym.T  # mirror plane -> x = 0
        free = (True, False, False, True, False, True, True)
        make_start = _rotation_x
    else:
        x0 = x - x.mean(axis=0)
        r_sym = np.eye(3)
        c_c = x.mean(axis=0)
        free = (True,) * 7
        make_start = _rotation_y
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
    _check_retarget(retarget)
    neutral = _neutral(capture)
    unit_scale = _unit_scale(capture, mesh, retarget)
    loc = _locator_for(mesh, locator)
    al = align_to_surface(
        mesh, neutral * unit_scale, locator=loc, angles=angles, symmetric=symmetric, max_iterations=max_iterations
    )
    sp = project_to_surface(mesh, al.apply(neutral * unit_scale), locator=loc)
    return Binding(
        names=capture.names,
        face_indices=sp.face_indices,
        triangle_vertices=sp.triangle_vertices,
        barycentrics=sp.barycentrics,
        nearest_vertices=sp.nearest_vertices,
        residuals=sp.distances,
        retarget=retarget,
        capture_to_mesh=to_matrix(al.rotation, al.scale * unit_scale, al.translation),
        unit_scale=unit_scale,
        method="auto",
    )
