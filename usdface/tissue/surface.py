"""The face surface as the tissue model needs it (seed 001 §5.1, step 1): its length scale, a
consistent outward winding (:func:`prepare_mesh`), vertex normals and lumped areas, and the edges
of its triangles."""
from __future__ import annotations

import dataclasses
import logging

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components

from ..errors import MeshError, list_names
from ..model.mesh import FaceMesh
from ..units import METERS_PER_UNIT

log = logging.getLogger("usdface")

__all__ = ["length_scale_of", "mesh_where", "inconsistent_faces", "rewind_faces", "triangle_normals",
           "vertex_normals", "vertex_areas", "prepare_mesh", "triangle_edges"]


def length_scale_of(mesh: FaceMesh) -> float:
    """1 cm in the mesh's units; for unknown units, the bounding-box diagonal / 25 (a face ~25 cm)."""
    if mesh.units in METERS_PER_UNIT:
        return 0.01 / METERS_PER_UNIT[mesh.units]
    return float(np.linalg.norm(np.ptp(mesh.points, axis=0))) / 25.0


def mesh_where(mesh: FaceMesh) -> str:
    """How messages name a mesh: its source file, else its name."""
    return mesh.source or repr(mesh.name)


def _polygon_sides(mesh: FaceMesh):
    counts, starts, idx = mesh.face_vertex_counts, mesh.face_starts, mesh.face_vertex_indices
    nxt = np.arange(1, idx.size + 1)
    nxt[starts + counts - 1] = starts
    face = np.repeat(np.arange(counts.size), counts)
    return idx, idx[nxt], face


def inconsistent_faces(mesh: FaceMesh) -> tuple[np.ndarray, np.ndarray]:
    """Polygons whose winding disagrees with their neighbours.

    Two polygons sharing an edge are consistently wound when they run along it in opposite
    directions. Within each connected patch the polygons are split into two classes of equal
    winding; the smaller class is reported (it is the one to re-wind).

    Parameters
    ----------
    mesh : FaceMesh

    Returns
    -------
    flip : ndarray (K,) int64
        Polygons to re-wind (sorted).
    non_orientable : ndarray (J,) int64
        Polygons of patches that cannot be wound consistently (Möbius-like), empty normally.

    Raises
    ------
    MeshError
        The mesh has an edge shared by more than two polygons.
    """
    frm, to, face = _polygon_sides(mesh)
    n = np.int64(mesh.n_points)
    lo, hi = np.minimum(frm, to), np.maximum(frm, to)
    key = lo * n + hi
    order = np.argsort(key, kind="stable")
    ks = key[order]
    uniq, start, cnt = np.unique(ks, return_index=True, return_counts=True)
    if (cnt > 2).any():
        bad = uniq[cnt > 2][:10]
        raise MeshError(f"mesh {mesh_where(mesh)}: {int((cnt > 2).sum())} edge(s) shared by more than two faces "
                        f"(non-manifold), e.g. vertex pairs {[(int(b // n), int(b % n)) for b in bad]}")
    pair = start[cnt == 2]
    s1, s2 = order[pair], order[pair + 1]
    same_dir = frm[s1] == frm[s2]  # both run a->b: inconsistent winding
    f1, f2 = face[s1], face[s2]
    p = mesh.n_faces
    # doubled graph: node (f, s) = face f with winding state s; consistent pairs link equal states
    a = np.concatenate([f1, f1 + p])
    b = np.concatenate([np.where(same_dir, f2 + p, f2), np.where(same_dir, f2, f2 + p)])
    g = sp.coo_matrix((np.ones(a.size), (a, b)), shape=(2 * p, 2 * p))
    _, lab = connected_components(g, directed=False)
    non_orientable = np.flatnonzero(lab[:p] == lab[p:])
    # faces in the same patch: same label for state 0 -> same class
    base = np.minimum(lab[:p], lab[p:])
    cls = lab[:p] == base
    flip = []
    for comp in np.unique(base):
        members = np.flatnonzero(base == comp)
        c = cls[members]
        minority = members[c] if c.sum() < (~c).sum() else members[~c]
        flip.append(minority)
    flip = np.sort(np.concatenate(flip)) if flip else np.zeros(0, dtype=np.int64)
    flip = np.setdiff1d(flip, non_orientable)
    return flip.astype(np.int64), non_orientable.astype(np.int64)


def rewind_faces(mesh: FaceMesh, faces) -> FaceMesh:
    """``mesh`` with the given polygons' vertex order reversed (v0 kept first: v0 v3 v2 v1).

    Keeping v0 first keeps a quad's fixed v0-v2 diagonal, so the triangulation has the same edges.
    """
    faces = np.asarray(faces, dtype=np.int64)
    if faces.size == 0:
        return mesh
    idx = mesh.face_vertex_indices.copy()
    uv_idx = None if mesh.uv_indices is None else mesh.uv_indices.copy()
    for f in faces.tolist():  # per flipped polygon (few): not the engine
        s, c = int(mesh.face_starts[f]), int(mesh.face_vertex_counts[f])
        sel = np.concatenate([[s], np.arange(s + c - 1, s, -1)])
        idx[s:s + c] = mesh.face_vertex_indices[sel]
        if uv_idx is not None:
            uv_idx[s:s + c] = mesh.uv_indices[sel]
    return dataclasses.replace(mesh, face_vertex_indices=idx, uv_indices=uv_idx)


def triangle_normals(points: np.ndarray, tris: np.ndarray) -> np.ndarray:
    """(T, 3) triangle normals, unnormalised: their length is twice the triangle's area."""
    p = points
    return np.cross(p[tris[:, 1]] - p[tris[:, 0]], p[tris[:, 2]] - p[tris[:, 0]])  # length = 2 area


def vertex_normals(points: np.ndarray, triangles: np.ndarray) -> np.ndarray:
    """Angle-weighted unit vertex normals.

    Parameters
    ----------
    points : ndarray (N, 3)
    triangles : ndarray (T, 3) int

    Returns
    -------
    ndarray (N, 3) float64
        Unit normals (zero for unreferenced vertices).
    """
    p = np.asarray(points, dtype=np.float64)
    t = np.asarray(triangles)
    fn = triangle_normals(p, t)
    fn /= np.maximum(np.linalg.norm(fn, axis=1, keepdims=True), 1e-300)
    out = np.zeros_like(p)
    for c in range(3):
        e1 = p[t[:, (c + 1) % 3]] - p[t[:, c]]
        e2 = p[t[:, (c + 2) % 3]] - p[t[:, c]]
        cosang = np.einsum("ij,ij->i", e1, e2) / np.maximum(np.linalg.norm(e1, axis=1) * np.linalg.norm(e2, axis=1), 1e-300)
        ang = np.arccos(np.clip(cosang, -1.0, 1.0))
        np.add.at(out, t[:, c], fn * ang[:, None])
    nrm = np.linalg.norm(out, axis=1, keepdims=True)
    return np.divide(out, nrm, out=np.zeros_like(out), where=nrm > 0)


def vertex_areas(points: np.ndarray, triangles: np.ndarray) -> np.ndarray:
    """(N,) lumped area per vertex (a third of each adjacent triangle's area)."""
    a = 0.5 * np.linalg.norm(triangle_normals(points, triangles), axis=1)
    return np.bincount(np.asarray(triangles).ravel(), weights=np.repeat(a / 3.0, 3), minlength=len(points))


def prepare_mesh(mesh: FaceMesh, *, orient: str = "fix") -> tuple[FaceMesh, np.ndarray]:
    """Check a mesh for the tissue model: no zero-area faces, consistent outward winding.

    Parameters
    ----------
    mesh : FaceMesh
    orient : {"fix", "error"}
        What to do with inconsistently wound polygons.

    Returns
    -------
    mesh : FaceMesh
        Consistently wound, normals pointing away from the mesh's interior (for a face mask:
        toward the viewer).
    flipped : ndarray (K,) int64
        Polygons re-wound (input numbering; all of them when the whole mesh was inside out).

    Raises
    ------
    MeshError
        Zero-area faces, non-manifold edges, a non-orientable patch, or (orient="error")
        inconsistent winding — each naming the faces.
    """
    mesh.check_degenerate()
    tris = mesh.triangles()
    a2 = np.linalg.norm(triangle_normals(mesh.points, tris), axis=1)
    scale = np.ptp(mesh.points, axis=0).max() ** 2
    bad_tri = np.flatnonzero(a2 <= 1e-12 * scale)
    if bad_tri.size:  # a polygon with area but a degenerate fan triangle (e.g. a folded quad)
        faces = np.unique(mesh.triangle_faces()[bad_tri])
        raise MeshError(f"mesh {mesh_where(mesh)}: {faces.size} face(s) have a zero-area triangle in their fixed "
                        f"v0-v2 split, e.g. faces {faces[:10].tolist()}; the tissue model needs a prism per triangle")
    flip, non_orientable = inconsistent_faces(mesh)
    if non_orientable.size:
        raise MeshError(f"mesh {mesh_where(mesh)}: {non_orientable.size} face(s) form a non-orientable patch, "
                        f"e.g. faces {non_orientable[:10].tolist()}")
    if flip.size:
        if orient == "error":
            raise MeshError(f"mesh {mesh_where(mesh)}: {flip.size} face(s) are wound against their neighbours "
                            f"(inconsistent normals): faces {list_names(flip.tolist(), 20)}")
        log.warning("mesh %s: re-wound %d face(s) with inconsistent normals: %s", mesh_where(mesh), flip.size,
                    list_names(flip.tolist(), 20))
        mesh = rewind_faces(mesh, flip)
    # global orientation: normals should point away from the interior (centroid behind a face mask)
    tris = mesh.triangles()
    fn = triangle_normals(mesh.points, tris)
    centre = mesh.points[np.unique(tris)].mean(axis=0)
    tc = mesh.points[tris].mean(axis=1)
    if np.einsum("ij,ij->", fn, tc - centre) < 0:
        log.warning("mesh %s: faces are wound inward; re-winding all of them", mesh_where(mesh))
        allf = np.arange(mesh.n_faces)
        mesh = rewind_faces(mesh, allf)
        flip = np.setdiff1d(allf, flip)
    return mesh, flip


def triangle_edges(triangles: np.ndarray, n_points: int) -> np.ndarray:
    """(E, 2) unique undirected edges (a < b) of a triangle list."""
    t = np.asarray(triangles, dtype=np.int64)
    e = np.concatenate([t[:, [0, 1]], t[:, [1, 2]], t[:, [2, 0]]])
    e.sort(axis=1)
    key = np.unique(e[:, 0] * np.int64(n_points) + e[:, 1])
    return np.stack([key // n_points, key % n_points], axis=1)
