"""Rasterisation for the preview renderer: triangles to a triangle-index and depth buffer.

:func:`rasterize` scan-converts every triangle over the pixel centres of its bounding box (a
pixel belongs to a triangle when its centre is inside or on an edge) with a z-buffer keeping the
nearest surface per pixel, whatever the drawing order: the numba kernel of
:mod:`usdface.preview._kernels` when numba is installed, else vectorised numpy
(:func:`_rasterize_numpy`, also the reference the tests compare the kernel with).
:func:`render_buffers` projects a mesh through a :class:`~usdface.preview.camera.Camera` into
:class:`Buffers`; :func:`point_visibility` tests points against them. No pxr, no OpenCV.
"""
from __future__ import annotations

import threading
from dataclasses import dataclass

import numpy as np

from ..errors import MeshError
from ._common import _compiled, _cv2
from .camera import Camera

# ================================================================================================
# rasterisation
# ================================================================================================
def rasterize(xy: np.ndarray, zkey: np.ndarray, triangles: np.ndarray, size, *,
              max_candidates: int = 1 << 16) -> tuple[np.ndarray, np.ndarray]:
    """Z-buffered scan conversion of triangles given in image coordinates.

    Runs the compiled kernel of :mod:`usdface.preview._kernels` when numba is installed (same
    result, bit for bit, as the vectorised numpy version :func:`_rasterize_numpy`, which it
    falls back to).

    Parameters
    ----------
    xy : ndarray, shape (N, 2)
        Vertex image positions (x right, y down; pixel (i, j) has its centre at (j + .5, i + .5)).
        Triangles with a non-finite vertex are skipped.
    zkey : ndarray, shape (N,)
        Per-vertex depth key, linear in image space, smaller = nearer: the depth for an
        orthographic camera, ``-1 / depth`` for a perspective one.
    triangles : ndarray, shape (T, 3), int
        Vertex indices.
    size : (int, int)
        Image (width, height).
    max_candidates : int
        Pixels processed per vectorised chunk (bounds memory: ~100 bytes each).

    Returns
    -------
    triangle : ndarray, shape (H, W), int32
        Index of the nearest triangle covering each pixel centre, -1 for background.
    zbuf : ndarray, shape (H, W), float64
        Its interpolated ``zkey``; +inf for background.

    Notes
    -----
    Scanline spans, vectorised over all triangles: for every pixel row whose centre line crosses a
    triangle, the three edge half-planes give the covered x-interval, and only covered pixels are
    generated. A pixel is covered when its centre lies inside the triangle or on an edge; edge
    crossings are computed in a canonical form, so triangles sharing an edge leave neither cracks
    nor gaps. Depth ties go to the later triangle. Cost is proportional to the number of covered
    pixels (with overdraw) plus the number of triangle rows.
    """
    kernels = _compiled()
    if kernels is not None:
        w, h = (int(s) for s in size)
        tri_index = np.full((h, w), -1, dtype=np.int32)
        zbuf = np.full((h, w), np.inf)
        _rasterize_compiled(kernels, xy, zkey, triangles, tri_index, zbuf)
        return tri_index, zbuf
    return _rasterize_numpy(xy, zkey, triangles, size, max_candidates=max_candidates)


_NO_BOX = (0, -1, 0, -1)


def _rasterize_compiled(kernels, xy, zkey, triangles, tri_index, zbuf, stale=_NO_BOX) -> tuple[np.ndarray, tuple]:
    """The compiled rasteriser into ``tri_index`` / ``zbuf`` ((H, W), holding -1 / +inf, except
    old depths inside the box ``stale``); returns the triangles' facing (T,) bool and the box of
    covered pixels (first/last row, first/last column)."""
    h, w = tri_index.shape
    tri = np.ascontiguousarray(np.asarray(triangles, dtype=np.int64).reshape(-1, 3))
    front = np.empty(tri.shape[0], dtype=bool)
    box = np.empty(4, dtype=np.int64)
    kernels.rasterize_kernel(np.ascontiguousarray(xy, dtype=np.float64), np.ascontiguousarray(zkey, dtype=np.float64),
                             tri, w, h, tri_index.reshape(-1), zbuf.reshape(-1), front, box,
                             np.asarray(stale, dtype=np.int64))
    return front, tuple(int(v) for v in box)


def _rasterize_numpy(xy: np.ndarray, zkey: np.ndarray, triangles: np.ndarray, size, *,
                     max_candidates: int = 1 << 16) -> tuple[np.ndarray, np.ndarray]:
    """:func:`rasterize` in vectorised numpy (the reference of the compiled kernel)."""
    w, h = (int(s) for s in size)
    xy = np.asarray(xy, dtype=np.float64)
    z = np.asarray(zkey, dtype=np.float64)
    tri = np.asarray(triangles, dtype=np.int64).reshape(-1, 3)
    tri_index = np.full(h * w, -1, dtype=np.int32)
    zbuf = np.full(h * w, np.inf)
    if tri.shape[0] == 0:
        return tri_index.reshape(h, w), zbuf.reshape(h, w)
    x, y, zt = xy[tri, 0], xy[tri, 1], z[tri]
    with np.errstate(invalid="ignore"):
        e1x, e1y = x[:, 1] - x[:, 0], y[:, 1] - y[:, 0]
        e2x, e2y = x[:, 2] - x[:, 0], y[:, 2] - y[:, 0]
        area = e1x * e2y - e2x * e1y
        ok = np.isfinite(area) & np.isfinite(zt).all(axis=1) & (area != 0)
        rmin = np.ceil(y.min(axis=1) - 0.5)  # first and last pixel rows whose centre is in range
        rmax = np.floor(y.max(axis=1) - 0.5)
        ok &= (rmax >= 0) & (rmin <= h - 1) & (rmax >= rmin)
        ok &= (x.max(axis=1) >= 0.5) & (x.min(axis=1) <= w - 0.5)
    ids = np.flatnonzero(ok)
    if ids.size == 0:
        return tri_index.reshape(h, w), zbuf.reshape(h, w)
    r0 = np.clip(rmin[ids], 0, h - 1).astype(np.int64)
    nrow = np.clip(rmax[ids], 0, h - 1).astype(np.int64) - r0 + 1
    # depth plane z = z0 + gx (x - x0) + gy (y - y0)
    a_ = area[ids]
    dz1, dz2 = zt[ids, 1] - zt[ids, 0], zt[ids, 2] - zt[ids, 0]
    gx = (dz1 * e2y[ids] - dz2 * e1y[ids]) / a_
    gy = (dz2 * e1x[ids] - dz1 * e2x[ids]) / a_
    # edges v0->v1, v1->v2, v2->v0 in a canonical form (low-y endpoint first) so that two
    # triangles sharing an edge compute bit-identical crossings: no cracks, no double gaps
    xa, ya = x[ids], y[ids]
    xb, yb = np.roll(xa, -1, axis=1), np.roll(ya, -1, axis=1)
    swap = yb < ya
    xl, yl = np.where(swap, xb, xa), np.where(swap, yb, ya)
    xh, yh = np.where(swap, xa, xb), np.where(swap, ya, yb)
    dy = yh - yl
    horizontal = dy == 0
    with np.errstate(divide="ignore", invalid="ignore"):
        slope = np.where(horizontal, 0.0, (xh - xl) / np.where(horizontal, 1.0, dy))
    sgn = np.sign(a_)[:, None]
    # inside <=> sgn * ((xb-xa)(py-ya) - (yb-ya)(px-xa)) >= 0
    kind = sgn * (yb - ya)  # > 0: crossing is an upper bound of x; < 0: a lower bound
    hsign = sgn * (xb - xa)  # horizontal edge: inside <=> hsign * (py - ya) >= 0
    row_cum = np.cumsum(nrow)
    t_start = 0
    while t_start < ids.size:  # chunks of triangles bounded by their number of rows
        base = row_cum[t_start - 1] if t_start else 0
        t_stop = max(int(np.searchsorted(row_cum, base + max_candidates // 4, side="right")), t_start + 1)
        sl = slice(t_start, t_stop)
        nr = nrow[sl]
        rt = np.repeat(np.arange(t_stop - t_start), nr)  # chunk-local triangle of each row
        row = r0[sl][rt] + (np.arange(rt.size) - (np.cumsum(nr) - nr)[rt])
        yc = row + 0.5
        lo = np.full(rt.size, -np.inf)
        hi = np.full(rt.size, np.inf)
        for e in range(3):
            te = t_start + rt
            xc = xl[te, e] + (yc - yl[te, e]) * slope[te, e]
            k = kind[te, e]
            lo = np.where(k < 0, np.maximum(lo, xc), lo)
            hi = np.where(k > 0, np.minimum(hi, xc), hi)
            dead = horizontal[te, e] & (hsign[te, e] * (yc - ya[te, e]) < 0)
            lo[dead] = np.inf
        with np.errstate(invalid="ignore"):
            j0 = np.maximum(np.ceil(lo - 0.5), 0.0)
            j1 = np.minimum(np.floor(hi - 0.5), w - 1.0)
            cnt = np.where(j1 >= j0, j1 - j0 + 1, 0.0).astype(np.int64)
        live = np.flatnonzero(cnt)
        rt, row, yc, j0, cnt = rt[live], row[live], yc[live], j0[live].astype(np.int64), cnt[live]
        te = t_start + rt
        zrow = zt[ids[te], 0] + gx[te] * (j0 + 0.5 - xa[te, 0]) + gy[te] * (yc - ya[te, 0])
        pix_cum = np.cumsum(cnt)
        r_start = 0
        while r_start < rt.size:  # chunks of rows bounded by their number of pixels
            pbase = pix_cum[r_start - 1] if r_start else 0
            r_stop = max(int(np.searchsorted(pix_cum, pbase + max_candidates, side="right")), r_start + 1)
            rs = slice(r_start, r_stop)
            c = cnt[rs]
            pr = np.repeat(np.arange(r_stop - r_start), c)
            kk = np.arange(pr.size) - (np.cumsum(c) - c)[pr]
            pix = row[rs][pr] * w + j0[rs][pr] + kk
            depth = zrow[rs][pr] + gx[te[rs]][pr] * kk
            np.minimum.at(zbuf, pix, depth)
            win = depth <= zbuf[pix]
            tri_index[pix[win]] = ids[te[rs]][pr[win]]
            r_start = r_stop
        t_start = t_stop
    return tri_index.reshape(h, w), zbuf.reshape(h, w)


@dataclass(frozen=True, eq=False)
class Buffers:
    """What the rasteriser saw: per-pixel triangle and depth, per-vertex projections.

    Attributes
    ----------
    camera : Camera
        The camera of the buffers (at the buffer resolution).
    triangle : ndarray, shape (H, W), int32
        Nearest triangle per pixel, -1 for background.
    depth : ndarray, shape (H, W), float64
        Distance along the viewing direction of the visible surface; +inf for background.
    xy : ndarray, shape (N, 2)
        Projected vertices.
    vertex_depth : ndarray, shape (N,)
        Vertex depths.
    front : ndarray, shape (T,), bool
        True for triangles facing the camera (counter-clockwise as seen by it).
    box : (int, int, int, int), optional
        First row, last row, first column, last column of the covered pixels (last < first when
        none is); None when not known.
    """

    camera: Camera
    triangle: np.ndarray
    depth: np.ndarray
    xy: np.ndarray
    vertex_depth: np.ndarray
    front: np.ndarray
    box: tuple | None = None

    @property
    def covered(self) -> np.ndarray:
        """(H, W) bool: pixels showing the mesh."""
        return self.triangle >= 0

    def facing(self) -> np.ndarray:
        """(H, W) int8: +1 front face, -1 back face, 0 background."""
        out = np.zeros(self.triangle.shape, dtype=np.int8)
        cov = self.covered
        out[cov] = np.where(self.front[self.triangle[cov]], 1, -1)
        return out


def render_buffers(points: np.ndarray, triangles: np.ndarray, camera: Camera, *, _reuse: bool = False,
                   _checked: bool = False) -> Buffers:
    """Rasterise a mesh through ``camera`` (see :func:`rasterize`).

    Parameters
    ----------
    points : ndarray, shape (N, 3)
    triangles : ndarray, shape (T, 3), int
    camera : Camera

    Returns
    -------
    Buffers

    Notes
    -----
    ``_reuse`` (internal, :func:`render_mesh`): with the compiled rasteriser, the triangle and depth
    buffers are this thread's scratch buffers, valid until its next ``_reuse`` call, and only the
    box the previous frame covered is cleared. A movie renders hundreds of frames: fresh
    full-size buffers cost more in page faults than the rasterisation itself. ``_checked``
    (internal): ``points`` and ``triangles`` already passed :func:`_check_mesh` (float64, int64).
    """
    if not _checked:
        points, triangles = _check_mesh(points, triangles)
    xy, depth = camera.project(points)
    if camera.perspective:
        with np.errstate(divide="ignore", invalid="ignore"):
            zkey = np.where(depth > 0, -1.0 / depth, np.nan)
    else:
        zkey = depth
    kernels = _compiled()
    box = None
    if kernels is not None:
        w, h = camera.size
        tri_index, zbuf, scratch, stale = _clean_buffers(w, h, _reuse)
        front, box = _rasterize_compiled(kernels, xy, zkey, triangles, tri_index, zbuf, stale)
        if scratch is not None:
            scratch[2] = box
    else:
        tri_index, zbuf = _rasterize_numpy(xy, zkey, triangles, camera.size)
        t = triangles
        with np.errstate(invalid="ignore"):
            area = ((xy[t[:, 1], 0] - xy[t[:, 0], 0]) * (xy[t[:, 2], 1] - xy[t[:, 0], 1])
                    - (xy[t[:, 2], 0] - xy[t[:, 0], 0]) * (xy[t[:, 1], 1] - xy[t[:, 0], 1]))
        front = area < 0  # image y points down: counter-clockwise in the world looks clockwise here
    if camera.perspective:  # the key -1/depth back to depth, on the covered pixels
        r0, r1, c0, c1 = box if box is not None else (0, tri_index.shape[0] - 1, 0, tri_index.shape[1] - 1)
        sub, cov = zbuf[r0:r1 + 1, c0:c1 + 1], tri_index[r0:r1 + 1, c0:c1 + 1] >= 0
        sub[cov] = -1.0 / sub[cov]
    return Buffers(camera=camera, triangle=tri_index, depth=zbuf, xy=xy, vertex_depth=depth, front=front, box=box)


#: largest buffers (pixels) kept per thread for reuse by render_mesh (~12 bytes a pixel)
_SCRATCH_MAX_PIXELS = 1 << 23
_SCRATCH = threading.local()


def _clean_buffers(w: int, h: int, reuse: bool):
    """(triangle, depth, scratch entry or None, stale box) for the compiled rasteriser: (H, W)
    int32 all -1 and float64 all +inf, fresh or this thread's. A reused pair has its triangles
    cleared in the box the last user covered (recorded in ``scratch[2]``) and keeps that user's
    depths there (the stale box), which the rasteriser ignores and resets."""
    if not reuse or w * h > _SCRATCH_MAX_PIXELS:
        return np.full((h, w), -1, dtype=np.int32), np.full((h, w), np.inf), None, _NO_BOX
    cache = getattr(_SCRATCH, "buffers", None)
    if cache is None:
        cache = _SCRATCH.buffers = {}
    entry = cache.get((w, h))
    if entry is None:
        if len(cache) >= 2:
            cache.clear()
        entry = cache[(w, h)] = [np.full((h, w), -1, dtype=np.int32), np.full((h, w), np.inf), None]
    tri_index, zbuf, dirty = entry
    stale = _NO_BOX
    if dirty is not None and dirty[1] >= dirty[0]:
        r0, r1, c0, c1 = stale = dirty
        tri_index[r0:r1 + 1, c0:c1 + 1] = -1
    entry[2] = (0, h - 1, 0, w - 1)  # until the rasteriser says which box it covered
    return tri_index, zbuf, entry, stale


def _neighbourhood_max(depth: np.ndarray, radius: int) -> np.ndarray:
    if radius <= 0:
        return depth
    cv2 = _cv2()
    d = np.where(np.isfinite(depth), depth, np.finfo(np.float32).max).astype(np.float32)
    return cv2.dilate(d, np.ones((2 * radius + 1, 2 * radius + 1), np.uint8)).astype(np.float64)


def point_visibility(points: np.ndarray, buffers: Buffers, *, tolerance: float, radius: int = 1,
                     _ref: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Which points the rendered surface hides.

    Parameters
    ----------
    points : ndarray, shape (M, 3)
        World points (markers...); NaN rows are neither in view nor visible.
    buffers : Buffers
        From :func:`render_buffers`.
    tolerance : float
        World units: a point up to this far behind the visible surface still counts as visible
        (points on the surface, bound points, markers glued to the skin).
    radius : int
        Compare against the farthest surface within this many pixels (absorbs the depth slope of
        surfaces seen at grazing angles).

    Returns
    -------
    in_view : ndarray, shape (M,), bool
        Finite, in front of the camera and inside the image.
    visible : ndarray, shape (M,), bool
        In view and not behind the surface.
    """
    pts = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    xy, depth = buffers.camera.project(pts)
    h, w = buffers.depth.shape
    with np.errstate(invalid="ignore"):
        in_view = (np.isfinite(xy).all(axis=1) & np.isfinite(depth) & (xy[:, 0] >= 0) & (xy[:, 0] < w)
                   & (xy[:, 1] >= 0) & (xy[:, 1] < h))
        if buffers.camera.perspective:
            in_view &= depth > 0
    visible = np.zeros(pts.shape[0], dtype=bool)
    idx = np.flatnonzero(in_view)
    if idx.size:
        j = np.floor(xy[idx, 0]).astype(np.int64)
        i = np.floor(xy[idx, 1]).astype(np.int64)
        near = _ref[i, j] if _ref is not None else _window_max(buffers.depth, i, j, radius)
        visible[idx] = depth[idx] <= near + tolerance
    return in_view, visible


def _window_max(depth: np.ndarray, i: np.ndarray, j: np.ndarray, radius: int) -> np.ndarray:
    """:func:`_neighbourhood_max` at the pixels (i, j) only (a few points: no full-image pass)."""
    h, w = depth.shape
    d = np.where(np.isfinite(depth), depth, np.finfo(np.float32).max)
    best = np.full(i.shape, -np.inf)
    for di in range(-radius, radius + 1):
        for dj in range(-radius, radius + 1):
            ii, jj = i + di, j + dj
            ok = (ii >= 0) & (ii < h) & (jj >= 0) & (jj < w)
            best = np.where(ok, np.maximum(best, d[np.clip(ii, 0, h - 1), np.clip(jj, 0, w - 1)]), best)
    # the full-image version works in float32: round the same way so both agree exactly
    return best.astype(np.float32).astype(np.float64)


def _check_mesh(points, triangles) -> tuple[np.ndarray, np.ndarray]:
    p = np.asarray(points, dtype=np.float64)
    if p.ndim != 2 or p.shape[1] != 3 or p.shape[0] == 0:
        raise MeshError(f"preview: points must have shape (N>0, 3); got {p.shape}")
    if not np.isfinite(p).all():
        raise MeshError(f"preview: {int((~np.isfinite(p)).any(axis=1).sum())} mesh points are NaN or infinite")
    t = np.asarray(triangles)
    if t.ndim != 2 or t.shape[1] != 3 or (t.size and not np.issubdtype(t.dtype, np.integer)):
        raise MeshError(f"preview: triangles must be an integer array of shape (T, 3); got {t.shape} {t.dtype}")
    t = t.astype(np.int64, copy=False)
    if t.size and (t.min() < 0 or t.max() >= p.shape[0]):
        raise MeshError(f"preview: triangle vertex indices must be in 0..{p.shape[0] - 1}; got {t.min()}..{t.max()}")
    return p, t
