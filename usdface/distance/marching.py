"""Fast marching with exact point-source triangle updates: accurate geodesics at graph-search cost.

The front is propagated in Dijkstra order (smallest distance first, each vertex settled once) like
the edge-graph search, but a vertex's distance comes from the *triangles* around it, not only from
its edges. When a triangle (u, a, b) has two settled vertices u and a, the source is placed in the
triangle's plane at the point s whose distances to u and a are d(u) and d(a) (the intersection of
two circles, on the far side of edge ua from b), and b receives ``|b - s|`` if the straight
segment from s to b crosses the edge ua (the wave enters the triangle through that edge); b also
receives the edge candidates ``d(u) + |ub|`` (paths that bend at a vertex: around holes and
saddles). This is the update of Novotni and Klein (2002), "Computing geodesic distances on
triangular meshes". Where the unfolded surface between the source and a vertex is planar it is
exact: the circle intersection recovers the true source from exact distances, so exactness
carries from triangle to triangle. The textbook fast-marching update (Kimmel and Sethian 1998)
assumes a plane wave instead and loses accuracy near the source.

Obtuse corners. A triangle update into a corner b wider than 90 degrees may come too late: the
other two vertices need not both be settled before b. As Kimmel and Sethian do, the triangles
across the opposite edge are unfolded into b's plane until a vertex w falls in b's acute section
(directions within 90 degrees of both of b's edges); the virtual triangles (b, u, w) and (b, w, a)
are causal (u and w settle before b when the wave crosses uw). They are evaluated when b leaves the
queue; if they give a shorter distance, b goes back in the queue with it.

Late updates. Close to a source (or a pseudo-source: a hole's rim, a saddle vertex) even an acute
corner can settle before the vertex its update needs, and a split may need a vertex farther out.
When a settled vertex later gets a shorter triangle update (beyond float32 rounding) it is
reopened and updates its neighbours again (a label-correcting step; rare, near the sources).
With it the result is exact, up to the float32 tables' rounding, wherever the surface develops
into the plane (tests/distance/test_marching.py: random planar and folded meshes).

Accuracy against exact polyhedral geodesics (MMP), mean relative error over vertex-source pairs
farther than one mean edge length: 0.34 % on the 2020-vertex MakeHuman face (half its triangles
are obtuse), 0.13 % on it refined to 31k vertices, 0.03 % at 560k (benchmarks/bench_distances.py,
pairs up to 3 kernel widths), 0.09 % on an isotropic 30k-vertex remesh; edge paths (``"graph"``)
are 5-9 % long on all of them. What error remains comes from where the wave wraps around a hole
or a saddle vertex (the true front there has another centre than the circle fit assumes) and
shrinks with the edge length.

A surface-point source starts from its triangle's vertices at their straight distance from the
point (exact: the point lies in the triangle's plane). Distances at the source points themselves
(the S x S matrix) come from the same triangle updates applied to the point inside its triangle.
The search is a numba kernel, one search per source, sources in parallel.
"""
from __future__ import annotations

import numpy as np

from ..errors import InputError
from ..numba_cache import CACHE, notice_compiling

try:
    import numba as _nb
    HAVE_NUMBA = True
except ImportError:  # pragma: no cover - numba is a dependency
    _nb = None
    HAVE_NUMBA = False

__all__ = ["HAVE_NUMBA", "MarchingMesh", "march", "marching_mesh_bytes", "triangle_neighbours"]

#: geometry of the update tables (float32 halves their memory traffic; the distances stay float64)
_GEOM = np.float32
#: a settled vertex is reopened when a later update is shorter by more than this factor (well above
#: the ~1e-7 relative rounding of float32 geometry, so rounding never reopens anything)
_REOPEN = 1.0 - 1e-6


class MarchingMesh:
    """The update tables of one triangle mesh, built once and shared by every search.

    Attributes
    ----------
    ptr : ndarray, shape (N + 1,), int64
        Wedges of vertex v: ``ptr[v]:ptr[v + 1]``.
    wa, wb : ndarray, shape (W,), int32
        For each corner v of each triangle, the two other vertices (a, b).
    wla, wlb, wcos, wsin : ndarray, shape (W,), float32
        ``|va|``, ``|vb|`` and the angle at v: with v at the origin and a on the x axis, b sits at
        ``|vb| (cos, -sin)``.
    sptr : ndarray, shape (N + 1,), int64
        Obtuse-corner splits targeting vertex b: ``sptr[b]:sptr[b + 1]``.
    su, sw : ndarray, shape (K,), int32
        Each virtual triangle (u, w) seen from its target b.
    slo, slu, slw, scos, ssin : ndarray, shape (K,), float32
        ``|uw|``, ``|ub|``, ``|wb|`` (unfolded) and the angle at u: u at the origin, w at
        (|uw|, 0), b at ``|ub| (cos, -sin)``.
    n_obtuse, n_split : int
        Obtuse corners, and those split (an unfolded vertex was found within ``max_unfold``
        triangles; the others keep their real triangle's update only).
    """

    _arrays = ("ptr", "wa", "wb", "wla", "wlb", "wcos", "wsin", "sptr", "su", "sw", "slo", "slu", "slw",
               "scos", "ssin")

    def __init__(self, points, triangles, *, max_unfold: int = 12):
        if not HAVE_NUMBA:  # pragma: no cover
            raise InputError("backend='fmm' needs numba (pip install numba)")
        p = np.asarray(points, dtype=np.float64)
        t = np.asarray(triangles, dtype=np.int64).reshape(-1, 3)
        n = p.shape[0]
        self.n_points = n
        self._build_wedges(p, t)
        nb = triangle_neighbours(t)
        notice_compiling("the geodesic search kernels", _unfold_obtuse_corners, _march_many)
        cnt, sb, su, sw, geo = _unfold_obtuse_corners(p, t, nb, int(max_unfold))
        k = int(cnt[1])
        order = np.argsort(sb[:k], kind="stable")
        self.sptr = np.zeros(n + 1, dtype=np.int64)
        np.cumsum(np.bincount(sb[:k], minlength=n), out=self.sptr[1:])
        self.su = su[:k][order].astype(np.int32)
        self.sw = sw[:k][order].astype(np.int32)
        g = geo[:k][order].astype(_GEOM)
        self.slo, self.slu, self.slw, self.scos, self.ssin = (np.ascontiguousarray(g[:, i]) for i in range(5))
        self.n_obtuse, self.n_split = int(cnt[0]), int(cnt[2])

    def _build_wedges(self, p, t):
        u = t.ravel()                                  # corner k of triangle f: t[f, k]
        a = t[:, [1, 2, 0]].ravel()
        b = t[:, [2, 0, 1]].ravel()
        ea = p[a] - p[u]
        eb = p[b] - p[u]
        la = np.sqrt(np.einsum("ij,ij->i", ea, ea))
        lb = np.sqrt(np.einsum("ij,ij->i", eb, eb))
        cross = np.cross(ea, eb)
        sin_ = np.sqrt(np.einsum("ij,ij->i", cross, cross))
        cos_ = np.einsum("ij,ij->i", ea, eb)
        norm = np.hypot(cos_, sin_)
        # a triangle with repeated vertices is no triangle; a flat one (zero area) keeps its edges
        # (a straight angle: its triangle update is the collinear case) and a zero-length side
        # gives edge candidates only (the triangle update refuses L = 0)
        keep = (u != a) & (u != b) & (a != b)
        flat = norm <= 0
        cos_[flat] = 1.0
        sin_[flat] = 0.0
        norm[flat] = 1.0
        u, a, b, la, lb, cos_, sin_, norm = (x[keep] for x in (u, a, b, la, lb, cos_, sin_, norm))
        order = np.argsort(u, kind="stable")
        self.ptr = np.zeros(self.n_points + 1, dtype=np.int64)
        np.cumsum(np.bincount(u, minlength=self.n_points), out=self.ptr[1:])
        self.wa = a[order].astype(np.int32)
        self.wb = b[order].astype(np.int32)
        self.wla = la[order].astype(_GEOM)
        self.wlb = lb[order].astype(_GEOM)
        self.wcos = (cos_ / norm)[order].astype(_GEOM)
        self.wsin = (sin_ / norm)[order].astype(_GEOM)

    @property
    def nbytes(self) -> int:
        return sum(getattr(self, k).nbytes for k in self._arrays)

    def tables(self) -> tuple:
        return tuple(getattr(self, k) for k in self._arrays)


def marching_mesh_bytes(n_points: int, n_triangles: int) -> int:
    """Upper bound of :class:`MarchingMesh`'s memory for a mesh of this size (bytes), including
    the temporaries of building it."""
    wedges = 3 * n_triangles * (2 * 4 + 4 * 4)
    splits = 2 * n_triangles * (2 * 4 + 5 * 4)   # at most one obtuse corner per triangle, 2 splits
    build = 3 * n_triangles * 8 * 12              # float64 temporaries of the wedge and unfold passes
    return 16 * (n_points + 1) + wedges + splits + build


def search_bytes(n_points: int) -> int:
    """Scratch memory of one running search (distance, heap, heap index), bytes."""
    return n_points * (8 + 4 + 8 + 4)


def triangle_neighbours(triangles) -> np.ndarray:
    """(T, 3) triangle across edge k = (t[f, k], t[f, k + 1]) of each triangle, -1 on a border.

    A non-manifold edge (three or more triangles) links its triangles in a cycle.
    """
    t = np.asarray(triangles, dtype=np.int64).reshape(-1, 3)
    nt = t.shape[0]
    a = t.ravel()
    b = t[:, [1, 2, 0]].ravel()
    lo, hi = np.minimum(a, b), np.maximum(a, b)
    n = int(hi.max()) + 1 if hi.size else 1
    key = lo * n + hi
    order = np.argsort(key, kind="stable")
    ks = key[order]
    start = np.concatenate([[True], ks[1:] != ks[:-1]])
    group = np.cumsum(start) - 1
    first = np.flatnonzero(start)
    size = np.diff(np.concatenate([first, [ks.size]]))
    at = np.arange(ks.size) - first[group]
    nxt = first[group] + (at + 1) % size[group]
    out = np.full(3 * nt, -1, dtype=np.int64)
    multi = size[group] > 1
    out[order[multi]] = order[nxt[multi]] // 3
    return out.reshape(nt, 3)


if HAVE_NUMBA:

    @_nb.njit(cache=CACHE, nogil=True, inline="always")
    def _through_edge(du, da, L, px, py):
        """Distance at (px, py), py <= 0, from the point source fitted to d = du at (0, 0) and
        d = da at (L, 0) (on the y > 0 side), when the straight ray source -> point crosses the edge
        [0, L] x {0}; +inf otherwise (no circle intersection, or the ray passes beside the edge)."""
        if not L > 0.0:
            return np.inf
        sx = ((du - da) * (du + da) + L * L) / (2.0 * L)
        sy2 = (du - sx) * (du + sx)
        # a source on the edge's line gives sy2 = 0 up to the rounding of float32 lengths
        if sy2 < -1e-6 * du * du:
            return np.inf
        sy = np.sqrt(max(sy2, 0.0))
        den = sy - py
        if den <= 0.0:
            return np.inf
        x0 = sx + (px - sx) * (sy / den)
        if x0 < 0.0 or x0 > L:
            return np.inf
        dx = px - sx
        dy = py - sy
        return np.sqrt(dx * dx + dy * dy)

    @_nb.njit(cache=CACHE, nogil=True, inline="always")
    def _sift_up(hk, hv, pos, i, key, v):
        """Move heap slot i (to hold vertex v with ``key``) up to its place."""
        while i > 0:
            par = (i - 1) >> 1
            if hk[par] <= key:
                break
            hk[i] = hk[par]
            w = hv[par]
            hv[i] = w
            pos[w] = i
            i = par
        hk[i] = key
        hv[i] = v
        pos[v] = i

    @_nb.njit(cache=CACHE, nogil=True, inline="always")
    def _offer(dist, pos, hk, hv, size, v, cand):
        """Lower v's tentative distance to ``cand`` if shorter (insert or decrease-key); returns
        the heap size."""
        if cand < dist[v]:
            dist[v] = cand
            i = pos[v]
            if i < 0:
                i = size
                size += 1
            _sift_up(hk, hv, pos, i, cand, v)
        return size

    @_nb.njit(cache=CACHE, nogil=True, inline="always")
    def _pop(hk, hv, pos, size):
        """Remove the root of a heap of ``size`` entries (the caller reads it first)."""
        size -= 1
        if size > 0:
            lk = hk[size]
            lv = hv[size]
            i = 0
            while True:
                c = 2 * i + 1
                if c >= size:
                    break
                if c + 1 < size and hk[c + 1] < hk[c]:
                    c += 1
                if hk[c] >= lk:
                    break
                hk[i] = hk[c]
                w = hv[c]
                hv[i] = w
                pos[w] = i
                i = c
            hk[i] = lk
            hv[i] = lv
            pos[lv] = i
        return size

    @_nb.njit(cache=CACHE, nogil=True)
    def _march_one(ptr, wa, wb, wla, wlb, wcos, wsin, sptr, su, sw, slo, slu, slw, scos, ssin,
                   st_v, st_d, needed, n_needed, limit, slack, dist, pos, hk, hv):
        """One search with an indexed binary heap; ``pos[v]``: heap slot, -1 not reached, -2 settled.

        Stops at ``limit``, or ``slack`` past the distance where the last needed vertex settled
        (late updates that reopen a vertex come from a little farther out). Returns the number of
        vertices settled. ``dist`` is final where ``pos == -2``.
        """
        n = ptr.size - 1
        for i in range(n):
            dist[i] = np.inf
            pos[i] = -1
        size = 0
        for k in range(st_v.size):
            size = _offer(dist, pos, hk, hv, size, st_v[k], st_d[k])
        settled = 0
        remaining = n_needed
        while size > 0:
            v = hv[0]
            d = hk[0]
            if d > limit:
                break
            size = _pop(hk, hv, pos, size)
            pos[v] = -1
            # obtuse corner of v: its virtual triangles, now that their vertices are settled
            best = d
            for k in range(sptr[v], sptr[v + 1]):
                w = sw[k]
                if pos[w] != -2:
                    continue
                dw = dist[w]
                c = dw + slw[k]
                u = su[k]
                if pos[u] == -2:
                    lu = slu[k]
                    c = min(c, _through_edge(dist[u], dw, slo[k], lu * scos[k], -lu * ssin[k]))
                if c < best:
                    best = c
            if best < d:        # shorter through the split: back in the queue with it
                dist[v] = np.inf
                size = _offer(dist, pos, hk, hv, size, v, best)
                continue
            pos[v] = -2
            settled += 1
            if n_needed > 0 and needed[v]:
                remaining -= 1
                if remaining == 0:
                    limit = min(limit, d + slack)
            # each triangle corner at v updates its two other vertices
            for k in range(ptr[v], ptr[v + 1]):
                a = wa[k]
                b = wb[k]
                a_done = pos[a] == -2
                b_done = pos[b] == -2
                if a_done and b_done:
                    # both settled already: one of them may have settled too early (its update
                    # needed v, which is farther from the source: obtuse corners and corners
                    # next to a source or pseudo-source). Reopen it if this update is shorter
                    # beyond rounding; it then updates its own neighbours again.
                    la = np.float64(wla[k])
                    lb = np.float64(wlb[k])
                    c = _through_edge(d, dist[a], la, lb * wcos[k], -lb * wsin[k])
                    if c < dist[b] * _REOPEN:
                        pos[b] = -1
                        settled -= 1
                        if n_needed > 0 and needed[b]:
                            remaining += 1
                        size = _offer(dist, pos, hk, hv, size, b, c)
                    c = _through_edge(d, dist[b], lb, la * wcos[k], -la * wsin[k])
                    if c < dist[a] * _REOPEN:
                        pos[a] = -1
                        settled -= 1
                        if n_needed > 0 and needed[a]:
                            remaining += 1
                        size = _offer(dist, pos, hk, hv, size, a, c)
                    continue
                la = np.float64(wla[k])
                lb = np.float64(wlb[k])
                if not b_done:
                    cand = d + lb
                    if a_done:
                        cand = min(cand, _through_edge(d, dist[a], la, lb * wcos[k], -lb * wsin[k]))
                    size = _offer(dist, pos, hk, hv, size, b, cand)
                if not a_done:
                    cand = d + la
                    if b_done:
                        cand = min(cand, _through_edge(d, dist[b], lb, la * wcos[k], -la * wsin[k]))
                    size = _offer(dist, pos, hk, hv, size, a, cand)
        return settled

    @_nb.njit(cache=CACHE, nogil=True)
    def _emit(out_b, out_u, out_w, out_g, k, b, u, w, ux, uy, wx, wy):
        """Row k = virtual triangle (u at (ux, uy), w at (wx, wy)) of target b at the origin; returns
        k + 1 (k when degenerate)."""
        ex = wx - ux
        ey = wy - uy
        bx = -ux
        by = -uy
        lo = np.sqrt(ex * ex + ey * ey)
        lu = np.sqrt(bx * bx + by * by)
        lw = np.sqrt(wx * wx + wy * wy)
        if lo <= 0.0 or lu <= 0.0 or lw <= 0.0:
            return k
        out_b[k] = b
        out_u[k] = u
        out_w[k] = w
        out_g[k, 0] = lo
        out_g[k, 1] = lu
        out_g[k, 2] = lw
        out_g[k, 3] = (ex * bx + ey * by) / (lo * lu)
        out_g[k, 4] = abs(ex * by - ey * bx) / (lo * lu)
        return k + 1

    @_nb.njit(cache=CACHE)
    def _unfold_obtuse_corners(p, t, nb, max_unfold):
        """Split every obtuse corner (see :class:`MarchingMesh`); returns (counts, b, u, w, geometry)."""
        nt = t.shape[0]
        out_b = np.empty(2 * nt, np.int64)
        out_u = np.empty(2 * nt, np.int64)
        out_w = np.empty(2 * nt, np.int64)
        out_g = np.empty((2 * nt, 5), np.float64)
        k = 0
        n_obtuse = 0
        n_split = 0
        for f in range(nt):
            for c in range(3):
                b = t[f, c]
                u = t[f, (c + 1) % 3]
                a = t[f, (c + 2) % 3]
                if b == u or b == a or u == a:
                    continue
                vu = p[u] - p[b]
                va = p[a] - p[b]
                lu = np.sqrt((vu * vu).sum())
                la = np.sqrt((va * va).sum())
                if lu <= 0.0 or la <= 0.0:
                    continue
                cb = (vu * va).sum() / (lu * la)
                if cb >= -1e-9:
                    continue
                n_obtuse += 1
                # b at the origin, u on the x axis, a at angle beta > 90 degrees
                sb = np.sqrt(max(0.0, 1.0 - cb * cb))
                ux, uy = lu, 0.0
                ax, ay = la * cb, la * sb
                # crossing edge (cu at P, ca at Q); X = the vertex behind it
                cu, ca = u, a
                px, py, qx, qy = ux, uy, ax, ay
                xx, xy = 0.0, 0.0
                g = f
                found = -1
                wx, wy = 0.0, 0.0
                for _ in range(max_unfold):
                    ke = -1
                    for kk in range(3):
                        x0 = t[g, kk]
                        x1 = t[g, (kk + 1) % 3]
                        if (x0 == cu and x1 == ca) or (x0 == ca and x1 == cu):
                            ke = kk
                    if ke < 0:
                        break
                    h = nb[g, ke]
                    if h < 0:
                        break
                    w = -1
                    for kk in range(3):
                        if t[h, kk] != cu and t[h, kk] != ca:
                            w = t[h, kk]
                    if w < 0 or w == b:
                        break
                    d1 = p[w] - p[cu]
                    d2 = p[w] - p[ca]
                    luw2 = (d1 * d1).sum()
                    law2 = (d2 * d2).sum()
                    ex = qx - px
                    ey = qy - py
                    L = np.sqrt(ex * ex + ey * ey)
                    if L <= 0.0:
                        break
                    ex /= L
                    ey /= L
                    x = (luw2 - law2 + L * L) / (2.0 * L)
                    y = np.sqrt(max(0.0, luw2 - x * x))
                    nx, ny = -ey, ex
                    if (xx - px) * nx + (xy - py) * ny > 0.0:
                        nx, ny = -nx, -ny
                    cx = px + x * ex + y * nx
                    cy = py + x * ey + y * ny
                    in_u = cx >= 0.0                     # within 90 degrees of b -> u
                    in_a = cx * ax + cy * ay >= 0.0      # within 90 degrees of b -> a
                    if in_u and in_a:
                        found = w
                        wx, wy = cx, cy
                        break
                    if not in_u:        # past the section on a's side: cross edge (cu, w)
                        xx, xy = qx, qy
                        ca = w
                        qx, qy = cx, cy
                    else:               # on u's side: cross edge (w, ca)
                        xx, xy = px, py
                        cu = w
                        px, py = cx, cy
                    g = h
                if found < 0 or found == u or found == a:
                    continue
                n_split += 1
                k = _emit(out_b, out_u, out_w, out_g, k, b, u, found, ux, uy, wx, wy)
                k = _emit(out_b, out_u, out_w, out_g, k, b, a, found, ax, ay, wx, wy)
        cnt = np.array([n_obtuse, k, n_split], np.int64)
        return cnt, out_b, out_u, out_w, out_g

    @_nb.njit(cache=CACHE, nogil=True)
    def _at_point(p0, p1, p2, d0, d1, d2, q):
        """Distance at point q inside triangle (p0, p1, p2) from its vertices' distances: the
        straight candidates d_i + |q - p_i| and the triangle update through each edge."""
        best = np.inf
        ps = (p0, p1, p2)
        ds = (d0, d1, d2)
        for e in range(3):
            pu = ps[e]
            pa = ps[(e + 1) % 3]
            pb = ps[(e + 2) % 3]
            du = ds[e]
            da = ds[(e + 1) % 3]
            best = min(best, du + np.sqrt(((q - pu) ** 2).sum()))
            ex = pa - pu
            L = np.sqrt((ex ** 2).sum())
            if L <= 0.0 or not (np.isfinite(du) and np.isfinite(da)):
                continue
            ex = ex / L
            # in the triangle's plane: x along ua, y away from b (the wave crosses edge ua)
            wb = pb - pu
            yb = wb - (wb * ex).sum() * ex
            nb_ = np.sqrt((yb ** 2).sum())
            if nb_ <= 0.0:
                continue
            ey = -yb / nb_
            wq = q - pu
            best = min(best, _through_edge(du, da, L, (wq * ex).sum(), min(0.0, (wq * ey).sum())))
        return best

    @_nb.njit(cache=CACHE, parallel=True)
    def _march_many(ptr, wa, wb, wla, wlb, wcos, wsin, sptr, su, sw, slo, slu, slw, scos, ssin,
                    start_ptr, start_v, start_d, needed, n_needed, limit, slack, pts, sink_tri, sink_q,
                    direct_ptr, direct_to, direct_d, out_v, out_s, settled):
        n = ptr.size - 1
        n_src = start_ptr.size - 1
        for s in _nb.prange(n_src):
            dist = np.empty(n, np.float64)
            pos = np.empty(n, np.int32)
            hk = np.empty(n, np.float64)
            hv = np.empty(n, np.int32)
            a0, b0 = start_ptr[s], start_ptr[s + 1]
            settled[s] = _march_one(ptr, wa, wb, wla, wlb, wcos, wsin, sptr, su, sw, slo, slu, slw, scos,
                                    ssin, start_v[a0:b0], start_d[a0:b0], needed, n_needed, limit + slack,
                                    slack, dist, pos, hk, hv)
            for i in range(n):
                if pos[i] != -2 or dist[i] > limit:
                    dist[i] = np.inf
            row = out_v[s]
            for i in range(n):
                row[i] = dist[i]
            for j in range(n_src):
                t0, t1, t2 = sink_tri[j, 0], sink_tri[j, 1], sink_tri[j, 2]
                if t0 == t1 and t1 == t2:
                    out_s[s, j] = dist[t0]
                else:
                    out_s[s, j] = _at_point(pts[t0], pts[t1], pts[t2], dist[t0], dist[t1], dist[t2], sink_q[j])
            for k in range(direct_ptr[s], direct_ptr[s + 1]):
                j = direct_to[k]
                out_s[s, j] = min(out_s[s, j], direct_d[k])
            for j in range(n_src):
                if out_s[s, j] > limit:
                    out_s[s, j] = np.inf
            out_s[s, s] = 0.0


def march(mesh: MarchingMesh, points, source_tri_vertices, source_barycentrics, *, needed=None,
          limit: float = np.inf, dtype=np.float64):
    """Geodesic distances from surface-point sources by fast marching (see the module docstring).

    Parameters
    ----------
    mesh : MarchingMesh
        The update tables of the mesh.
    points : array_like, shape (N, 3), float
        Vertex positions (mesh units).
    source_tri_vertices, source_barycentrics : array_like, shape (S, 3)
        Surface-point sources: triangle vertices and barycentric weights (a vertex source is
        ``(v, v, v), (1, 0, 0)``).
    needed : array_like of bool, shape (N,), optional
        Each search stops once these vertices are settled (entries of other vertices are then
        +inf or final, whichever the search reached).
    limit : float
        Stop each search at this distance (entries beyond are +inf).
    dtype : {numpy.float64, numpy.float32}
        Type of the vertex matrix.

    Returns
    -------
    vertex : ndarray, shape (N, S)
        Mesh units; Fortran-ordered view of an (S, N) array.
    sources : ndarray, shape (S, S), float64
        ``sources[i, j]``: source i's distance field at source point j (close to, not exactly,
        symmetric).
    settled : ndarray, shape (S,), int64
        Vertices each search settled (the work done).
    """
    from .graph import source_starts

    p = np.asarray(points, dtype=np.float64)
    n = p.shape[0]
    if n != mesh.n_points:
        raise InputError(f"march: {n} points for a marching mesh of {mesh.n_points}")
    tri = np.asarray(source_tri_vertices, dtype=np.int64).reshape(-1, 3)
    bary = np.asarray(source_barycentrics, dtype=np.float64).reshape(-1, 3)
    s = tri.shape[0]
    start_ptr, sv, sd, _, _, _, direct = source_starts(p, tri, bary)
    if direct.size:
        direct = direct[np.lexsort((direct[:, 1], direct[:, 0]))]
    direct_ptr = np.zeros(s + 1, dtype=np.int64)
    np.cumsum(np.bincount(direct[:, 0].astype(np.int64), minlength=s), out=direct_ptr[1:])
    if needed is None:
        need = np.zeros(0, dtype=np.bool_)
        n_needed = 0
    else:
        need = np.asarray(needed, dtype=np.bool_).reshape(-1)
        if need.size != n:
            raise InputError(f"needed mask has {need.size} entries for {n} vertices")
        n_needed = int(need.sum())
        if n_needed == 0:  # nothing needed: stop each search after its first vertex
            need = np.ones(n, dtype=np.bool_)
            n_needed = 1
    q = np.einsum("sk,skd->sd", bary, p[tri])
    # bounded searches run a few edges farther, for the late updates that come from there
    slack = 4.0 * float(mesh.wla.mean()) if mesh.wla.size else 0.0
    out_v = np.empty((s, n), dtype=dtype)
    out_s = np.empty((s, s), dtype=np.float64)
    settled = np.zeros(s, dtype=np.int64)
    notice_compiling("the geodesic search kernels", _march_many)
    old_chunk = _nb.get_parallel_chunksize()
    _nb.set_parallel_chunksize(1)   # hand sources out one at a time: balanced when CPUs are shared
    try:
        _march_many(*mesh.tables(), start_ptr, sv.astype(np.int64), sd, need, n_needed, float(limit), slack, p,
                    tri, q, direct_ptr, direct[:, 1].astype(np.int64), direct[:, 2].astype(np.float64),
                    out_v, out_s, settled)
    finally:
        _nb.set_parallel_chunksize(old_chunk)
    return out_v.T, out_s, settled
