"""Fast marching with exact point-source triangle updates: accurate geodesics at graph-search cost.

The front is propagated in distance order like the edge-graph search, but a vertex's distance
comes from the *triangles* around it, not only from its edges. When a triangle (u, a, b) has two
settled vertices u and a, the source is placed in the triangle's plane at the point s whose
distances to u and a are d(u) and d(a) (the intersection of two circles, on the far side of edge
ua from b), and b receives ``|b - s|`` if the straight segment from s to b crosses the edge ua (the
wave enters the triangle through that edge); b also receives the edge candidates
``d(u) + |ub|`` (paths that bend at a vertex: around holes and saddles). This is the update of
Novotni and Klein (2002), "Computing geodesic distances on triangular meshes". Where the unfolded
surface between the source and a vertex is planar it is exact: the circle intersection recovers
the true source from exact distances, so exactness carries from triangle to triangle. The
textbook fast-marching update (Kimmel and Sethian 1998) assumes a plane wave instead and loses
accuracy near the source.

Obtuse corners. A triangle update into a corner b wider than 90 degrees may come too late: the
other two vertices need not both be settled before b. As Kimmel and Sethian do, the triangles
across the opposite edge are unfolded into b's plane until a vertex w falls in b's acute section;
the virtual triangles (b, u, w) and (b, w, a) are causal (:mod:`usdface.distance.marching_tables`).
They are evaluated when b leaves the queue; if they give a shorter distance, b goes back in the
queue with it.

Late updates. Close to a source (or a pseudo-source: a hole's rim, a saddle vertex) even an acute
corner can settle before the vertex its update needs, and a split may need a vertex farther out.
When a settled vertex later gets a shorter triangle update (beyond float32 rounding) it is
reopened and updates its neighbours again (a label-correcting step). With it the result is
exact, up to the float32 tables' rounding, wherever the surface develops into the plane
(tests/distance/test_marching.py: random planar and folded meshes).

The queue. An *untidy* priority queue (Yatziv, Bartesaghi and Sapiro 2006, "O(N) implementation
of the fast marching algorithm", J. Comput. Phys. 212): buckets of width ``mean edge /
BUCKETS_PER_EDGE``, first in first out within a bucket, so a push and a pop cost O(1) instead of
the O(log front) of a binary heap, and the vertices of a bucket are visited in the order the
front reached them (memory stays local). Two vertices closer in distance than a bucket's width may
settle in either order; when the second one's triangle update would have shortened the first,
the late-update reopening above corrects it. Against a search in strict distance order the
distances differ by less than 3e-5 relative (tests/distance/test_marching.py: the slow
reference in either order on the sample faces), a hundredth of the method's error against exact
geodesics, and not beyond rounding on planar meshes.

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
The search is a numba kernel, one search per source, sources in parallel on every core numba
uses (``NUMBA_NUM_THREADS``).
"""
from __future__ import annotations

import numpy as np

from ..errors import InputError
from ..numba_cache import njit, notice_compiling
from .marching_tables import HAVE_NUMBA, MarchingMesh, marching_mesh_bytes, search_bytes

if HAVE_NUMBA:
    import numba as _nb
    from llvmlite import ir as _ir
    from numba import prange, types
    from numba.core.extending import intrinsic
else:  # pragma: no cover - numba is a dependency
    prange = range

__all__ = ["BUCKETS_PER_EDGE", "HAVE_NUMBA", "MarchingMesh", "march", "marching_mesh_bytes", "queue_buckets",
           "search_bytes"]

#: a settled vertex is reopened when a later update is shorter by more than this factor (well above
#: the ~1e-7 relative rounding of float32 geometry, so rounding never reopens anything)
_REOPEN = 1.0 - 1e-6
#: buckets of the untidy queue per mean edge length: 4 and 16 give the same distances (within
#: 3e-5 relative of a strict-order search) at the same speed on the refined face; 1 is 10x less
#: accurate (measured in the benchmark's development, 560k-vertex MakeHuman face)
BUCKETS_PER_EDGE = 8
#: the bucket ring never grows beyond this many slots (a mesh whose longest edge is this many
#: bucket widths gets wider buckets)
_MAX_BUCKETS = 1 << 22


def queue_buckets(mesh: MarchingMesh) -> tuple[float, int]:
    """Bucket width (mesh units) and ring size (a power of two) of the untidy queue.

    A candidate is at most one edge longer than the distance being settled, so the ring spans the
    longest wedge side plus two buckets.
    """
    geom = mesh.wedge_geom
    longest = float(geom[:, :2].max()) if geom.size else 0.0
    width = mesh.mean_edge / BUCKETS_PER_EDGE
    if not width > 0.0:
        width = 1.0
    if longest / width + 3 > _MAX_BUCKETS:
        width = longest / (_MAX_BUCKETS - 3)
    slots = 1 << int(np.ceil(np.log2(longest / width + 3)))
    return width, slots



@njit(cache=True, nogil=True, inline="always")
def _through_edge(du, da, L, px, py, bound):
    """Distance at (px, py), py <= 0, from the point source fitted to d = du at (0, 0) and
    d = da at (L, 0) (on the y > 0 side) when the straight ray source -> point crosses the edge
    [0, L] x {0} and the distance is below ``bound``; +inf otherwise (no circle intersection,
    a ray beside the edge, or not shorter than ``bound``)."""
    if not L > 0.0:
        return np.inf
    sx = ((du - da) * (du + da) + L * L) / (2.0 * L)
    sy2 = (du - sx) * (du + sx)
    # a source on the edge's line gives sy2 = 0 up to the rounding of float32 lengths
    if sy2 < -1e-6 * du * du:
        return np.inf
    sy2 = max(sy2, 0.0)
    dx = px - sx
    # |b - s|^2 = dx^2 + (py - sy)^2 >= dx^2 + py^2 + sy^2 (py <= 0 <= sy): most late-update
    # checks end here, before any square root
    if dx * dx + py * py + sy2 >= bound * bound:
        return np.inf
    sy = np.sqrt(sy2)
    den = sy - py
    if den <= 0.0:
        return np.inf
    # where the ray crosses the edge's line, times den: x0 = sx + dx * sy / den in [0, L]
    cross = sx * den + dx * sy
    if cross < 0.0 or cross > L * den:
        return np.inf
    dy = py - sy
    dist = np.sqrt(dx * dx + dy * dy)
    return dist if dist < bound else np.inf


if HAVE_NUMBA:

    @intrinsic
    def _prefetch(typingctx, array, index):
        """Ask the CPU to bring ``array.flat[index]``'s cache line in (LLVM's ``llvm.prefetch``, a
        read, kept in all cache levels); no effect on the results."""
        def codegen(context, builder, signature, args):
            data = context.make_array(signature.args[0])(context, builder, args[0]).data
            byte_ptr = _ir.IntType(8).as_pointer()
            i32 = _ir.IntType(32)
            fn = builder.module.declare_intrinsic(
                "llvm.prefetch", fnty=_ir.FunctionType(_ir.VoidType(), [byte_ptr, i32, i32, i32]))
            builder.call(fn, [builder.bitcast(builder.gep(data, [args[1]]), byte_ptr), _ir.Constant(i32, 0),
                              _ir.Constant(i32, 3), _ir.Constant(i32, 1)])
            return context.get_dummy_value()
        return types.void(array, index), codegen


@njit(cache=True, nogil=True, inline="always")
def _frame(wg, k, side, la, lb):
    """The target of wedge k's update on ``side`` in the frame of the edge it crosses: b at
    (bx, by) (side 0), a at (bx, by) |va| / |vb| (side 1)."""
    bx = np.float64(wg[k, 4])
    by = np.float64(wg[k, 5])
    if side == 0:
        return bx, by
    r = la / lb if lb > 0.0 else 0.0
    return bx * r, by * r


@njit(cache=True, nogil=True, inline="always")
def _enqueue(head, tail, e_v, e_next, free, used, slot, v):
    """Append v to bucket ``slot`` (an entry from the free list, else a new one); returns the
    free list's head and the entries used."""
    if free >= 0:
        e = free
        free = e_next[e]
    else:
        e = used
        used += 1
    e_v[e] = v
    e_next[e] = -1
    if head[slot] < 0:
        head[slot] = e
    else:
        e_next[tail[slot]] = e
    tail[slot] = e
    return free, used


@njit(cache=True, nogil=True)
def _grow(a, size):
    out = np.empty(size, a.dtype)
    out[:a.size] = a
    return out


@njit(cache=True, nogil=True)
def _march_one(ptr, wv, wg, sptr, sv, sg, st_v, st_d, needed, n_needed, limit, slack, width, n_buckets,
               dist, done):
    """One search from the start vertices ``st_v`` at distances ``st_d`` (see the module docstring).

    Parameters
    ----------
    ptr, wv, wg, sptr, sv, sg : the :class:`MarchingMesh` tables.
    needed : (N,) bool or (0,); n_needed : int
        Stop ``slack`` past the distance where the last needed vertex settled (late updates
        that reopen a vertex come from a little farther out).
    limit : float
        Leave vertices farther than this unsettled.
    width, n_buckets : float, int
        The untidy queue's bucket width (mesh units) and ring size (a power of two).
    dist : (N,) float64, out
        Distances, final where ``done``.
    done : (N,) uint8, out
        1 where settled.

    Returns
    -------
    int
        Vertices settled.
    """
    n = ptr.size - 1
    for i in range(n):
        dist[i] = np.inf
        done[i] = 0
    inv_width = 1.0 / width
    mask = n_buckets - 1
    head = np.full(n_buckets, -1, np.int32)
    tail = np.empty(n_buckets, np.int32)
    e_v = np.empty(1024, np.int32)
    e_next = np.empty(1024, np.int32)
    free = -1
    used = 0
    live = 0
    cur = np.int64(st_d.min() * inv_width) if st_d.size else 0
    for k in range(st_v.size):
        v = st_v[k]
        if st_d[k] < dist[v]:
            dist[v] = st_d[k]
            b = max(np.int64(st_d[k] * inv_width), cur)
            free, used = _enqueue(head, tail, e_v, e_next, free, used, b & mask, v)
            live += 1
    settled = 0
    remaining = n_needed
    while live > 0:
        slot = cur & mask
        e = head[slot]
        if e < 0:
            cur += 1
            if cur * width > limit:
                break
            continue
        head[slot] = e_next[e]
        v = e_v[e]
        # the table rows of the vertex two places behind in this bucket: fetched while this one
        # and the next are processed (the rows are where a search waits on memory: -25% time)
        ahead = e_next[e]
        if ahead >= 0:
            ahead = e_next[ahead]
            if ahead >= 0:
                u = e_v[ahead]
                k = ptr[u]
                _prefetch(wg, 6 * k)                    # 24-byte rows: 6 wedges in 3 lines
                _prefetch(wg, 6 * k + 16)
                _prefetch(wg, 6 * k + 32)
                _prefetch(sg, 6 * sptr[u])
                _prefetch(sg, 6 * sptr[u] + 12)
                _prefetch(dist, u)
        e_next[e] = free
        free = e
        live -= 1
        if done[v]:
            continue            # an older entry of a vertex settled since
        d = dist[v]
        if d > limit:
            continue
        if used + 2 * (ptr[v + 1] - ptr[v]) + 1 > e_v.size:
            e_v = _grow(e_v, 2 * e_v.size + 2 * (ptr[v + 1] - ptr[v]) + 1)
            e_next = _grow(e_next, e_v.size)
        # obtuse corner of v: its virtual triangles, now that their vertices are settled
        best = d
        for k in range(sptr[v], sptr[v + 1]):
            w = sv[k, 1]
            if not done[w]:
                continue
            c = dist[w] + sg[k, 3]
            u = sv[k, 0]
            if done[u]:
                c = min(c, _through_edge(dist[u], dist[w], np.float64(sg[k, 2]), np.float64(sg[k, 4]),
                                         np.float64(sg[k, 5]), min(c, best)))
            best = min(best, c)
        if best < d:        # shorter through the split: back in the queue with it
            dist[v] = best
            free, used = _enqueue(head, tail, e_v, e_next, free, used, slot, v)
            live += 1
            continue
        done[v] = 1
        settled += 1
        if n_needed > 0 and needed[v]:
            remaining -= 1
            if remaining == 0:
                limit = min(limit, d + slack)
        # each triangle corner at v updates its two other vertices: b through edge (v, a)
        # (side 0), a through edge (v, b) (side 1: a sits at (bx, by) |va| / |vb| in that frame)
        for k in range(ptr[v], ptr[v + 1]):
            la = np.float64(wg[k, 2])
            lb = np.float64(wg[k, 3])
            for side in range(2):
                tgt = wv[k, 1 - side]
                oth = wv[k, side]
                L = lb if side else la
                if done[tgt]:
                    if not done[oth]:
                        continue
                    # both settled already: the target may have settled too early (its update
                    # needed v, farther out: obtuse corners, corners next to a source or a
                    # pseudo-source, or the queue's untidy order). Reopen it if this update is
                    # shorter beyond rounding; it then updates its own neighbours again.
                    px, py = _frame(wg, k, side, la, lb)
                    c = _through_edge(d, dist[oth], L, px, py, dist[tgt] * _REOPEN)
                    if not c < np.inf:
                        continue
                    done[tgt] = 0
                    settled -= 1
                    if n_needed > 0 and needed[tgt]:
                        remaining += 1
                else:
                    c = d + (la if side else lb)
                    if done[oth]:
                        px, py = _frame(wg, k, side, la, lb)
                        c = min(c, _through_edge(d, dist[oth], L, px, py, min(c, dist[tgt])))
                    if not c < dist[tgt]:
                        continue
                dist[tgt] = c
                b = max(np.int64(c * inv_width), cur)
                free, used = _enqueue(head, tail, e_v, e_next, free, used, b & mask, tgt)
                live += 1
    return settled


@njit(cache=True, nogil=True)
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
        best = min(best, _through_edge(du, da, L, (wq * ex).sum(), min(0.0, (wq * ey).sum()), np.inf))
    return best


@njit(cache=True, parallel=True)
def _march_many(ptr, wv, wg, sptr, sv, sg, start_ptr, start_v, start_d, needed, n_needed, limit, slack,
                width, n_buckets, rank, pts, sink_tri, sink_q, direct_ptr, direct_to, direct_d, out_v, out_s,
                settled):
    """All sources, in parallel: row s of ``out_v`` (S, N) and ``out_s`` (S, S) from source s.

    Vertices are in the tables' order except the columns of ``out_v``: column i is the mesh's
    vertex i, at position ``rank[i]`` of the tables.
    """
    n = ptr.size - 1
    n_src = start_ptr.size - 1
    for s in prange(n_src):
        dist = np.empty(n, np.float64)
        done = np.empty(n, np.uint8)
        a0, b0 = start_ptr[s], start_ptr[s + 1]
        settled[s] = _march_one(ptr, wv, wg, sptr, sv, sg, start_v[a0:b0], start_d[a0:b0], needed, n_needed,
                                limit + slack, slack, width, n_buckets, dist, done)
        for i in range(n):
            if not done[i] or dist[i] > limit:
                dist[i] = np.inf
        row = out_v[s]
        for i in range(n):
            row[i] = dist[rank[i]]
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


@njit(cache=True, parallel=True)
def _vertex_major(rows, out):
    """``out[i, s] = rows[s, i]``: (S, N) -> (N, S), by blocks of vertices whose rows of ``out``
    stay in cache."""
    n_src, n = rows.shape
    block = 512
    for k in prange((n + block - 1) // block):
        i0 = k * block
        i1 = min(n, i0 + block)
        for s in range(n_src):
            for i in range(i0, i1):
                out[i, s] = rows[s, i]


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
    vertex : ndarray, shape (N, S), ``dtype``, C-contiguous
        Mesh units (vertex-major, as the analysis layer stores it).
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
    bary = np.asarray(source_barycentrics, dtype=np.float64).reshape(-1, 3)
    tri = mesh.rank[np.asarray(source_tri_vertices, dtype=np.int64).reshape(-1, 3)]     # the tables' order
    p = mesh.points
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
        need = need[mesh.order]
    q = np.einsum("sk,skd->sd", bary, p[tri])
    # bounded searches run a few edges farther, for the late updates that come from there
    slack = 4.0 * mesh.mean_edge
    width, n_buckets = queue_buckets(mesh)
    out_v = np.empty((s, n), dtype=dtype)
    out_s = np.empty((s, s), dtype=np.float64)
    settled = np.zeros(s, dtype=np.int64)
    notice_compiling("the geodesic search kernels", _march_many, _vertex_major)
    old_chunk = _nb.get_parallel_chunksize()
    _nb.set_parallel_chunksize(1)   # hand sources out one at a time: balanced when CPUs are shared
    try:
        _march_many(*mesh.tables(), start_ptr, sv.astype(np.int64), sd, need, n_needed, float(limit), slack,
                    width, n_buckets, mesh.rank, p, tri, q, direct_ptr, direct[:, 1].astype(np.int64),
                    direct[:, 2].astype(np.float64), out_v, out_s, settled)
    finally:
        _nb.set_parallel_chunksize(old_chunk)
    vertex = np.empty((n, s), dtype=dtype)
    _vertex_major(out_v, vertex)
    return vertex, out_s, settled
