"""Gap filling: fill short runs of invalid samples of a marker.

Methods
-------
``"linear"``
    Straight line between the valid samples on both sides of the gap (the baseline). Edge gaps
    (at the start or end of the take) hold the nearest valid sample.
``"regression"`` (default)
    Facial markers move together. For each gap:

    1. Neighbours: markers valid throughout the gap and its two boundary frames (and on >= 90 %
       of the training frames), ranked by how well each alone predicts the marker (affine least
       squares) over the whole take, where every expression of the take is seen; the best
       ``neighbors`` are kept (fewer when training frames are scarce: >= 4 frames per
       coefficient).
    2. Model: the marker's position as an affine function of the neighbours' positions, fitted
       by ridge-regularised least squares on the training frames (within ``context`` frames of
       the gap on either side, marker and neighbours valid).
    3. Boundary matching: the prediction's errors at the two boundary frames are interpolated
       linearly across the gap and removed, so the fill meets the valid samples at both ends (no
       jumps). An edge gap has one boundary: its error is removed as a constant offset.
    4. Self-validation: gaps of the same length are simulated at up to 6 places in the training
       window, filled both ways with the model refitted without them, and the weight ``shrink``
       in [0, 1] of the regression's departure from the linear (or hold) fill that minimises the
       simulated error is applied: ``fill = base + shrink * (regression - base)``. Where the
       neighbours do not help (a quiet marker, an unrelated motion), the fill falls back toward
       the baseline instead of adding their noise.

    When no neighbour qualifies or too few training frames exist, the gap is filled with
    ``"linear"`` (``"hold"`` at an edge), and the report says so.

A marker with no valid sample at all is left invalid and reported.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..errors import OptionError
from ..model.capture import Capture

__all__ = ["fill_gaps", "find_gaps", "Gap", "GapReport", "METHODS"]

METHODS = ("regression", "linear")


@dataclass(frozen=True)
class Gap:
    """One run of invalid samples of one marker: frames ``start`` (inclusive) to ``stop`` (exclusive).

    ``method`` is how it was filled (``"regression"``, ``"linear"``, ``"hold"``) or why not
    (``"too_long"``, ``"no_data"``); ``neighbors`` are the predictor markers of a regression fill
    and ``shrink`` the weight (0..1) given to its departure from the linear / hold baseline.
    """

    marker: str
    start: int
    stop: int
    method: str = ""
    neighbors: tuple[str, ...] = ()
    shrink: float | None = None

    @property
    def length(self) -> int:
        return self.stop - self.start


@dataclass(frozen=True)
class GapReport:
    """What :func:`fill_gaps` did.

    Attributes
    ----------
    filled : list of Gap
        Gaps filled, with the method used.
    unfilled : list of Gap
        Gaps left invalid: ``"too_long"`` (longer than ``max_gap``) or ``"no_data"`` (marker never
        valid).
    n_frames : int
        Frames in the capture (a gap with ``start == 0`` or ``stop == n_frames`` is an edge gap).
    """

    filled: list = field(default_factory=list)
    unfilled: list = field(default_factory=list)
    n_frames: int = 0

    @property
    def n_filled_samples(self) -> int:
        return int(sum(g.length for g in self.filled))

    @property
    def n_unfilled_samples(self) -> int:
        return int(sum(g.length for g in self.unfilled))

    def summary(self) -> dict:
        methods = {}
        for g in self.filled:
            methods[g.method] = methods.get(g.method, 0) + 1
        return {
            "filled_gaps": len(self.filled),
            "filled_samples": self.n_filled_samples,
            "methods": methods,
            "unfilled_gaps": len(self.unfilled),
            "unfilled_samples": self.n_unfilled_samples,
            "unfilled": [[g.marker, g.start, g.stop, g.method] for g in self.unfilled],
            # every filled gap (marker, first frame, end frame exclusive, method): the QC report plots them
            "filled": [[g.marker, g.start, g.stop, g.method] for g in self.filled],
        }


def find_gaps(valid):
    """Runs of False in a validity mask, per column.

    Parameters
    ----------
    valid : ndarray, shape (F, M), bool

    Returns
    -------
    list of (marker_index, start, stop)
        Half-open frame ranges ``[start, stop)`` of invalid samples, ordered by marker then start.
    """
    valid = np.asarray(valid, dtype=bool)
    n_frames, n_markers = valid.shape
    pad = np.ones((1, n_markers), dtype=bool)
    inv = ~np.concatenate([pad, valid, pad], axis=0)
    d = np.diff(inv.astype(np.int8), axis=0)
    starts = np.argwhere(d.T == 1)  # (marker, frame)
    stops = np.argwhere(d.T == -1)
    return [(int(m), int(a), int(b)) for (m, a), (_, b) in zip(starts, stops)]


# -- kernels ------------------------------------------------------------------------------------


def _linear_fill(track, a, b):
    """(L, 3) linear (or hold, at edges) values for frames [a, b) of one marker's (F, 3) track."""
    n = track.shape[0]
    frames = np.arange(a, b)
    if a > 0 and b < n:
        w = ((frames - (a - 1)) / (b - (a - 1)))[:, None]
        return (1 - w) * track[a - 1] + w * track[b]
    if a > 0:
        return np.repeat(track[a - 1][None], b - a, axis=0)
    return np.repeat(track[b][None], b - a, axis=0)


def _lstsq_ridge(x, y, ridge):
    """Solve min |[x 1] beta - y|^2 + ridge * n * |beta_x|^2 with centred features.

    x : (N, P), y : (N, 3). Returns (mean_x (P,), mean_y (3,), beta (P, 3)).
    """
    mx = x.mean(axis=0)
    my = y.mean(axis=0)
    xc = x - mx
    g = xc.T @ xc
    scale = np.trace(g) / max(g.shape[0], 1)
    g[np.diag_indices_from(g)] += ridge * scale + 1e-12
    beta = np.linalg.solve(g, xc.T @ (y - my))
    return mx, my, beta


def _rank_neighbors(pos, m, cands, train):
    """Order candidate neighbours by single-neighbour regression residual (vectorised)."""
    y = pos[train, m]  # (N, 3)
    x = pos[train][:, cands]  # (N, C, 3)
    xc = x - x.mean(axis=0)
    yc = y - y.mean(axis=0)
    g = np.einsum("nci,ncj->cij", xc, xc)
    scale = np.trace(g, axis1=1, axis2=2) / 3.0
    g = g + (1e-6 * scale + 1e-12)[:, None, None] * np.eye(3)
    rhs = np.einsum("nci,nk->cik", xc, yc)
    beta = np.linalg.solve(g, rhs)  # (C, 3, 3)
    res = yc[:, None, :] - np.einsum("nci,cik->nck", xc, beta)
    err = (res**2).sum(axis=(0, 2))
    return [cands[i] for i in np.argsort(err, kind="stable")]


def _boundary_corrected(pred, y, a, b, lo, n_frames):
    """Remove the prediction error at the gap's boundary frames from ``pred``.

    ``pred`` holds predictions for frames ``lo .. lo+len(pred)-1`` covering [a-1, b] (clipped to
    the take). Two boundaries: the errors are interpolated linearly across the gap; one boundary
    (edge gap): the error there is removed as a constant. Returns the (b-a, 3) gap values.
    """
    frames = np.arange(a, b)
    inner = pred[a - lo:b - lo]
    if a > 0 and b < n_frames:
        e0 = y[a - 1] - pred[a - 1 - lo]
        e1 = y[b] - pred[b - lo]
        w = ((frames - (a - 1)) / (b - (a - 1)))[:, None]
        return inner + (1 - w) * e0 + w * e1
    if a > 0:
        return inner + (y[a - 1] - pred[a - 1 - lo])
    return inner + (y[b] - pred[b - lo])


def _fit_predict(pos, m, nb, train, lo, hi, ridge):
    """Fit marker m on neighbours nb over ``train`` frames; predict frames [lo, hi)."""
    n = int(train.sum())
    x = pos[train][:, nb].reshape(n, -1)
    mx, my, beta = _lstsq_ridge(x, pos[train, m], ridge)
    xs = pos[lo:hi][:, nb].reshape(hi - lo, -1)
    return (xs - mx) @ beta + my


def _sim_starts(ok, length, need_before, need_after, n_sim):
    """Up to ``n_sim`` evenly spread starts s with ok[s-need_before : s+length+need_after] all True."""
    n = ok.size
    w = length + need_before + need_after
    if n < w:
        return np.zeros(0, dtype=np.int64)
    c = np.concatenate([[0], np.cumsum(~ok)])
    firsts = np.arange(0, n - w + 1)
    good = firsts[(c[firsts + w] - c[firsts]) == 0] + need_before
    if good.size <= n_sim:
        return good
    return good[np.linspace(0, good.size - 1, n_sim).round().astype(int)]


def _regression_fill(pos, valid, m, a, b, *, neighbors, context, ridge, n_sim=6):
    """Regression fill of frames [a, b) of marker m.

    Returns ``(values (L, 3), neighbour indices, shrink)`` or None when not possible. ``shrink`` in
    [0, 1] is the weight of the regression's departure from the baseline (linear / hold), chosen
    by simulating gaps of the same length in the training window (cross-validated).
    """
    n_frames = pos.shape[0]
    length = b - a
    lo, hi = max(a - 1, 0), min(b + 1, n_frames)  # the gap plus its boundary frames
    span_ok = valid[lo:hi].all(axis=0)
    span_ok[m] = False
    cands = np.flatnonzero(span_ok)
    if cands.size == 0:
        return None
    win = np.zeros(n_frames, dtype=bool)
    win[max(a - context, 0):a] = True
    win[b:min(b + context, n_frames)] = True
    train_m = win & valid[:, m]
    if train_m.sum() < 10:
        return None
    # candidates must be valid on most training frames
    cands = cands[valid[train_m][:, cands].mean(axis=0) >= 0.9]
    if cands.size == 0:
        return None
    # rank neighbours on the whole take (co-activation seen in every expression, not only the
    # quiet frames that often surround a gap)
    whole = valid[:, m] & valid[:, cands].all(axis=1)
    order = _rank_neighbors(pos, m, list(cands), whole if whole.sum() >= 10 else train_m)
    k = min(neighbors, len(order))
    train = train_m & valid[:, order[:k]].all(axis=1)
    while k > 1 and train.sum() < 4 * 3 * k:  # keep >= 4 frames per coefficient
        k -= 1
        train = train_m & valid[:, order[:k]].all(axis=1)
    if train.sum() < 10:
        return None
    nb = order[:k]

    # self-validation: simulated gaps of the same length inside the training window
    two_sided = a > 0 and b < n_frames
    need_before = 1 if (a > 0) else 0
    need_after = 1 if (b < n_frames) else 0
    starts = _sim_starts(train, length, need_before, need_after, n_sim)
    num = den = 0.0
    for s in starts:
        e = s + length
        s_lo, s_hi = s - need_before, e + need_after
        tr = train.copy()
        tr[max(s_lo - 1, 0):s_hi + 1] = False
        if tr.sum() < 4 * 3 * k:
            continue
        pred = _fit_predict(pos, m, nb, tr, s_lo, s_hi, ridge)
        y = pos[:, m]
        # simulate the edge/interior type of the real gap
        sa, sb = s, e
        if two_sided:
            reg = _boundary_corrected(pred, y, sa, sb, s_lo, n_frames)
            base = _linear_fill(y, sa, sb)
        elif a > 0:  # gap runs to the end: boundary before only
            reg = pred[sa - s_lo:sb - s_lo] + (y[sa - 1] - pred[0])
            base = np.repeat(y[sa - 1][None], length, axis=0)
        else:  # gap from the start: boundary after only
            reg = pred[sa - s_lo:sb - s_lo] + (y[sb] - pred[-1])
            base = np.repeat(y[sb][None], length, axis=0)
        d_pred = reg - base
        d_true = y[sa:sb] - base
        num += float((d_pred * d_true).sum())
        den += float((d_pred * d_pred).sum())
    shrink = 1.0 if den <= 0 else float(np.clip(num / den, 0.0, 1.0))

    pred = _fit_predict(pos, m, nb, train, lo, hi, ridge)
    reg = _boundary_corrected(pred, pos[:, m], a, b, lo, n_frames)
    base = _linear_fill(pos[:, m], a, b)
    return base + shrink * (reg - base), nb, shrink


def fill_gaps(capture: Capture, *, max_gap: int = 30, method: str = "regression", neighbors: int = 8,
              context: int = 120, ridge: float = 1e-2):
    """Fill runs of invalid samples no longer than ``max_gap`` frames.

    Parameters
    ----------
    capture : Capture
        Input capture (not modified).
    max_gap : int
        Longest run of invalid frames filled (>= 1); longer runs stay invalid and are reported.
    method : {"regression", "linear"}
        See the module docstring. Gaps at the start or end of the take (edge gaps): ``"linear"``
        holds the nearest valid sample; ``"regression"`` predicts from the neighbours and matches
        the one valid boundary sample with a constant offset.
    neighbors : int
        Number of predictor markers for ``"regression"`` (>= 1).
    context : int
        Frames on each side of a gap used to train the regression (>= 1).
    ridge : float
        Ridge regularisation, relative to the mean feature variance (>= 0).

    Returns
    -------
    capture : Capture
        Filled positions (F, M, 3); a history entry ``{"step": "fill_gaps", ...}``.
    report : GapReport

    Notes
    -----
    Only originally valid samples are used as predictors and training data, so the result does
    not depend on the order in which gaps are filled. A filled sample is not marked as such in
    the capture; the report lists them.
    """
    if method not in METHODS:
        raise OptionError(f"method: unknown gap-filling method {method!r}; expected one of {', '.join(METHODS)}")
    for name, val, lo in (("max_gap", max_gap, 1), ("neighbors", neighbors, 1), ("context", context, 1)):
        if isinstance(val, (bool, np.bool_)) or not isinstance(val, (int, np.integer)) or val < lo:
            raise OptionError(f"{name} must be an integer >= {lo}; got {val!r}")
    if not (np.isfinite(ridge) and ridge >= 0):
        raise OptionError(f"ridge must be a non-negative number; got {ridge!r}")

    pos = capture.positions
    valid = capture.valid
    out = pos.copy()
    n_frames = capture.n_frames
    filled, unfilled = [], []
    for m, a, b in find_gaps(valid):
        name = capture.names[m]
        if a == 0 and b == n_frames:
            unfilled.append(Gap(name, a, b, "no_data"))
            continue
        if b - a > max_gap:
            unfilled.append(Gap(name, a, b, "too_long"))
            continue
        used, nb, shrink = None, (), None
        if method == "regression":
            r = _regression_fill(pos, valid, m, a, b, neighbors=int(neighbors), context=int(context), ridge=float(ridge))
            if r is not None:
                vals, nbi, shrink = r
                used, nb = "regression", tuple(capture.names[j] for j in nbi)
        if used is None:
            vals = _linear_fill(pos[:, m], a, b)
            used = "linear" if (a > 0 and b < n_frames) else "hold"
        out[a:b, m] = vals
        filled.append(Gap(name, a, b, used, nb, shrink))

    report = GapReport(filled=filled, unfilled=unfilled, n_frames=n_frames)
    step = {
        "step": "fill_gaps",
        "method": method,
        "max_gap": int(max_gap),
        "neighbors": int(neighbors),
        "context": int(context),
        "ridge": float(ridge),
        "filled_gaps": len(filled),
        "filled_samples": report.n_filled_samples,
        "unfilled_gaps": len(unfilled),
    }
    return capture.replace(step=step, positions=out), report
