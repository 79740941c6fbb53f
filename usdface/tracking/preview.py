"""A tracked frame drawn for people: the dots found, their recent paths and the lost ones."""
from __future__ import annotations

import numpy as np

__all__ = ["render_track_preview"]


def render_track_preview(frame: np.ndarray, result, index: int, *, trail: int = 12) -> np.ndarray:
    """The frame with tracked dots: green circle = valid, red cross = invalid (at its last valid
    position), yellow trails over the last ``trail`` frames, marker names and a valid count.

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

    img = frame.copy()
    pos = result.positions
    lo = max(0, index - trail)
    for j, name in enumerate(result.names):
        pts = pos[lo:index + 1, j]
        ok = np.isfinite(pts).all(axis=1)
        for a, b in zip(pts[:-1][ok[:-1] & ok[1:]], pts[1:][ok[:-1] & ok[1:]]):
            cv2.line(img, (int(round(a[0] * 4)), int(round(a[1] * 4))), (int(round(b[0] * 4)), int(round(b[1] * 4))),
                     (0, 255, 255), 1, cv2.LINE_AA, shift=2)
        p = pos[index, j]
        if np.isfinite(p).all():
            cv2.circle(img, (int(round(p[0] * 16)), int(round(p[1] * 16))), 9 * 16, (40, 220, 40), 1, cv2.LINE_AA,
                       shift=4)
            label_at = p
        else:
            valid_before = np.flatnonzero(np.isfinite(pos[:index + 1, j]).all(axis=1))
            if valid_before.size == 0:
                continue
            q = pos[valid_before[-1], j]
            c = (int(round(q[0])), int(round(q[1])))
            cv2.drawMarker(img, c, (30, 30, 230), cv2.MARKER_TILTED_CROSS, 14, 2, cv2.LINE_AA)
            label_at = q
        cv2.putText(img, name, (int(label_at[0]) + 8, int(label_at[1]) - 6), cv2.FONT_HERSHEY_SIMPLEX, 0.33,
                    (255, 255, 255), 1, cv2.LINE_AA)
    n_valid = int(np.isfinite(pos[index]).all(axis=1).sum())
    label = f"frame {index}: {n_valid}/{len(result.names)} valid"
    cv2.putText(img, label, (8, 20), cv2.FONT_HERSHEY_SIMPLEX, 0.55, (255, 255, 255), 2, cv2.LINE_AA)
    cv2.putText(img, label, (8, 20), cv2.FONT_HERSHEY_SIMPLEX, 0.55, (0, 0, 0), 1, cv2.LINE_AA)
    return img
