"""Frame-to-frame marker tracking: identities kept through fast motion, occlusion and merges.

For each frame (:meth:`MarkerTracker.step`):

1. **Prediction.** Tracked markers: constant velocity. Lost markers: their last estimate moved
   with the mean frame-to-frame motion of their nearest tracked neighbours (a face moves
   coherently), so they are looked for where they should be when they reappear.
2. **Global motion.** A head jerk moves every dot by more than the gate; the median vector from
   each prediction to its nearest detection (the shared motion, robust to outliers), applied
   twice, re-centres all predictions first.
3. **Merged blobs.** A detection whose area fits two or more dots and which has that many
   predictions near it is split by weighted k-means started at the predictions.
4. **Assignment.** Hungarian assignment (``scipy.optimize.linear_sum_assignment``) of detections
   to predictions minimising total distance, with a gate per marker (half the smallest marker
   spacing; wider for a marker lost for a while, up to the spacing).
5. **Validity.** A match is a measurement only if its confidence is high enough and its area is
   at least ``min_area_ratio`` of the marker's usual area (a half-hidden dot's centroid is
   biased). Everything else is invalid (NaN): positions are never invented.
6. **Colour adaptation.** The colour model's mean follows the dots' measured chroma (slow
   exponential average), so a lighting change across the clip does not lose them.
"""
from __future__ import annotations

import logging
import math
from dataclasses import dataclass, field

import numpy as np
from scipy.optimize import linear_sum_assignment

from ..errors import MarkerError, OptionError, list_names
from .detect import ColourModel, Detections, MarkerDetector, learn_colour_model, to_ycrcb

log = logging.getLogger("usdface")

__all__ = ["MarkerTracker", "TrackResult", "initialise_from_seeds", "initialise_auto", "track_frames"]

_BIG = 1e9


@dataclass
class TrackResult:
    """Tracked 2D marker positions.

    Attributes
    ----------
    names : tuple of str, length M
    positions : ndarray, shape (F, M, 2), float64
        Pixels (OpenCV convention: integer = pixel centre, y down); NaN where invalid.
    confidence : ndarray, shape (F, M), float64
        In [0, 1]; 0 where invalid.
    size : (W, H)
        Frame size in pixels.
    rate : float
        Frames per second.
    stats : dict
        Counters (frames, detections, splits, reacquisitions, colour updates...).
    """

    names: tuple
    positions: np.ndarray
    confidence: np.ndarray
    size: tuple
    rate: float
    stats: dict = field(default_factory=dict)

    @property
    def valid(self) -> np.ndarray:
        return np.isfinite(self.positions).all(axis=2)

    def to_capture(self, *, source: str = "", units: str | None = "px", start_frame: int = 0):
        """A :class:`~usdface.model.capture.Capture` (z = 0, history step with ``"dims": 2``)."""
        from ..model.capture import Capture

        pos = np.zeros(self.positions.shape[:2] + (3,))
        pos[..., :2] = self.positions
        pos[~self.valid] = np.nan
        return Capture(names=self.names, positions=pos, rate=self.rate, units=units, start_frame=start_frame,
                       source=source, history=({"step": "track", "dims": 2, "width": int(self.size[0]),
                                                "height": int(self.size[1])},))


def _nn_spacing(xy: np.ndarray) -> float:
    d = np.linalg.norm(xy[:, None, :] - xy[None, :, :], axis=2)
    np.fill_diagonal(d, np.inf)
    return float(d.min()) if xy.shape[0] > 1 else 100.0


class MarkerTracker:
    """Track M named markers through frames, starting from known positions on the first frame.

    Parameters
    ----------
    detector : MarkerDetector
    names : sequence of str, length M
    initial : ndarray, shape (M, 2)
        Positions on the first frame (pixels).
    initial_area : ndarray, shape (M,), optional
        Dot areas on the first frame (pixels^2); default pi r^2 at the middle of the radius range.
    gate : float, optional
        Largest distance (pixels) between a prediction and its detection; default half the smallest
        marker spacing on the first frame (at least 2 r_max).
    min_confidence : float
        Detections below this confidence are not measurements.
    min_area_ratio : float
        A detection smaller than this fraction of the marker's usual area is a partly hidden dot: invalid.
    adapt : float
        Rate (0..1) at which the colour model follows the dots' chroma per frame (0: fixed model).
    """

    def __init__(self, detector: MarkerDetector, names, initial, *, initial_area=None, gate: float | None = None,
                 min_confidence: float = 0.2, min_area_ratio: float = 0.6, adapt: float = 0.1):
        self.detector = detector
        self.names = tuple(names)
        xy = np.asarray(initial, dtype=np.float64).reshape(-1, 2)
        m = xy.shape[0]
        if m != len(self.names):
            raise OptionError(f"tracker: {len(self.names)} names for {m} initial positions")
        r1, r2 = detector.radius
        self.spacing = _nn_spacing(xy)
        self.gate = float(gate) if gate is not None else max(0.5 * self.spacing, 2.0 * r2)
        if not self.gate > 0:
            raise OptionError(f"--gate: expected a positive distance in pixels; got {gate}")
        self.min_confidence = float(min_confidence)
        self.min_area_ratio = float(min_area_ratio)
        self.adapt = float(adapt)
        self.pos = xy.copy()                 # best estimate (measured or predicted)
        self.vel = np.zeros((m, 2))
        self.valid = np.ones(m, bool)
        self.lost = np.zeros(m, int)
        mid = 0.5 * (r1 + r2)
        self.area = (np.full(m, math.pi * mid * mid) if initial_area is None
                     else np.asarray(initial_area, dtype=np.float64).copy())
        d = np.linalg.norm(xy[:, None, :] - xy[None, :, :], axis=2)
        np.fill_diagonal(d, np.inf)
        self.neighbours = np.argsort(d, axis=1)[:, :min(6, max(m - 1, 1))]
        self._model_mean = detector.model.mean.copy()
        self.stats = {"frames": 0, "detections": 0, "splits": 0, "reacquired": 0, "colourUpdates": 0,
                      "globalShiftMax": 0.0}

    # -- prediction ----------------------------------------------------------------------------------
    def predict(self) -> np.ndarray:
        """(M, 2) predicted positions for the next frame."""
        return self.pos + np.where(self.valid[:, None], self.vel, 0.0)

    def _gates(self) -> np.ndarray:
        g = self.gate * (1.0 + 0.25 * np.minimum(self.lost, 4))
        return np.minimum(g, max(self.gate, 0.9 * self.spacing))

    # -- one frame ---------------------------------------------------------------------------------
    def step(self, frame_bgr: np.ndarray, detections: Detections | None = None):
        """Track one frame; returns ``(positions (M, 2) with NaN where invalid, confidence (M,))``."""
        det = self.detector.detect(frame_bgr) if detections is None else detections
        self.stats["frames"] += 1
        self.stats["detections"] += len(det)
        m = len(self.names)
        pred = self.predict()
        out = np.full((m, 2), np.nan)
        conf = np.zeros(m)
        if len(det) == 0:
            self._update(pred, np.zeros(m, bool), out)
            return out, conf

        # global motion: median of prediction -> nearest detection, twice
        shift_total = np.zeros(2)
        for _ in range(2):
            d = np.linalg.norm(pred[:, None, :] - det.xy[None, :, :], axis=2)
            k = d.argmin(axis=1)
            near = d[np.arange(m), k] < 0.9 * self.spacing
            if near.sum() >= max(3, m // 4):
                shift = np.median(det.xy[k[near]] - pred[near], axis=0)
                pred = pred + shift
                shift_total += shift
        self.stats["globalShiftMax"] = max(self.stats["globalShiftMax"], float(np.hypot(*shift_total)))

        det = self._split_merged(det, pred, frame_bgr)
        gates = self._gates()
        d = np.linalg.norm(pred[:, None, :] - det.xy[None, :, :], axis=2)
        cost = np.where(d <= gates[:, None], d, _BIG)
        rows, cols = linear_sum_assignment(cost)
        keep = cost[rows, cols] < _BIG
        rows, cols = rows[keep], cols[keep]
        measured = np.zeros(m, bool)
        chroma = []
        for j, k in zip(rows, cols):
            c = float(det.confidence[k])
            area_ok = det.area[k] >= self.min_area_ratio * self.area[j]
            too_big = det.area[k] > 1.8 * self.area[j] and det.hough[k] != -2
            if c < self.min_confidence or not area_ok or too_big:
                continue
            if self.lost[j] > 0 and c < 0.5:
                continue  # re-acquire only on a clear dot
            measured[j] = True
            out[j] = det.xy[k]
            # confidence: detection x agreement with the prediction
            conf[j] = c * math.exp(-0.5 * (d[j, k] / max(0.5 * gates[j], 1e-9)) ** 2) ** 0.25
            if c > 0.5:
                chroma.append(det.chroma[k])
                self.area[j] = 0.9 * self.area[j] + 0.1 * det.area[k]
            if self.lost[j] > 0:
                self.stats["reacquired"] += 1
        self._update(pred, measured, out)
        if self.adapt > 0 and len(chroma) >= 3:
            self._adapt(np.asarray(chroma))
        return out, conf

    def _update(self, pred, measured, out) -> None:
        prev = self.pos.copy()
        newpos = pred.copy()
        newpos[measured] = out[measured]
        # lost markers follow their tracked neighbours' motion
        lost = ~measured
        if lost.any() and measured.any():
            motion = newpos - prev
            for j in np.flatnonzero(lost):
                nb = [i for i in self.neighbours[j] if measured[i] and self.valid[i]]
                if nb:
                    newpos[j] = prev[j] + motion[nb].mean(axis=0)
        vel_new = newpos - prev
        both = measured & self.valid
        self.vel[both] = vel_new[both]
        self.vel[~both] *= 0.5
        self.pos = newpos
        self.lost = np.where(measured, 0, self.lost + 1)
        self.valid = measured

    def _adapt(self, chroma: np.ndarray) -> None:
        target = np.median(chroma[:, 1:3], axis=0)
        model = self.detector.model
        mean = (1 - self.adapt) * model.mean + self.adapt * target
        luma = (1 - self.adapt) * model.luma + self.adapt * float(np.median(chroma[:, 0]))
        if np.abs(mean - self._model_mean).max() > 1.0:
            self.detector.set_model(model.moved_to(mean, luma))
            self._model_mean = mean.copy()
            self.stats["colourUpdates"] += 1
        else:
            self.detector.model = model.moved_to(mean, luma)

    def _group_touching(self, det: Detections, single: float) -> Detections:
        """Touching dots seen as two blobs whose windows overlap (each then holds part of the other
        and is biased): replace each such pair by one blob over the union window, to be split."""
        if len(det) < 2 or any(w is None for w in det.windows):
            return det
        r2 = self.detector.radius[1]
        d = np.linalg.norm(det.xy[:, None, :] - det.xy[None, :, :], axis=2)
        np.fill_diagonal(d, np.inf)
        i, j = np.nonzero(np.triu(d < 2.0 * r2))
        pairs = [(a, b) for a, b in zip(i, j) if det.area[a] > 1.15 * single or det.area[b] > 1.15 * single]
        if not pairs:
            return det
        used = set()
        windows = list(det.windows)
        area = det.area.copy()
        xy = det.xy.copy()
        drop = []
        for a, b in pairs:
            if a in used or b in used:
                continue
            used.update((a, b))
            wa, wb = det.windows[a], det.windows[b]
            windows[a] = (min(wa[0], wb[0]), min(wa[1], wb[1]), max(wa[2], wb[2]), max(wa[3], wb[3]),
                          min(wa[4], wb[4]), min(wa[5], wb[5]), max(wa[6], wb[6]), max(wa[7], wb[7]))
            area[a] = 2.0 * single
            xy[a] = 0.5 * (det.xy[a] + det.xy[b])
            drop.append(b)
        keep = np.setdiff1d(np.arange(len(det)), drop)
        out = det.subset(keep)
        out.windows = [windows[k] for k in keep]
        out.area = area[keep]
        out.xy = xy[keep]
        return out

    def _split_merged(self, det: Detections, pred: np.ndarray, frame_bgr) -> Detections:
        """Replace blobs holding several dots by one detection per dot (k-means at the predictions)."""
        single = float(np.median(self.area))
        det = self._group_touching(det, single)
        big = np.flatnonzero(det.area > 1.6 * single)
        if big.size == 0:
            return det
        keep = np.ones(len(det), bool)
        add = []
        for k in big:
            n_fit = int(round(det.area[k] / single))
            reach = math.sqrt(det.area[k] / math.pi) + 0.5 * self.gate
            dist = np.linalg.norm(pred - det.xy[k], axis=1)
            near = np.flatnonzero(dist < reach)
            if n_fit < 2 or near.size < 2:
                continue
            near = near[np.argsort(dist[near])][:n_fit]
            centres = self.detector.split(frame_bgr, det, k, pred[near])
            keep[k] = False
            self.stats["splits"] += 1
            for c in centres:
                add.append((c, det.area[k] / len(centres), det.confidence[k] * 0.8, det.chroma[k]))
        if not add:
            return det
        out = det.subset(np.flatnonzero(keep))
        xy = np.vstack([out.xy] + [a[0][None] for a in add])
        area = np.r_[out.area, [a[1] for a in add]]
        n_add = len(add)
        return Detections(xy, area, np.r_[out.radius, np.sqrt(area[-n_add:] / math.pi)],
                          np.r_[out.elongation, np.ones(n_add)], np.r_[out.confidence, [a[2] for a in add]],
                          np.vstack([out.chroma] + [a[3][None] for a in add]), np.r_[out.hough, np.full(n_add, -2)],
                          out.windows + [None] * n_add)


# ================================================================================================
# initialisation
# ================================================================================================
def initialise_from_seeds(frame_bgr: np.ndarray, seeds: dict, *, radius, threshold: float = 4.0,
                          min_std: float = 8.0):
    """Learn the colour model at seed points and find each seeded dot on the first frame.

    Parameters
    ----------
    frame_bgr : ndarray (H, W, 3) uint8
    seeds : dict
        ``{name: (x, y)}`` pixels (already validated against the image size).
    radius : (r_min, r_max)

    Returns
    -------
    detector : MarkerDetector
    names : tuple of str
    xy : ndarray (M, 2)
    area : ndarray (M,)

    Raises
    ------
    MarkerError
        A seeded marker has no dot near it (names them).
    """
    names = tuple(seeds)
    pts = np.array([seeds[n] for n in names], dtype=np.float64)
    model = learn_colour_model(frame_bgr, pts, radius=radius[0], min_std=min_std)
    if model.regularised:
        log.info("colour model regularised (degenerate or very tight seed colours): covariance floor %.1f levels",
                 min_std)
    detector = MarkerDetector(model, radius, threshold=threshold)
    det = detector.detect(frame_bgr, hough=True)
    reach = 2.0 * radius[1] + 3.0
    if len(det):
        d = np.linalg.norm(pts[:, None, :] - det.xy[None, :, :], axis=2)
        cost = np.where(d <= reach, d, _BIG)
        rows, cols = linear_sum_assignment(cost)
        ok = cost[rows, cols] < _BIG
        match = dict(zip(rows[ok], cols[ok]))
    else:
        match = {}
    missing = [f"{names[i]} ({pts[i, 0]:g}, {pts[i, 1]:g})" for i in range(len(names)) if i not in match]
    if missing:
        raise MarkerError(f"first frame: no dot of the seeds' colour (radius {radius[0]:g}-{radius[1]:g} px) within "
                          f"{reach:g} px of the seed for marker(s) {list_names(missing)}; "
                          f"{len(det)} dot(s) found in the frame")
    idx = np.array([match[i] for i in range(len(names))])
    return detector, names, det.xy[idx].copy(), det.area[idx].copy()


def _procrustes_2d(src: np.ndarray, dst: np.ndarray):
    """Similarity (s, R, t) minimising |s R src + t - dst|^2 (no reflection)."""
    ms, md = src.mean(axis=0), dst.mean(axis=0)
    a, b = src - ms, dst - md
    u, sv, vt = np.linalg.svd(b.T @ a)
    dd = np.sign(np.linalg.det(u @ vt))
    rot = u @ np.diag([1.0, dd]) @ vt
    scale = float((sv * [1.0, dd]).sum() / max((a * a).sum(), 1e-12))
    return scale, rot, md - scale * rot @ ms


def name_by_layout(xy: np.ndarray, layout_names, layout_xy: np.ndarray):
    """Name detected dots by matching them to a layout's projected positions.

    Parameters
    ----------
    xy : ndarray (N, 2)
        Detected dots (pixels, y down).
    layout_names : sequence of str, length L >= N
    layout_xy : ndarray (L, 2)
        Layout positions in any unit, **y down** (a front view: x, -y of the 3D layout).

    Returns
    -------
    list of str, length N (the layout name of each dot), and the mean residual (pixels).
    """
    lay = np.asarray(layout_xy, dtype=np.float64)
    s = np.sqrt(((xy - xy.mean(0)) ** 2).sum(1).mean() / max(((lay - lay.mean(0)) ** 2).sum(1).mean(), 1e-12))
    rot = np.eye(2)
    t = xy.mean(0) - s * lay.mean(0)
    for _ in range(30):
        moved = (s * (rot @ lay.T)).T + t
        d = np.linalg.norm(moved[:, None, :] - xy[None, :, :], axis=2)
        rows, cols = linear_sum_assignment(d)
        s_new, rot_new, t_new = _procrustes_2d(lay[rows], xy[cols])
        if abs(s_new - s) < 1e-9 * s and np.allclose(t_new, t, atol=1e-6):
            break
        s, rot, t = s_new, rot_new, t_new
    moved = (s * (rot @ lay.T)).T + t
    d = np.linalg.norm(moved[:, None, :] - xy[None, :, :], axis=2)
    rows, cols = linear_sum_assignment(d)
    names = [None] * xy.shape[0]
    for r, c in zip(rows, cols):
        names[c] = str(layout_names[r])
    return names, float(d[rows, cols].mean())


def initialise_auto(frame_bgr: np.ndarray, n: int, *, radius, threshold: float = 4.0, min_std: float = 8.0,
                    layout=None):
    """Find ``n`` dots on the first frame without seeds: circular Hough transform, then colour.

    Circles found by the Hough transform on the luma are kept when their inside differs in chroma
    from the ring around them; the largest group of such circles of one colour gives the colour
    model; the ``n`` most confident dots of that colour are the markers. Names come from
    ``layout`` ``(names, xy_down)`` (see :func:`name_by_layout`) when given, else ``m00, m01, ...``
    in reading order (top to bottom, left to right).
    """
    import cv2

    if n < 1:
        raise OptionError(f"--auto: expected a number of markers >= 1; got {n}")
    r1, r2 = radius
    ycc = to_ycrcb(frame_bgr).astype(np.float32)
    gray = cv2.cvtColor(frame_bgr, cv2.COLOR_BGR2GRAY)
    circles = cv2.HoughCircles(gray, cv2.HOUGH_GRADIENT, dp=1.0, minDist=max(2.0 * r1, 3.0), param1=80,
                               param2=max(8.0, 0.35 * 2 * math.pi * r1), minRadius=max(1, int(math.floor(r1 * 0.8))),
                               maxRadius=int(math.ceil(r2 * 1.2)))
    if circles is None:
        raise MarkerError(f"--auto {n}: the circular Hough transform found no dot of radius {r1:g}-{r2:g} px "
                          f"on the first frame")
    circles = circles.reshape(-1, 3)
    h, w = gray.shape
    inner_px, inner_c = [], []
    for x, y, r in circles:
        ri = max(1.0, 0.6 * r)
        x0, x1 = int(max(x - 2.5 * r, 0)), int(min(x + 2.5 * r + 1, w))
        y0, y1 = int(max(y - 2.5 * r, 0)), int(min(y + 2.5 * r + 1, h))
        yy, xx = np.mgrid[y0:y1, x0:x1]
        dd = np.hypot(xx - x, yy - y)
        win = ycc[y0:y1, x0:x1]
        inner = win[dd <= ri]
        ring = win[(dd >= 1.5 * r) & (dd <= 2.5 * r)]
        if inner.size == 0 or ring.size == 0:
            continue
        ci, cr = np.median(inner, axis=0), np.median(ring, axis=0)
        if np.hypot(*(ci[1:] - cr[1:])) < 15.0:
            continue
        inner_px.append(inner)
        inner_c.append(ci[1:])
    if not inner_c:
        raise MarkerError(f"--auto {n}: no coloured dot (radius {r1:g}-{r2:g} px) on the first frame")
    c = np.asarray(inner_c)
    close = np.linalg.norm(c[:, None, :] - c[None, :, :], axis=2) < 15.0
    mode = int(close.sum(axis=1).argmax())
    members = np.flatnonzero(close[mode])
    model = ColourModel.from_pixels(np.concatenate([inner_px[i] for i in members]), min_std=min_std)
    detector = MarkerDetector(model, radius, threshold=threshold)
    det = detector.detect(frame_bgr, hough=True)
    good = np.flatnonzero(det.confidence >= 0.5)
    if good.size < n:
        raise MarkerError(f"--auto {n}: only {good.size} dot(s) of the markers' colour found on the first frame "
                          f"(radius {r1:g}-{r2:g} px)")
    best = good[np.argsort(-det.confidence[good], kind="stable")[:n]]
    xy, area = det.xy[best], det.area[best]
    if layout is not None:
        lnames, lxy = layout
        if len(lnames) < n:
            raise MarkerError(f"--auto {n}: the layout has only {len(lnames)} markers")
        names, resid = name_by_layout(xy, lnames, lxy)
        log.info("auto: dots named by the layout (mean residual %.1f px)", resid)
    else:
        order = np.lexsort((xy[:, 0], np.round(xy[:, 1] / max(2 * r2, 1.0))))
        xy, area = xy[order], area[order]
        names = [f"m{i:02d}" for i in range(n)]
    return detector, tuple(names), xy.copy(), area.copy()


def track_frames(frames, detector: MarkerDetector, names, initial, *, initial_area=None, rate: float,
                 size, n_frames: int | None = None, progress=None, **options) -> TrackResult:
    """Track markers through an iterable of frames (the first frame is where ``initial`` holds).

    Parameters
    ----------
    frames : iterable of ndarray (H, W, 3) uint8, or of (index, frame)
    detector, names, initial, initial_area
        From :func:`initialise_from_seeds` or :func:`initialise_auto`.
    rate : float
    size : (W, H)
    progress : callable, optional
        Wraps the iterable (e.g. :func:`usdface.progress.progress`).
    **options
        :class:`MarkerTracker` options (gate, min_confidence, min_area_ratio, adapt).
    """
    tracker = MarkerTracker(detector, names, initial, initial_area=initial_area, **options)
    pos, conf = [], []
    it = progress(frames) if progress is not None else frames
    first = True
    for item in it:
        frame = item[1] if isinstance(item, tuple) else item
        if first:
            first = False
            p, c = tracker.step(frame)
            # the first frame is where the initialisation found the dots
            p = np.where(np.isfinite(p), p, np.nan)
        else:
            p, c = tracker.step(frame)
        pos.append(p)
        conf.append(c)
    if not pos:
        raise MarkerError("tracking: zero frames")
    positions = np.stack(pos)
    confidence = np.stack(conf)
    never = [n for n, ok in zip(names, np.isfinite(positions).all(axis=2).any(axis=0)) if not ok]
    if never:
        raise MarkerError(f"tracking: marker(s) never found in any frame: {list_names(never)}")
    stats = dict(tracker.stats, gate=tracker.gate, spacing=tracker.spacing)
    return TrackResult(names=tuple(names), positions=positions, confidence=confidence,
                       size=tuple(int(v) for v in size), rate=float(rate), stats=stats)
