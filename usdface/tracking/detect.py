"""Coloured-dot detection in video frames (seed 002: YCbCr colour model, Mahalanobis threshold,
morphology, connected components, centroids, circular Hough transform).

Pipeline for one frame (:meth:`MarkerDetector.detect`):

1. **Segmentation** (half resolution when the dots are big enough, since video chroma is
   subsampled 2x anyway): convert to YCbCr, look up the squared Mahalanobis distance
   ``d^2 = (c - mu)^T S^-1 (c - mu)`` of each pixel's chroma ``c = (Cb, Cr)`` to the dots' colour
   model (a 256 x 256 table, so the cost does not depend on the model), keep ``d < threshold``,
   morphological opening (removes specks) then closing (fills holes), connected components.
2. **Blob filter**: components whose area is plausible for one dot of radius in ``radius``
   (or a few merged dots, kept for the tracker to split) survive.
3. **Sub-pixel centroid** at full resolution: in a window around the blob, each pixel's
   *coverage* ``alpha`` is its YCbCr colour projected on the segment from the local background
   (median of the ring around the blob) to the dot colour (median of the blob's core), clipped to
   [0, 1]. For an anti-aliased, blurred or compressed disc this is the fraction of the pixel the dot
   covers, so the alpha-weighted centroid is the disc centre (motion blur: the centre of the path),
   and ``sum(alpha)`` is the dot's area ``pi r^2`` whatever the blur (equivalent radius).
4. **Circular Hough transform** (OpenCV's gradient Hough on the coverage window, radius in
   ``radius``) confirms a blob is a dot, and gives the centres used to split merged blobs.
5. **Confidence** in [0, 1]: colour agreement x size agreement x roundness (x Hough vote when run).

Pixel convention (OpenCV's): integer coordinates are pixel centres, x right, y down.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ..errors import ComputeError, InputError, OptionError, list_names

__all__ = ["ColourModel", "Detections", "MarkerDetector", "learn_colour_model", "check_radius_range",
           "check_seeds", "to_ycrcb", "find_circles"]


def _cv2():
    import cv2

    return cv2


def to_ycrcb(bgr: np.ndarray) -> np.ndarray:
    """BGR uint8 image (H, W, 3) -> YCrCb uint8 (H, W, 3) (OpenCV's channel order Y, Cr, Cb)."""
    return _cv2().cvtColor(np.ascontiguousarray(bgr), _cv2().COLOR_BGR2YCrCb)


def check_radius_range(radius, *, size=None) -> tuple[float, float]:
    """Validate a dot radius range (pixels) ``(r_min, r_max)``; OptionError when impossible."""
    try:
        r1, r2 = (float(r) for r in radius)
    except (TypeError, ValueError):
        raise OptionError(f"--radius: expected two numbers R_MIN R_MAX (pixels); got {radius!r}") from None
    if not (math.isfinite(r1) and math.isfinite(r2)) or r1 < 1.0 or r2 < r1:
        raise OptionError(f"--radius {r1:g} {r2:g}: impossible radius range; expected 1 <= R_MIN <= R_MAX (pixels)")
    if size is not None:
        w, h = size
        if 2 * r2 >= min(w, h) / 2:
            raise OptionError(f"--radius {r1:g} {r2:g}: impossible radius range for a {w}x{h} video "
                              f"(a dot of diameter {2 * r2:g} px would cover half of the frame)")
    return r1, r2


def check_seeds(seeds: dict, size, *, source: str = "--seeds") -> dict:
    """Validate seed points ``{name: (x, y)}`` (pixels) against the image size ``(W, H)``."""
    if not isinstance(seeds, dict) or not seeds:
        raise InputError(f"{source}: expected a JSON object {{\"MarkerName\": [x, y], ...}} with at least one marker")
    w, h = size
    out, outside = {}, []
    for name, xy in seeds.items():
        numbers = (isinstance(xy, (list, tuple)) and len(xy) == 2
                   and all(isinstance(v, (int, float, np.integer, np.floating)) and not isinstance(v, (bool, np.bool_))
                           for v in xy))
        try:  # (a string "12" would otherwise iterate to (1, 2); 10**400 overflows float)
            x, y = (float(v) for v in xy) if numbers else (None, None)
        except OverflowError:
            numbers = False
        if not numbers:
            raise InputError(f"{source}: marker {name!r}: expected [x, y] in pixels; got {str(xy)[:60]!r}") from None
        if not (math.isfinite(x) and math.isfinite(y)):
            raise InputError(f"{source}: marker {name!r}: coordinates must be finite; got {xy!r}")
        if not (-0.5 <= x <= w - 0.5 and -0.5 <= y <= h - 0.5):
            outside.append(f"{name} ({x:g}, {y:g})")
        out[str(name)] = (x, y)
    if outside:
        raise InputError(f"{source}: seed point(s) outside the {w}x{h} image (x in -0.5..{w - 0.5}, "
                         f"y in -0.5..{h - 0.5}): {list_names(outside)}")
    return out


# ================================================================================================
# colour model
# ================================================================================================
@dataclass(frozen=True)
class ColourModel:
    """Gaussian model of the dots' chroma in YCbCr.

    Attributes
    ----------
    mean : ndarray, shape (2,)
        Mean (Cb, Cr), 8-bit levels.
    cov : ndarray, shape (2, 2)
        Covariance of (Cb, Cr), levels^2, regularised (eigenvalues >= ``min_std**2``).
    luma : float
        Mean Y of the dots (levels).
    min_std : float
        The regularisation floor (levels).
    regularised : bool
        True when the sample covariance was degenerate or below the floor and was raised.
    """

    mean: np.ndarray
    cov: np.ndarray
    luma: float = 0.0
    min_std: float = 8.0
    regularised: bool = False

    @classmethod
    def from_pixels(cls, ycrcb: np.ndarray, *, min_std: float = 8.0) -> "ColourModel":
        """Fit the model to pixels (N, 3) YCrCb; the covariance is regularised so it is never singular."""
        px = np.asarray(ycrcb, dtype=np.float64).reshape(-1, 3)
        if px.shape[0] == 0:
            raise ComputeError("colour model: no pixels to learn from")
        cbcr = px[:, [2, 1]]
        mean = cbcr.mean(axis=0)
        cov = np.cov(cbcr.T) if px.shape[0] > 2 else np.zeros((2, 2))
        cov = np.nan_to_num(0.5 * (cov + cov.T))
        vals, vecs = np.linalg.eigh(cov)
        floor = float(min_std) ** 2
        regularised = bool(vals.min() < floor)
        vals = np.maximum(vals, floor)
        cov = (vecs * vals) @ vecs.T
        return cls(mean=mean, cov=cov, luma=float(px[:, 0].mean()), min_std=float(min_std), regularised=regularised)

    def distance2(self, cb, cr) -> np.ndarray:
        """Squared Mahalanobis distance of chroma values (any shape) to the model."""
        inv = np.linalg.inv(self.cov)
        d0 = np.asarray(cb, dtype=np.float64) - self.mean[0]
        d1 = np.asarray(cr, dtype=np.float64) - self.mean[1]
        return inv[0, 0] * d0 * d0 + 2 * inv[0, 1] * d0 * d1 + inv[1, 1] * d1 * d1

    def table(self) -> np.ndarray:
        """(65536,) float32 squared distances indexed by ``Cr * 256 + Cb``."""
        lv = np.arange(256, dtype=np.float64)
        return self.distance2(lv[None, :], lv[:, None]).astype(np.float32).ravel()

    def moved_to(self, mean, luma=None) -> "ColourModel":
        """The same covariance around a new mean (online adaptation to lighting changes)."""
        return ColourModel(mean=np.asarray(mean, dtype=np.float64), cov=self.cov,
                           luma=self.luma if luma is None else float(luma), min_std=self.min_std,
                           regularised=self.regularised)


def learn_colour_model(frame_bgr: np.ndarray, points, *, radius: float, min_std: float = 8.0) -> ColourModel:
    """Learn the dots' colour from pixels around seed points on one frame.

    Parameters
    ----------
    frame_bgr : ndarray, shape (H, W, 3), uint8
    points : array_like, shape (M, 2)
        Seed points (x, y) in pixels, OpenCV convention (integer = pixel centre).
    radius : float
        Pixels within ``max(0.5, 0.5 * radius)`` of each seed are sampled (the dot's core).
    min_std : float
        Covariance floor (levels): a degenerate model (one pixel, flat colour) is regularised; the
        default 8 levels absorbs video compression and chroma subsampling.
    """
    ycc = to_ycrcb(frame_bgr)
    h, w = ycc.shape[:2]
    pts = np.asarray(points, dtype=np.float64).reshape(-1, 2)
    r = max(0.5, 0.5 * float(radius))
    ri = int(math.ceil(r))
    samples = []
    for x, y in pts:
        cx, cy = int(round(x)), int(round(y))
        x0, x1 = max(cx - ri, 0), min(cx + ri + 1, w)
        y0, y1 = max(cy - ri, 0), min(cy + ri + 1, h)
        yy, xx = np.mgrid[y0:y1, x0:x1]
        inside = (xx - x) ** 2 + (yy - y) ** 2 <= r * r
        if not inside.any():
            inside = (xx == cx) & (yy == cy)
        samples.append(ycc[y0:y1, x0:x1][inside])
    return ColourModel.from_pixels(np.concatenate(samples), min_std=min_std)


# ================================================================================================
# detections
# ================================================================================================
@dataclass
class Detections:
    """Dots found in one frame.

    Attributes
    ----------
    xy : ndarray, shape (K, 2), float64
        Sub-pixel centres (x, y), pixels.
    area : ndarray, shape (K,)
        Dot area ``sum(alpha)`` in pixels^2 (``pi r^2`` for one dot, about twice for two merged).
    radius : ndarray, shape (K,)
        Equivalent radius ``sqrt(area / pi)``.
    elongation : ndarray, shape (K,)
        Ratio of the principal standard deviations of the coverage (1 for a disc).
    confidence : ndarray, shape (K,)
        In [0, 1].
    chroma : ndarray, shape (K, 3)
        Median YCbCr (Y, Cb, Cr) of each dot's core (for colour adaptation).
    hough : ndarray, shape (K,), int
        Circles the Hough transform found in the blob (-1: not run).
    windows : list
        Per detection ``(x0, y0, x1, y1, bx0, by0, bx1, by1)``: its window and blob box (pixels),
        to recompute the coverage when a merged blob is split (None for split products).
    """

    xy: np.ndarray
    area: np.ndarray
    radius: np.ndarray
    elongation: np.ndarray
    confidence: np.ndarray
    chroma: np.ndarray
    hough: np.ndarray
    windows: list = field(default_factory=list, repr=False)

    def __len__(self) -> int:
        return self.xy.shape[0]

    @classmethod
    def empty(cls) -> "Detections":
        z = np.zeros(0)
        return cls(np.zeros((0, 2)), z, z, z, z, np.zeros((0, 3)), np.zeros(0, int), [])

    def subset(self, idx) -> "Detections":
        idx = np.asarray(idx, dtype=int)
        return Detections(self.xy[idx], self.area[idx], self.radius[idx], self.elongation[idx],
                          self.confidence[idx], self.chroma[idx], self.hough[idx], [self.windows[i] for i in idx])


def find_circles(alpha: np.ndarray, radius, *, min_dist: float | None = None, vote: float = 0.6) -> np.ndarray:
    """Circular Hough transform on a coverage image.

    Parameters
    ----------
    alpha : ndarray, shape (h, w), float in [0, 1]
    radius : (r_min, r_max), pixels
    vote : float
        Accumulator threshold as a fraction of a quarter circumference of the smallest circle
        (OpenCV's gradient Hough transform; Canny high threshold 100 on the 8-bit coverage).

    Returns
    -------
    ndarray, shape (K, 3): x, y, r of the circles found (window pixels).
    """
    cv2 = _cv2()
    r1, r2 = radius
    img = (np.clip(alpha, 0, 1) * 255).astype(np.uint8)
    pad = int(math.ceil(r2)) + 2
    img = cv2.copyMakeBorder(img, pad, pad, pad, pad, cv2.BORDER_CONSTANT, value=0)
    votes = max(5.0, vote * 0.5 * math.pi * r1)
    circles = cv2.HoughCircles(img, cv2.HOUGH_GRADIENT, dp=1.0, minDist=float(min_dist or max(r1, 2.0)),
                               param1=100, param2=votes, minRadius=max(1, int(math.floor(r1 * 0.8))),
                               maxRadius=int(math.ceil(r2 * 1.2)))
    if circles is None:
        return np.zeros((0, 3))
    c = np.asarray(circles, dtype=np.float64).reshape(-1, 3)
    c[:, :2] -= pad
    return c


class MarkerDetector:
    """Find coloured dots in frames (see the module docstring for the method).

    Parameters
    ----------
    model : ColourModel
    radius : (r_min, r_max)
        Dot radius range in pixels.
    threshold : float
        Mahalanobis distance below which a pixel's chroma is the dots' colour.
    hough : bool
        Run the circular Hough transform on every blob (slower; the tracker runs it on demand).
    max_merged : int
        Largest number of touching dots a blob may hold and still be kept (for splitting).
    """

    def __init__(self, model: ColourModel, radius=(3.0, 10.0), *, threshold: float = 4.0, hough: bool = False,
                 max_merged: int = 3):
        self.radius = check_radius_range(radius)
        if not (threshold > 0):
            raise OptionError(f"--threshold: expected a positive Mahalanobis distance; got {threshold}")
        self.threshold = float(threshold)
        self.hough = bool(hough)
        self.max_merged = int(max_merged)
        self.scale = 2 if self.radius[0] >= 3.5 else 1
        #: weights of (Y, Cr, Cb) in the coverage projection: chroma only by default (luma picks up
        #: dark eyebrows, eyes and nostrils next to a dot)
        self._channel_weights = np.array([0.0, 1.0, 1.0], np.float32)
        from ._kernels import HAVE_NUMBA

        #: use the compiled refinement (False: the numpy reference path)
        self.fast = HAVE_NUMBA
        self.set_model(model)

    def set_model(self, model: ColourModel) -> None:
        """Use a new colour model (rebuilds the 256 x 256 distance table)."""
        self.model = model
        self._d2 = model.table()
        self._mask_lut = np.where(self._d2 < self.threshold ** 2, 255, 0).astype(np.uint8)

    # -- segmentation ----------------------------------------------------------------------------
    def mask(self, frame_bgr: np.ndarray) -> np.ndarray:
        """Binary mask (uint8 0/255) of dot-coloured pixels after opening and closing, at the
        segmentation scale (half resolution for dots of radius >= 3.5 px)."""
        cv2 = _cv2()
        s = self.scale
        small = frame_bgr if s == 1 else cv2.resize(frame_bgr, None, fx=1.0 / s, fy=1.0 / s,
                                                    interpolation=cv2.INTER_AREA)
        ycc = cv2.cvtColor(small, cv2.COLOR_BGR2YCrCb)
        idx = (ycc[:, :, 1].astype(np.uint16) << 8) | ycc[:, :, 2]
        m = self._mask_lut[idx]
        k = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (3, 3))
        m = cv2.morphologyEx(m, cv2.MORPH_OPEN, k)
        m = cv2.morphologyEx(m, cv2.MORPH_CLOSE, k)
        return m

    def detect(self, frame_bgr: np.ndarray, *, hough: bool | None = None, roi=None) -> Detections:
        """Dots in one frame.

        Parameters
        ----------
        frame_bgr : ndarray, shape (H, W, 3), uint8
        hough : bool, optional
            Override the detector's ``hough`` setting for this call.
        roi : (x0, y0, x1, y1), optional
            Only look inside this rectangle (pixels).

        Returns
        -------
        Detections
        """
        cv2 = _cv2()
        hough = self.hough if hough is None else hough
        h, w = frame_bgr.shape[:2]
        ox = oy = 0
        img = frame_bgr
        if roi is not None:
            x0, y0, x1, y1 = (int(v) for v in roi)
            x0, y0, x1, y1 = max(x0, 0), max(y0, 0), min(x1, w), min(y1, h)
            if x1 - x0 < 4 or y1 - y0 < 4:
                return Detections.empty()
            img, ox, oy = frame_bgr[y0:y1, x0:x1], x0, y0
        m = self.mask(img)
        n, _, stats, _ = cv2.connectedComponentsWithStats(m, connectivity=8)
        s = self.scale
        r1, r2 = self.radius
        a_min = 0.25 * math.pi * r1 * r1
        a_max = self.max_merged * 1.3 * math.pi * r2 * r2 + 4 * math.pi * r2 * r2
        st = stats[1:]
        keep = (st[:, 4] * s * s >= a_min * 0.5) & (st[:, 4] * s * s <= a_max)
        st = st[keep]
        if self.fast and not hough:
            return self._detect_fast(frame_bgr, st, ox, oy)
        out = []
        for bx, by, bw, bh, area in st:
            res = self._refine(frame_bgr, ox + bx * s, oy + by * s, bw * s, bh * s, hough)
            if res is not None:
                out.append(res)
        if not out:
            return Detections.empty()
        xy, area, rad, elong, conf, chroma, hv, win = zip(*out)
        return Detections(np.array(xy, float), np.array(area), np.array(rad), np.array(elong), np.array(conf),
                          np.array(chroma, float), np.array(hv, int), list(win))

    # -- sub-pixel refinement --------------------------------------------------------------------
    def _boxes(self, frame_shape, st, ox, oy):
        h, w = frame_shape[:2]
        s = self.scale
        pad = int(math.ceil(self.radius[1] * 0.5)) + 5
        bx, by = ox + st[:, 0] * s, oy + st[:, 1] * s
        bw, bh = st[:, 2] * s, st[:, 3] * s
        blobs = np.stack([bx, by, bx + bw, by + bh], axis=1).astype(np.int64)
        boxes = np.stack([np.maximum(bx - pad, 0), np.maximum(by - pad, 0), np.minimum(bx + bw + pad, w),
                          np.minimum(by + bh + pad, h)], axis=1).astype(np.int64)
        return boxes, blobs

    def _detect_fast(self, frame_bgr, st, ox, oy) -> Detections:
        from ._kernels import refine_blobs

        if st.shape[0] == 0:
            return Detections.empty()
        h, w = frame_bgr.shape[:2]
        boxes, blobs = self._boxes(frame_bgr.shape, st, ox, oy)
        ri = max(2, int(math.ceil(self.radius[1] * 0.5)) + 2)
        res = refine_blobs(np.ascontiguousarray(frame_bgr), self._d2, np.float32(self.threshold ** 2), boxes, blobs,
                           ri, self._channel_weights.astype(np.float32), np.float32(0.08))
        ok = res[:, 0] > 0
        res, boxes, blobs = res[ok], boxes[ok], blobs[ok]
        if res.shape[0] == 0:
            return Detections.empty()
        total = res[:, 3]
        sxx, syy, sxy = res[:, 4], res[:, 5], res[:, 6]
        tr, det = sxx + syy, sxx * syy - sxy * sxy
        disc = np.sqrt(np.maximum(tr * tr / 4 - det, 0.0))
        l1, l2 = tr / 2 + disc, np.maximum(tr / 2 - disc, 1e-9)
        elong = np.sqrt(l1 / l2)
        radius = np.sqrt(total / math.pi)
        at_border = (boxes[:, 0] == 0) | (boxes[:, 1] == 0) | (boxes[:, 2] == w) | (boxes[:, 3] == h)
        conf = self._confidence(res[:, 9], res[:, 8], radius, elong, at_border)
        chroma = np.stack([res[:, 7], res[:, 9], res[:, 8]], axis=1)  # (Y, Cb, Cr)
        windows = [tuple(b) + tuple(bl) for b, bl in zip(boxes.tolist(), blobs.tolist())]
        return Detections(res[:, 1:3].copy(), total, radius, elong, conf, chroma, np.full(len(total), -1), windows)

    def _confidence(self, cb, cr, radius, elong, at_border):
        """Colour x size x roundness (vectorised), each in [0, 1]."""
        r1, r2 = self.radius
        d = np.sqrt(np.maximum(self.model.distance2(cb, cr), 0.0))
        c_colour = np.exp(-0.5 * np.maximum(0.0, d - 1.0) ** 2 / 4.0)
        c_size = np.where(radius < r1, np.exp(-((r1 - radius) / (0.25 * r1)) ** 2),
                          np.where(radius > r2, np.exp(-((radius - r2) / (0.25 * r2)) ** 2), 1.0))
        c_round = np.where(elong < 1.6, 1.0, np.exp(-(elong - 1.6) ** 2 / 0.5))
        return c_colour * c_size * c_round * np.where(at_border, 0.7, 1.0)

    def coverage(self, frame_bgr: np.ndarray, x0: int, y0: int, x1: int, y1: int, centre=None):
        """Coverage (alpha) of the dot colour in a window, with the core colour and background.

        Returns ``(alpha (h, w) float32, core YCbCr (3,), background YCbCr (3,), core mask)`` or
        None when the window has no dot-coloured pixel.
        """
        cv2 = _cv2()
        win = cv2.cvtColor(np.ascontiguousarray(frame_bgr[y0:y1, x0:x1]), cv2.COLOR_BGR2YCrCb)
        idx = (win[:, :, 1].astype(np.uint16) << 8) | win[:, :, 2]
        d2 = self._d2[idx]
        core = d2 < self.threshold ** 2
        if core.sum() < 1:
            return None
        if centre is not None:
            # keep only the dot-coloured components inside the blob (another dot or a blue thing in
            # the window must not pull the centroid)
            n, lab = cv2.connectedComponents(core.view(np.uint8), connectivity=8)
            if n > 2:
                bx0, by0, bx1, by1 = centre
                counts = np.bincount(lab[by0:by1, bx0:bx1].ravel(), minlength=n)
                counts[0] = 0
                core = (counts > 0)[lab]
        ri = max(2, int(math.ceil(self.radius[1] * 0.5)) + 2)
        k = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * ri + 1, 2 * ri + 1))
        support = cv2.dilate(core.view(np.uint8), k).astype(bool)
        ring = ~support
        f = win.astype(np.float32)
        if ring.sum() < 4:
            return None
        bg = np.median(f[ring], axis=0)
        # the dot colour: the core pixels farthest from the background (the least mixed ones)
        cpx = f[core]
        dist = np.abs(cpx - bg).sum(axis=1)
        top = cpx[dist >= np.quantile(dist, 0.5)] if cpx.shape[0] > 3 else cpx
        dot = np.median(top, axis=0)
        axis = (dot - bg) * self._channel_weights
        nn = float(axis @ (dot - bg))
        if nn < 100.0:  # dot and background colours closer than 10 levels: no contrast
            return None
        alpha = ((f - bg) @ (axis / nn)).astype(np.float32)
        alpha[~support] = 0.0
        np.clip(alpha, 0.0, 1.0, out=alpha)
        alpha[alpha < 0.08] = 0.0
        return alpha, dot, bg, core

    def _refine(self, frame_bgr, bx, by, bw, bh, hough):
        h, w = frame_bgr.shape[:2]
        r1, r2 = self.radius
        pad = int(math.ceil(r2 * 0.5)) + 5
        x0, y0 = max(bx - pad, 0), max(by - pad, 0)
        x1, y1 = min(bx + bw + pad, w), min(by + bh + pad, h)
        cov = self.coverage(frame_bgr, x0, y0, x1, y1, centre=(bx - x0, by - y0, bx - x0 + bw, by - y0 + bh))
        if cov is None:
            return None
        alpha, dot, bg, core = cov
        res = self._measure(alpha, x0, y0, dot, hough, at_border=(x0 == 0 or y0 == 0 or x1 == w or y1 == h))
        if res is None:
            return None
        return res[:-1] + ((x0, y0, x1, y1, bx, by, bx + bw, by + bh),)

    def _measure(self, alpha, x0, y0, dot, hough, *, at_border=False):
        r1, r2 = self.radius
        total = float(alpha.sum())
        if total <= 1e-6:
            return None
        hh, ww = alpha.shape
        ys = np.arange(hh, dtype=np.float64)
        xs = np.arange(ww, dtype=np.float64)
        col = alpha.sum(axis=0, dtype=np.float64)
        row = alpha.sum(axis=1, dtype=np.float64)
        cx = float(col @ xs) / total
        cy = float(row @ ys) / total
        dx, dy = xs - cx, ys - cy
        sxx = float(col @ (dx * dx)) / total
        syy = float(row @ (dy * dy)) / total
        sxy = float(dy @ alpha.astype(np.float64) @ dx) / total
        tr, det = sxx + syy, sxx * syy - sxy * sxy
        disc = math.sqrt(max(tr * tr / 4 - det, 0.0))
        l1, l2 = tr / 2 + disc, max(tr / 2 - disc, 1e-9)
        elong = math.sqrt(l1 / l2)
        radius = math.sqrt(total / math.pi)
        conf = float(self._confidence(np.float64(dot[2]), np.float64(dot[1]), np.float64(radius),
                                      np.float64(elong), bool(at_border)))
        nh = -1
        if hough:
            circles = find_circles(alpha, self.radius)
            nh = int(circles.shape[0])
            conf *= 1.0 if nh >= 1 else 0.5
        return ((x0 + cx, y0 + cy), total, radius, elong, conf, (dot[0], dot[2], dot[1]), nh, (x0, y0, alpha))

    def split(self, frame_bgr: np.ndarray, det: Detections, i: int, centres) -> np.ndarray:
        """Split detection ``i`` (a blob holding several touching dots) around initial ``centres``.

        Weighted k-means (Lloyd) on the blob's coverage, started at ``centres`` (K, 2) (the
        tracker's predictions); returns the K refined centres (K, 2) in frame pixels.
        """
        x0, y0, x1, y1, bx0, by0, bx1, by1 = det.windows[i]
        cov = self.coverage(frame_bgr, x0, y0, x1, y1, centre=(bx0 - x0, by0 - y0, bx1 - x0, by1 - y0))
        c = np.asarray(centres, dtype=np.float64).reshape(-1, 2).copy()
        if cov is None:
            return c
        alpha = cov[0]
        yy, xx = np.nonzero(alpha > 0)
        wts = alpha[yy, xx].astype(np.float64)
        pts = np.stack([xx + x0, yy + y0], axis=1).astype(np.float64)
        for _ in range(20):
            d = ((pts[:, None, :] - c[None, :, :]) ** 2).sum(axis=2)
            lab = d.argmin(axis=1)
            new = c.copy()
            for k in range(c.shape[0]):
                sel = lab == k
                if wts[sel].sum() > 0:
                    new[k] = (pts[sel] * wts[sel, None]).sum(axis=0) / wts[sel].sum()
            if np.abs(new - c).max() < 1e-3:
                c = new
                break
            c = new
        return c
