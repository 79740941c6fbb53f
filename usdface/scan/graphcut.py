"""Stereo matching by graph cuts: a matching-cost volume and alpha-expansion moves.

The seed paper (seed 001, section 2) uses Kolmogorov and Zabih's KZ1 algorithm: a disparity map
is the labelling minimising an energy of a data term, a smoothness term and an occlusion term,
found by alpha-expansion moves, each one an exact minimum cut. This module follows that scheme:

``E(f) = sum_p D_p(f_p) + sum_{(p,q) in N} w_pq * V(f_p, f_q)``              (KZ1 energy, Eq. 1)

- ``D_p(d)``: the matching cost of pixel p at disparity d, a census-transform Hamming distance
  (robust to the gain and bias differences between two cameras) mixed with a truncated absolute
  difference of horizontal gradients, aggregated over a small window;
- ``V(a, b) = lambda * min(|a - b|, K)``: truncated linear, a metric, so alpha-expansion applies
  (Boykov, Veksler & Zabih 2001); ``K = 1`` gives KZ1's Potts model, larger ``K`` lets slanted
  surfaces such as a face change disparity by one pixel at a time at a lower price;
- ``w_pq``: KZ1's contrast-sensitive weight, 3 when the intensities of p and q differ by less than
  ``contrast_threshold`` and 1 otherwise, so disparity edges snap to intensity edges;
- occlusions: KZ1 labels them inside the energy; here they are detected after the fact from the
  uniqueness constraint (two left pixels cannot see the same right pixel: the one with the smaller
  disparity is hidden) and, when both views are matched, by left-right consistency.

Each expansion move on label ``alpha`` is one s-t minimum cut (PyMaxflow, the Boykov-Kolmogorov
algorithm) over the pixels for which alpha is plausible (alpha within ``candidates`` of the best
labels of their cost, or next to such a pixel); other pixels keep their label, which keeps every
move an exact minimiser of a restricted move and the energy monotone.
"""
from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from ..errors import OptionError, UsdFaceError

__all__ = ["census_transform", "matching_cost", "contrast_weights", "alpha_expansion", "labelling_energy", "subpixel_refine",
           "uniqueness_occlusions", "GraphCutParameters", "GraphCutResult", "graphcut_disparity"]


def _maxflow():
    try:
        import maxflow
    except ImportError as exc:
        raise UsdFaceError("the graph-cut stereo method needs PyMaxflow: pip install PyMaxflow") from exc
    return maxflow


def _gray(img) -> np.ndarray:
    a = np.asarray(img)
    if a.ndim == 3:
        a = a[..., :3].astype(np.float32) @ np.array([0.114, 0.587, 0.299], np.float32)  # BGR order
    return a.astype(np.float32)


# ================================================================================================
# data term
# ================================================================================================
def census_transform(gray, *, radius: int = 3) -> np.ndarray:
    """Census transform: one bit per window neighbour, set when it is darker than the centre.

    Parameters
    ----------
    gray : ndarray, shape (H, W)
        Intensity image.
    radius : int
        Window half-size; the window is ``(2 radius + 1)^2`` minus the centre, at most 63 bits.

    Returns
    -------
    ndarray, shape (H, W), uint64
        Bit strings (borders replicate the edge pixels).
    """
    g = np.asarray(gray, dtype=np.float32)
    n_bits = (2 * radius + 1) ** 2 - 1
    if n_bits > 63:
        raise OptionError(f"census radius {radius} needs {n_bits} bits; at most 63 (radius <= 3)")
    pad = np.pad(g, radius, mode="edge")
    h, w = g.shape
    out = np.zeros((h, w), dtype=np.uint64)
    bit = 0
    for dy in range(-radius, radius + 1):
        for dx in range(-radius, radius + 1):
            if dx == 0 and dy == 0:
                continue
            nb = pad[radius + dy:radius + dy + h, radius + dx:radius + dx + w]
            out |= (nb < g).astype(np.uint64) << np.uint64(bit)
            bit += 1
    return out


def _box(a: np.ndarray, window: int) -> np.ndarray:
    """Mean over a ``window`` x ``window`` box of each (H, W) slice of an (H, W, L) array."""
    if window <= 1:
        return a
    from scipy.ndimage import uniform_filter

    return uniform_filter(a, size=(window, window, 1), mode="nearest")



_BYTE_BITS = np.array([bin(i).count("1") for i in range(256)], dtype=np.uint8)


def popcount(a: np.ndarray) -> np.ndarray:
    """Set bits of each element of an unsigned integer array (``np.bitwise_count`` of numpy 2,
    which numpy 1.26 — still supported, and what Blender's bpy pins — lacks)."""
    if hasattr(np, "bitwise_count"):
        return np.bitwise_count(a)
    a = np.ascontiguousarray(a)
    as_bytes = a.view(np.uint8).reshape(a.shape + (a.dtype.itemsize,))
    return _BYTE_BITS[as_bytes].sum(axis=-1, dtype=np.uint8)

def matching_cost(left, right, *, min_disparity: int = 0, num_disparities: int = 64, census_radius: int = 3,
                  gradient_weight: float = 0.3, gradient_truncation: float = 20.0, window: int = 5) -> np.ndarray:
    """Matching-cost volume of a rectified pair (the data term ``D_p(d)``).

    Parameters
    ----------
    left, right : ndarray, shape (H, W) or (H, W, 3)
        Rectified images (BGR when colour), same size; a scene point at column x in ``left`` is
        at column ``x - d`` in ``right``.
    min_disparity, num_disparities : int
        Disparities ``min_disparity .. min_disparity + num_disparities - 1`` (pixels).
    census_radius : int
        Census window half-size (3: 7x7, 48 bits).
    gradient_weight : float
        Weight of the truncated gradient difference against the census distance (both in [0, 1]).
    gradient_truncation : float
        Gradient differences above this (grey levels per pixel) cost the same.
    window : int
        Side of the box the pixel costs are averaged over (1: none).

    Returns
    -------
    ndarray, shape (H, W, L), float32
        Cost in [0, 1 + gradient_weight]; columns whose match falls outside the right image
        repeat the cost of the first column that has one.
    """
    gl, gr = _gray(left), _gray(right)
    if gl.shape != gr.shape:
        raise OptionError(f"left and right images differ in size: {gl.shape[::-1]} vs {gr.shape[::-1]}")
    if num_disparities < 1:
        raise OptionError(f"num_disparities must be >= 1; got {num_disparities}")
    h, w = gl.shape
    cl, cr = census_transform(gl, radius=census_radius), census_transform(gr, radius=census_radius)
    n_bits = float((2 * census_radius + 1) ** 2 - 1)
    gxl = np.gradient(gl, axis=1)
    gxr = np.gradient(gr, axis=1)
    cost = np.empty((h, w, num_disparities), dtype=np.float32)
    for k in range(num_disparities):
        d = min_disparity + k
        # column x of the left image matches column x - d of the right one
        src = np.clip(np.arange(w) - d, 0, w - 1)
        ham = popcount(cl ^ cr[:, src]).astype(np.float32) / n_bits
        grad = np.minimum(np.abs(gxl - gxr[:, src]), gradient_truncation) / gradient_truncation
        c = ham + gradient_weight * grad
        first = max(d, 0)  # columns with no counterpart in the right image
        if 0 < first < w:
            c[:, :first] = c[:, first:first + 1]
        cost[:, :, k] = c
    return _box(cost, window)


# ================================================================================================
# smoothness term and alpha-expansion
# ================================================================================================
def contrast_weights(image, *, threshold: float = 8.0, high: float = 3.0, low: float = 1.0):
    """KZ1's contrast-sensitive neighbour weights ``w_pq``.

    Parameters
    ----------
    image : ndarray, shape (H, W) or (H, W, 3)
        The reference (left) image.
    threshold : float
        Grey-level (max over channels) difference under which the pair gets ``high``.

    Returns
    -------
    wh : ndarray, shape (H, W - 1), float32
        Weight of the pair (x, x + 1) on each row.
    wv : ndarray, shape (H - 1, W), float32
        Weight of the pair (y, y + 1) in each column.
    """
    a = np.asarray(image, dtype=np.float32)
    if a.ndim == 2:
        a = a[..., None]
    dh = np.abs(np.diff(a, axis=1)).max(axis=2)
    dv = np.abs(np.diff(a, axis=0)).max(axis=2)
    return (np.where(dh < threshold, high, low).astype(np.float32),
            np.where(dv < threshold, high, low).astype(np.float32))


def _pair_cost(a, b, lam, trunc):
    return lam * np.minimum(np.abs(a - b), trunc).astype(np.float32)


def labelling_energy(labels, cost, wh, wv, *, smoothness: float, truncation: float) -> float:
    """``E(f)`` of a labelling (KZ1 Eq. 1 without the occlusion term); for tests and logs."""
    f = np.asarray(labels, dtype=np.int64)
    data = np.take_along_axis(cost, f[..., None], axis=2).sum(dtype=np.float64)
    sh = (wh * _pair_cost(f[:, 1:], f[:, :-1], smoothness, truncation)).sum(dtype=np.float64)
    sv = (wv * _pair_cost(f[1:, :], f[:-1, :], smoothness, truncation)).sum(dtype=np.float64)
    return float(data + sh + sv)


def _expand(maxflow, f, alpha, cost, wh, wv, lam, trunc, active):
    """One alpha-expansion move restricted to the pixels ``active``; returns the new labelling.

    Binary variable x_p = 1 switches p to alpha. A neighbour pair's term
    ``E(x_p, x_q)`` with ``A = V(f_p, f_q)``, ``B = V(f_p, alpha)``, ``C = V(alpha, f_q)``,
    ``D = V(alpha, alpha) = 0`` is ``A + (C - A) x_p + (D - C) x_q + (B + C - A - D)(1 - x_p) x_q``
    (Kolmogorov & Zabih 2004); ``B + C - A >= 0`` because V is a metric, so the cut is exact.
    Pairs with one inactive pixel (x = 0 fixed) only add a unary term to the active one.
    """
    h, w = f.shape
    idx = np.flatnonzero(active.ravel())
    n = idx.size
    node = np.full(h * w, -1, dtype=np.int64)
    node[idx] = np.arange(n)
    node = node.reshape(h, w)
    d_alpha = cost[..., alpha]
    d_cur = np.take_along_axis(cost, f[..., None], axis=2)[..., 0]
    e1 = d_alpha.astype(np.float64).copy()  # cost of x_p = 1 (source capacity)
    e0 = d_cur.astype(np.float64).copy()  # cost of x_p = 0 (sink capacity)
    edges_from, edges_to, edges_cap = [], [], []
    for axis, wgt in ((1, wh), (0, wv)):
        if axis == 1:
            fp, fq = f[:, :-1], f[:, 1:]
            ap, aq = active[:, :-1], active[:, 1:]
            np_, nq = node[:, :-1], node[:, 1:]
            sl_p, sl_q = (slice(None), slice(0, w - 1)), (slice(None), slice(1, w))
        else:
            fp, fq = f[:-1, :], f[1:, :]
            ap, aq = active[:-1, :], active[1:, :]
            np_, nq = node[:-1, :], node[1:, :]
            sl_p, sl_q = (slice(0, h - 1), slice(None)), (slice(1, h), slice(None))
        A = wgt * _pair_cost(fp, fq, lam, trunc)
        B = wgt * _pair_cost(fp, alpha, lam, trunc)
        C = wgt * _pair_cost(alpha, fq, lam, trunc)
        both = ap & aq
        only_p = ap & ~aq  # q stays: E(x_p) = A (x_p = 0) or B (x_p = 1)
        only_q = aq & ~ap  # p stays: E(x_q) = A (x_q = 0) or C... with x_p = 0: E(0, x_q) = A or B
        # both active: unary parts (C - A) x_p and -C x_q, pairwise (B + C - A)(1 - x_p) x_q
        cpa = np.where(both, C - A, 0.0)
        e1[sl_p] += np.where(both, np.maximum(cpa, 0), 0)
        e0[sl_p] += np.where(both, np.maximum(-cpa, 0), 0)
        e0[sl_q] += np.where(both, C, 0)
        e0[sl_p] += np.where(only_p, A, 0)
        e1[sl_p] += np.where(only_p, C, 0)
        e0[sl_q] += np.where(only_q, A, 0)
        e1[sl_q] += np.where(only_q, B, 0)
        cap = np.maximum(B + C - A, 0)
        sel = both & (cap > 0)
        edges_from.append(np_[sel])
        edges_to.append(nq[sel])
        edges_cap.append(cap[sel])
    g = maxflow.Graph[float](n, 2 * n)
    g.add_nodes(n)
    src = e1.ravel()[idx]
    snk = e0.ravel()[idx]
    m = np.minimum(src, snk)
    g.add_grid_tedges(np.arange(n), src - m, snk - m)
    ef, et, ec = np.concatenate(edges_from), np.concatenate(edges_to), np.concatenate(edges_cap)
    if ef.size:
        g.add_edges(ef, et, ec, np.zeros_like(ec))
    g.maxflow()
    switch = g.get_grid_segments(np.arange(n))
    out = f.copy().ravel()
    out[idx[switch]] = alpha
    return out.reshape(h, w)


def alpha_expansion(cost, *, wh=None, wv=None, smoothness: float = 0.08, truncation: float = 2.0,
                    max_cycles: int = 3, candidates: int = 6, labels=None, time_limit: float | None = None,
                    progress=None) -> tuple[np.ndarray, dict]:
    """Minimise ``sum_p D_p(f_p) + sum w_pq lambda min(|f_p - f_q|, K)`` by alpha-expansion.

    Parameters
    ----------
    cost : ndarray, shape (H, W, L), float
        Data term ``D_p(l)`` for labels ``0 .. L-1``.
    wh, wv : ndarray, shapes (H, W-1) and (H-1, W), optional
        Neighbour weights ``w_pq`` (default 1; see :func:`contrast_weights`).
    smoothness : float
        ``lambda``, in cost units per label step.
    truncation : float
        ``K``, label steps after which a jump costs the same (1: Potts).
    max_cycles : int
        Cycles over all labels (each label one move per cycle); stops earlier when a cycle
        changes no pixel.
    candidates : int
        A pixel takes part in the move on ``alpha`` only if alpha is among its ``candidates``
        lowest-cost labels or within ``truncation`` of its current label (0: every pixel, the
        unrestricted move).
    labels : ndarray, shape (H, W), int, optional
        Initial labelling (default: the per-pixel minimum of ``cost``).
    time_limit : float, optional
        Seconds; no new move starts after it.
    progress : callable(cycle, label, energy), optional

    Returns
    -------
    labels : ndarray, shape (H, W), int32
    info : dict
        ``cycles`` (completed), ``moves``, ``energy`` (per cycle, first = initial), ``seconds``.
    """
    maxflow = _maxflow()
    cost = np.asarray(cost, dtype=np.float32)
    if cost.ndim != 3:
        raise OptionError(f"cost must have shape (H, W, L); got {cost.shape}")
    h, w, n_labels = cost.shape
    wh = np.ones((h, w - 1), np.float32) if wh is None else np.asarray(wh, np.float32)
    wv = np.ones((h - 1, w), np.float32) if wv is None else np.asarray(wv, np.float32)
    if max_cycles < 1:
        raise OptionError(f"max_cycles must be >= 1; got {max_cycles}")
    f = (np.argmin(cost, axis=2) if labels is None else np.asarray(labels)).astype(np.int64)
    if candidates and candidates < n_labels:
        kth = np.argpartition(cost, candidates - 1, axis=2)[..., :candidates]
        plausible = np.zeros((h, w, n_labels), dtype=bool)
        np.put_along_axis(plausible, kth, True, axis=2)
        from scipy.ndimage import binary_dilation

        plausible = binary_dilation(plausible, structure=np.ones((3, 3, 1), bool))
    else:
        plausible = None
    t0 = time.perf_counter()
    energies = [labelling_energy(f, cost, wh, wv, smoothness=smoothness, truncation=truncation)]
    moves = cycles = 0
    stopped = False
    rng = np.random.default_rng(0)
    for cycle in range(max_cycles):
        changed = 0
        for alpha in rng.permutation(n_labels):
            if time_limit is not None and time.perf_counter() - t0 > time_limit:
                stopped = True
                break
            if plausible is None:
                active = f != alpha
            else:
                active = (plausible[..., alpha] | (np.abs(f - alpha) <= truncation)) & (f != alpha)
            if not active.any():
                continue
            nf = _expand(maxflow, f, int(alpha), cost, wh, wv, smoothness, truncation, active)
            changed += int((nf != f).sum())
            f = nf
            moves += 1
        if stopped:
            break
        cycles += 1
        energies.append(labelling_energy(f, cost, wh, wv, smoothness=smoothness, truncation=truncation))
        if progress is not None:
            progress(cycle, n_labels, energies[-1])
        if changed == 0:
            break
    return f.astype(np.int32), {"cycles": cycles, "moves": moves, "energy": energies,
                                "seconds": time.perf_counter() - t0, "time_limited": stopped}


def subpixel_refine(labels, cost) -> np.ndarray:
    """Sub-pixel label by a parabola through the costs at ``f - 1, f, f + 1``.

    Returns
    -------
    ndarray, shape (H, W), float32
        ``f + delta`` with ``|delta| <= 0.5``; labels at the ends of the range stay integers.
    """
    f = np.asarray(labels, dtype=np.int64)
    n = cost.shape[2]
    fm = np.clip(f - 1, 0, n - 1)
    fp = np.clip(f + 1, 0, n - 1)
    c0 = np.take_along_axis(cost, f[..., None], 2)[..., 0].astype(np.float64)
    cm = np.take_along_axis(cost, fm[..., None], 2)[..., 0].astype(np.float64)
    cp = np.take_along_axis(cost, fp[..., None], 2)[..., 0].astype(np.float64)
    den = cm - 2 * c0 + cp
    with np.errstate(divide="ignore", invalid="ignore"):
        delta = np.where(den > 1e-9, 0.5 * (cm - cp) / den, 0.0)
    delta = np.clip(delta, -0.5, 0.5)
    delta[(f == 0) | (f == n - 1)] = 0.0
    return (f + delta).astype(np.float32)


def uniqueness_occlusions(disparity) -> np.ndarray:
    """Left pixels hidden in the right view, from the left disparity map alone.

    A left pixel at column x with disparity d is seen at column ``x - d`` of the right image.
    When two left pixels of a row land on the same right pixel (rounded), the nearer one (larger
    disparity) is the one the right camera sees; the other is occluded (KZ1's uniqueness
    constraint).

    Parameters
    ----------
    disparity : ndarray, shape (H, W), float
        NaN where unknown.

    Returns
    -------
    ndarray, shape (H, W), bool
        True where occluded.
    """
    d = np.asarray(disparity, dtype=np.float64)
    h, w = d.shape
    ok = np.isfinite(d)
    xr = np.round(np.arange(w)[None, :] - np.where(ok, d, 0)).astype(np.int64)
    inside = ok & (xr >= 0) & (xr < w)
    rows = np.repeat(np.arange(h), w).reshape(h, w)
    key = rows * w + np.clip(xr, 0, w - 1)
    best = np.full(h * w, -np.inf)
    np.maximum.at(best, key[inside], d[inside])
    occluded = inside & (d < best[key] - 0.5)
    return occluded


@dataclass(frozen=True)
class GraphCutResult:
    """Result of :func:`graphcut_disparity`.

    Attributes
    ----------
    disparity : ndarray, shape (H, W), float32
        Sub-pixel disparity of every pixel (pixels), dense.
    occluded : ndarray, shape (H, W), bool
        Pixels found hidden in the other view.
    info : dict
        Cycles, moves, energies, timings.
    """

    disparity: np.ndarray
    occluded: np.ndarray
    info: dict


@dataclass(frozen=True)
class GraphCutParameters:
    """Settings of :func:`graphcut_disparity` besides the disparity range.

    Attributes
    ----------
    smoothness : float
        ``lambda`` of the smoothness term, in cost units per label step (:func:`alpha_expansion`).
    truncation : float
        ``K``: label steps after which a jump costs the same (1: Potts).
    max_cycles : int
        Expansion cycles over all labels.
    candidates : int
        Labels per pixel taking part in a move (:func:`alpha_expansion`; 0: every pixel).
    window, census_radius : int
        Cost aggregation window and census radius (pixels; :func:`matching_cost`).
    contrast_threshold : float
        Grey-level difference below which neighbours get the high weight (:func:`contrast_weights`).
    time_limit : float, optional
        Seconds after which no new expansion move starts.
    """

    smoothness: float = 0.08
    truncation: float = 2.0
    max_cycles: int = 3
    candidates: int = 6
    window: int = 5
    census_radius: int = 3
    contrast_threshold: float = 8.0
    time_limit: float | None = None


def graphcut_disparity(left, right, *, min_disparity: int = 0, num_disparities: int = 64,
                       params: GraphCutParameters = GraphCutParameters(), progress=None) -> GraphCutResult:
    """Disparity of a rectified pair by graph cuts (KZ1-style energy, alpha-expansion).

    Parameters
    ----------
    left, right : ndarray, shape (H, W) or (H, W, 3)
        Rectified images (column x in ``left`` matches ``x - d`` in ``right``).
    min_disparity, num_disparities : int
        Searched disparity range (pixels).
    params : GraphCutParameters
        Energy, move and cost settings.
    progress : callable(cycle, label, energy), optional
        See :func:`alpha_expansion`.

    Returns
    -------
    GraphCutResult
    """
    t0 = time.perf_counter()
    cost = matching_cost(left, right, min_disparity=min_disparity, num_disparities=num_disparities,
                         census_radius=params.census_radius, window=params.window)
    t_cost = time.perf_counter() - t0
    wh, wv = contrast_weights(left, threshold=params.contrast_threshold)
    labels, info = alpha_expansion(cost, wh=wh, wv=wv, smoothness=params.smoothness, truncation=params.truncation,
                                   max_cycles=params.max_cycles, candidates=params.candidates,
                                   time_limit=params.time_limit, progress=progress)
    disp = subpixel_refine(labels, cost) + np.float32(min_disparity)
    occ = uniqueness_occlusions(disp)
    info = dict(info, cost_seconds=t_cost, total_seconds=time.perf_counter() - t0)
    return GraphCutResult(disparity=disp, occluded=occ, info=info)
