"""Compiled (numba) kernel for the per-dot sub-pixel refinement of :mod:`usdface.tracking.detect`.

:func:`refine_blobs` does for every blob what :meth:`MarkerDetector.coverage` and
:meth:`MarkerDetector._measure` do in numpy (the slow, obvious reference the tests compare it
with): BGR -> YCrCb in the window (OpenCV's formulas), Mahalanobis table look-up, the dot-coloured
component at the blob, its dilation (support), background = median of the ring outside it, dot
colour = median of the core's less mixed half, coverage by projection, weighted moments.
"""
from __future__ import annotations

import numpy as np

from ..numba_cache import AVAILABLE as HAVE_NUMBA, njit

__all__ = ["HAVE_NUMBA", "refine_blobs"]

#: columns of refine_blobs' output
COLUMNS = ("ok", "cx", "cy", "total", "sxx", "syy", "sxy", "Y", "Cr", "Cb")


def _refine_blobs_py(frame, d2lut, thr2, boxes, blobs, ri, weights, min_alpha):
    k = boxes.shape[0]
    out = np.zeros((k, 10))
    n_off = 0
    for dy in range(-ri, ri + 1):
        for dx in range(-ri, ri + 1):
            if dx * dx + dy * dy <= ri * ri:
                n_off += 1
    offs = np.empty((n_off, 2), np.int64)
    o = 0
    for dy in range(-ri, ri + 1):
        for dx in range(-ri, ri + 1):
            if dx * dx + dy * dy <= ri * ri:
                offs[o, 0] = dy
                offs[o, 1] = dx
                o += 1
    for b in range(k):
        x0, y0, x1, y1 = boxes[b, 0], boxes[b, 1], boxes[b, 2], boxes[b, 3]
        h, w = y1 - y0, x1 - x0
        if h < 3 or w < 3:
            continue
        ycc = np.empty((h, w, 3), np.float32)
        core = np.zeros((h, w), np.int32)
        for yy in range(h):
            for xx in range(w):
                bb = float(frame[y0 + yy, x0 + xx, 0])
                gg = float(frame[y0 + yy, x0 + xx, 1])
                rr = float(frame[y0 + yy, x0 + xx, 2])
                yv = 0.299 * rr + 0.587 * gg + 0.114 * bb
                cr = (rr - yv) * 0.713 + 128.0
                cb = (bb - yv) * 0.564 + 128.0
                yi = min(max(int(yv + 0.5), 0), 255)
                cri = min(max(int(cr + 0.5), 0), 255)
                cbi = min(max(int(cb + 0.5), 0), 255)
                ycc[yy, xx, 0] = yi
                ycc[yy, xx, 1] = cri
                ycc[yy, xx, 2] = cbi
                if d2lut[cri * 256 + cbi] < thr2:
                    core[yy, xx] = -1
        # label components (4-stack flood fill, 8-connectivity); keep the one with most pixels in the blob box
        label = 0
        stack = np.empty((h * w, 2), np.int32)
        best = 0
        inside = np.zeros(h * w + 1, np.bool_)
        bx0, by0, bx1, by1 = blobs[b, 0] - x0, blobs[b, 1] - y0, blobs[b, 2] - x0, blobs[b, 3] - y0
        for yy in range(h):
            for xx in range(w):
                if core[yy, xx] != -1:
                    continue
                label += 1
                count = 0
                top = 0
                stack[0, 0] = yy
                stack[0, 1] = xx
                top = 1
                core[yy, xx] = label
                while top > 0:
                    top -= 1
                    cy_, cx_ = stack[top, 0], stack[top, 1]
                    if by0 <= cy_ < by1 and bx0 <= cx_ < bx1:
                        count += 1
                    for ddy in range(-1, 2):
                        for ddx in range(-1, 2):
                            ny, nx = cy_ + ddy, cx_ + ddx
                            if 0 <= ny < h and 0 <= nx < w and core[ny, nx] == -1:
                                core[ny, nx] = label
                                stack[top, 0] = ny
                                stack[top, 1] = nx
                                top += 1
                if count > 0:
                    inside[label] = True
                    best = 1
        if best == 0:
            continue
        support = np.zeros((h, w), np.bool_)
        n_core = 0
        for yy in range(h):
            for xx in range(w):
                if core[yy, xx] > 0 and inside[core[yy, xx]]:
                    n_core += 1
                    for o in range(n_off):
                        ny, nx = yy + offs[o, 0], xx + offs[o, 1]
                        if 0 <= ny < h and 0 <= nx < w:
                            support[ny, nx] = True
        n_ring = h * w - int(support.sum())
        if n_ring < 4:
            continue
        ring = np.empty((n_ring, 3), np.float32)
        cpx = np.empty((n_core, 3), np.float32)
        i_r, i_c = 0, 0
        for yy in range(h):
            for xx in range(w):
                if not support[yy, xx]:
                    ring[i_r] = ycc[yy, xx]
                    i_r += 1
                if core[yy, xx] > 0 and inside[core[yy, xx]]:
                    cpx[i_c] = ycc[yy, xx]
                    i_c += 1
        bg = np.empty(3, np.float32)
        for c in range(3):
            bg[c] = np.median(ring[:, c])
        dist = np.empty(n_core, np.float32)
        for i in range(n_core):
            dist[i] = abs(cpx[i, 0] - bg[0]) + abs(cpx[i, 1] - bg[1]) + abs(cpx[i, 2] - bg[2])
        if n_core > 3:
            cut = np.median(dist)
        else:
            cut = -1.0
        n_top = 0
        for i in range(n_core):
            if dist[i] >= cut:
                n_top += 1
        top_px = np.empty((n_top, 3), np.float32)
        j = 0
        for i in range(n_core):
            if dist[i] >= cut:
                top_px[j] = cpx[i]
                j += 1
        dot = np.empty(3, np.float32)
        for c in range(3):
            dot[c] = np.median(top_px[:, c])
        ax0 = (dot[0] - bg[0]) * weights[0]
        ax1 = (dot[1] - bg[1]) * weights[1]
        ax2 = (dot[2] - bg[2]) * weights[2]
        nn = ax0 * (dot[0] - bg[0]) + ax1 * (dot[1] - bg[1]) + ax2 * (dot[2] - bg[2])
        if nn < 100.0:
            continue
        tot = 0.0
        mx = 0.0
        my = 0.0
        mxx = 0.0
        myy = 0.0
        mxy = 0.0
        for yy in range(h):
            for xx in range(w):
                if not support[yy, xx]:
                    continue
                a = ((ycc[yy, xx, 0] - bg[0]) * ax0 + (ycc[yy, xx, 1] - bg[1]) * ax1
                     + (ycc[yy, xx, 2] - bg[2]) * ax2) / nn
                if a > 1.0:
                    a = 1.0
                if a < min_alpha:
                    continue
                tot += a
                mx += a * xx
                my += a * yy
                mxx += a * xx * xx
                myy += a * yy * yy
                mxy += a * xx * yy
        if tot <= 1e-6:
            continue
        cx = mx / tot
        cy = my / tot
        out[b, 0] = 1.0
        out[b, 1] = x0 + cx
        out[b, 2] = y0 + cy
        out[b, 3] = tot
        out[b, 4] = mxx / tot - cx * cx
        out[b, 5] = myy / tot - cy * cy
        out[b, 6] = mxy / tot - cx * cy
        out[b, 7] = dot[0]
        out[b, 8] = dot[1]
        out[b, 9] = dot[2]
    return out


if HAVE_NUMBA:
    refine_blobs = njit(cache=True, nogil=True)(_refine_blobs_py)
else:  # pragma: no cover
    refine_blobs = _refine_blobs_py
