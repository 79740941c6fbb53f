"""Edge-graph helpers: the mesh as a weighted graph, connected components and multi-source shortest
paths from surface points. (Mesh refinement and point insertion live in
:mod:`usdface.distance.refinement`; their names stay importable from here.)

The paper's mesh-based geodesic distance (Eq. 7) is the length of the shortest path along mesh
edges, ``||p - q||_Geo = sum_a ||V[a] - V[a+1]||``. Here every source is a point on the surface; it
enters the graph as a *virtual node* joined to the three vertices of its triangle by straight
segments inside the triangle (Euclidean length). To evaluate distances at the source points
themselves each source also gets a *sink* node, reached from its triangle's vertices (and straight
from another source in the same triangle). Sources only emit and sinks only absorb, so virtual
nodes never shorten a path between two vertices, whatever edge set is used.

The search kernel is a Dijkstra with a bucket queue (Dial's algorithm, bucket width = the shortest
mesh edge, which keeps it exact: no two labels in one bucket can improve each other) or, when the
edge lengths spread too widely for buckets, a binary heap; numba compiles it and runs the sources
in parallel. Without numba, :func:`scipy.sparse.csgraph.dijkstra` on the explicit augmented graph
is used (same distances; no bounded search).
"""
from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from ..errors import InputError
from ..numba_cache import CACHE, notice_compiling
from .refinement import boundary_loops, insert_surface_points, refine_triangles  # noqa: F401

if TYPE_CHECKING:  # annotations only: imported where used
    import scipy.sparse

try:  # numba is optional: the scipy path gives the same distances
    import numba as _nb
    HAVE_NUMBA = True
except ImportError:  # pragma: no cover - exercised only without numba
    _nb = None
    HAVE_NUMBA = False

__all__ = [
    "HAVE_NUMBA",
    "augmented_graph",
    "boundary_loops",
    "connected_components",
    "edge_graph",
    "insert_surface_points",
    "mesh_edges",
    "polygon_edges",
    "refine_triangles",
    "source_starts",
    "multi_source_shortest_paths",
]


# ----------------------------------------------------------------------------------------------
# graph construction
# ----------------------------------------------------------------------------------------------

def mesh_edges(triangles) -> np.ndarray:
    """Unique undirected edges of a triangle mesh.

    Parameters
    ----------
    triangles : array_like, shape (T, 3), int

    Returns
    -------
    ndarray, shape (E, 2), int64
        Each edge once, ``edges[:, 0] < edges[:, 1]``, sorted.
    """
    t = np.asarray(triangles, dtype=np.int64).reshape(-1, 3)
    e = np.concatenate([t[:, [0, 1]], t[:, [1, 2]], t[:, [2, 0]]])
    return _unique_edges(e)


def _unique_edges(e: np.ndarray) -> np.ndarray:
    """Unique undirected (a < b) rows of an (E, 2) int array, sorted; self-loops dropped."""
    if e.size == 0:
        return np.zeros((0, 2), dtype=np.int64)
    lo = np.minimum(e[:, 0], e[:, 1])
    hi = np.maximum(e[:, 0], e[:, 1])
    keep = lo != hi
    lo, hi = lo[keep], hi[keep]
    n = int(hi.max()) + 1 if hi.size else 1
    key = np.sort(lo * n + hi)            # one int64 key per edge: much faster than unique(axis=0)
    key = key[np.concatenate([[True], key[1:] != key[:-1]])]
    return np.stack([key // n, key % n], axis=1)


def polygon_edges(face_vertex_counts, face_vertex_indices) -> np.ndarray:
    """Unique undirected edges of a polygon mesh (no triangulation diagonals).

    Parameters
    ----------
    face_vertex_counts : array_like, shape (P,), int
    face_vertex_indices : array_like, shape (sum(counts),), int

    Returns
    -------
    ndarray, shape (E, 2), int64
        As :func:`mesh_edges`. Use it as ``GeodesicSolver(..., edges=...)`` to search along the
        polygon edges only (Maya's shortest edge path on a quad mesh, as in the paper's code).
    """
    counts = np.asarray(face_vertex_counts, dtype=np.int64).ravel()
    idx = np.asarray(face_vertex_indices, dtype=np.int64).ravel()
    starts = np.concatenate([[0], np.cumsum(counts)[:-1]])
    nxt = np.arange(idx.size) + 1
    last = starts + counts - 1
    nxt[last] = starts
    return _unique_edges(np.stack([idx, idx[nxt]], axis=1))


def edge_graph(points, edges) -> scipy.sparse.csr_matrix:
    """Symmetric sparse graph of the mesh edges weighted by their Euclidean length.

    Parameters
    ----------
    points : array_like, shape (N, 3)
    edges : array_like, shape (E, 2), int

    Returns
    -------
    scipy.sparse.csr_matrix, shape (N, N), float64
        ``G[a, b] = G[b, a] = ||points[a] - points[b]||``. A zero-length edge (coincident
        vertices) is stored as an explicit zero, which scipy.sparse.csgraph treats as an edge.
    """
    import scipy.sparse as sp  # here, not at import: the fast-marching back-end needs no sparse graph

    p = np.asarray(points, dtype=np.float64)
    e = np.asarray(edges, dtype=np.int64).reshape(-1, 2)
    n = p.shape[0]
    w = np.linalg.norm(p[e[:, 0]] - p[e[:, 1]], axis=1)
    rows = np.concatenate([e[:, 0], e[:, 1]])
    cols = np.concatenate([e[:, 1], e[:, 0]])
    order = np.lexsort((cols, rows))
    rows, cols, data = rows[order], cols[order], np.concatenate([w, w])[order]
    indptr = np.zeros(n + 1, dtype=np.int64)
    np.cumsum(np.bincount(rows, minlength=n), out=indptr[1:])
    return sp.csr_matrix((data, cols.astype(np.int32), indptr), shape=(n, n))


def connected_components(n_points: int, triangles=None, *, edges=None) -> tuple[int, np.ndarray]:
    """Connected components of a mesh (vertices joined by triangle edges).

    Parameters
    ----------
    n_points : int
    triangles : array_like, shape (T, 3), int, optional
    edges : array_like, shape (E, 2), int, optional
        Used instead of ``triangles`` when given.

    Returns
    -------
    n_components : int
    labels : ndarray, shape (N,), int64
        Component of each vertex, numbered by decreasing size (0 = largest); a vertex used by no
        triangle is a component of its own.
    """
    import scipy.sparse as sp
    from scipy.sparse import csgraph

    e = mesh_edges(triangles) if edges is None else np.asarray(edges, dtype=np.int64).reshape(-1, 2)
    a = sp.coo_matrix((np.ones(e.shape[0], dtype=np.int8), (e[:, 0], e[:, 1])), shape=(n_points, n_points))
    n, labels = csgraph.connected_components(a, directed=False)
    sizes = np.bincount(labels, minlength=n)
    order = np.argsort(-sizes, kind="stable")
    rank = np.empty(n, dtype=np.int64)
    rank[order] = np.arange(n)
    return int(n), rank[labels]


def source_starts(points, source_tri_vertices, source_barycentrics):
    """Start vertices and initial distances of surface-point sources.

    Returns
    -------
    start_ptr : ndarray, shape (S + 1,), int64
        Source s starts from ``start_vertex[start_ptr[s]:start_ptr[s + 1]]``.
    start_vertex : ndarray, int64
        The distinct vertices of each source's triangle.
    start_dist : ndarray, float64
        Euclidean distance from the source point to each of those vertices.
    sink_ptr, sink_source, sink_weight : ndarrays
        For each vertex v (CSR over N vertices), the sources whose triangle holds v and the
        distance from v to that source point: the edges into the sink nodes.
    direct : ndarray, shape (K, 3)
        ``(i, j, d)`` rows: sources i != j in the same triangle, straight distance d.
    """
    p = np.asarray(points, dtype=np.float64)
    tri = np.asarray(source_tri_vertices, dtype=np.int64).reshape(-1, 3)
    bary = np.asarray(source_barycentrics, dtype=np.float64).reshape(-1, 3)
    s = tri.shape[0]
    q = np.einsum("sk,skd->sd", bary, p[tri])
    d = np.linalg.norm(p[tri] - q[:, None, :], axis=2)                       # (S, 3)
    # distinct vertices per source (a vertex source is (v, v, v))
    dup = np.zeros((s, 3), dtype=bool)
    dup[:, 1] = tri[:, 1] == tri[:, 0]
    dup[:, 2] = (tri[:, 2] == tri[:, 0]) | (tri[:, 2] == tri[:, 1])
    keep = ~dup
    counts = keep.sum(axis=1)
    start_ptr = np.concatenate([[0], np.cumsum(counts)]).astype(np.int64)
    start_vertex = tri[keep]
    start_dist = d[keep]
    src_of = np.repeat(np.arange(s), counts)
    n = p.shape[0]
    order = np.argsort(start_vertex, kind="stable")
    sink_ptr = np.zeros(n + 1, dtype=np.int64)
    np.cumsum(np.bincount(start_vertex, minlength=n), out=sink_ptr[1:])
    sink_source = src_of[order].astype(np.int64)
    sink_weight = start_dist[order]
    # sources sharing a triangle see each other along the straight segment
    key = np.sort(tri, axis=1)
    direct = []
    if s > 1:
        _, inv = np.unique(key, axis=0, return_inverse=True)
        inv = inv.ravel()
        for g in np.flatnonzero(np.bincount(inv) > 1):
            members = np.flatnonzero(inv == g)
            for i in members:
                for j in members:
                    if i != j:
                        direct.append((i, j, float(np.linalg.norm(q[i] - q[j]))))
    direct = np.asarray(direct, dtype=np.float64).reshape(-1, 3)
    return start_ptr, start_vertex, start_dist, sink_ptr, sink_source, sink_weight, direct


def augmented_graph(graph, points, source_tri_vertices, source_barycentrics) -> scipy.sparse.csr_matrix:
    """The edge graph with one source node and one sink node per surface-point source.

    Node ``N + s`` is source s (edges to its triangle's vertices, Euclidean lengths), node
    ``N + S + s`` its sink (edges from those vertices, and from the other sources of the same
    triangle). Directed: searching from node ``N + s`` gives distances to every vertex (columns
    ``:N``) and to every source point (columns ``N + S:``).

    Parameters
    ----------
    graph : scipy.sparse matrix, shape (N, N)
        Symmetric edge graph (:func:`edge_graph`).
    points : array_like, shape (N, 3)
    source_tri_vertices, source_barycentrics : array_like, shape (S, 3)

    Returns
    -------
    scipy.sparse.csr_matrix, shape (N + 2S, N + 2S)
    """
    import scipy.sparse as sp

    g = sp.coo_matrix(graph)
    n = g.shape[0]
    start_ptr, sv, sd, _, _, _, direct = source_starts(points, source_tri_vertices, source_barycentrics)
    s = start_ptr.size - 1
    src_of = np.repeat(np.arange(s), np.diff(start_ptr))
    rows = [g.row, n + src_of, sv]
    cols = [g.col, sv, n + s + src_of]
    data = [g.data, sd, sd]
    if direct.size:
        rows.append(n + direct[:, 0].astype(np.int64))
        cols.append(n + s + direct[:, 1].astype(np.int64))
        data.append(direct[:, 2])
    m = n + 2 * s
    r, c, w = np.concatenate(rows), np.concatenate(cols), np.concatenate(data)
    order = np.lexsort((c, r))
    r, c, w = r[order], c[order], w[order]
    indptr = np.zeros(m + 1, dtype=np.int64)
    np.cumsum(np.bincount(r, minlength=m), out=indptr[1:])
    return sp.csr_matrix((w, c.astype(np.int32), indptr), shape=(m, m))


# ----------------------------------------------------------------------------------------------
# search kernels
# ----------------------------------------------------------------------------------------------

if HAVE_NUMBA:

    @_nb.njit(cache=CACHE, nogil=True)
    def _sssp_one(indptr, indices, weights, st_v, st_d, sink_ptr, sink_src, sink_w, direct_to, direct_d,
                  needed, n_needed, limit, delta, n_slots, dist, done, sink_dist):
        """One search; returns the number of vertices settled. Bucket queue if delta > 0 else heap."""
        n = indptr.size - 1
        for i in range(n):
            dist[i] = np.inf
            done[i] = False
        for j in range(sink_dist.size):
            sink_dist[j] = np.inf
        for k in range(direct_to.size):
            sink_dist[direct_to[k]] = direct_d[k]
        settled = 0
        remaining = n_needed
        use_buckets = delta > 0.0
        # --- queue storage: bucket lists (linked entries) or binary heap, both growable
        cap = 1024
        e_node = np.empty(cap, np.int64)
        e_key = np.empty(cap, np.float64)
        e_next = np.empty(cap, np.int64)
        head = np.full(n_slots if use_buckets else 1, -1, np.int64)
        free = -1
        used = 0
        size = 0  # live entries
        for k in range(st_v.size):
            v = st_v[k]
            if st_d[k] < dist[v]:
                dist[v] = st_d[k]
        for k in range(st_v.size):
            v = st_v[k]
            d = dist[v]
            if d != st_d[k]:
                continue
            # push v
            if use_buckets:
                if free >= 0:
                    slot_e = free
                    free = e_next[free]
                else:
                    if used == e_node.size:
                        e_node = np.concatenate((e_node, np.empty(e_node.size, np.int64)))
                        e_next = np.concatenate((e_next, np.empty(e_next.size, np.int64)))
                    slot_e = used
                    used += 1
                b = np.int64(d / delta) % n_slots
                e_node[slot_e] = v
                e_next[slot_e] = head[b]
                head[b] = slot_e
                size += 1
            else:
                if size == e_node.size:
                    e_node = np.concatenate((e_node, np.empty(e_node.size, np.int64)))
                    e_key = np.concatenate((e_key, np.empty(e_key.size, np.float64)))
                i = size
                size += 1
                while i > 0:
                    par = (i - 1) >> 1
                    if e_key[par] <= d:
                        break
                    e_key[i] = e_key[par]
                    e_node[i] = e_node[par]
                    i = par
                e_key[i] = d
                e_node[i] = v
        bucket = np.int64(0)
        if use_buckets and st_d.size > 0:
            bucket = np.int64(np.min(st_d) / delta)
        while size > 0:
            # ---- pop
            if use_buckets:
                b = bucket % n_slots
                while head[b] < 0:
                    bucket += 1
                    b = bucket % n_slots
                ent = head[b]
                head[b] = e_next[ent]
                v = e_node[ent]
                e_next[ent] = free
                free = ent
                size -= 1
                if done[v]:
                    continue
                d = dist[v]
                if bucket * delta > limit:
                    break
                if d > limit:  # same bucket, beyond the limit: others in it may not be
                    continue
            else:
                v = e_node[0]
                d = e_key[0]
                size -= 1
                lk = e_key[size]
                lv = e_node[size]
                i = 0
                while True:
                    c = 2 * i + 1
                    if c >= size:
                        break
                    if c + 1 < size and e_key[c + 1] < e_key[c]:
                        c += 1
                    if e_key[c] >= lk:
                        break
                    e_key[i] = e_key[c]
                    e_node[i] = e_node[c]
                    i = c
                e_key[i] = lk
                e_node[i] = lv
                if done[v] or d > dist[v]:
                    continue
            if d > limit:
                break
            done[v] = True
            settled += 1
            for k in range(sink_ptr[v], sink_ptr[v + 1]):
                nd = d + sink_w[k]
                if nd < sink_dist[sink_src[k]]:
                    sink_dist[sink_src[k]] = nd
            if n_needed > 0 and needed[v]:
                remaining -= 1
                if remaining == 0:
                    break
            for k in range(indptr[v], indptr[v + 1]):
                u = indices[k]
                if done[u]:
                    continue
                nd = d + weights[k]
                if nd < dist[u]:
                    dist[u] = nd
                    if use_buckets:
                        if free >= 0:
                            slot_e = free
                            free = e_next[free]
                        else:
                            if used == e_node.size:
                                e_node = np.concatenate((e_node, np.empty(e_node.size, np.int64)))
                                e_next = np.concatenate((e_next, np.empty(e_next.size, np.int64)))
                            slot_e = used
                            used += 1
                        b = np.int64(nd / delta) % n_slots
                        e_node[slot_e] = u
                        e_next[slot_e] = head[b]
                        head[b] = slot_e
                        size += 1
                    else:
                        if size == e_node.size:
                            e_node = np.concatenate((e_node, np.empty(e_node.size, np.int64)))
                            e_key = np.concatenate((e_key, np.empty(e_key.size, np.float64)))
                        i = size
                        size += 1
                        while i > 0:
                            par = (i - 1) >> 1
                            if e_key[par] <= nd:
                                break
                            e_key[i] = e_key[par]
                            e_node[i] = e_node[par]
                            i = par
                        e_key[i] = nd
                        e_node[i] = u
        return settled

    @_nb.njit(cache=CACHE, parallel=True)
    def _sssp_many(indptr, indices, weights, start_ptr, start_v, start_d, sink_ptr, sink_src, sink_w,
                   direct_ptr, direct_to, direct_d, needed, n_needed, limit, delta, n_slots,
                   out_v, out_s, settled):
        n = indptr.size - 1
        n_src = start_ptr.size - 1
        for s in _nb.prange(n_src):
            dist = np.empty(n, np.float64)
            done = np.empty(n, np.bool_)
            sink_dist = np.empty(n_src, np.float64)
            a, b = start_ptr[s], start_ptr[s + 1]
            settled[s] = _sssp_one(indptr, indices, weights, start_v[a:b], start_d[a:b],
                                   sink_ptr, sink_src, sink_w,
                                   direct_to[direct_ptr[s]:direct_ptr[s + 1]],
                                   direct_d[direct_ptr[s]:direct_ptr[s + 1]],
                                   needed, n_needed, limit, delta, n_slots, dist, done, sink_dist)
            row = out_v[s]
            for i in range(n):
                row[i] = dist[i] if done[i] else np.inf
            lim = limit if n_needed == 0 else np.inf
            for j in range(n_src):
                out_s[s, j] = sink_dist[j] if sink_dist[j] <= lim else np.inf
            out_s[s, s] = 0.0


def _bucket_width(graph) -> tuple[float, int]:
    """Bucket width and slot count for the bucket queue, or (0, 1) to use the heap."""
    w = graph.data
    if w.size == 0:
        return 0.0, 1
    wmin, wmax = float(w.min()), float(w.max())
    if not wmin > 0.0:
        return 0.0, 1
    slots = int(np.ceil(wmax / wmin)) + 2
    # a pass over the buckets costs (path length / wmin); keep it within a few times N
    n = graph.shape[0]
    if slots > 4096 or slots * np.sqrt(n) > 64.0 * n + 4096:
        return 0.0, 1
    return wmin, slots


def multi_source_shortest_paths(graph, points, source_tri_vertices, source_barycentrics, *,
                                needed=None, limit: float = np.inf, dtype=np.float64,
                                engine: str = "auto"):
    """Shortest edge-path distances from surface-point sources (paper Eq. 7), one search each.

    Parameters
    ----------
    graph : scipy.sparse.csr_matrix, shape (N, N)
        Symmetric edge graph (:func:`edge_graph`).
    points : array_like, shape (N, 3)
    source_tri_vertices, source_barycentrics : array_like, shape (S, 3)
        Surface-point sources; each starts from its triangle's vertices at their Euclidean
        distance from the point.
    needed : array_like of bool, shape (N,), optional
        Vertices whose distances are needed: each search stops once all of them are settled
        (entries of other vertices are then +inf or exact, whichever the search reached). The
        distances between sources are exact only for sources whose triangle vertices are needed.
    limit : float
        Stop each search at this distance (entries beyond are +inf), like scipy's ``limit``.
    dtype : {numpy.float64, numpy.float32}
        Type of the vertex matrix.
    engine : {"auto", "numba", "scipy"}
        ``"scipy"`` runs scipy.sparse.csgraph.dijkstra on :func:`augmented_graph` (no ``needed``
        early stop).

    Returns
    -------
    vertex : ndarray, shape (N, S)
        Fortran-ordered (a transposed (S, N) array; no copy made).
    sources : ndarray, shape (S, S), float64
        ``sources[i, j]`` = distance from source i to source j (exact graph distance).
    settled : ndarray, shape (S,), int64
        Vertices each search settled (the work done).
    """
    import scipy.sparse as sp
    from scipy.sparse import csgraph

    g = sp.csr_matrix(graph)
    n = g.shape[0]
    tri = np.asarray(source_tri_vertices, dtype=np.int64).reshape(-1, 3)
    s = tri.shape[0]
    if engine == "auto":
        engine = "numba" if HAVE_NUMBA else "scipy"
    if engine == "numba" and not HAVE_NUMBA:
        raise InputError("engine='numba' needs numba (pip install numba)")
    if engine == "scipy":
        aug = augmented_graph(g, points, tri, source_barycentrics)
        d = csgraph.dijkstra(aug, directed=True, indices=n + np.arange(s), limit=limit)
        vertex = d[:, :n].astype(dtype, copy=False).T
        srcs = np.array(d[:, n + s:], dtype=np.float64)
        np.fill_diagonal(srcs, 0.0)
        settled = np.isfinite(d[:, :n]).sum(axis=1).astype(np.int64)
        return vertex, srcs, settled
    start_ptr, sv, sd, sink_ptr, sink_src, sink_w, direct = source_starts(points, tri, source_barycentrics)
    if direct.size:
        order = np.lexsort((direct[:, 1], direct[:, 0]))
        direct = direct[order]
    dsrc = direct[:, 0].astype(np.int64)
    direct_ptr = np.zeros(s + 1, dtype=np.int64)
    np.cumsum(np.bincount(dsrc, minlength=s), out=direct_ptr[1:])
    direct_to = direct[:, 1].astype(np.int64)
    direct_d = direct[:, 2].astype(np.float64)
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
    delta, slots = _bucket_width(g)
    out_v = np.empty((s, n), dtype=dtype)
    out_s = np.empty((s, s), dtype=np.float64)
    settled = np.zeros(s, dtype=np.int64)
    indices = g.indices.astype(np.int32, copy=False)
    indptr = g.indptr.astype(np.int64, copy=False)
    notice_compiling("the geodesic search kernels", _sssp_many)
    old_chunk = _nb.get_parallel_chunksize()
    _nb.set_parallel_chunksize(1)   # hand sources out one at a time: balanced when CPUs are shared
    try:
        _sssp_many(indptr, indices, g.data.astype(np.float64, copy=False), start_ptr, sv, sd, sink_ptr, sink_src,
                   sink_w, direct_ptr, direct_to, direct_d, need, n_needed,
                   float(limit), float(delta), int(slots), out_v, out_s, settled)
    finally:
        _nb.set_parallel_chunksize(old_chunk)
    return out_v.T, out_s, settled

