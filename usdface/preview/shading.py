"""Shading of rasterised meshes: per-pixel Lambert lighting of interpolated normals and colours
(or of a scalar through a colour map), back faces tinted, the background, the wireframe mask.

The per-pixel work runs in the compiled kernel of :mod:`usdface.preview._kernels` when numba is
installed, else in vectorised numpy (:func:`_shade_pixels`, the reference the tests compare with).
"""
from __future__ import annotations

from functools import lru_cache
from typing import TYPE_CHECKING

import numpy as np

from ._common import _bgr, _compiled, _rgb
from .colormap import NAN_COLOR

if TYPE_CHECKING:  # pragma: no cover
    from .raster import Buffers

#: default background: vertical gradient, RGB 0..255, top then bottom
BACKGROUND = ((72, 76, 84), (30, 32, 36))
#: tint mixed into back faces (RGB 0..1)
BACK_TINT = (0.42, 0.33, 0.48)


def vertex_normals(points: np.ndarray, triangles: np.ndarray) -> np.ndarray:
    """(N, 3) unit vertex normals, area-weighted average of the incident triangle normals
    (right-hand rule: counter-clockwise triangles face the viewer). Isolated vertices get (0, 0, 0)."""
    p = np.asarray(points, dtype=np.float64)
    t = np.asarray(triangles, dtype=np.int64)
    fn = np.cross(p[t[:, 1]] - p[t[:, 0]], p[t[:, 2]] - p[t[:, 0]])  # length = 2 * area
    flat = t.ravel()
    n = np.stack([np.bincount(flat, weights=np.repeat(fn[:, k], 3), minlength=p.shape[0]) for k in range(3)], axis=1)
    length = np.linalg.norm(n, axis=1, keepdims=True)
    return np.divide(n, length, out=np.zeros_like(n), where=length > 0)


def _normalize(v) -> np.ndarray:
    v = np.asarray(v, dtype=np.float64)
    return v / np.linalg.norm(v)


# lights in camera coordinates (right, up, viewing direction); vectors point toward the light
_KEY = _normalize((-0.35, 0.45, -1.0))
_FILL = _normalize((0.85, -0.05, -0.45))
_HALF = _normalize(_KEY + np.array([0.0, 0.0, -1.0]))
_KEY32, _FILL32, _HALF32 = (v.astype(np.float32) for v in (_KEY, _FILL, _HALF))


def _shade(buf: Buffers, points: np.ndarray, tris: np.ndarray, colors: np.ndarray, out: np.ndarray, *,
           shading: str, specular: float, scalar_t: np.ndarray | None = None,
           lut: np.ndarray | None = None, compiled: bool | None = None) -> None:
    """Shade the covered pixels of ``out`` ((H, W, 3) uint8 BGR, written in place).

    ``compiled``: use the numba kernels (default: when numba is installed) or the numpy reference.
    Orthographic cameras take the compiled plane shader (:func:`_shade_planes`).

    Per-triangle data (barycentric gradients, per-corner normal and colour) is packed once into a
    contiguous float32 block, so each pixel needs a single row gather.

    With ``scalar_t`` ((N,) values normalised to [0, 1], NaN for none) the scalar itself is
    interpolated and looked up in ``lut`` per pixel, so a pixel between a low and a high vertex
    shows a colour of the map (interpolating the colours would show colours that are not on it);
    pixels mostly weighted by NaN vertices show :data:`NAN_COLOR`.
    """
    h, w = buf.triangle.shape
    kernels = _compiled() if compiled is None or compiled else None
    compiled = kernels is not None
    if compiled and not buf.camera.perspective:
        _shade_planes(kernels, buf, points, tris, colors, out, shading=shading, specular=specular,
                      scalar_t=scalar_t, lut=lut)
        return
    flat_tri = buf.triangle.ravel()
    if not compiled:
        pix = np.flatnonzero(flat_tri >= 0)
        if pix.size == 0:
            return
        t = flat_tri[pix]
    # --- per triangle ---------------------------------------------------------------------------
    v = buf.xy[tris]  # (T, 3, 2)
    e1 = v[:, 1] - v[:, 0]
    e2 = v[:, 2] - v[:, 0]
    with np.errstate(divide="ignore", invalid="ignore"):
        inv = 1.0 / (e1[:, 0] * e2[:, 1] - e2[:, 0] * e1[:, 1])
    inv[~np.isfinite(inv)] = 0.0
    rot = buf.camera.rotation
    flat = shading == "flat"
    if shading == "unlit":
        corner_n = np.zeros((tris.shape[0], 3, 3))
    elif flat:
        fn = np.cross(points[tris[:, 1]] - points[tris[:, 0]], points[tris[:, 2]] - points[tris[:, 0]]) @ rot.T
        corner_n = np.repeat(fn[:, None, :], 3, axis=1)
    else:
        corner_n = (vertex_normals(points, tris) @ rot.T)[tris]
    front = buf.front.astype(np.float64)[:, None, None]
    corner_n = corner_n * (2.0 * front - 1.0)  # back faces: lit from their own side
    geo = np.stack([v[:, 0, 0], v[:, 0, 1], e2[:, 1] * inv, -e2[:, 0] * inv, -e1[:, 1] * inv, e1[:, 0] * inv], axis=1)
    parts = [geo, corner_n.reshape(-1, 9), colors[tris].reshape(-1, 9), buf.front[:, None].astype(np.float64)]
    if buf.camera.perspective:
        with np.errstate(divide="ignore"):
            parts.append(1.0 / buf.vertex_depth[tris])
    else:
        parts.append(np.ones((tris.shape[0], 3)))
    if scalar_t is not None:
        ct = scalar_t[tris]
        bad = ~np.isfinite(ct)
        if bad.any():  # a NaN corner takes the mean of the triangle's finite corners (or 0)
            cnt = (~bad).sum(axis=1)
            mean = np.divide(np.where(bad, 0.0, ct).sum(axis=1), cnt, out=np.zeros(len(ct)), where=cnt > 0)
            ct = np.where(bad, mean[:, None], ct)
        parts += [ct, bad.astype(np.float64)]
    # (C, T) so that the per-pixel gather gives (C, K) with contiguous rows (a (K, C) block would
    # be read column by column with a cache miss per element)
    block = np.ascontiguousarray(np.concatenate(parts, axis=1).T, dtype=np.float32)
    lut32 = None if lut is None else np.ascontiguousarray(lut.T, dtype=np.float32)
    flat_out = out.reshape(-1, 3)
    if compiled:  # the kernel reads one triangle's row at a time: (T, C) layout
        kernels.shade_kernel(np.ascontiguousarray(block.T), np.ascontiguousarray(flat_tri), w, 1 if shading == "unlit" else 0,
                              float(specular), bool(buf.camera.perspective), scalar_t is not None,
                              np.zeros((3, 1), np.float32) if lut32 is None else lut32, _NAN32[:, 0],
                              _TINT32[:, 0], _KEY32, _FILL32, _HALF32, flat_out)
        return
    # --- per pixel, in cache-sized chunks -------------------------------------------------------
    step = 1 << 15
    for k in range(0, pix.size, step):
        flat_out[pix[k:k + step]] = _shade_pixels(block, t[k:k + step], pix[k:k + step], w, shading=shading,
                                                  specular=specular, perspective=buf.camera.perspective,
                                                  scalar=scalar_t is not None, lut=lut32)


def _shade_planes(kernels, buf: Buffers, points, tris, colors, out, *, shading, specular, scalar_t, lut) -> None:
    """:func:`_shade` under an orthographic camera, compiled: every interpolated attribute (colour,
    normal, scalar) is affine in image space over a triangle, so the per-triangle set-up
    (:func:`usdface.preview._kernels.ortho_planes_kernel`, with the normals of
    ``camera_normals_kernel``) stores its plane and a pixel costs one evaluation per attribute;
    only the box of covered pixels is visited. Same picture as the barycentric reference within
    float32 rounding (a level of 255 on a few pixels)."""
    box = buf.box
    if box is None:
        box = _covered_box(buf.triangle)
    if box[1] < box[0]:
        return
    rot = np.ascontiguousarray(buf.camera.rotation, dtype=np.float64)
    flat = shading == "flat"
    normals = np.zeros((tris.shape[0] if flat else points.shape[0], 3))
    if shading != "unlit":
        kernels.camera_normals_kernel(points, tris, rot, flat, normals)
    planes = np.empty((tris.shape[0], kernels.P_COLUMNS), np.float32)
    st = _EMPTY if scalar_t is None else np.ascontiguousarray(scalar_t, dtype=np.float64)
    kernels.ortho_planes_kernel(np.ascontiguousarray(buf.xy, dtype=np.float64), tris, buf.front, normals, not flat,
                                np.ascontiguousarray(colors, dtype=np.float64), st, planes)
    lut32 = _NO_LUT if lut is None else np.ascontiguousarray(lut.T, dtype=np.float32)
    kernels.ortho_shade_kernel(planes, buf.triangle, np.asarray(box, dtype=np.int64), shading != "unlit",
                               scalar_t is not None, float(specular), lut32, _NAN32[:, 0], _TINT06, _KEY32, _FILL32,
                               _HALF32, out)


def _covered_box(triangle: np.ndarray) -> tuple[int, int, int, int]:
    """(first row, last row, first column, last column) of the pixels showing a triangle (last <
    first when none does)."""
    cov = triangle >= 0
    rows, cols = np.flatnonzero(cov.any(axis=1)), np.flatnonzero(cov.any(axis=0))
    if rows.size == 0:
        return 0, -1, 0, -1
    return int(rows[0]), int(rows[-1]), int(cols[0]), int(cols[-1])


_EMPTY = np.zeros(0)
_NO_LUT = np.zeros((3, 1), np.float32)
_TINT06 = (0.6 * np.asarray(BACK_TINT, dtype=np.float32)).astype(np.float32)
_NAN32 = np.asarray(NAN_COLOR, dtype=np.float32)[:, None]
_TINT32 = np.asarray(BACK_TINT, dtype=np.float32)[:, None]


def _shade_pixels(block, t, pix, w, *, shading, specular, perspective, scalar, lut) -> np.ndarray:
    c = np.take(block, t, axis=1)
    py, px = np.divmod(pix, w)
    dx = px.astype(np.float32)
    dx += 0.5
    dx -= c[0]
    dy = py.astype(np.float32)
    dy += 0.5
    dy -= c[1]
    b1 = np.clip(c[2] * dx + c[3] * dy, 0.0, 1.0)
    b2 = np.clip(c[4] * dx + c[5] * dy, 0.0, 1.0)
    b0 = np.clip(1.0 - b1 - b2, 0.0, 1.0)
    if perspective:  # perspective-correct: interpolate attribute/depth, then divide
        b0 *= c[25]
        b1 *= c[26]
        b2 *= c[27]
    norm = b0 + b1 + b2
    norm[norm <= 0] = 1.0
    b0 /= norm
    b1 /= norm
    b2 /= norm
    if scalar:
        tt = b0 * c[28] + b1 * c[29] + b2 * c[30]
        nanw = b0 * c[31] + b1 * c[32] + b2 * c[33]
        idx = np.clip(np.rint(tt * (lut.shape[1] - 1)), 0, lut.shape[1] - 1).astype(np.intp)
        base = np.where(nanw < 0.5, lut[:, idx], _NAN32)
    else:
        base = b0 * c[15:18] + b1 * c[18:21] + b2 * c[21:24]  # (3, K)
    if shading == "unlit":
        base *= 255.0
        base += 0.5
        np.clip(base, 0.0, 255.0, out=base)
        return base[::-1].T.astype(np.uint8)
    n = b0 * c[6:9] + b1 * c[9:12] + b2 * c[12:15]
    n /= np.maximum(np.sqrt((n * n).sum(axis=0)), 1e-20)
    key = np.clip(_KEY32 @ n, 0.0, None)
    fill = np.clip(_FILL32 @ n, 0.0, None)
    light = 0.20 + 0.72 * key + 0.26 * fill
    hv = np.clip(_HALF32 @ n, 0.0, None)
    h8 = hv * hv
    h8 *= h8
    h8 *= h8
    spec = h8 * h8
    spec *= spec
    spec *= h8  # hv ** 40
    spec *= specular
    back = c[24] < 0.5
    if back.any():
        base[:, back] = 0.4 * base[:, back] + 0.6 * _TINT32
        light[back] *= 0.62
        spec[back] = 0.0
    rgb = base * light
    rgb += spec
    rgb *= 255.0
    rgb += 0.5
    np.clip(rgb, 0.0, 255.0, out=rgb)
    return rgb[::-1].T.astype(np.uint8)


def _background(size, background) -> np.ndarray:
    """(H, W, 3) uint8 BGR background (a fresh copy of a cached image: every frame of a movie
    starts from the same one, and filling 3-channel pixels costs more than copying them)."""
    rgb = None if background is None else _rgb(background, "background")
    return _background_cached(int(size[0]), int(size[1]), rgb).copy()


@lru_cache(maxsize=8)
def _background_cached(w: int, h: int, rgb) -> np.ndarray:
    if rgb is None:
        top, bottom = (np.asarray(c[::-1], dtype=np.float32) for c in BACKGROUND)
        t = np.linspace(0.0, 1.0, h, dtype=np.float32)[:, None]
        col = (top * (1 - t) + bottom * t + 0.5).astype(np.uint8)
        out = np.ascontiguousarray(np.repeat(col[:, None, :], w, axis=1))
    else:
        out = np.empty((h, w, 3), np.uint8)
        out[:] = _bgr(rgb)
    out.flags.writeable = False
    return out


def _wire_mask(buf: Buffers, edges: np.ndarray, tolerance: float, ref: np.ndarray) -> np.ndarray:
    """(H, W) bool: pixels on visible parts of the edges."""
    h, w = buf.triangle.shape
    p0, p1 = buf.xy[edges[:, 0]], buf.xy[edges[:, 1]]
    d0, d1 = buf.vertex_depth[edges[:, 0]], buf.vertex_depth[edges[:, 1]]
    ok = np.isfinite(p0).all(axis=1) & np.isfinite(p1).all(axis=1)
    p0, p1, d0, d1 = p0[ok], p1[ok], d0[ok], d1[ok]
    mask = np.zeros(h * w, dtype=bool)
    if p0.shape[0] == 0:
        return mask.reshape(h, w)
    length = np.abs(p1 - p0).max(axis=1)
    nseg = np.clip(np.ceil(length * 1.5).astype(np.int64), 1, 4 * (w + h))
    e = np.repeat(np.arange(p0.shape[0]), nseg + 1)
    first = np.cumsum(nseg + 1) - (nseg + 1)
    s = (np.arange(e.size) - first[e]) / nseg[e]
    xy = p0[e] + (p1 - p0)[e] * s[:, None]
    if buf.camera.perspective:
        depth = 1.0 / ((1 - s) / d0[e] + s / d1[e])
    else:
        depth = d0[e] + (d1 - d0)[e] * s
    j = np.floor(xy[:, 0]).astype(np.int64)
    i = np.floor(xy[:, 1]).astype(np.int64)
    inside = (j >= 0) & (j < w) & (i >= 0) & (i < h)
    j, i, depth = j[inside], i[inside], depth[inside]
    vis = depth <= ref[i, j] + tolerance
    mask[i[vis] * w + j[vis]] = True
    return mask.reshape(h, w)
