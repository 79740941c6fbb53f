"""The update tables of the fast-marching search (:mod:`usdface.distance.marching`), built once per mesh.

Two tables, both in compressed rows over the vertices:

- the *wedges*: every corner v of every triangle (v, a, b), with the triangle laid flat around v
  (v at the origin, a on the x axis, b below it): what v's settling offers a and b;
- the *splits* of obtuse corners (Kimmel and Sethian 1998, Sec. 4): a corner b wider than 90
  degrees gets two virtual triangles (b, u, w) and (b, w, a), w a vertex unfolded from the
  triangles across the opposite edge into b's plane until it falls within 90 degrees of both of b's
  edges.

Every pass is a numba kernel over the triangles (no sort: the rows are filled by counting), so
the tables of a 560k-vertex face build in about half a second; the geometry is computed in
float64 and stored in float32 (it halves the memory the searches stream through). The passes run
on one thread: they are bound by memory, and parallel ones ran twice as long when other processes
shared the CPUs (1.3 s against 0.7 s at a load average of 6).
"""
from __future__ import annotations

import numpy as np

from ..errors import InputError
from ..numba_cache import AVAILABLE as HAVE_NUMBA
from ..numba_cache import njit, notice_compiling

__all__ = ["HAVE_NUMBA", "MarchingMesh", "marching_mesh_bytes", "morton_order", "search_bytes"]

#: the 24-byte rows of :attr:`MarchingMesh.wedges` and :attr:`MarchingMesh.splits`: two int32
#: vertex indices (read through an int32 view of the same memory), then four float32 lengths
WEDGE_COLUMNS = ("a", "b", "la", "lb", "bx", "by")
SPLIT_COLUMNS = ("u", "w", "luw", "lwb", "bx", "by")
#: unfolding gives up after this many triangles (the corner then keeps its real triangle only)
MAX_UNFOLD = 12


class MarchingMesh:
    """The update tables of one triangle mesh, built once and shared by every search.

    The tables number the vertices in their own order, along a space-filling (Morton) curve, so
    that the vertices a search visits one after the other lie close in memory whatever order the
    mesh file has (a shuffled vertex order made the search 2.6x slower on the 560k-vertex face).

    Parameters
    ----------
    points : array_like, shape (N, 3), float
        Vertex positions, mesh units.
    triangles : array_like, shape (T, 3), int
    max_unfold : int
        Triangles an obtuse corner's unfolding may cross.

    Attributes
    ----------
    n_points : int
    order : ndarray, shape (N,), int64
        The mesh's vertex at each position of the tables' order.
    rank : ndarray, shape (N,), int64
        The position of each of the mesh's vertices in the tables' order (``rank[order] = 0..N-1``).
    points : ndarray, shape (N, 3), float64
        The vertices in the tables' order.
    ptr : ndarray, shape (N + 1,), int64
        Wedges of vertex v (tables' order): rows ``ptr[v]:ptr[v + 1]``, in triangle order.
    wedges : ndarray, shape (W, 6), float32
        One row per corner v of each triangle (v, a, b), :data:`WEDGE_COLUMNS`: a and b (int32,
        tables' order; :attr:`wedge_vertices`), ``|va|``, ``|vb|`` and b at (bx, by) in the frame
        v = origin, a on +x, by <= 0 (:attr:`wedge_geom`). Mesh units. (a in the frame v = origin,
        b on +x is ``(bx, by) |va| / |vb|``.)
    sptr : ndarray, shape (N + 1,), int64
        Split rows targeting vertex b (tables' order): ``sptr[b]:sptr[b + 1]``.
    splits : ndarray, shape (K, 6), float32
        One row per virtual triangle (u, w) of an obtuse corner b, :data:`SPLIT_COLUMNS`: u and w
        (int32; :attr:`split_vertices`), ``|uw|``, ``|wb|`` (unfolded) and b at (bx, by) in the
        frame u = origin, w on +x, by <= 0 (:attr:`split_geom`).
    n_obtuse, n_split : int
        Obtuse corners, and those split (the others keep their real triangle's update only).
    """

    _arrays = ("ptr", "wedges", "sptr", "splits")

    def __init__(self, points, triangles, *, max_unfold: int = MAX_UNFOLD):
        if not HAVE_NUMBA:  # pragma: no cover
            raise InputError("backend='fmm' needs numba (pip install numba)")
        p = np.ascontiguousarray(points, dtype=np.float64)
        n = p.shape[0]
        self.n_points = n
        notice_compiling("the geodesic search kernels", _wedge_tables, _split_tables, _rows_by_target)
        self.order = morton_order(p)
        self.rank = np.empty(n, dtype=np.int64)
        self.rank[self.order] = np.arange(n)
        self.points = p = p[self.order]
        t = self.rank[np.asarray(triangles, dtype=np.int64).reshape(-1, 3)]
        self.ptr, self.wedges = _wedge_tables(p, t, n)
        counts = np.zeros(2, dtype=np.int64)
        slot_b, slots = _split_tables(p, t, self.ptr, self.wedges.view(np.int32), int(max_unfold), counts)
        self.sptr, self.splits = _rows_by_target(slot_b, slots, n)
        self.n_obtuse, self.n_split = int(counts[0]), int(counts[1])

    @property
    def nbytes(self) -> int:
        return sum(getattr(self, k).nbytes for k in self._arrays)

    @property
    def wedge_vertices(self) -> np.ndarray:
        """(W, 2) int32 view: a and b of each wedge (tables' order)."""
        return self.wedges.view(np.int32)[:, :2]

    @property
    def wedge_geom(self) -> np.ndarray:
        """(W, 4) float32 view: ``|va|``, ``|vb|``, bx, by of each wedge."""
        return self.wedges[:, 2:]

    @property
    def split_vertices(self) -> np.ndarray:
        """(K, 2) int32 view: u and w of each split row (tables' order)."""
        return self.splits.view(np.int32)[:, :2]

    @property
    def split_geom(self) -> np.ndarray:
        """(K, 4) float32 view: ``|uw|``, ``|wb|``, bx, by of each split row."""
        return self.splits[:, 2:]

    @property
    def mean_edge(self) -> float:
        """Mean length of the wedges' sides (mesh units; 0 for a mesh without one)."""
        return float(self.wedges[:, 2].mean(dtype=np.float64)) if self.wedges.size else 0.0

    def tables(self) -> tuple:
        """The arrays the search kernel reads: ptr, wedges (int32 view, float32), sptr, splits
        (int32 view, float32)."""
        return self.ptr, self.wedges.view(np.int32), self.wedges, self.sptr, self.splits.view(np.int32), self.splits


def marching_mesh_bytes(n_points: int, n_triangles: int) -> int:
    """Upper bound of :class:`MarchingMesh`'s memory for a mesh of this size (bytes), including
    the temporaries of building it."""
    wedges = 3 * n_triangles * 24
    splits = 2 * n_triangles * 24                 # at most one obtuse corner per triangle, 2 splits
    # corner slots (int64, 3 per triangle), split slots (target int64 + a row)
    build = n_triangles * (3 * 8 + 2 * (8 + 24)) + 8 * (n_points + 1)
    reorder = n_points * (8 + 8 + 24) + n_triangles * 3 * 8 * 2    # order, rank, points, renumbered triangles
    return 2 * 8 * (n_points + 1) + wedges + splits + build + reorder


def search_bytes(n_points: int) -> int:
    """Scratch memory of one running search (distance and settled flag per vertex), bytes; the
    bucket queue holds only the front (small)."""
    return n_points * (8 + 1)


def morton_order(points) -> np.ndarray:
    """(N,) int64 vertex order along a Morton (Z-order) curve through the bounding box: points
    close in the order are close in space. 10 bits per axis (a 1024^3 grid: cells about one edge
    long on a 560k-vertex face); points in one cell keep their input order."""
    p = np.ascontiguousarray(points, dtype=np.float64)
    if p.shape[0] == 0:
        return np.zeros(0, dtype=np.int64)
    return _morton_order(p)


@njit(cache=True, nogil=True, inline="always")
def _spread_bits(x):
    """Bits 0-9 of x moved to bits 0, 3, 6, ..., 27."""
    x = x & 0x3FF
    x = (x | (x << 16)) & 0x30000FF
    x = (x | (x << 8)) & 0x300F00F
    x = (x | (x << 4)) & 0x30C30C3
    x = (x | (x << 2)) & 0x9249249
    return x


@njit(cache=True, nogil=True)
def _morton_order(p):
    """Morton codes (30 bits) and a stable radix sort by them (two 15-bit passes)."""
    n = p.shape[0]
    lo = p[0].copy()
    hi = p[0].copy()
    for i in range(n):
        for k in range(3):
            lo[k] = min(lo[k], p[i, k])
            hi[k] = max(hi[k], p[i, k])
    span = max(hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2])
    scale = 1023.0 / span if span > 0 else 0.0
    code = np.empty(n, np.int64)
    for i in range(n):
        c = 0
        for k in range(3):
            c |= _spread_bits(np.int64((p[i, k] - lo[k]) * scale)) << k
        code[i] = c
    order = np.arange(n)
    other = np.empty(n, np.int64)
    count = np.empty((1 << 15) + 1, np.int64)
    for shift in (0, 15):
        count[:] = 0
        for i in range(n):
            count[((code[order[i]] >> shift) & 0x7FFF) + 1] += 1
        for j in range(1 << 15):
            count[j + 1] += count[j]
        for i in range(n):
            digit = (code[order[i]] >> shift) & 0x7FFF
            other[count[digit]] = order[i]
            count[digit] += 1
        order, other = other, order
    return order


@njit(cache=True, nogil=True)
def _wedge_tables(p, t, n):
    """The wedge rows (see :class:`MarchingMesh`): each vertex's corners in triangle order.

    Parameters
    ----------
    p : (N, 3) float64; t : (T, 3) int64; n : int, N

    Returns
    -------
    ptr : (N + 1,) int64 row offsets; (W, 6) float32 wedge rows (:data:`WEDGE_COLUMNS`).
    """
    nt = t.shape[0]
    # rows by counting (a stable counting sort of the corners by vertex), then the geometry of
    # every corner
    ptr = np.zeros(n + 1, np.int64)
    slot = np.full(3 * nt, -1, np.int64)
    for f in range(nt):
        if t[f, 0] != t[f, 1] and t[f, 1] != t[f, 2] and t[f, 0] != t[f, 2]:
            for c in range(3):
                ptr[t[f, c] + 1] += 1
    for v in range(n):
        ptr[v + 1] += ptr[v]
    fill = ptr[:-1].copy()
    for f in range(nt):
        if t[f, 0] != t[f, 1] and t[f, 1] != t[f, 2] and t[f, 0] != t[f, 2]:
            for c in range(3):
                slot[3 * f + c] = fill[t[f, c]]
                fill[t[f, c]] += 1
    wg = np.empty((ptr[n], 6), np.float32)
    wv = wg.view(np.int32)
    for f in range(nt):
        for c in range(3):
            k = slot[3 * f + c]
            if k < 0:
                continue
            v = t[f, c]
            a = t[f, (c + 1) % 3]
            b = t[f, (c + 2) % 3]
            ax = p[a, 0] - p[v, 0]
            ay = p[a, 1] - p[v, 1]
            az = p[a, 2] - p[v, 2]
            bx = p[b, 0] - p[v, 0]
            by = p[b, 1] - p[v, 1]
            bz = p[b, 2] - p[v, 2]
            la = np.sqrt(ax * ax + ay * ay + az * az)
            lb = np.sqrt(bx * bx + by * by + bz * bz)
            cx = ay * bz - az * by
            cy = az * bx - ax * bz
            cz = ax * by - ay * bx
            sin_ = np.sqrt(cx * cx + cy * cy + cz * cz)
            cos_ = ax * bx + ay * by + az * bz
            norm = np.hypot(cos_, sin_)
            # a flat triangle (zero area) keeps its edges: a straight angle; a zero-length side
            # gives edge candidates only (the triangle update refuses L = 0)
            if norm <= 0.0:
                cos_, sin_, norm = 1.0, 0.0, 1.0
            cos_ /= norm
            sin_ /= norm
            wv[k, 0] = a
            wv[k, 1] = b
            wg[k, 2] = la
            wg[k, 3] = lb
            wg[k, 4] = lb * cos_
            wg[k, 5] = -lb * sin_
    return ptr, wg


@njit(cache=True, nogil=True)
def _rows_by_target(slot_b, slots, n):
    """The filled split slots as rows grouped by target vertex (a stable counting sort).

    Returns
    -------
    sptr : (N + 1,) int64; (K, 6) float32 split rows (:data:`SPLIT_COLUMNS`).
    """
    sptr = np.zeros(n + 1, np.int64)
    for i in range(slot_b.size):
        if slot_b[i] >= 0:
            sptr[slot_b[i] + 1] += 1
    for v in range(n):
        sptr[v + 1] += sptr[v]
    rows = np.empty((sptr[n], 6), np.float32)
    out = rows.view(np.int32)          # copied bit for bit: two of the columns are integers
    src = slots.view(np.int32)
    fill = sptr[:-1].copy()
    for i in range(slot_b.size):
        b = slot_b[i]
        if b < 0:
            continue
        k = fill[b]
        fill[b] += 1
        for j in range(6):
            out[k, j] = src[i, j]
    return sptr, rows


@njit(cache=True, nogil=True, inline="always")
def _across(ptr, wv, cu, ca, x):
    """The third vertex of a triangle on edge (cu, ca) other than x (the first in cu's wedges:
    the triangle across the edge from x on a manifold mesh), -1 on a border."""
    for k in range(ptr[cu], ptr[cu + 1]):
        a = wv[k, 0]
        b = wv[k, 1]
        if a == ca and b != x:
            return b
        if b == ca and a != x:
            return a
    return -1


@njit(cache=True, nogil=True, inline="always")
def _emit(slot_b, slots, k, b, u, w, ux, uy, wx, wy):
    """Slot k = virtual triangle (u at (ux, uy), w at (wx, wy)) of target b at the origin;
    left empty (b = -1) when degenerate."""
    ex = wx - ux
    ey = wy - uy
    lo = np.sqrt(ex * ex + ey * ey)
    lu = np.sqrt(ux * ux + uy * uy)
    lw = np.sqrt(wx * wx + wy * wy)
    if lo <= 0.0 or lu <= 0.0 or lw <= 0.0:
        return
    cos_u = (-ex * ux - ey * uy) / (lo * lu)
    sin_u = abs(-ex * uy + ey * ux) / (lo * lu)
    slot_b[k] = b
    ints = slots.view(np.int32)
    ints[k, 0] = u
    ints[k, 1] = w
    slots[k, 2] = lo
    slots[k, 3] = lw
    slots[k, 4] = lu * cos_u
    slots[k, 5] = -lu * sin_u


@njit(cache=True, nogil=True)
def _unfold(p, ptr, wv, b, u, a, ux, ax, ay, max_unfold):
    """Unfold the triangles across edge (u, a) of the obtuse corner b into b's plane (b at the
    origin, u at (ux, 0), a at (ax, ay)) until a vertex w falls within 90 degrees of both b -> u
    and b -> a. Returns (w, wx, wy), w = -1 when none is found."""
    cu, ca = u, a                    # the edge crossed next: cu at (px, py), ca at (qx, qy)
    px, py, qx, qy = ux, 0.0, ax, ay
    behind = b                       # the vertex behind that edge, at (xx, yy)
    xx, xy = 0.0, 0.0
    for _ in range(max_unfold):
        w = _across(ptr, wv, cu, ca, behind)
        if w < 0 or w == b:
            break
        luw2 = 0.0
        law2 = 0.0
        for d in range(3):
            luw2 += (p[w, d] - p[cu, d]) ** 2
            law2 += (p[w, d] - p[ca, d]) ** 2
        ex = qx - px
        ey = qy - py
        L = np.sqrt(ex * ex + ey * ey)
        if L <= 0.0:
            break
        ex /= L
        ey /= L
        x = (luw2 - law2 + L * L) / (2.0 * L)
        y = np.sqrt(max(0.0, luw2 - x * x))
        nx, ny = -ey, ex             # w goes on the side of the edge away from the vertex behind
        if (xx - px) * nx + (xy - py) * ny > 0.0:
            nx, ny = -nx, -ny
        cx = px + x * ex + y * nx
        cy = py + x * ey + y * ny
        in_u = cx >= 0.0                     # within 90 degrees of b -> u
        in_a = cx * ax + cy * ay >= 0.0      # within 90 degrees of b -> a
        if in_u and in_a:
            return w, cx, cy
        if not in_u:        # past the section on a's side: cross edge (cu, w) next
            behind, xx, xy = ca, qx, qy
            ca = w
            qx, qy = cx, cy
        else:               # on u's side: cross edge (w, ca) next
            behind, xx, xy = cu, px, py
            cu = w
            px, py = cx, cy
    return -1, 0.0, 0.0


@njit(cache=True, nogil=True)
def _split_tables(p, t, ptr, wv, max_unfold, counts):
    """Two slots per triangle (a triangle has at most one obtuse corner): target b (-1 for an
    empty slot) and the row (:data:`SPLIT_COLUMNS`). ``counts`` receives (obtuse corners, split
    corners)."""
    nt = t.shape[0]
    slot_b = np.full(2 * nt, -1, np.int64)
    slots = np.empty((2 * nt, 6), np.float32)
    obtuse = np.zeros(nt, np.int64)
    split = np.zeros(nt, np.int64)
    for f in range(nt):
        for c in range(3):
            b = t[f, c]
            u = t[f, (c + 1) % 3]
            a = t[f, (c + 2) % 3]
            if b == u or b == a or u == a:
                continue
            vux = p[u, 0] - p[b, 0]
            vuy = p[u, 1] - p[b, 1]
            vuz = p[u, 2] - p[b, 2]
            vax = p[a, 0] - p[b, 0]
            vay = p[a, 1] - p[b, 1]
            vaz = p[a, 2] - p[b, 2]
            lu = np.sqrt(vux * vux + vuy * vuy + vuz * vuz)
            la = np.sqrt(vax * vax + vay * vay + vaz * vaz)
            if lu <= 0.0 or la <= 0.0:
                continue
            cb = (vux * vax + vuy * vay + vuz * vaz) / (lu * la)
            if cb >= -1e-9 or obtuse[f] > 0:
                continue
            obtuse[f] = 1
            # b at the origin, u on the x axis, a at angle beta > 90 degrees
            ax = la * cb
            ay = la * np.sqrt(max(0.0, 1.0 - cb * cb))
            w, wx, wy = _unfold(p, ptr, wv, b, u, a, lu, ax, ay, max_unfold)
            if w < 0 or w == u or w == a:
                continue
            split[f] = 1
            _emit(slot_b, slots, 2 * f, b, u, w, lu, 0.0, wx, wy)
            _emit(slot_b, slots, 2 * f + 1, b, a, w, ax, ay, wx, wy)
    counts[0] = obtuse.sum()
    counts[1] = split.sum()
    return slot_b, slots
