"""Overlays drawn at the final resolution: text (with cached sprites), point glyphs, labels placed
without overlaps (:mod:`usdface.preview.labels`) with leader lines, the colour bar and legends.

Images are ``(H, W, 3) uint8`` BGR; colours given as arguments are RGB.
"""
from __future__ import annotations

from functools import lru_cache

import numpy as np

from ._common import _bgr, _compiled, _cv2


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
    """Blend a text sprite into ``img`` with its top-left corner at (x, y), clipped to the image
    (compiled when numba is installed: the same float32 arithmetic, without the temporaries)."""
    h, w = img.shape[:2]
    sh, sw = base.shape[:2]
    x0, y0 = max(x, 0), max(y, 0)
    x1, y1 = min(x + sw, w), min(y + sh, h)
    if x1 <= x0 or y1 <= y0:
        return
    kernels = _compiled()
    if kernels is not None and img.flags.c_contiguous and base.flags.c_contiguous and gain.flags.c_contiguous:
        kernels.paste_kernel(img, base, gain, y0, x0, y0 - y, x0 - x, y1 - y0, x1 - x0)
        return
    sl = (slice(y0 - y, y1 - y), slice(x0 - x, x1 - x))
    under = img[y0:y1, x0:x1].astype(np.float32)
    img[y0:y1, x0:x1] = np.clip(base[sl] + gain[sl] * under + 0.5, 0, 255).astype(np.uint8)


def _dim(rgb, k: float = 0.5, toward=(110, 110, 110)) -> tuple[int, int, int]:
    return tuple(int(round(c * (1 - k) + t * k)) for c, t in zip(rgb, toward))


def _draw_points(img, xy, in_view, visible, rgb, *, radius: float, shape: str) -> None:
    """Point glyphs: filled dots / diamonds where visible, hollow and dimmer where hidden."""
    cv2 = _cv2()
    sh = 4
    f = 1 << sh
    hidden_rgb = _dim(rgb, 0.45)
    rim = max(min(radius * 0.25, 1.0), 0.5)  # dark rim: thinner on small glyphs
    order = np.argsort(visible, kind="stable")  # hidden first, visible on top
    for m in order:
        if not in_view[m]:
            continue
        cx, cy = xy[m, 0] - 0.5, xy[m, 1] - 0.5
        c = (int(round(cx * f)), int(round(cy * f)))
        vis = bool(visible[m])
        thin = 1 if radius < 3 else 2
        if shape == "circle":
            r = int(round(radius * f))
            if vis:
                cv2.circle(img, c, r + int(round(rim * f)), (15, 15, 15), -1, cv2.LINE_AA, sh)
                cv2.circle(img, c, r, _bgr(rgb), -1, cv2.LINE_AA, sh)
            else:
                cv2.circle(img, c, r, (15, 15, 15), thin, cv2.LINE_AA, sh)
                cv2.circle(img, c, r, _bgr(hidden_rgb), 1, cv2.LINE_AA, sh)
        else:  # diamond
            r = radius * 1.25
            poly = np.array([[cx, cy - r], [cx + r, cy], [cx, cy + r], [cx - r, cy]])
            ip = np.round(poly * f).astype(np.int32).reshape(-1, 1, 2)
            if vis:
                g = 1.3 * rim
                big = np.array([[cx, cy - r - g], [cx + r + g, cy], [cx, cy + r + g], [cx - r - g, cy]])
                cv2.fillConvexPoly(img, np.round(big * f).astype(np.int32), (15, 15, 15), cv2.LINE_AA, sh)
                cv2.fillConvexPoly(img, ip.reshape(-1, 2), _bgr(rgb), cv2.LINE_AA, sh)
            else:
                cv2.polylines(img, [ip], True, (15, 15, 15), thin, cv2.LINE_AA, sh)
                cv2.polylines(img, [ip], True, _bgr(hidden_rgb), 1, cv2.LINE_AA, sh)


def glyph_radius(point_sets, size, *, scale: float) -> float:
    """Glyph radius in pixels: the image's default (4 px at 512, 3.5 px at least) but no more than
    0.35 of the median distance between neighbouring points, so glyphs never swamp a small
    picture (1.5 px at the least).

    ``point_sets``: list of (K, 2) projected points (NaN rows ignored)."""
    default = max(4.0 * scale, 3.5)
    spacing = []
    for xy in point_sets:
        p = np.asarray(xy, dtype=np.float64).reshape(-1, 2)
        p = p[np.isfinite(p).all(axis=1)]
        if p.shape[0] < 2:
            continue
        d = np.hypot(*(p[:, None, :] - p[None, :, :]).transpose(2, 0, 1))
        np.fill_diagonal(d, np.inf)
        near = d.min(axis=1)
        near = near[near > 0.25]  # coincident points (a marker on its own bound point) do not count
        if near.size:
            spacing.append(float(np.median(near)))
    if not spacing:
        return default
    return float(np.clip(0.35 * min(spacing), 1.5, default))


#: smallest label font scale (Hershey simplex 0.3: about 7 px capitals), so labels stay legible
MIN_LABEL_FONT = 0.3


def label_font(scale: float) -> float:
    """Font scale of point labels for an overlay scale (0.34 at 512 px, never below MIN_LABEL_FONT)."""
    return max(0.34 * scale, MIN_LABEL_FONT)


def place_point_labels(img_size, entries, *, radius: float, font: float, obstacles, own_nearest: bool = False):
    """Lay out point labels; ``entries`` = [(xy (2,), text, rgb, visible)]; ``own_nearest``: see
    :func:`usdface.preview.labels.place_labels`. Returns (placement, sizes, baselines)."""
    from .labels import place_labels

    cv2 = _cv2()
    sizes, bases = [], []
    for _, text, _, _ in entries:
        (tw, th), bl = cv2.getTextSize(text, _FONT, font, 3)  # the outline is 3 px thick
        sizes.append((tw + 2, th + bl + 2))
        bases.append(th + 1)
    anchors = np.array([e[0] for e in entries], dtype=np.float64).reshape(-1, 2) - 0.5
    placement = place_labels(anchors, np.array(sizes, dtype=np.float64).reshape(-1, 2), image_size=img_size,
                             gap=1.15 * radius + 2.0, obstacles=obstacles, pad=1.0, own_nearest=own_nearest)
    return placement, sizes, bases


def draw_point_labels(img, entries, placement, bases, *, radius: float, font: float) -> None:
    """Leader lines (for labels away from their point), then the labels."""
    cv2 = _cv2()
    for (xy, _, rgb, vis), box, lead in zip(entries, placement.boxes, placement.leader):
        if not lead or not np.isfinite(box).all():
            continue
        ax, ay = xy[0] - 0.5, xy[1] - 0.5
        qx, qy = np.clip(ax, box[0], box[2] - 1), np.clip(ay, box[1], box[3] - 1)  # nearest point of the box
        d = np.hypot(qx - ax, qy - ay)
        if d <= radius + 1:
            continue
        sx, sy = ax + (qx - ax) * (radius + 0.5) / d, ay + (qy - ay) * (radius + 0.5) / d
        f = 16
        p0, p1 = (int(round(sx * f)), int(round(sy * f))), (int(round(qx * f)), int(round(qy * f)))
        cv2.line(img, p0, p1, (15, 15, 15), 3, cv2.LINE_AA, 4)
        cv2.line(img, p0, p1, _bgr(rgb if vis else _dim(rgb, 0.45)), 1, cv2.LINE_AA, 4)
    for (xy, text, rgb, vis), box, base in zip(entries, placement.boxes, bases):
        if np.isfinite(box).all():
            _text(img, text, (box[0] + 1, box[1] + base), font, rgb if vis else _dim(rgb, 0.45))


def _colorbar(img, lut: np.ndarray, lo: float, hi: float, label: str, s: float, has_nan: bool) -> tuple:
    """Draw the colour bar at the right; returns its box (x0, y0, x1, y1) with labels."""
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
    bottom = y0 + n + 4 * s
    if has_nan:
        yy = y0 + n + int(round(8 * s))
        cv2.rectangle(img, (x0, yy), (x1 - 1, yy + bw - 1), (140, 140, 140), -1)
        _text(img, "n/a", (x0 - 6, yy + bw - 2), font, (235, 235, 235), align="right")
        bottom = yy + bw + 2
    (lw, _), _ = cv2.getTextSize(label or "", _FONT, 0.42 * s, 1)
    (tw, _), _ = cv2.getTextSize(max((fmt(lo), fmt(hi), fmt((lo + hi) / 2)), key=len), _FONT, font, 1)
    return (min(x0 - 8 - tw, x1 - lw) - 2, y0 - 13 * s - 12 * s, w, bottom)


def _fmt_range(lo: float, hi: float):
    span = abs(hi - lo) or max(abs(hi), abs(lo), 1.0)
    mag = max(abs(lo), abs(hi))
    if mag >= 1e5 or (mag > 0 and mag < 1e-3):
        return lambda v: f"{v:.3g}"
    digits = int(np.clip(2 - np.floor(np.log10(span)), 0, 6))
    return lambda v: f"{v:.{digits}f}"


def _legend(img, entries, s: float, *, corner: str = "bottom-left", draw: bool = True):
    """entries: (kind, rgb, text); kind 'swatch' | 'circle' | 'diamond'. Returns the legend's box
    (x0, y0, x1, y1) or None; ``draw=False`` only measures."""
    cv2 = _cv2()
    if not entries:
        return None
    h, w = img.shape[:2]
    font = 0.40 * s
    step = int(round(17 * s))
    sw = int(round(10 * s))
    widths = [cv2.getTextSize(t, _FONT, font, 1)[0][0] for _, _, t in entries]
    pad = int(round(8 * s))
    y = h - pad - step * (len(entries) - 1)
    x = pad if corner == "bottom-left" else w - pad - max(widths) - sw - int(round(6 * s))
    rect = (x - 2, y - step - 2, x + sw + int(round(6 * s)) + max(widths) + 3, h - pad + int(round(5 * s)) + 2)
    if not draw:
        return rect
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
    return rect
