"""numba kernels of the preview renderer: the rasteriser and the per-pixel shader, compiled.

They compute what :func:`usdface.preview.render._rasterize_numpy` and
:func:`usdface.preview.render._shade_pixels` compute in vectorised numpy (the slow, obvious
references the tests compare them with), one triangle row or one pixel at a time, without the
temporary arrays. Playblasts render every frame of a take, where the numpy versions cost about
0.1 s per 960x540 frame and these a few milliseconds.

The rasteriser is bit-identical to the numpy one (same float operations in the same order, same
"last triangle with the smallest depth wins" rule). The shader works in float32 like the numpy one;
a pixel may differ by one level of 255 where float32 rounding lands on the other side of .5.
Imported only when numba is available (:data:`AVAILABLE`).
"""
from __future__ import annotations

import math

import numpy as np

try:
    from numba import njit
    AVAILABLE = True
except ImportError:  # pragma: no cover - numba is a dependency; stay importable without it
    AVAILABLE = False

    def njit(*args, **kwargs):
        def wrap(f):
            return f
        return wrap(args[0]) if args and callable(args[0]) else wrap

__all__ = ["AVAILABLE", "rasterize_kernel", "shade_kernel"]


@njit(cache=True, nogil=True)
def rasterize_kernel(xy, z, tri, w, h, tri_index, zbuf):  # pragma: no cover - compiled
    """Z-buffered scanline rasterisation into ``tri_index`` (H*W int32) and ``zbuf`` (H*W float64).

    Same coverage rule and edge arithmetic as :func:`usdface.preview.render.rasterize`: per row,
    each edge (in canonical low-y-first form) bounds the covered x-interval of pixel centres.
    """
    inf = np.inf
    for t in range(tri.shape[0]):
        a, b, c = tri[t, 0], tri[t, 1], tri[t, 2]
        x0, x1, x2 = xy[a, 0], xy[b, 0], xy[c, 0]
        y0, y1, y2 = xy[a, 1], xy[b, 1], xy[c, 1]
        z0, z1, z2 = z[a], z[b], z[c]
        e1x, e1y = x1 - x0, y1 - y0
        e2x, e2y = x2 - x0, y2 - y0
        area = e1x * e2y - e2x * e1y
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
        xs = (x0, x1, x2)
        ys = (y0, y1, y2)
        for row in range(r0, r1 + 1):
            yc = row + 0.5
            lo = -inf
            hi = inf
            for e in range(3):
                xa, ya = xs[e], ys[e]
                xb, yb = xs[(e + 1) % 3], ys[(e + 1) % 3]
                if yb < ya:
                    xl, yl, xh, yh = xb, yb, xa, ya
                else:
                    xl, yl, xh, yh = xa, ya, xb, yb
                dy = yh - yl
                horizontal = dy == 0.0
                slope = 0.0 if horizontal else (xh - xl) / dy
                xc = xl + (yc - yl) * slope
                k = sgn * (yb - ya)
                if k < 0:
                    lo = max(lo, xc)
                if k > 0:
                    hi = min(hi, xc)
                if horizontal and sgn * (xb - xa) * (yc - ya) < 0:
                    lo = inf
            j0 = max(math.ceil(lo - 0.5), 0.0)
            j1 = min(math.floor(hi - 0.5), w - 1.0)
            if not j1 >= j0:
                continue
            cnt = int(j1 - j0 + 1)
            jj = int(j0)
            zrow = z0 + gx * (j0 + 0.5 - x0) + gy * (yc - y0)
            base = row * w + jj
            for kk in range(cnt):
                d = zrow + gx * kk
                p = base + kk
                if d <= zbuf[p]:
                    zbuf[p] = d
                    tri_index[p] = t


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
