"""The prism elements of the tissue model (seed 001 §5.1, steps 2-4): their signed volumes and
validity, and the offset field that places the fascia and bone nodes below the skin without
inverting a prism."""
from __future__ import annotations

import logging

import numpy as np
import scipy.sparse as sp

from ..errors import MeshError, list_names
from .surface import mesh_where, triangle_normals

log = logging.getLogger("usdface")

__all__ = ["prism_volumes", "prisms_valid", "offset_field"]


def prism_volumes(x: np.ndarray, prisms: np.ndarray) -> np.ndarray:
    """Signed volume of triangular prisms, split into three tetrahedra.

    Parameters
    ----------
    x : ndarray (n, 3)
        Node positions.
    prisms : ndarray (P, 6) int
        Top triangle ``a b c`` (outward, counter-clockwise seen from outside) and the nodes
        ``a' b' c'`` below them.

    Returns
    -------
    ndarray (P,)
        ``V = V(a,b,c,a') + V(b,c,a',b') + V(c,a',b',c')`` with the sign chosen so that a
        prism whose bottom lies below its outward top has positive volume.
    """
    p = [x[prisms[:, k]] for k in range(6)]
    return -(_tet(p[0], p[1], p[2], p[3]) + _tet(p[1], p[2], p[3], p[4]) + _tet(p[2], p[3], p[4], p[5]))


def _tet(a, b, c, d):
    return np.einsum("ij,ij->i", np.cross(b - a, c - a), d - a) / 6.0


def prisms_valid(x: np.ndarray, prisms: np.ndarray) -> np.ndarray:
    """(P,) bool: prism has positive volume and its bottom triangle is not flipped against its top."""
    top = triangle_normals(x, prisms[:, :3])
    bottom = triangle_normals(x, prisms[:, 3:])
    return (prism_volumes(x, prisms) > 0) & (np.einsum("ij,ij->i", top, bottom) > 0)


def _sphere_centre(points: np.ndarray) -> np.ndarray:
    """Least-squares sphere through the points (the skull's rough centre for a face)."""
    a = np.c_[2.0 * points, np.ones(len(points))]
    sol = np.linalg.lstsq(a, (points ** 2).sum(axis=1), rcond=None)[0]
    return sol[:3]


def _keep_in_cone(d: np.ndarray, nrm: np.ndarray, min_cos: float) -> np.ndarray:
    """Unit directions turned toward ``nrm`` until their cosine with it is at least ``min_cos``."""
    d = d / np.maximum(np.linalg.norm(d, axis=1, keepdims=True), 1e-300)
    c = np.einsum("ij,ij->i", d, nrm)
    low = c < min_cos
    if low.any():
        tang = d[low] - c[low, None] * nrm[low]
        tn = np.linalg.norm(tang, axis=1, keepdims=True)
        tang = np.divide(tang, tn, out=np.zeros_like(tang), where=tn > 1e-12)
        s = np.sqrt(1.0 - min_cos ** 2)
        d[low] = min_cos * nrm[low] + s * tang
    return d


def offset_field(mesh, tris, edges, normals, used, prisms, *, depths, min_fraction, max_inverted):
    """Directions and per-vertex depth scales giving non-inverted prisms.

    Start from the vertex normal smoothed over the surface, blended half-and-half with the direction
    toward the best-fit sphere's centre (offset rays then cannot cross under the surface); where a
    prism is still inverted (lip and eyelid rims rolled into the holes), turn its vertices' directions
    toward their own normals and shrink their depth, down to ``min_fraction`` of the request.

    Parameters
    ----------
    mesh : FaceMesh
        The consistently wound face (:func:`usdface.tissue.surface.prepare_mesh`); its points are
        the epidermis nodes (N, 3), mesh units.
    tris : ndarray (T, 3) int64
        Its triangles.
    edges : ndarray (E, 2) int64
        Its triangle edges (:func:`usdface.tissue.surface.triangle_edges`).
    normals : ndarray (N, 3) float64
        Unit vertex normals (zero for unused vertices).
    used : ndarray (N,) bool
        Vertices that belong to a face.
    prisms : ndarray (2T, 6) int64
        The dermal then deep prisms (see :class:`usdface.tissue.model.TissueModel`).
    depths : (float, float)
        Fascia depth and bone depth below it, mesh units.
    min_fraction : float
        Smallest depth scale allowed, in (0, 1].
    max_inverted : float
        Fraction of the polygons whose prisms may stay inverted at that depth (folds).

    Returns
    -------
    direction : ndarray (N, 3) float64
        Unit offset directions (zero for unused vertices).
    depth : ndarray (N,) float64
        Depth scale per vertex in [min_fraction, 1].
    folded : ndarray (J,) int64
        Polygons whose prisms are still inverted (kept as they are).

    Raises
    ------
    MeshError
        More than ``max_inverted`` of the polygons stay inverted (named).
    """
    pts, nrm = mesh.points, normals
    d_f, d_b = depths
    n = len(pts)
    adj = sp.coo_matrix((np.ones(2 * len(edges)), (np.r_[edges[:, 0], edges[:, 1]], np.r_[edges[:, 1], edges[:, 0]])),
                        shape=(n, n)).tocsr()
    smooth = nrm.copy()
    for _ in range(20):
        smooth = smooth + adj @ smooth
        smooth /= np.maximum(np.linalg.norm(smooth, axis=1, keepdims=True), 1e-300)
    centre = _sphere_centre(pts[used])
    radial = pts - centre
    radial /= np.maximum(np.linalg.norm(radial, axis=1, keepdims=True), 1e-300)
    direction = _keep_in_cone(smooth + radial, nrm, 0.5)
    direction[~used] = 0.0
    depth = np.ones(n)
    t = len(tris)
    deg = np.asarray(adj.sum(axis=1)).ravel()
    for it in range(200):
        rest = np.concatenate([pts, pts - (d_f * depth)[:, None] * direction,
                               pts - ((d_f + d_b) * depth)[:, None] * direction])
        bad = np.flatnonzero(~prisms_valid(rest, prisms))
        if bad.size == 0:
            return direction, depth, np.zeros(0, dtype=np.int64)
        verts = np.unique(tris[bad % t].ravel())
        if depth[verts].min() <= min_fraction + 1e-12:
            faces = np.unique(mesh.triangle_faces()[bad % t])
            if faces.size > max_inverted * mesh.n_faces:
                raise MeshError(
                    f"mesh {mesh_where(mesh)}: {faces.size} face(s) give inverted tissue prisms even at "
                    f"{min_fraction:.0%} of the depth (folded or very sharply curved), e.g. faces "
                    f"{faces[:10].tolist()}; smooth the mesh there or lower fascia_depth/bone_depth")
            log.info("mesh %s: %d face(s) are folded (their tissue prisms are inverted at rest; they keep "
                     "that shape): %s", mesh_where(mesh), faces.size, list_names(faces.tolist(), 20))
            return direction, depth, faces
        # smooth the directions around the bad prisms (shear comes from diverging directions) ...
        nb = direction + (adj @ direction) / np.maximum(deg, 1)[:, None]
        nb = _keep_in_cone(nb, nrm, 0.5)
        direction[verts] = nb[verts]
        # ... and thin the tissue there, smoothly (a depth step also shears prisms)
        depth[verts] = np.maximum(depth[verts] * 0.9, min_fraction)
        depth = np.minimum(depth, 0.5 * (depth + (adj @ depth) / np.maximum(deg, 1)) + 0.5 * depth)
    raise MeshError(f"mesh {mesh_where(mesh)}: could not build non-inverted tissue prisms")
