"""Mesh refinement and surface-point insertion for the field back-ends (heat, exact), the tests and
the benchmarks: boundary loops, regular 1-to-n^2 refinement, and splitting triangles at surface
points so that they become vertices. No graph search here (:mod:`usdface.distance.graph`).
"""
from __future__ import annotations

import numpy as np

from ..errors import InputError

__all__ = ["boundary_loops", "insert_surface_points", "refine_triangles"]


def boundary_loops(triangles) -> list[np.ndarray]:
    """Closed boundary loops of a triangle mesh, longest (most vertices) first.

    Parameters
    ----------
    triangles : array_like, shape (T, 3), int

    Returns
    -------
    list of ndarray, int64
        Ordered vertex indices of each loop. Non-manifold boundaries are split where they branch.
    """
    t = np.asarray(triangles, dtype=np.int64).reshape(-1, 3)
    he = np.concatenate([t[:, [0, 1]], t[:, [1, 2]], t[:, [2, 0]]])
    key = np.sort(he, axis=1)
    _, inv, cnt = np.unique(key, axis=0, return_inverse=True, return_counts=True)
    b = he[cnt[inv.ravel()] == 1]
    nxt: dict[int, list[int]] = {}
    for a, c in b.tolist():
        nxt.setdefault(a, []).append(c)
    loops = []
    while nxt:
        start = next(iter(nxt))
        loop = [start]
        cur = start
        while True:
            outs = nxt.get(cur)
            if not outs:
                break
            nx = outs.pop()
            if not outs:
                del nxt[cur]
            if nx == start:
                break
            loop.append(nx)
            cur = nx
        loops.append(np.asarray(loop, dtype=np.int64))
    loops.sort(key=len, reverse=True)
    return loops


def refine_triangles(points, triangles, n: int) -> tuple[np.ndarray, np.ndarray]:
    """Split every triangle into ``n * n`` (regular 1-to-n^2 refinement, planar).

    Each edge gets ``n - 1`` new vertices shared by its triangles, so holes and borders stay
    exactly as they are and the surface does not change: exact geodesics on the refined mesh equal
    those of the original at the original vertices (which keep their indices ``0..N-1``). Used to
    build large test and benchmark faces (the MakeHuman face, 2020 vertices, gives 31k at n = 4
    and 328k at n = 13).

    Parameters
    ----------
    points : array_like, shape (N, 3)
    triangles : array_like, shape (T, 3), int
    n : int, >= 1

    Returns
    -------
    points : ndarray, shape (N + E (n-1) + T (n-1)(n-2)/2, 3)
    triangles : ndarray, shape (T n^2, 3), int64, same orientation as the input
    """
    p = np.asarray(points, dtype=np.float64)
    t = np.asarray(triangles, dtype=np.int64).reshape(-1, 3)
    if n < 1:
        raise InputError(f"refine_triangles: n must be >= 1; got {n}")
    if n == 1:
        return p.copy(), t.copy()
    nv, nt = p.shape[0], t.shape[0]
    he = np.concatenate([t[:, [0, 1]], t[:, [1, 2]], t[:, [2, 0]]])
    ue, inv = np.unique(np.sort(he, axis=1), axis=0, return_inverse=True)
    inv = inv.ravel()
    n_e = ue.shape[0]
    k = np.arange(1, n) / n
    edge_pts = p[ue[:, 0], None, :] * (1 - k)[None, :, None] + p[ue[:, 1], None, :] * k[None, :, None]
    edge_base = nv + np.arange(n_e) * (n - 1)
    interior = [(i, j, n - i - j) for i in range(1, n) for j in range(1, n) if n - i - j >= 1]
    n_i = len(interior)
    lut = {ijl: c for c, ijl in enumerate(interior)}
    if n_i:
        bw = np.asarray(interior, dtype=np.float64) / n
        int_pts = np.einsum("ik,tkd->tid", bw, p[t]).reshape(-1, 3)
    else:
        int_pts = np.zeros((0, 3))
    int_base = nv + n_e * (n - 1) + np.arange(nt) * n_i
    eid = inv.reshape(3, nt).T  # edges v0v1, v1v2, v2v0 of each triangle

    def vid(i, j, l):  # lattice point with weights (i, j, l)/n on (v0, v1, v2)
        if i == n:
            return t[:, 0]
        if j == n:
            return t[:, 1]
        if l == n:
            return t[:, 2]
        if l == 0:
            a, b, w, e = 0, 1, j, eid[:, 0]
        elif i == 0:
            a, b, w, e = 1, 2, l, eid[:, 1]
        elif j == 0:
            a, b, w, e = 2, 0, i, eid[:, 2]
        else:
            return int_base + lut[(i, j, l)]
        forward = t[:, a] < t[:, b]
        return edge_base[e] + np.where(forward, w, n - w) - 1

    tris = []
    for i in range(n):
        for j in range(n - i):
            l = n - i - j
            tris.append(np.stack([vid(i, j, l), vid(i + 1, j, l - 1), vid(i, j + 1, l - 1)], axis=1))
            if i + j <= n - 2:
                tris.append(np.stack([vid(i + 1, j, l - 1), vid(i + 1, j + 1, l - 2), vid(i, j + 1, l - 1)], axis=1))
    new_t = np.stack(tris, axis=1).reshape(-1, 3)
    return np.concatenate([p, edge_pts.reshape(-1, 3), int_pts]), new_t


def _find_faces(t: np.ndarray, wanted: list) -> dict:
    """{sorted vertex triple: first row of t with those vertices} for the wanted triples."""
    wanted = sorted(set(wanted))
    if not wanted:
        return {}
    n = int(max(t.max(), max(max(w) for w in wanted))) + 1
    ts = np.sort(t, axis=1)
    if n < 2_000_000:
        key = (ts[:, 0] * n + ts[:, 1]) * n + ts[:, 2]
        wk = np.array([(a * n + b) * n + c for a, b, c in wanted], dtype=np.int64)
        order = np.argsort(key, kind="stable")
        pos = np.searchsorted(key[order], wk)
        out = {}
        for w, k, ps in zip(wanted, wk, pos):
            if ps < key.size and key[order[ps]] == k:
                out[w] = int(order[ps])
        return out
    out = {}  # pragma: no cover - very large meshes
    for w in wanted:
        hit = np.flatnonzero((ts == np.asarray(w)).all(axis=1))
        if hit.size:
            out[w] = int(hit[0])
    return out


def insert_surface_points(points, triangles, source_tri_vertices, source_barycentrics, *,
                          min_barycentric: float = 1e-4, names=None):
    """Insert surface points into a triangle mesh as new vertices (1-to-3 triangle splits).

    The split triangles lie in the plane of the original one, so the surface is unchanged and
    any intrinsic distance (heat method, exact MMP) from the new vertex is the distance from the
    point. A point within ``1e-9`` (barycentric) of a vertex is that vertex. A point closer than
    ``min_barycentric`` (barycentric) to an edge of the triangle it splits is moved onto
    ``min_barycentric``, i.e. by at most ``min_barycentric`` times the triangle's size, to keep the
    new triangles non-degenerate. Several points in one triangle split it in turn; coincident
    points share one vertex.

    Parameters
    ----------
    points : array_like, shape (N, 3)
    triangles : array_like, shape (T, 3), int
    source_tri_vertices, source_barycentrics : array_like, shape (S, 3)
        Each triple must be the vertices of one of ``triangles`` (any order) or ``(v, v, v)``.
    min_barycentric : float
    names : sequence of str, optional
        For error messages.

    Returns
    -------
    points : ndarray, shape (N + K, 3)
        The K <= S new vertices appended.
    triangles : ndarray, shape (T + 2K, 3), int64
        Split triangles keep their row (first piece) and orientation.
    source_vertex : ndarray, shape (S,), int64
        The vertex standing for each source.
    moved : ndarray, shape (S,), float64
        How far each source was moved (mesh units; 0 unless snapped).
    """
    p = np.asarray(points, dtype=np.float64)
    t = np.asarray(triangles, dtype=np.int64).reshape(-1, 3)
    tri = np.asarray(source_tri_vertices, dtype=np.int64).reshape(-1, 3)
    bary = np.asarray(source_barycentrics, dtype=np.float64).reshape(-1, 3)
    s = tri.shape[0]
    names = [f"source {i}" for i in range(s)] if names is None else list(names)
    src_vertex = np.empty(s, dtype=np.int64)
    moved = np.zeros(s, dtype=np.float64)
    need_split = []
    for i in range(s):
        w: dict[int, float] = {}
        for v, b in zip(tri[i].tolist(), bary[i].tolist()):
            w[v] = w.get(v, 0.0) + b
        vmax = max(w, key=w.get)
        if w[vmax] >= 1.0 - 1e-9:
            src_vertex[i] = vmax
            moved[i] = float(np.linalg.norm(p[vmax] - bary[i] @ p[tri[i]]))
        else:
            need_split.append(i)
    if not need_split:
        return p.copy(), t.copy(), src_vertex, moved
    face_of = _find_faces(t, [tuple(sorted(tri[i].tolist())) for i in need_split])
    t_out = t.copy()                      # split triangles keep their row (first piece)
    t_new: list[np.ndarray] = []          # the other pieces, appended
    new_pts: list[np.ndarray] = []
    # per original triangle f: its corner vertices, and its current pieces as
    # (vertex triple, barycentric coordinates of those vertices in f (3 x 3), row)
    corners_of: dict[int, np.ndarray] = {}
    pieces_of: dict[int, list] = {}
    n0 = p.shape[0]
    for i in need_split:
        kk = tuple(sorted(tri[i].tolist()))
        f = face_of.get(kk)
        if f is None:
            kind = "a degenerate triangle" if len(set(kk)) < 3 else "not a triangle of the mesh"
            raise InputError(f"{names[i]}: vertices ({', '.join(map(str, tri[i].tolist()))}) with "
                             f"barycentrics {np.round(bary[i], 6).tolist()} are {kind}")
        if f not in corners_of:
            corners_of[f] = t[f].copy()
            pieces_of[f] = [(t[f].copy(), np.eye(3), f)]
        corners = corners_of[f].tolist()
        b = np.zeros(3)
        for v, bb in zip(tri[i].tolist(), bary[i].tolist()):
            b[corners.index(v)] += bb
        cpos = p[corners_of[f]]
        best, best_lam = 0, None
        for k, (_, sb, _) in enumerate(pieces_of[f]):
            lam = np.linalg.solve(sb.T, b)
            if best_lam is None or lam.min() > best_lam.min():
                best, best_lam = k, lam
        sv, sb, row = pieces_of[f][best]
        lam = np.clip(best_lam, 0.0, None)
        lam /= lam.sum()
        if lam.max() >= 1.0 - 1e-9:
            src_vertex[i] = sv[int(np.argmax(lam))]
            moved[i] = float(np.linalg.norm((sb.T @ lam - b) @ cpos))
            continue
        lam = np.maximum(lam, min_barycentric)
        lam /= lam.sum()
        bnew = sb.T @ lam
        pos = bnew @ cpos
        moved[i] = float(np.linalg.norm(pos - b @ cpos))
        vnew = n0 + len(new_pts)
        new_pts.append(pos)
        src_vertex[i] = vnew
        (a, bv, c), (ba, bb_, bc) = sv, sb
        split = [(np.array([a, bv, vnew]), np.stack([ba, bb_, bnew])),
                 (np.array([bv, c, vnew]), np.stack([bb_, bc, bnew])),
                 (np.array([c, a, vnew]), np.stack([bc, ba, bnew]))]
        if row < t_out.shape[0]:
            t_out[row] = split[0][0]
        else:
            t_new[row - t_out.shape[0]] = split[0][0]
        rows = [row]
        for pv, _ in split[1:]:
            t_new.append(pv)
            rows.append(t_out.shape[0] + len(t_new) - 1)
        pieces_of[f][best:best + 1] = [(pv, pb, r) for (pv, pb), r in zip(split, rows)]
    out_p = np.concatenate([p, np.asarray(new_pts, dtype=np.float64).reshape(-1, 3)])
    return out_p, np.concatenate([t_out, np.asarray(t_new, dtype=np.int64).reshape(-1, 3)]), src_vertex, moved
