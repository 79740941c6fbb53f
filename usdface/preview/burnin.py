"""Frame furniture for review movies: burn-in text, panels side by side, a source video frame fitted
into a panel, and placeholders for frames a panel does not have.

Pure functions on ``(H, W, 3) uint8`` BGR images (OpenCV order); colours given as arguments are RGB.
"""
from __future__ import annotations

import numpy as np

from ..errors import OptionError
from .render import _cv2, _overlay_scale, _text

__all__ = ["burn_in", "fit_into", "hstack_panels", "placeholder", "timecode"]

_FONT = 0  # cv2.FONT_HERSHEY_SIMPLEX


def timecode(frame: int, rate: float) -> str:
    """SMPTE-style ``HH:MM:SS:FF`` of a frame number at ``rate`` (non-drop: FF counts whole frames
    of the rounded rate, as editors show 29.97 footage without drop-frame)."""
    fps = max(int(round(float(rate))), 1)
    f = int(frame)
    sign = "-" if f < 0 else ""
    f = abs(f)
    ff = f % fps
    s = f // fps
    return f"{sign}{s // 3600:02d}:{(s // 60) % 60:02d}:{s % 60:02d}:{ff:02d}"


def burn_in(img: np.ndarray, top_left=(), top_right=(), *, color=(245, 245, 245), band: bool = True,
            scale: float | None = None) -> np.ndarray:
    """Write lines of text in the top corners of ``img`` (in place; also returned).

    Parameters
    ----------
    img : ndarray (H, W, 3) uint8 BGR
    top_left, top_right : sequence of str
        Lines, the first one larger (the shot name, the frame number).
    band : bool
        Darken a band behind the text so it reads over any picture.
    scale : float, optional
        Text scale; default from the image size (as the preview's overlays).
    """
    cv2 = _cv2()
    h, w = img.shape[:2]
    s = _overlay_scale((w, h)) if scale is None else float(scale)
    lines = max(len(top_left), len(top_right))
    if not lines:
        return img
    step = 18 * s
    if band:
        y1 = min(int(round(6 * s + step * lines)), h)
        img[:y1] = (img[:y1].astype(np.uint16) * 3 // 5).astype(np.uint8)
    for column, align in ((top_left, "left"), (top_right, "right")):
        for k, line in enumerate(column):
            if not line:
                continue
            size = (0.52 if k == 0 else 0.42) * s
            x = 8 * s if align == "left" else w - 8 * s
            # never wider than half the image: shrink a long line rather than overlap the other corner
            (tw, _), _ = cv2.getTextSize(line, _FONT, size, 1)
            if tw > w / 2 - 12 * s:
                size *= (w / 2 - 12 * s) / tw
            _text(img, line, (x, (17 + 18 * k) * s), size, color, align=align)
    return img


def fit_into(frame: np.ndarray, size, *, background=(0, 0, 0)) -> np.ndarray:
    """``frame`` scaled to fit ``size`` (width, height) keeping its aspect ratio, centred (letterbox)."""
    cv2 = _cv2()
    w, h = (int(v) for v in size)
    fh, fw = frame.shape[:2]
    k = min(w / fw, h / fh)
    nw, nh = max(1, int(round(fw * k))), max(1, int(round(fh * k)))
    small = cv2.resize(frame, (nw, nh), interpolation=cv2.INTER_AREA if k < 1 else cv2.INTER_LINEAR)
    out = np.empty((h, w, 3), np.uint8)
    out[:] = background[::-1]
    y0, x0 = (h - nh) // 2, (w - nw) // 2
    out[y0:y0 + nh, x0:x0 + nw] = small
    return out


def placeholder(size, text: str, *, background=(18, 18, 20)) -> np.ndarray:
    """A dark panel with ``text`` in the middle (a frame the panel's shot or video does not have)."""
    cv2 = _cv2()
    w, h = (int(v) for v in size)
    out = np.empty((h, w, 3), np.uint8)
    out[:] = background[::-1]
    s = _overlay_scale((w, h))
    size_ = 0.5 * s
    (tw, th), _ = cv2.getTextSize(text, _FONT, size_, 1)
    if tw > w - 16:
        size_ *= (w - 16) / tw
        (tw, th), _ = cv2.getTextSize(text, _FONT, size_, 1)
    _text(out, text, ((w - tw) / 2, (h + th) / 2), size_, (200, 200, 200))
    return out


def hstack_panels(panels, *, divider: int = 2, color=(10, 10, 10)) -> np.ndarray:
    """Panels of one height side by side, with a thin divider drawn over their shared edge
    (the total width stays the sum of the panels' widths)."""
    panels = [np.asarray(p) for p in panels]
    if not panels:
        raise OptionError("side by side: no panels")
    if len({p.shape[0] for p in panels}) != 1:
        raise OptionError(f"side by side: panels have different heights {[p.shape[0] for p in panels]}")
    out = np.concatenate(panels, axis=1)
    x = 0
    for p in panels[:-1]:
        x += p.shape[1]
        lo = max(x - divider // 2, 0)
        out[:, lo:lo + divider] = color[::-1]
    return out
