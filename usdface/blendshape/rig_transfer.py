"""A generic rig carried onto a face without one (pure numpy/scipy).

Input: the generic rig (neutral + shapes, generic topology), the generic *registered* onto the
target face (``usdface register``: the generic's vertices moved onto the target surface, generic
topology kept: a dense correspondence), and the target mesh (any topology).

1. Shapes on the registered generic (generic topology), two ways:

   - ``displacement``: each offset rotated and scaled by the similarity that best maps the generic
     onto its registration (``s R d``): the motion keeps its direction relative to the face.
   - ``deformation`` (default; Sumner & Popovic 2004, "Deformation transfer for triangle meshes",
     here between two meshes of the same topology so the triangle correspondence is the
     identity): each triangle's deformation gradient ``S_t = V'_t V_t^-1`` (V = the two edges and
     the scaled normal, Sumner's fourth vertex) is applied to the registered triangle's edges, and
     the registered offsets D solve, in the least-squares sense over all triangles (area
     weighted), ``D_j - D_i = (S_t - I)(r_j - r_i)`` for the three edges of every triangle t, plus
     a weak pull ``mu |D_i - d_i|^2`` toward the generic's own offsets that pins the free
     translation (one sparse factorisation for all shapes). Solved in the generic's frame (the
     registration taken back by the inverse of the best similarity), the offsets then turned and
     scaled like the face. The motion follows the target's local shape (a rounder cheek turns the
     motion with its surface).

2. Registered generic -> target vertices: each target vertex takes the offset of its closest point
   on the registered generic surface (barycentric interpolation). Near the mouth the closest
   point is looked for only on the same lip (upper-lip vertices of the target on triangles that
   do not lie wholly on the generic's lower lip, and the other way round; lips are told apart by
   surface distance to the mouth loop's upper and lower rims): the lips of the sample faces touch,
   and a closest point across the slit would make the upper lip follow the jaw.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from ..errors import MeshError, OptionError
from ..model.mesh import FaceMesh
from .parameters import RIG_TRANSFER_METHODS
from .rig import BlendShapeRig

__all__ = ["TRANSFER_METHODS", "RigTransfer", "transfer_rig", "shapes_on_registration", "copy_through_topology"]

TRANSFER_METHODS = RIG_TRANSFER_METHODS
#: weight of the pull toward the displacement transfer in the deformation solve (per unit area,
#: relative to the gradient term)
ANCHOR_WEIGHT = 1e-3


@dataclass
class RigTransfer:
    """A transferred rig and how the correspondence went."""

    rig: BlendShapeRig
    registered_deltas: np.ndarray  # (K, N_generic, 3) offsets on the registered generic
    distance: np.ndarray           # (N_target,) target vertex to the registered generic surface
    similarity_scale: float
    info: dict


def _similarity(src, dst):
    from ..scan.register import similarity_fit

    return similarity_fit(src, dst)


def _frames(points, tris):
    """(T, 3, 3) Sumner frames: columns e1, e2, n / sqrt(|n|)."""
    p = np.asarray(points, dtype=np.float64)
    v0, v1, v2 = p[tris[:, 0]], p[tris[:, 1]], p[tris[:, 2]]
    e1, e2 = v1 - v0, v2 - v0
    n = np.cross(e1, e2)
    nn = np.linalg.norm(n, axis=1, keepdims=True)
    n = n / np.sqrt(np.maximum(nn, 1e-300))
    return np.stack([e1, e2, n], axis=2)


def shapes_on_registration(generic: BlendShapeRig, registered_points, *, method: str = "deformation",
                           anchor_weight: float = ANCHOR_WEIGHT) -> tuple[np.ndarray, float]:
    """Offsets of every generic shape on the registered generic (same topology).

    Parameters
    ----------
    generic : BlendShapeRig
    registered_points : ndarray (N, 3)
        The generic's vertices registered onto the target.
    method : {"deformation", "displacement"}

    Returns
    -------
    deltas : ndarray (K, N, 3)
    scale : float
        The similarity scale generic -> registration.
    """
    if method not in TRANSFER_METHODS:
        raise OptionError(f"--method {method}: expected one of {', '.join(TRANSFER_METHODS)}")
    r = np.asarray(registered_points, dtype=np.float64)
    g = generic.neutral
    if r.shape != g.shape:
        raise MeshError(f"registered generic has {r.shape[0]} points, the generic rig {g.shape[0]}")
    s, rot, t = _similarity(g, r)
    disp = s * np.einsum("ij,knj->kni", rot, generic.deltas)
    if method == "displacement":
        return disp, s
    # deformation gradients act in the generic's frame: solve there, on the registration taken
    # back by the inverse similarity, then turn and scale the offsets like the face
    r = (r - t) @ rot / s
    tris = generic.mesh.triangles()
    n = g.shape[0]
    src = _frames(g, tris)
    src_inv = np.linalg.inv(src)
    area = 0.5 * np.linalg.norm(np.cross(r[tris[:, 1]] - r[tris[:, 0]], r[tris[:, 2]] - r[tris[:, 0]]), axis=1)
    # edge rows: for each triangle its 3 edges (i -> j)
    ei = np.concatenate([tris[:, 0], tris[:, 1], tris[:, 2]])
    ej = np.concatenate([tris[:, 1], tris[:, 2], tris[:, 0]])
    t_of = np.tile(np.arange(tris.shape[0]), 3)
    w = np.sqrt(np.tile(area, 3))
    n_rows = ei.size
    rows = np.repeat(np.arange(n_rows), 2)
    cols = np.stack([ej, ei], axis=1).ravel()
    vals = np.stack([w, -w], axis=1).ravel()
    grad = sp.csr_matrix((vals, (rows, cols)), shape=(n_rows, n))
    # vertex areas for the anchor term
    varea = np.bincount(tris.ravel(), weights=np.repeat(area / 3.0, 3), minlength=n)
    anchor = sp.diags(np.sqrt(anchor_weight * varea))
    lhs = (grad.T @ grad + anchor.T @ anchor).tocsc()
    from scipy.sparse.linalg import factorized

    solve = factorized(lhs)
    rest_edges = r[ej] - r[ei]  # (E, 3)
    out = np.empty_like(disp)
    for k in range(generic.n_shapes):
        deformed = _frames(g + generic.deltas[k], tris)
        grads = np.einsum("tij,tjk->tik", deformed, src_inv)  # S_t (T, 3, 3)
        target_edges = np.einsum("eij,ej->ei", grads[t_of], rest_edges) - rest_edges  # (S_t - I) r_e
        rhs = grad.T @ (w[:, None] * target_edges) + (anchor.T @ anchor) @ generic.deltas[k]
        out[k] = np.stack([solve(rhs[:, c]) for c in range(3)], axis=1)
        if not np.abs(generic.deltas[k]).any():
            out[k] = 0.0
    return s * np.einsum("ij,knj->kni", rot, out), float(s)


def _lip_masks(mesh: FaceMesh, regions, *, radius_cm: float = 1.5) -> tuple[np.ndarray, np.ndarray]:
    """(upper, lower) lip masks: vertices within ``radius_cm`` (along the surface) of the mouth loop,
    labelled by the rim (corner to corner, above / below) they are nearer to *along the surface*.

    Surface distance, not height: the lips meet only at the corners, so every vertex of the lower
    lip is nearer its own rim even where the mouth line curves above it. Corner vertices are on
    both rims and in both masks. Empty masks without a mouth region.
    """
    from scipy.sparse.csgraph import dijkstra

    from ..units import scale_between

    n = mesh.n_points
    mouth = [r for r in regions if r.role == "mouth" and r.loop is not None]
    if not mouth:
        return np.zeros(n, dtype=bool), np.zeros(n, dtype=bool)
    upper, lower = _oriented_rims(mesh.points, mouth[0].loop)
    tris = mesh.triangles()
    e = np.concatenate([tris[:, [0, 1]], tris[:, [1, 2]], tris[:, [2, 0]]])
    w = np.linalg.norm(mesh.points[e[:, 0]] - mesh.points[e[:, 1]], axis=1)
    graph = sp.coo_matrix((w, (e[:, 0], e[:, 1])), shape=(n, n)).tocsr()
    graph = graph.maximum(graph.T)
    limit = radius_cm * (scale_between("cm", mesh.units) if mesh.units else 1.0)
    d_up = dijkstra(graph, directed=False, indices=upper, min_only=True, limit=limit)
    d_low = dijkstra(graph, directed=False, indices=lower, min_only=True, limit=limit)
    near = np.isfinite(d_up) | np.isfinite(d_low)
    return near & (d_up <= d_low), near & (d_low <= d_up)


def _sided_closest(target: FaceMesh, target_regions, generic: FaceMesh, generic_regions, registered_points):
    """Closest points on the registered generic, keeping each lip on its own side."""
    from ..mesh.closest import SurfaceLocator

    tris = generic.triangles()
    reg = np.asarray(registered_points, dtype=np.float64)
    q = target.points
    tri_all, bary_all, _, dist_all = SurfaceLocator(reg, tris).closest(q)
    g_up, g_low = _lip_masks(generic.with_points(reg), generic_regions)
    t_up, t_low = _lip_masks(target, target_regions)
    for t_mask, forbid in ((t_up & ~t_low, g_low & ~g_up), (t_low & ~t_up, g_up & ~g_low)):
        if not t_mask.any() or not forbid.any():
            continue
        keep = np.flatnonzero(~forbid[tris].all(axis=1))  # no triangle lying wholly on the other lip
        loc = SurfaceLocator(reg, tris[keep])
        idx = np.flatnonzero(t_mask)
        tri, bary, _, dist = loc.closest(q[idx])
        tri_all[idx], bary_all[idx], dist_all[idx] = keep[tri], bary, dist
    return tris[tri_all], bary_all, dist_all


def _oriented_rims(points, loop):
    """(upper, lower) rims of a hole loop, each ordered from its smallest-x corner to its largest."""
    from ..evaluation.quality import loop_rims

    out = []
    for rim in loop_rims(points, loop):
        out.append(rim if points[rim[0], 0] <= points[rim[-1], 0] else rim[::-1])
    return out


def transfer_rig(generic: BlendShapeRig, generic_regions, registered_points, target: FaceMesh, target_regions, *,
                 method: str = "displacement") -> RigTransfer:
    """The generic rig on the target mesh (see the module docstring).

    Parameters
    ----------
    generic : BlendShapeRig
    generic_regions : list of Region
        The generic's hole regions (mouth, eyes).
    registered_points : ndarray (N_generic, 3)
        From ``usdface register`` (or :class:`usdface.scan.register.GenericRegistration`).
    target : FaceMesh
    target_regions : list of Region
        The target's hole regions (``find_hole_regions``).
    method : {"deformation", "displacement"}

    Returns
    -------
    RigTransfer
    """
    if generic.units and target.units and generic.units != target.units:
        raise MeshError(f"generic rig in {generic.units}, target mesh {target.source or target.name} in "
                        f"{target.units}: convert one first")
    reg_deltas, scale = shapes_on_registration(generic, registered_points, method=method)
    tri_v, bary, dist = _sided_closest(target, target_regions, generic.mesh, generic_regions, registered_points)
    deltas = np.einsum("nj,knjd->knd", bary, reg_deltas[:, tri_v])
    rig = BlendShapeRig(generic.names, deltas, target, source=f"{generic.source} transferred ({method})",
                        notes=generic.notes + (f"transferred from {generic.source} by {method} transfer",))
    info = {"method": method, "similarityScale": scale, "distanceMedian": float(np.median(dist)),
            "distanceMax": float(dist.max())}
    return RigTransfer(rig, reg_deltas, dist, scale, info)


def copy_through_topology(generic: BlendShapeRig, target: FaceMesh) -> BlendShapeRig:
    """The generic's offsets copied vertex for vertex onto a mesh of the same topology (the
    reference a transfer is compared with when the target shares the generic's topology)."""
    from .rig import check_same_topology

    check_same_topology(generic.mesh, target, what=f"target {target.source or target.name}")
    return BlendShapeRig(generic.names, generic.deltas, target, source=f"{generic.source} copied by vertex index")
