"""A tracked frame drawn for people: the dots found, their recent paths and the lost ones, each
named by a label that stays inside the image and overlaps no other label, dot or the header
(placed by :func:`usdface.preview.overlays.place_point_labels`, with a leader line when a crowd
pushes a label away from its dot)."""
from __future__ import annotations

import numpy as np

__all__ = ["render_track_preview", "track_label_layout"]

#: radius of the circle around a valid dot (pixels)
DOT_RADIUS = 9
#: label colours (RGB): a dot found on this frame, and one lost (named at its last position)
VALID_RGB, LOST_RGB = (255, 255, 255), (255, 120, 110)
HEADER_ORIGIN, HEADER_FONT = (8, 20), 0.55


def _header(result, index: int) -> str:
    n_valid = int(np.isfinite(result.positions[index]).all(axis=1).sum())
    return f"frame {index}: {n_valid}/{len(result.names)} valid"


def _header_box(text: str) -> tuple[float, float, float, float]:
    import cv2

    (tw, th), bl = cv2.getTextSize(text, cv2.FONT_HERSHEY_SIMPLEX, HEADER_FONT, 2)
    x, y = HEADER_ORIGIN
    return (x - 2.0, y - th - 2.0, x + tw + 2.0, y + bl + 2.0)


def _shown(result, index: int) -> list:
    """(marker, xy, valid) of every dot drawn on frame ``index``: its position, or its last valid
    one before (a lost dot); markers never seen by then are not drawn."""
    pos = result.positions
    out = []
    for j in range(len(result.names)):
        p = pos[index, j]
        if np.isfinite(p).all():
            out.append((j, p, True))
            continue
        before = np.flatnonzero(np.isfinite(pos[:index + 1, j]).all(axis=1))
        if before.size:
            out.append((j, pos[before[-1], j], False))
    return out


def track_label_layout(result, index: int, image_size):
    """Where the labels of frame ``index`` go.

    Parameters
    ----------
    result : usdface.tracking.tracker.TrackResult
        ``positions`` (F, M, 2) pixels (NaN where invalid), ``names``.
    index : int
    image_size : (int, int)
        (width, height) in pixels.

    Returns
    -------
    entries : list of (xy, name, rgb, valid)
    placement : usdface.preview.labels.LabelPlacement
        ``boxes`` (K, 4) ``x0, y0, x1, y1`` inside the image, pairwise apart, clear of the dots
        (boxes of half-side 0.8 x the circle's radius) and of the header.
    bases : list of int
        Baseline of each label below its box's top.
    """
    from ..preview.overlays import label_font, place_point_labels

    shown = _shown(result, index)
    entries = [(np.asarray(xy, dtype=np.float64) + 0.5, result.names[j], VALID_RGB if ok else LOST_RGB, ok)
               for j, xy, ok in shown]
    half = 0.8 * DOT_RADIUS
    obstacles = [(xy[0] - half, xy[1] - half, xy[0] + half, xy[1] + half) for _, xy, _ in shown]
    obstacles.append(_header_box(_header(result, index)))
    placement, _, bases = place_point_labels(tuple(int(v) for v in image_size), entries, radius=DOT_RADIUS,
                                             font=label_font(1.0), obstacles=np.array(obstacles, dtype=np.float64),
                                             own_nearest=True)
    return entries, placement, bases


def render_track_preview(frame: np.ndarray, result, index: int, *, trail: int = 12) -> np.ndarray:
    """The frame with tracked dots: green circle = valid, red cross = invalid (at its last valid
    position), yellow trails over the last ``trail`` frames, marker names (:func:`track_label_layout`)
    and a valid count.

    Parameters
    ----------
    frame : ndarray, shape (H, W, 3), uint8 BGR
        The video frame ``index``.
    result : usdface.tracking.tracker.TrackResult
        Tracks: ``positions`` (F, M, 2) pixels, NaN where invalid; ``names``.
    index : int
        The frame shown.

    Returns
    -------
    ndarray, shape (H, W, 3), uint8 BGR
        A copy of ``frame`` with the drawing.
    """
    import cv2

    from ..preview.overlays import draw_point_labels, label_font

    img = frame.copy()
    pos = result.positions
    lo = max(0, index - trail)
    for j in range(len(result.names)):
        pts = pos[lo:index + 1, j]
        ok = np.isfinite(pts).all(axis=1)
        for a, b in zip(pts[:-1][ok[:-1] & ok[1:]], pts[1:][ok[:-1] & ok[1:]]):
            cv2.line(img, (int(round(a[0] * 4)), int(round(a[1] * 4))), (int(round(b[0] * 4)), int(round(b[1] * 4))),
                     (0, 255, 255), 1, cv2.LINE_AA, shift=2)
    for _, p, valid in _shown(result, index):
        if valid:
            cv2.circle(img, (int(round(p[0] * 16)), int(round(p[1] * 16))), DOT_RADIUS * 16, (40, 220, 40), 1,
                       cv2.LINE_AA, shift=4)
        else:
            cv2.drawMarker(img, (int(round(p[0])), int(round(p[1]))), (30, 30, 230), cv2.MARKER_TILTED_CROSS, 14, 2,
                           cv2.LINE_AA)
    entries, placement, bases = track_label_layout(result, index, (img.shape[1], img.shape[0]))
    draw_point_labels(img, entries, placement, bases, radius=DOT_RADIUS, font=label_font(1.0))
    header = _header(result, index)
    cv2.putText(img, header, HEADER_ORIGIN, cv2.FONT_HERSHEY_SIMPLEX, HEADER_FONT, (255, 255, 255), 2, cv2.LINE_AA)
    cv2.putText(img, header, HEADER_ORIGIN, cv2.FONT_HERSHEY_SIMPLEX, HEADER_FONT, (0, 0, 0), 1, cv2.LINE_AA)
    return img
