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
     a weak pull ``mu |D_i - s R d_i|^2`` toward the displacement transfer that pins the free
     translation (one sparse Cholesky-like factorisation for all shapes). The motion follows the
     target's local shape (a rounder cheek turns the motion with its surface).

2. Registered generic -> target vertices: each target vertex takes the offset of its closest point
   on the registered generic surface (barycentric interpolation). Near the mouth the closest
   point is looked for only on the same lip (upper-lip vertices of the target on triangles that
   are not on the generic's lower lip, and the other way round): the lips of the sample faces
   touch, and a closest point across the slit would make the upper lip follow the jaw.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from ..errors import MeshError, OptionError
from ..mesh.model import FaceMesh
from .rig import BlendShapeRig

__all__ = ["TRANSFER_METHODS", "RigTransfer", "transfer_rig", "shapes_on_registration", "copy_through_topology"]

TRANSFER_METHODS = ("deformation", "displacement")
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
    s, rot, _ = _similarity(g, r)
    disp = s * np.einsum("ij,knj->kni", rot, generic.deltas)
    if method == "displacement":
        return disp, s
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
        rhs = grad.T @ (w[:, None] * target_edges) + (anchor.T @ anchor) @ disp[k]
        out[k] = np.stack([solve(rhs[:, c]) for c in range(3)], axis=1)
        if not np.abs(generic.deltas[k]).any():
            out[k] = 0.0
    return out, float(s)


def _lip_masks(mesh: FaceMesh, regions) -> tuple[np.ndarray, np.ndarray]:
    """(upper, lower) lip vertex masks of a face with a mouth hole (empty masks without one)."""
    from ..evaluation.quality import REGION_RADIUS_CM, evaluation_regions
    from ..units import scale_between

    cm = scale_between("cm", mesh.units) if mesh.units else 1.0
    ev = evaluation_regions(mesh, regions, radius=REGION_RADIUS_CM * cm)
    return ev["upperLip"], ev["lowerLip"]


def _sided_closest(target: FaceMesh, target_regions, generic: FaceMesh, generic_regions, registered_points):
    """Closest points on the registered generic, keeping each lip on its own side."""
    from ..mesh.closest import SurfaceLocator

    tris = generic.triangles()
    reg = np.asarray(registered_points, dtype=np.float64)
    q = target.points
    tri_all, bary_all, _, dist_all = SurfaceLocator(reg, tris).closest(q)
    g_up, g_low = _lip_masks(generic.with_points(reg), generic_regions)
    t_up, t_low = _lip_masks(target, target_regions)
    for t_mask, forbid in ((t_up, g_low), (t_low, g_up)):
        if not t_mask.any() or not forbid.any():
            continue
        keep = np.flatnonzero(~forbid[tris].any(axis=1))
        loc = SurfaceLocator(reg, tris[keep])
        idx = np.flatnonzero(t_mask)
        tri, bary, _, dist = loc.closest(q[idx])
        tri_all[idx], bary_all[idx], dist_all[idx] = keep[tri], bary, dist
    return tris[tri_all], bary_all, dist_all


def _rim_params(points, rim):
    """Normalised arc length (0 at the rim's first vertex, 1 at its last) of a rim polyline."""
    seg = np.linalg.norm(np.diff(points[rim], axis=0), axis=1)
    s = np.concatenate([[0.0], np.cumsum(seg)])
    return s / max(s[-1], 1e-300)


def _oriented_rims(points, loop):
    """(upper, lower) rims of a hole loop, each ordered from its smallest-x corner to its largest."""
    from ..evaluation.quality import loop_rims

    out = []
    for rim in loop_rims(points, loop):
        out.append(rim if points[rim[0], 0] <= points[rim[-1], 0] else rim[::-1])
    return out


def _matching_holes(generic_regions, target_regions, generic_points, target_points):
    """Pairs (generic loop, target loop) of the mouth and of each eye (matched by side)."""
    def holes(regions, points):
        mouth = [r for r in regions if r.role == "mouth" and r.loop is not None]
        eyes = [r for r in regions if r.role == "eye" and r.loop is not None]
        mid = 0.5 * (points[:, 0].min() + points[:, 0].max())
        out = {"mouth": mouth[0].loop} if mouth else {}
        for r in eyes:
            out["leftEye" if points[r.loop, 0].mean() > mid else "rightEye"] = r.loop
        return out

    g = holes(generic_regions, generic_points)
    t = holes(target_regions, target_points)
    return [(g[k], t[k]) for k in ("mouth", "leftEye", "rightEye") if k in g and k in t]


def refine_hole_correspondence(generic: FaceMesh, generic_regions, registered_points, target: FaceMesh,
                               target_regions, *, radius_cm: float = 1.5) -> tuple[np.ndarray, dict]:
    """Slide the registered generic so its mouth and eye loops lie on the target's, rim by rim.

    The registration leaves the holes free (no data term near them), so a lip can slide along the
    target surface by a few millimetres (0.35 cm on the stylized face's upper lip), which moves the
    shapes' strongest motion to the wrong place. Each rim (upper / lower, corner to corner) of a
    generic loop is put onto the same rim of the target loop at equal normalised arc length; the
    correction is spread over the surface by harmonic interpolation on the generic's edge graph
    (so the upper lip follows the upper rim, across the slit from the lower one), fading to zero
    ``radius_cm`` away from the loop, and the moved vertices are projected back onto the target.

    Returns
    -------
    points : ndarray (N, 3)
    info : dict ``holes`` (loops matched), ``meanShift`` (mesh units)
    """
    from scipy.sparse.linalg import spsolve
    from scipy.spatial import cKDTree

    from ..mesh.closest import SurfaceLocator
    from ..units import scale_between

    reg = np.asarray(registered_points, dtype=np.float64)
    pairs = _matching_holes(generic_regions, target_regions, reg, target.points)
    if not pairs:
        return reg, {"holes": 0, "meanShift": 0.0}
    n = reg.shape[0]
    fixed = {}
    for g_loop, t_loop in pairs:
        for g_rim, t_rim in zip(_oriented_rims(reg, g_loop), _oriented_rims(target.points, t_loop)):
            sg = _rim_params(reg, g_rim)
            st = _rim_params(target.points, t_rim)
            want = np.stack([np.interp(sg, st, target.points[t_rim, c]) for c in range(3)], axis=1)
            for v, w in zip(g_rim, want):
                fixed.setdefault(int(v), []).append(w)
    loop_v = np.array(sorted(fixed), dtype=np.int64)
    delta_loop = np.array([np.mean(fixed[v], axis=0) for v in loop_v]) - reg[loop_v]
    cm = scale_between("cm", generic.units) if generic.units else 1.0
    dist, _ = cKDTree(reg[loop_v]).query(reg)
    inner = np.flatnonzero((dist < radius_cm * cm) & ~np.isin(np.arange(n), loop_v))
    zero = np.flatnonzero(dist >= radius_cm * cm)
    tris = generic.triangles()
    e = np.concatenate([tris[:, [0, 1]], tris[:, [1, 2]], tris[:, [2, 0]]])
    adj = sp.coo_matrix((np.ones(len(e)), (e[:, 0], e[:, 1])), shape=(n, n)).tocsr()
    adj = ((adj + adj.T) > 0).astype(np.float64)
    lap = sp.diags(np.asarray(adj.sum(axis=1)).ravel()) - adj
    delta = np.zeros((n, 3))
    delta[loop_v] = delta_loop
    if inner.size:
        known = np.concatenate([loop_v, zero])
        a_ii = lap[inner][:, inner].tocsc()
        rhs = -lap[inner][:, known] @ delta[known]
        delta[inner] = np.stack([spsolve(a_ii, rhs[:, c]) for c in range(3)], axis=1)
    moved = reg + delta
    touched = np.concatenate([loop_v, inner])
    _, _, proj, _ = SurfaceLocator(target.points, target.triangles()).closest(moved[touched])
    moved[touched] = proj
    return moved, {"holes": len(pairs), "meanShift": float(np.linalg.norm(moved - reg, axis=1)[touched].mean())}


def transfer_rig(generic: BlendShapeRig, generic_regions, registered_points, target: FaceMesh, target_regions, *,
                 method: str = "displacement", refine_holes: bool = True) -> RigTransfer:
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
    hole_info = {"holes": 0, "meanShift": 0.0}
    if refine_holes:
        registered_points, hole_info = refine_hole_correspondence(generic.mesh, generic_regions, registered_points,
                                                                  target, target_regions)
    reg_deltas, scale = shapes_on_registration(generic, registered_points, method=method)
    tri_v, bary, dist = _sided_closest(target, target_regions, generic.mesh, generic_regions, registered_points)
    deltas = np.einsum("nj,knjd->knd", bary, reg_deltas[:, tri_v])
    rig = BlendShapeRig(generic.names, deltas, target, source=f"{generic.source} transferred ({method})",
                        notes=generic.notes + (f"transferred from {generic.source} by {method} transfer",))
    info = {"method": method, "similarityScale": scale, "distanceMedian": float(np.median(dist)),
            "distanceMax": float(dist.max()), "holeLoopsMatched": hole_info["holes"],
            "holeShiftMean": hole_info["meanShift"]}
    return RigTransfer(rig, reg_deltas, dist, scale, info)


def copy_through_topology(generic: BlendShapeRig, target: FaceMesh) -> BlendShapeRig:
    """The generic's offsets copied vertex for vertex onto a mesh of the same topology (the
    reference a transfer is compared with when the target shares the generic's topology)."""
    from .rig import check_same_topology

    check_same_topology(generic.mesh, target, what=f"target {target.source or target.name}")
    return BlendShapeRig(generic.names, generic.deltas, target, source=f"{generic.source} copied by vertex index")
