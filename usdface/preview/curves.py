"""Line plots of weight curves (and any per-frame series) drawn with OpenCV: no matplotlib.

:func:`plot_curves` draws one panel: the curves against time, a y range, tick labels, optional
shaded frame spans (e.g. the holds a check is about) and a legend; :func:`stack_panels` puts
panels under each other. Images are ``(H, W, 3) uint8`` BGR like the rest of :mod:`usdface.preview`;
colours given as arguments are RGB 0..255.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .render import _cv2, _text

__all__ = ["CURVE_COLORS", "CurveStyle", "plot_curves", "stack_panels"]

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


@dataclass(frozen=True)
class CurveStyle:
    """How :func:`plot_curves` draws a panel: ``size`` (width, height) in pixels, line ``colors``
    (RGB, cycled), ``background`` (RGB) and ``line_width`` in pixels."""

    size: tuple = (1200, 360)
    colors: tuple = CURVE_COLORS
    background: tuple = (250, 250, 250)
    line_width: int = 2


#: the shaded spans' colour (BGR)
_SPAN_BGR = (215, 235, 250)


@dataclass(frozen=True)
class _Frame:
    """The plot area of a panel and its data ranges: maps data (x, y) to pixels."""

    left: int
    right: int
    top: int
    bottom: int
    w: int
    h: int
    x0: float
    x1: float
    lo: float
    hi: float

    def px(self, x, y):
        return (self.left + (x - self.x0) / (self.x1 - self.x0) * (self.w - self.left - self.right),
                self.top + (self.hi - y) / (self.hi - self.lo) * (self.h - self.top - self.bottom))


def plot_curves(times, curves, labels, *, title: str = "", y_range=None, y_label: str = "", x_label: str = "s",
                spans=(), span_label: str = "", style: CurveStyle = CurveStyle()) -> np.ndarray:
    """One panel of curves.

    Parameters
    ----------
    times : array_like, shape (F,)
        x values (seconds, frames...).
    curves : array_like, shape (F, C)
        One column per curve; NaN breaks a line.
    labels : sequence of str, length C
    title, y_label, x_label : str
    y_range : (lo, hi), optional
        Default: the data's range (0..1 for weights in [0, 1]).
    spans : sequence of (x0, x1)
        Shaded x intervals (drawn under the curves), named once in the legend by ``span_label``.
    style : CurveStyle
        Size, colours, background, line width.

    Returns
    -------
    ndarray (H, W, 3) uint8, BGR
    """
    t = np.asarray(times, dtype=np.float64)
    c = np.asarray(curves, dtype=np.float64).reshape(t.size, -1)
    w, h = int(style.size[0]), int(style.size[1])
    img = np.empty((h, w, 3), dtype=np.uint8)
    img[:] = style.background[::-1]
    x0, x1 = float(t.min()), float(t.max()) if t.max() > t.min() else float(t.min()) + 1.0
    if y_range is None:
        lo, hi = np.nanmin(c), np.nanmax(c)
        lo, hi = (0.0, 1.0) if not np.isfinite(lo) else (float(lo), float(hi) if hi > lo else float(lo) + 1.0)
    else:
        lo, hi = map(float, y_range)
    frame = _Frame(64, 180, 30 if title else 12, 34, w, h, x0, x1, lo, hi)
    _draw_axes(img, frame, spans)
    _draw_lines(img, frame, t, c, style)
    _draw_titles(img, frame, title, x_label, y_label)
    _draw_legend(img, frame, labels, style.colors, span_label if spans else "")
    return img


def _draw_axes(img, f: _Frame, spans) -> None:
    """Shaded spans, grid lines with tick labels, the plot area's frame."""
    cv2 = _cv2()
    for a, b in spans:
        p0, p1 = f.px(a, f.hi), f.px(b, f.lo)
        cv2.rectangle(img, (int(p0[0]), int(p0[1])), (int(p1[0]), int(p1[1])), _SPAN_BGR, -1)
    grid = (222, 222, 222)
    ys = _nice_step(f.hi - f.lo, 4)
    for y in np.arange(np.ceil(f.lo / ys) * ys, f.hi + 1e-9, ys):
        p = f.px(f.x0, y)
        cv2.line(img, (f.left, int(round(p[1]))), (f.w - f.right, int(round(p[1]))), grid, 1, cv2.LINE_AA)
        _text(img, f"{y:g}", (f.left - 6, p[1] + 4), 0.4, (60, 60, 60), outline=False, align="right")
    xs = _nice_step(f.x1 - f.x0, 10)
    for x in np.arange(np.ceil(f.x0 / xs) * xs, f.x1 + 1e-9, xs):
        p = f.px(x, f.lo)
        cv2.line(img, (int(round(p[0])), f.top), (int(round(p[0])), f.h - f.bottom), grid, 1, cv2.LINE_AA)
        _text(img, f"{x:g}", (p[0] - 8, f.h - f.bottom + 16), 0.4, (60, 60, 60), outline=False)
    cv2.rectangle(img, (f.left, f.top), (f.w - f.right, f.h - f.bottom), (90, 90, 90), 1)


def _draw_lines(img, f: _Frame, t: np.ndarray, c: np.ndarray, style: CurveStyle) -> None:
    """Each curve as anti-aliased polylines, broken where it is NaN (sub-pixel positions)."""
    cv2 = _cv2()
    sh, scale = 4, 16
    colors = style.colors
    for j in range(c.shape[1]):
        rgb = colors[j % len(colors)]
        ok = np.isfinite(c[:, j])
        pts = np.array([f.px(x, y) for x, y in zip(t, np.where(ok, c[:, j], f.lo))])
        for run in np.split(np.arange(t.size), np.flatnonzero(np.diff(ok.astype(int)) != 0) + 1):
            if run.size > 1 and ok[run[0]]:
                poly = np.round(pts[run] * scale).astype(np.int32).reshape(-1, 1, 2)
                cv2.polylines(img, [poly], False, rgb[::-1], style.line_width, cv2.LINE_AA, sh)


def _draw_titles(img, f: _Frame, title: str, x_label: str, y_label: str) -> None:
    if title:
        _text(img, title, (f.left, 20), 0.5, (20, 20, 20), outline=False)
    if x_label:
        _text(img, x_label, (f.w - f.right + 6, f.h - f.bottom + 16), 0.4, (60, 60, 60), outline=False)
    if y_label:
        _text(img, y_label, (6, f.top + 12), 0.4, (60, 60, 60), outline=False)


def _draw_legend(img, f: _Frame, labels, colors, span_label: str) -> None:
    """A line sample and name per curve at the right, then the spans' swatch."""
    cv2 = _cv2()
    x = f.w - f.right
    ly = f.top + 14
    for j, lab in enumerate(labels):
        rgb = colors[j % len(colors)]
        cv2.line(img, (x + 10, ly - 4), (x + 34, ly - 4), rgb[::-1], 3, cv2.LINE_AA)
        _text(img, str(lab), (x + 40, ly), 0.42, (30, 30, 30), outline=False)
        ly += 18
    if span_label:
        cv2.rectangle(img, (x + 10, ly - 10), (x + 34, ly), _SPAN_BGR, -1)
        _text(img, span_label, (x + 40, ly), 0.42, (30, 30, 30), outline=False)


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
