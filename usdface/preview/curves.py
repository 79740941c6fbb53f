"""Line plots of weight curves (and any per-frame series) drawn with OpenCV: no matplotlib.

:func:`plot_curves` draws one panel: the curves against time, a y range, tick labels, optional
shaded frame spans (e.g. the holds a check is about) and a legend; :func:`stack_panels` puts
panels under each other. Images are ``(H, W, 3) uint8`` BGR like the rest of :mod:`usdface.preview`;
colours given as arguments are RGB 0..255.
"""
from __future__ import annotations

import numpy as np

from .render import _cv2, _text

__all__ = ["plot_curves", "stack_panels", "CURVE_COLORS"]

#: distinct line colours (RGB), cycled
CURVE_COLORS = ((31, 119, 180), (255, 127, 14), (44, 160, 44), (214, 39, 40), (148, 103, 189), (140, 86, 75),
                (227, 119, 194), (127, 127, 127), (188, 189, 34), (23, 190, 207))


def _nice_step(span: float, target: int) -> float:
    raw = span / max(target, 1)
    mag = 10 ** np.floor(np.log10(raw)) if raw > 0 else 1.0
    for m in (1, 2, 2.5, 5, 10):
        if m * mag >= raw:
            return float(m * mag)
    return float(10 * mag)


def plot_curves(times, curves, labels, *, title: str = "", y_range=None, y_label: str = "", x_label: str = "s",
                spans=(), span_label: str = "", size=(1200, 360), colors=CURVE_COLORS, background=(250, 250, 250),
                line_width: int = 2) -> np.ndarray:
    """One panel of curves.

    Parameters
    ----------
    times : array_like, shape (F,)
        x values (seconds, frames...).
    curves : array_like, shape (F, C)
        One column per curve; NaN breaks a line.
    labels : sequence of str, length C
    y_range : (lo, hi), optional
        Default: the data's range (0..1 for weights in [0, 1]).
    spans : sequence of (x0, x1)
        Shaded x intervals (drawn under the curves), named once in the legend by ``span_label``.
    size : (width, height)

    Returns
    -------
    ndarray (H, W, 3) uint8, BGR
    """
    cv2 = _cv2()
    t = np.asarray(times, dtype=np.float64)
    c = np.asarray(curves, dtype=np.float64).reshape(t.size, -1)
    w, h = int(size[0]), int(size[1])
    img = np.empty((h, w, 3), dtype=np.uint8)
    img[:] = background[::-1]
    left, right, top, bottom = 64, 180, 30 if title else 12, 34
    x0, x1 = float(t.min()), float(t.max()) if t.max() > t.min() else float(t.min()) + 1.0
    if y_range is None:
        lo, hi = np.nanmin(c), np.nanmax(c)
        lo, hi = (0.0, 1.0) if not np.isfinite(lo) else (float(lo), float(hi) if hi > lo else float(lo) + 1.0)
    else:
        lo, hi = map(float, y_range)

    def px(x, y):
        return (left + (x - x0) / (x1 - x0) * (w - left - right), top + (hi - y) / (hi - lo) * (h - top - bottom))

    for a, b in spans:
        p0, p1 = px(a, hi), px(b, lo)
        cv2.rectangle(img, (int(p0[0]), int(p0[1])), (int(p1[0]), int(p1[1])), (215, 235, 250), -1)
    grid = (222, 222, 222)
    ys = _nice_step(hi - lo, 4)
    for y in np.arange(np.ceil(lo / ys) * ys, hi + 1e-9, ys):
        p = px(x0, y)
        cv2.line(img, (left, int(round(p[1]))), (w - right, int(round(p[1]))), grid, 1, cv2.LINE_AA)
        _text(img, f"{y:g}", (left - 6, p[1] + 4), 0.4, (60, 60, 60), outline=False, align="right")
    xs = _nice_step(x1 - x0, 10)
    for x in np.arange(np.ceil(x0 / xs) * xs, x1 + 1e-9, xs):
        p = px(x, lo)
        cv2.line(img, (int(round(p[0])), top), (int(round(p[0])), h - bottom), grid, 1, cv2.LINE_AA)
        _text(img, f"{x:g}", (p[0] - 8, h - bottom + 16), 0.4, (60, 60, 60), outline=False)
    cv2.rectangle(img, (left, top), (w - right, h - bottom), (90, 90, 90), 1)
    sh, f = 4, 16
    for j in range(c.shape[1]):
        rgb = colors[j % len(colors)]
        ok = np.isfinite(c[:, j])
        pts = np.array([px(x, y) for x, y in zip(t, np.where(ok, c[:, j], lo))])
        for run in np.split(np.arange(t.size), np.flatnonzero(np.diff(ok.astype(int)) != 0) + 1):
            if run.size > 1 and ok[run[0]]:
                poly = np.round(pts[run] * f).astype(np.int32).reshape(-1, 1, 2)
                cv2.polylines(img, [poly], False, rgb[::-1], line_width, cv2.LINE_AA, sh)
    if title:
        _text(img, title, (left, 20), 0.5, (20, 20, 20), outline=False)
    if x_label:
        _text(img, x_label, (w - right + 6, h - bottom + 16), 0.4, (60, 60, 60), outline=False)
    if y_label:
        _text(img, y_label, (6, top + 12), 0.4, (60, 60, 60), outline=False)
    ly = top + 14
    for j, lab in enumerate(labels):
        rgb = colors[j % len(colors)]
        cv2.line(img, (w - right + 10, ly - 4), (w - right + 34, ly - 4), rgb[::-1], 3, cv2.LINE_AA)
        _text(img, str(lab), (w - right + 40, ly), 0.42, (30, 30, 30), outline=False)
        ly += 18
    if spans and span_label:
        cv2.rectangle(img, (w - right + 10, ly - 10), (w - right + 34, ly), (215, 235, 250), -1)
        _text(img, span_label, (w - right + 40, ly), 0.42, (30, 30, 30), outline=False)
    return img


def stack_panels(panels, gap: int = 4, background=(255, 255, 255)) -> np.ndarray:
    """Panels of equal width under each other."""
    w = max(p.shape[1] for p in panels)
    rows = []
    for p in panels:
        if p.shape[1] < w:
            pad = np.empty((p.shape[0], w - p.shape[1], 3), dtype=np.uint8)
            pad[:] = background[::-1]
            p = np.concatenate([p, pad], axis=1)
        rows.append(p)
        sep = np.empty((gap, w, 3), dtype=np.uint8)
        sep[:] = background[::-1]
        rows.append(sep)
    return np.concatenate(rows[:-1], axis=0)
