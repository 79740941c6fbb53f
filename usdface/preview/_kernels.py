"""numba kernels of the preview renderer: the rasteriser and the per-pixel shaders, compiled.

They compute what :func:`usdface.preview.raster._rasterize_numpy` and
:func:`usdface.preview.render._shade_pixels` compute in vectorised numpy (the slow, obvious
references the tests compare them with), one triangle row or one pixel at a time, without the
temporary arrays. Playblasts render every frame of a take, where the numpy versions cost about
0.1 s per 960x540 frame and these about a millisecond each.

The rasteriser is bit-identical to the numpy one (same float operations in the same order, same
"last triangle with the smallest depth wins" rule). The shaders work in float32 like the numpy one;
a pixel may differ by one level of 255 where float32 rounding lands on the other side of .5 (and
a scalar pixel by one step of the colour map). Orthographic cameras take a faster shader
(:func:`ortho_shade_kernel`): there every interpolated attribute is a plane in image space, set up
once per triangle, instead of barycentric weights per pixel.
Imported only when numba is available (:data:`AVAILABLE`).
"""
from __future__ import annotations

import math

import numpy as np

from ..numba_cache import AVAILABLE, njit  # the renderer keeps its numpy path without numba

__all__ = ["AVAILABLE", "camera_normals_kernel", "ortho_planes_kernel", "ortho_shade_kernel", "paste_kernel",
           "rasterize_kernel", "shade_kernel"]


@njit(cache=True, nogil=True, inline="always")
def _edge(xa, ya, xb, yb, sgn):  # pragma: no cover - compiled
    """One edge of a triangle in the canonical (low-y endpoint first) form of the numpy rasteriser:
    (xl, yl, slope, kind, horizontal, hsign)."""
    if yb < ya:
        xl, yl, xh, yh = xb, yb, xa, ya
    else:
        xl, yl, xh, yh = xa, ya, xb, yb
    dy = yh - yl
    horizontal = dy == 0.0
    slope = 0.0 if horizontal else (xh - xl) / dy
    return xl, yl, slope, sgn * (yb - ya), horizontal, sgn * (xb - xa)


@njit(cache=True, nogil=True, inline="always")
def _bound(lo, hi, yc, xl, yl, slope, kind, horizontal, hsign, ya):  # pragma: no cover - compiled
    xc = xl + (yc - yl) * slope
    if kind < 0:
        lo = max(lo, xc)
    if kind > 0:
        hi = min(hi, xc)
    if horizontal and hsign * (yc - ya) < 0:
        lo = np.inf
    return lo, hi


@njit(cache=True, nogil=True)
def rasterize_kernel(xy, z, tri, w, h, tri_index, zbuf, front, box, stale):  # pragma: no cover - compiled
    """Z-buffered scanline rasterisation into ``tri_index`` (H*W int32) and ``zbuf`` (H*W float64).

    Same coverage rule and edge arithmetic as :func:`usdface.preview.raster.rasterize`: per row,
    each edge (in canonical low-y-first form, set up once per triangle) bounds the covered
    x-interval of pixel centres. Also writes ``front`` ((T,) bool: signed image area < 0, the
    camera-facing triangles) and ``box`` ((4,) int64: first row, last row, first column, last
    column of the covered pixels; last < first when nothing is covered).

    ``tri_index`` must hold -1 on entry; ``zbuf`` counts as +inf wherever ``tri_index`` is -1, and
    must hold +inf there except inside ``stale`` ((4,) int64 box, empty when last < first): a
    reused buffer need not clear its old depths, only its triangle indices (a third of the bytes).
    On return ``zbuf`` is +inf at every uncovered pixel.
    """
    inf = np.inf
    bi0, bi1, bj0, bj1 = h, -1, w, -1
    for t in range(tri.shape[0]):
        a, b, c = tri[t, 0], tri[t, 1], tri[t, 2]
        x0, x1, x2 = xy[a, 0], xy[b, 0], xy[c, 0]
        y0, y1, y2 = xy[a, 1], xy[b, 1], xy[c, 1]
        z0, z1, z2 = z[a], z[b], z[c]
        e1x, e1y = x1 - x0, y1 - y0
        e2x, e2y = x2 - x0, y2 - y0
        area = e1x * e2y - e2x * e1y
        front[t] = area < 0.0
        if not (math.isfinite(area) and math.isfinite(z0) and math.isfinite(z1) and math.isfinite(z2)):
            continue
        if area == 0.0:
            continue
        ymin = min(y0, min(y1, y2))
        ymax = max(y0, max(y1, y2))
        rmin = math.ceil(ymin - 0.5)
        rmax = math.floor(ymax - 0.5)
        if not (rmax >= 0 and rmin <= h - 1 and rmax >= rmin):
            continue
        if not (max(x0, max(x1, x2)) >= 0.5 and min(x0, min(x1, x2)) <= w - 0.5):
            continue
        r0 = int(min(max(rmin, 0.0), h - 1.0))
        r1 = int(min(max(rmax, 0.0), h - 1.0))
        dz1, dz2 = z1 - z0, z2 - z0
        gx = (dz1 * e2y - dz2 * e1y) / area
        gy = (dz2 * e1x - dz1 * e2x) / area
        sgn = 1.0 if area > 0 else -1.0
        t32 = np.int32(t)
        al, ay, asl, ak, ah, ahs = _edge(x0, y0, x1, y1, sgn)
        bl, by, bsl, bk, bh, bhs = _edge(x1, y1, x2, y2, sgn)
        cl, cy, csl, ck, ch, chs = _edge(x2, y2, x0, y0, sgn)
        for row in range(r0, r1 + 1):
            yc = row + 0.5
            lo, hi = _bound(-inf, inf, yc, al, ay, asl, ak, ah, ahs, y0)
            lo, hi = _bound(lo, hi, yc, bl, by, bsl, bk, bh, bhs, y1)
            lo, hi = _bound(lo, hi, yc, cl, cy, csl, ck, ch, chs, y2)
            # np.ceil / np.floor as the numpy rasteriser: float results (math.ceil gives an int64,
            # undefined for the +inf that the horizontal-edge rule uses to empty a row)
            j0 = max(np.ceil(lo - 0.5), 0.0)
            j1 = min(np.floor(hi - 0.5), w - 1.0)
            if not j1 >= j0:
                continue
            cnt = int(j1 - j0 + 1)
            jj = int(j0)
            bi0 = min(bi0, row)
            bi1 = max(bi1, row)
            bj0 = min(bj0, jj)
            bj1 = max(bj1, jj + cnt - 1)
            zrow = z0 + gx * (j0 + 0.5 - x0) + gy * (yc - y0)
            base = np.uint64(row * w + jj)  # unsigned: no negative-index wrap-around per access
            for kk in range(cnt):
                d = zrow + gx * kk
                p = base + np.uint64(kk)
                cur = tri_index[p]
                old = zbuf[p] if cur >= 0 else inf
                take = d <= old  # branch-free select
                zbuf[p] = d if take else old
                tri_index[p] = t32 if take else cur
    box[0], box[1], box[2], box[3] = bi0, bi1, bj0, bj1
    for row in range(max(stale[0], 0), min(stale[1], h - 1) + 1):  # old depths left uncovered
        base = np.uint64(row * w)
        for col in range(max(stale[2], 0), min(stale[3], w - 1) + 1):
            p = base + np.uint64(col)
            if tri_index[p] < 0:
                zbuf[p] = inf


@njit(cache=True, nogil=True)
def shade_kernel(block, tri_index, w, mode, specular, perspective, scalar, lut, nan_rgb, tint, key, fill, half,
                 out):  # pragma: no cover - compiled
    """Shade every covered pixel into ``out`` ((H*W, 3) uint8 BGR), as ``_shade_pixels`` does.

    ``block`` is the (T, C) float32 per-triangle table built by ``_shade`` (transposed); ``mode`` 0 = lit, 1 =
    unlit; ``lut`` (3, L) float32 when ``scalar``.
    """
    n = tri_index.shape[0]
    nl = lut.shape[1]
    for p in range(n):
        t = tri_index[p]
        if t < 0:
            continue
        py = p // w
        px = p - py * w
        dx = np.float32(px) + np.float32(0.5) - block[t, 0]
        dy = np.float32(py) + np.float32(0.5) - block[t, 1]
        b1 = min(max(block[t, 2] * dx + block[t, 3] * dy, np.float32(0.0)), np.float32(1.0))
        b2 = min(max(block[t, 4] * dx + block[t, 5] * dy, np.float32(0.0)), np.float32(1.0))
        b0 = min(max(np.float32(1.0) - b1 - b2, np.float32(0.0)), np.float32(1.0))
        if perspective:
            b0 *= block[t, 25]
            b1 *= block[t, 26]
            b2 *= block[t, 27]
        norm = b0 + b1 + b2
        if norm <= 0:
            norm = np.float32(1.0)
        b0 /= norm
        b1 /= norm
        b2 /= norm
        r = np.float32(0.0)
        g = np.float32(0.0)
        bl = np.float32(0.0)
        if scalar:
            tt = b0 * block[t, 28] + b1 * block[t, 29] + b2 * block[t, 30]
            nanw = b0 * block[t, 31] + b1 * block[t, 32] + b2 * block[t, 33]
            if nanw < 0.5:
                idx = int(np.rint(tt * np.float32(nl - 1)))
                idx = min(max(idx, 0), nl - 1)
                r, g, bl = lut[0, idx], lut[1, idx], lut[2, idx]
            else:
                r, g, bl = nan_rgb[0], nan_rgb[1], nan_rgb[2]
        else:
            r = b0 * block[t, 15] + b1 * block[t, 18] + b2 * block[t, 21]
            g = b0 * block[t, 16] + b1 * block[t, 19] + b2 * block[t, 22]
            bl = b0 * block[t, 17] + b1 * block[t, 20] + b2 * block[t, 23]
        if mode == 1:
            r = min(max(r * np.float32(255.0) + np.float32(0.5), np.float32(0.0)), np.float32(255.0))
            g = min(max(g * np.float32(255.0) + np.float32(0.5), np.float32(0.0)), np.float32(255.0))
            bl = min(max(bl * np.float32(255.0) + np.float32(0.5), np.float32(0.0)), np.float32(255.0))
            out[p, 0] = np.uint8(bl)
            out[p, 1] = np.uint8(g)
            out[p, 2] = np.uint8(r)
            continue
        nx = b0 * block[t, 6] + b1 * block[t, 9] + b2 * block[t, 12]
        ny = b0 * block[t, 7] + b1 * block[t, 10] + b2 * block[t, 13]
        nz = b0 * block[t, 8] + b1 * block[t, 11] + b2 * block[t, 14]
        ln = max(math.sqrt(nx * nx + ny * ny + nz * nz), np.float32(1e-20))
        nx /= ln
        ny /= ln
        nz /= ln
        kd = max(key[0] * nx + key[1] * ny + key[2] * nz, np.float32(0.0))
        fd = max(fill[0] * nx + fill[1] * ny + fill[2] * nz, np.float32(0.0))
        light = np.float32(0.20) + np.float32(0.72) * kd + np.float32(0.26) * fd
        hv = max(half[0] * nx + half[1] * ny + half[2] * nz, np.float32(0.0))
        h8 = hv * hv
        h8 *= h8
        h8 *= h8
        spec = h8 * h8
        spec *= spec
        spec *= h8
        spec *= np.float32(specular)
        if block[t, 24] < 0.5:  # back face: tinted, darker, no highlight
            r = np.float32(0.4) * r + np.float32(0.6) * tint[0]
            g = np.float32(0.4) * g + np.float32(0.6) * tint[1]
            bl = np.float32(0.4) * bl + np.float32(0.6) * tint[2]
            light *= np.float32(0.62)
            spec = np.float32(0.0)
        r = min(max((r * light + spec) * np.float32(255.0) + np.float32(0.5), np.float32(0.0)), np.float32(255.0))
        g = min(max((g * light + spec) * np.float32(255.0) + np.float32(0.5), np.float32(0.0)), np.float32(255.0))
        bl = min(max((bl * light + spec) * np.float32(255.0) + np.float32(0.5), np.float32(0.0)), np.float32(255.0))
        out[p, 0] = np.uint8(bl)
        out[p, 1] = np.uint8(g)
        out[p, 2] = np.uint8(r)


# ------------------------------------------------------------------------------------------------
# orthographic fast path: attributes as planes in screen space
# ------------------------------------------------------------------------------------------------
#: columns of the plane table of :func:`ortho_planes_kernel` ((T, P_COLUMNS) float32, a triangle
#: per row: 27 used, padded to 128 bytes): the triangle's origin (its first vertex), 1.0 for a back
#: face, then (value at the origin, d/dx, d/dy) of red, green, blue, normal x, y, z, the
#: normalised scalar and the NaN weight
P_ORIGIN, P_BACK, P_RGB, P_NORMAL, P_SCALAR, P_NAN, P_COLUMNS = 0, 2, 3, 12, 21, 24, 32


@njit(cache=True, nogil=True)
def camera_normals_kernel(points, tri, rot, flat, out):  # pragma: no cover - compiled
    """Per-vertex (``flat`` False) or per-triangle (``flat`` True) normals in camera coordinates
    into ``out`` ((N, 3) or (T, 3) float64).

    Vertex normals as :func:`usdface.preview.shading.vertex_normals` (area-weighted sum of the
    triangle normals, normalised; (0, 0, 0) for isolated vertices); triangle normals are the
    unnormalised cross products, as the flat shading of ``_shade`` uses them. Both are then rotated
    by the camera's ``rot`` (n @ rot.T).
    """
    acc = np.zeros((tri.shape[0] if flat else points.shape[0], 3))
    for t in range(tri.shape[0]):
        a, b, c = tri[t, 0], tri[t, 1], tri[t, 2]
        ux, uy, uz = points[b, 0] - points[a, 0], points[b, 1] - points[a, 1], points[b, 2] - points[a, 2]
        vx, vy, vz = points[c, 0] - points[a, 0], points[c, 1] - points[a, 1], points[c, 2] - points[a, 2]
        nx, ny, nz = uy * vz - uz * vy, uz * vx - ux * vz, ux * vy - uy * vx
        if flat:
            acc[t, 0], acc[t, 1], acc[t, 2] = nx, ny, nz
        else:
            for v in (a, b, c):
                acc[v, 0] += nx
                acc[v, 1] += ny
                acc[v, 2] += nz
    for i in range(acc.shape[0]):
        nx, ny, nz = acc[i, 0], acc[i, 1], acc[i, 2]
        if not flat:
            ln = math.sqrt(nx * nx + ny * ny + nz * nz)
            if ln > 0:
                nx, ny, nz = nx / ln, ny / ln, nz / ln
            else:
                nx, ny, nz = 0.0, 0.0, 0.0
        for k in range(3):
            out[i, k] = nx * rot[k, 0] + ny * rot[k, 1] + nz * rot[k, 2]


@njit(cache=True, nogil=True, inline="always")
def _plane(planes, t, row, a0, a1, a2, g2, g3, g4, g5):  # pragma: no cover - compiled
    d1, d2 = a1 - a0, a2 - a0
    planes[t, row] = a0
    planes[t, row + 1] = d1 * g2 + d2 * g4
    planes[t, row + 2] = d1 * g3 + d2 * g5


@njit(cache=True, nogil=True)
def ortho_planes_kernel(xy, tri, front, normals, per_vertex, colors, scalar_t, planes):  # pragma: no cover - compiled
    """Per-triangle plane table ((T, P_COLUMNS) float32) for :func:`ortho_shade_kernel`.

    Under an orthographic camera an attribute interpolated with barycentric weights is an affine
    function of the image position over a triangle: ``a + ax (x - x0) + ay (y - y0)`` with (x0, y0)
    its first vertex; the coefficients come from the barycentric gradients the numpy reference of
    ``_shade`` uses per pixel. ``normals`` are camera-space normals per vertex (``per_vertex``) or
    per triangle, flipped here for back faces (lit from their own side); ``scalar_t`` (N,)
    normalised scalars or an empty array: a NaN corner takes the mean of the triangle's finite
    corners (or 0), and the NaN weight plane says how much of a pixel is NaN.
    """
    scalar = scalar_t.shape[0] > 0
    for t in range(tri.shape[0]):
        a, b, c = tri[t, 0], tri[t, 1], tri[t, 2]
        x0, y0 = xy[a, 0], xy[a, 1]
        e1x, e1y = xy[b, 0] - x0, xy[b, 1] - y0
        e2x, e2y = xy[c, 0] - x0, xy[c, 1] - y0
        area = e1x * e2y - e2x * e1y
        inv = 1.0 / area if area != 0.0 else 0.0  # as the reference: no gradient without an area
        if not math.isfinite(inv):
            inv = 0.0
        g2, g3, g4, g5 = e2y * inv, -e2x * inv, -e1y * inv, e1x * inv
        planes[t, P_ORIGIN] = x0 if math.isfinite(x0) else 0.0
        planes[t, P_ORIGIN + 1] = y0 if math.isfinite(y0) else 0.0
        planes[t, P_BACK] = 0.0 if front[t] else 1.0
        for k in range(3):
            _plane(planes, t, P_RGB + 3 * k, colors[a, k], colors[b, k], colors[c, k], g2, g3, g4, g5)
        sign = 1.0 if front[t] else -1.0
        for k in range(3):
            if per_vertex:
                n0, n1, n2 = normals[a, k], normals[b, k], normals[c, k]
            else:
                n0 = n1 = n2 = normals[t, k]
            _plane(planes, t, P_NORMAL + 3 * k, sign * n0, sign * n1, sign * n2, g2, g3, g4, g5)
        if scalar:
            s0, s1, s2 = scalar_t[a], scalar_t[b], scalar_t[c]
            f0, f1, f2 = math.isfinite(s0), math.isfinite(s1), math.isfinite(s2)
            cnt = int(f0) + int(f1) + int(f2)
            mean = ((s0 if f0 else 0.0) + (s1 if f1 else 0.0) + (s2 if f2 else 0.0)) / cnt if cnt else 0.0
            _plane(planes, t, P_SCALAR, s0 if f0 else mean, s1 if f1 else mean, s2 if f2 else mean, g2, g3, g4, g5)
            _plane(planes, t, P_NAN, 0.0 if f0 else 1.0, 0.0 if f1 else 1.0, 0.0 if f2 else 1.0, g2, g3, g4, g5)
        else:
            for k in range(6):
                planes[t, P_SCALAR + k] = 0.0


@njit(cache=True, nogil=True, fastmath=True)
def _light_span(n, lit, nx, ny, nz, r, g, b, back, specular, tint, key, fill, half, ob, og, orr):  # pragma: no cover - compiled
    """Lighting of n pixels from their interpolated normal and colour (contiguous arrays, the
    light vectors held in scalars: a loop the compiler vectorises) into ``ob``, ``og``, ``orr``
    ((n,) float32, 0..255 before the uint8 cast)."""
    zero, top, hp, one = np.float32(0.0), np.float32(255.0), np.float32(0.5), np.float32(1.0)
    if not lit:
        for k in range(n):
            ob[k] = min(max(b[k] * top + hp, zero), top)
            og[k] = min(max(g[k] * top + hp, zero), top)
            orr[k] = min(max(r[k] * top + hp, zero), top)
        return
    k0, k1, k2 = key[0], key[1], key[2]
    f0, f1, f2 = fill[0], fill[1], fill[2]
    h0, h1, h2 = half[0], half[1], half[2]
    t0, t1, t2 = tint[0], tint[1], tint[2]
    for k in range(n):
        x, y, z = nx[k], ny[k], nz[k]
        inv = one / max(np.sqrt(x * x + y * y + z * z), np.float32(1e-20))
        x *= inv
        y *= inv
        z *= inv
        kd = max(k0 * x + k1 * y + k2 * z, zero)
        fd = max(f0 * x + f1 * y + f2 * z, zero)
        hv = max(h0 * x + h1 * y + h2 * z, zero)
        h8 = hv * hv
        h8 *= h8
        h8 *= h8
        spec = h8 * h8
        spec *= spec
        spec *= h8  # hv ** 40
        f = back[k]  # 1 for a back face: tinted, darker, no highlight
        m = one - np.float32(0.6) * f
        light = (np.float32(0.20) + np.float32(0.72) * kd + np.float32(0.26) * fd) * (one - np.float32(0.38) * f)
        spec *= specular * (one - f)
        ob[k] = min(max(((b[k] * m + t2 * f) * light + spec) * top + hp, zero), top)
        og[k] = min(max(((g[k] * m + t1 * f) * light + spec) * top + hp, zero), top)
        orr[k] = min(max(((r[k] * m + t0 * f) * light + spec) * top + hp, zero), top)


@njit(cache=True, nogil=True)
def ortho_shade_kernel(planes, tri_index, box, lit, scalar, specular, lut, nan_rgb, tint, key, fill, half,
                       out):  # pragma: no cover - compiled
    """Shade the covered pixels of ``out`` ((H, W, 3) uint8 BGR) inside ``box`` (first/last row,
    first/last column) from the plane table of :func:`ortho_planes_kernel`, as ``_shade_pixels``
    does (same lighting, in float32; ``tint`` is 0.6 times the back-face tint, RGB).

    Row by row: each covered pixel's attributes are one plane evaluation each (no barycentric
    weights, no normalisation), with the plane coefficients held while the row stays on one
    triangle (about five pixels on a face); then the lighting runs over the row's pixels as
    contiguous float32 arrays."""
    r0, r1, c0, c1 = box[0], box[1], box[2], box[3]
    if r1 < r0 or c1 < c0:
        return
    wb = c1 - c0 + 1
    cols = np.empty(wb, np.int64)
    att = np.zeros((9, wb), np.float32)
    r_, g_, b_, nx_, ny_, nz_, nan_, sc_, bk_ = att[0], att[1], att[2], att[3], att[4], att[5], att[6], att[7], att[8]
    o = np.empty((3, wb), np.float32)
    ob, og, orr = o[0], o[1], o[2]
    nl = lut.shape[1]
    hp = np.float32(0.5)
    sp = np.float32(specular)
    z = np.float32(0.0)
    # the planes of the first three attributes: the colour, or the scalar and its NaN weight
    q0, q1, q2 = (P_SCALAR, P_NAN, P_NAN) if scalar else (P_RGB, P_RGB + 3, P_RGB + 6)
    one = np.uint64(1)
    for i in range(r0, r1 + 1):
        row = tri_index[i]
        fy = np.float32(i) + hp
        # unsigned indices below: numba checks signed ones for negative wrap-around on every access
        m = np.uint64(0)
        tprev = -1
        tu = np.uint64(0)
        x0 = dy = bv = z
        a0 = a1 = a2 = a3 = a4 = a5 = z  # value at the triangle's origin
        s0 = s1 = s2 = s3 = s4 = s5 = z  # d/dx
        u0 = u1 = u2 = u3 = u4 = u5 = z  # d/dy
        for j in range(c0, c1 + 1):
            t = row[np.uint64(j)]
            if t < 0:
                continue
            if t != tprev:
                tprev = t
                tu = np.uint64(t)
                x0 = planes[tu, P_ORIGIN]
                dy = fy - planes[tu, P_ORIGIN + 1]
                bv = planes[tu, P_BACK]
                a0, s0, u0 = planes[tu, q0], planes[tu, q0 + 1], planes[tu, q0 + 2]
                a1, s1, u1 = planes[tu, q1], planes[tu, q1 + 1], planes[tu, q1 + 2]
                a2, s2, u2 = planes[tu, q2], planes[tu, q2 + 1], planes[tu, q2 + 2]
                if lit:
                    a3, s3, u3 = planes[tu, P_NORMAL], planes[tu, P_NORMAL + 1], planes[tu, P_NORMAL + 2]
                    a4, s4, u4 = planes[tu, P_NORMAL + 3], planes[tu, P_NORMAL + 4], planes[tu, P_NORMAL + 5]
                    a5, s5, u5 = planes[tu, P_NORMAL + 6], planes[tu, P_NORMAL + 7], planes[tu, P_NORMAL + 8]
            dx = np.float32(j) + hp - x0
            cols[m] = j
            if scalar:
                sc_[m] = a0 + s0 * dx + u0 * dy
                nan_[m] = a1 + s1 * dx + u1 * dy
            else:
                r_[m] = a0 + s0 * dx + u0 * dy
                g_[m] = a1 + s1 * dx + u1 * dy
                b_[m] = a2 + s2 * dx + u2 * dy
            if lit:
                nx_[m] = a3 + s3 * dx + u3 * dy
                ny_[m] = a4 + s4 * dx + u4 * dy
                nz_[m] = a5 + s5 * dx + u5 * dy
                bk_[m] = bv
            m += one
        n = np.int64(m)
        if n == 0:
            continue
        if scalar:
            for k in range(n):
                if nan_[k] < 0.5:
                    idx = min(max(int(np.rint(sc_[k] * np.float32(nl - 1))), 0), nl - 1)
                    r_[k], g_[k], b_[k] = lut[0, idx], lut[1, idx], lut[2, idx]
                else:
                    r_[k], g_[k], b_[k] = nan_rgb[0], nan_rgb[1], nan_rgb[2]
        _light_span(n, lit, nx_, ny_, nz_, r_, g_, b_, bk_, sp, tint, key, fill, half, ob, og, orr)
        orow = out[i]
        for k in range(n):
            ku = np.uint64(k)
            j = np.uint64(cols[ku])
            orow[j, 0] = np.uint8(ob[ku])
            orow[j, 1] = np.uint8(og[ku])
            orow[j, 2] = np.uint8(orr[ku])


@njit(cache=True, nogil=True)
def paste_kernel(img, base, gain, y0, x0, sy, sx, rows, cols):  # pragma: no cover - compiled
    """Blend a text sprite into ``img`` ((H, W, 3) uint8, C-contiguous) as
    ``usdface.preview.overlays._paste`` does in numpy, bit for bit: ``img[y0 + i, x0 + j] =
    uint8(clip(base + gain * img + 0.5, 0, 255))`` in float32, with ``base`` and ``gain`` ((h, w,
    3) float32, C-contiguous) read at (sy + i, sx + j), for i < ``rows``, j < ``cols``. A frame
    has a dozen texts: numpy's temporaries cost more than the blend."""
    zero, top, hp = np.float32(0.0), np.float32(255.0), np.float32(0.5)
    n = np.uint64(3 * cols)
    for i in range(rows):
        dst = img[y0 + i, x0:x0 + cols].reshape(-1)  # a pixel run of one row: contiguous
        b = base[sy + i, sx:sx + cols].reshape(-1)
        g = gain[sy + i, sx:sx + cols].reshape(-1)
        for k in range(n):
            ku = np.uint64(k)
            v = b[ku] + g[ku] * np.float32(dst[ku]) + hp
            dst[ku] = np.uint8(min(max(v, zero), top))
