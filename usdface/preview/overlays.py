"""Overlays drawn at the final resolution: text (with cached sprites), point glyphs, labels placed
without overlaps (:mod:`usdface.preview.labels`) with leader lines, the colour bar and legends.

Images are ``(H, W, 3) uint8`` BGR; colours given as arguments are RGB.
"""
from __future__ import annotations

from functools import lru_cache

import numpy as np

from ._common import _bgr, _cv2


def _overlay_scale(size) -> float:
    return max(min(int(size[0]), int(size[1])) / 512.0, 0.5)


_FONT = 0  # cv2.FONT_HERSHEY_SIMPLEX


def _text(img, text: str, org, scale: float, rgb, *, thickness: int = 1, outline: bool = True,
          align: str = "left") -> None:
    """Anti-aliased text with a dark outline; org is the baseline start (or end if align=right).

    Text drawn again (legends, names on every frame of a movie) is pasted from a cached sprite
    instead of being rasterised again (Hershey glyphs with anti-aliasing cost ~0.1 ms a line).
    """
    cv2 = _cv2()
    x, y = int(round(org[0])), int(round(org[1]))
    if align == "right":
        (tw, _), _ = cv2.getTextSize(text, _FONT, scale, thickness)
        x -= tw
    key = (text, round(float(scale), 6), tuple(int(c) for c in rgb), int(thickness), bool(outline))
    if key in _TEXT_SEEN:
        base, gain, (ox, oy) = _text_sprite(*key)
        _paste(img, base, gain, x - ox, y - oy)
        return
    if len(_TEXT_SEEN) > 4096:
        _TEXT_SEEN.clear()
    _TEXT_SEEN.add(key)
    _put_text(img, text, (x, y), scale, rgb, thickness=thickness, outline=outline)


def _put_text(img, text, org, scale, rgb, *, thickness, outline) -> None:
    cv2 = _cv2()
    if outline:
        cv2.putText(img, text, org, _FONT, scale, (12, 12, 12), thickness + 2, cv2.LINE_AA)
    cv2.putText(img, text, org, _FONT, scale, _bgr(rgb), thickness, cv2.LINE_AA)


_TEXT_SEEN: set = set()


@lru_cache(maxsize=2048)
def _text_sprite(text, scale, rgb, thickness, outline):
    """(base, gain, origin) of a text drawn over black and over white: anti-aliased drawing is a
    per-pixel blend ``out = base + gain * under`` (gain = (white - black) / 255), so pasting it
    gives what drawing on the image gives (within a few levels of 255 at glyph edges)."""
    cv2 = _cv2()
    t = thickness + 2 if outline else thickness
    (tw, th), bl = cv2.getTextSize(text, _FONT, scale, t)
    pad = t + 2
    w, h = tw + 2 * pad, th + bl + 2 * pad
    origin = (pad, pad + th)
    black = np.zeros((h, w, 3), np.uint8)
    white = np.full((h, w, 3), 255, np.uint8)
    for canvas in (black, white):
        _put_text(canvas, text, origin, scale, rgb, thickness=thickness, outline=outline)
    base = black.astype(np.float32)
    gain = (white.astype(np.float32) - base) / 255.0
    rows = np.flatnonzero((gain < 0.999).any(axis=(1, 2)))
    cols = np.flatnonzero((gain < 0.999).any(axis=(0, 2)))
    if rows.size == 0:
        return base[:0, :0], gain[:0, :0], origin
    r0, r1, c0, c1 = rows[0], rows[-1] + 1, cols[0], cols[-1] + 1
    return (base[r0:r1, c0:c1].copy(), gain[r0:r1, c0:c1].copy(), (origin[0] - c0, origin[1] - r0))


def _paste(img, base, gain, x, y) -> None:
    """Blend a text sprite into ``img`` with its top-left corner at (x, y), clipped to the image."""
    h, w = img.shape[:2]
    sh, sw = base.shape[:2]
    x0, y0 = max(x, 0), max(y, 0)
    x1, y1 = min(x + sw, w), min(y + sh, h)
    if x1 <= x0 or y1 <= y0:
        return
    sl = (slice(y0 - y, y1 - y), slice(x0 - x, x1 - x))
    under = img[y0:y1, x0:x1].astype(np.float32)
    img[y0:y1, x0:x1] = np.clip(base[sl] + gain[sl] * under + 0.5, 0, 255).astype(np.uint8)


def _dim(rgb, k: float = 0.5, toward=(110, 110, 110)) -> tuple[int, int, int]:
    return tuple(int(round(c * (1 - k) + t * k)) for c, t in zip(rgb, toward))


def _draw_points(img, xy, in_view, visible, labels, rgb, *, radius: float, shape: str,
                 font: float) -> None:
    cv2 = _cv2()
    sh = 4
    f = 1 << sh
    hidden_rgb = _dim(rgb, 0.45)
    order = np.argsort(visible, kind="stable")  # hidden first, visible on top
    for m in order:
        if not in_view[m]:
            continue
        cx, cy = xy[m, 0] - 0.5, xy[m, 1] - 0.5
        c = (int(round(cx * f)), int(round(cy * f)))
        vis = bool(visible[m])
        if shape == "circle":
            r = int(round(radius * f))
            if vis:
                cv2.circle(img, c, r + f, (15, 15, 15), -1, cv2.LINE_AA, sh)
                cv2.circle(img, c, r, _bgr(rgb), -1, cv2.LINE_AA, sh)
            else:
                cv2.circle(img, c, r, (15, 15, 15), 2, cv2.LINE_AA, sh)
                cv2.circle(img, c, r, _bgr(hidden_rgb), 1, cv2.LINE_AA, sh)
        else:  # diamond
            r = radius * 1.25
            poly = np.array([[cx, cy - r], [cx + r, cy], [cx, cy + r], [cx - r, cy]])
            ip = np.round(poly * f).astype(np.int32).reshape(-1, 1, 2)
            if vis:
                big = np.array([[cx, cy - r - 1.3], [cx + r + 1.3, cy], [cx, cy + r + 1.3], [cx - r - 1.3, cy]])
                cv2.fillConvexPoly(img, np.round(big * f).astype(np.int32), (15, 15, 15), cv2.LINE_AA, sh)
                cv2.fillConvexPoly(img, ip.reshape(-1, 2), _bgr(rgb), cv2.LINE_AA, sh)
            else:
                cv2.polylines(img, [ip], True, (15, 15, 15), 2, cv2.LINE_AA, sh)
                cv2.polylines(img, [ip], True, _bgr(hidden_rgb), 1, cv2.LINE_AA, sh)
        if labels is not None and labels[m]:
            _text(img, labels[m], (cx + radius + 2, cy - radius - 1), font, rgb if vis else hidden_rgb)


def _colorbar(img, lut: np.ndarray, lo: float, hi: float, label: str, s: float, has_nan: bool) -> None:
    cv2 = _cv2()
    h, w = img.shape[:2]
    bw = max(8, int(round(12 * s)))
    x1 = w - int(round(12 * s))
    x0 = x1 - bw
    y0, y1 = int(round(h * 0.22)), int(round(h * 0.74))
    n = max(y1 - y0, 2)
    col = lut[np.rint(np.linspace(lut.shape[0] - 1, 0, n)).astype(int)]  # top = high
    img[y0:y0 + n, x0:x1] = (np.round(col[:, ::-1] * 255).astype(np.uint8))[:, None, :]
    cv2.rectangle(img, (x0 - 1, y0 - 1), (x1, y0 + n), (200, 200, 200), 1, cv2.LINE_8)  # outside the bar
    font = 0.38 * s
    fmt = _fmt_range(lo, hi)
    for frac, val in ((0.0, hi), (0.5, (lo + hi) / 2), (1.0, lo)):
        y = y0 + frac * (n - 1)
        cv2.line(img, (x0 - 4, int(round(y))), (x0 - 1, int(round(y))), (220, 220, 220), 1, cv2.LINE_AA)
        _text(img, fmt(val), (x0 - 6, y + 4 * s), font, (235, 235, 235), align="right")
    if label:
        _text(img, label, (x1, y0 - 13 * s), 0.42 * s, (240, 240, 240), align="right")
    if has_nan:
        yy = y0 + n + int(round(8 * s))
        cv2.rectangle(img, (x0, yy), (x1 - 1, yy + bw - 1), (140, 140, 140), -1)
        _text(img, "n/a", (x0 - 6, yy + bw - 2), font, (235, 235, 235), align="right")


def _fmt_range(lo: float, hi: float):
    span = abs(hi - lo) or max(abs(hi), abs(lo), 1.0)
    mag = max(abs(lo), abs(hi))
    if mag >= 1e5 or (mag > 0 and mag < 1e-3):
        return lambda v: f"{v:.3g}"
    digits = int(np.clip(2 - np.floor(np.log10(span)), 0, 6))
    return lambda v: f"{v:.{digits}f}"


def _legend(img, entries, s: float, *, corner: str = "bottom-left") -> None:
    """entries: (kind, rgb, text); kind 'swatch' | 'circle' | 'diamond'."""
    cv2 = _cv2()
    if not entries:
        return
    h, w = img.shape[:2]
    font = 0.40 * s
    step = int(round(17 * s))
    sw = int(round(10 * s))
    widths = [cv2.getTextSize(t, _FONT, font, 1)[0][0] for _, _, t in entries]
    pad = int(round(8 * s))
    y = h - pad - step * (len(entries) - 1)
    x = pad if corner == "bottom-left" else w - pad - max(widths) - sw - int(round(6 * s))
    for kind, rgb, text in entries:
        cy = y - sw // 2 - 1
        if kind == "swatch":
            cv2.rectangle(img, (x - 1, cy - sw // 2 - 1), (x + sw, cy + sw // 2 + 1), (15, 15, 15), -1)
            cv2.rectangle(img, (x, cy - sw // 2), (x + sw - 1, cy + sw // 2), _bgr(rgb), -1)
        elif kind == "circle":
            cv2.circle(img, (x + sw // 2, cy), sw // 2 + 1, (15, 15, 15), -1, cv2.LINE_AA)
            cv2.circle(img, (x + sw // 2, cy), sw // 2, _bgr(rgb), -1, cv2.LINE_AA)
        else:
            r = sw // 2 + 1
            c = (x + sw // 2, cy)
            pts = np.array([[c[0], c[1] - r], [c[0] + r, c[1]], [c[0], c[1] + r], [c[0] - r, c[1]]], np.int32)
            cv2.fillConvexPoly(img, pts, _bgr(rgb), cv2.LINE_AA)
        _text(img, text, (x + sw + int(round(6 * s)), y), font, (235, 235, 235))
        y += step
