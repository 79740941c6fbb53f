"""Exact (signed) linear-blend-skinning weights from the RBF transfer matrix.

Why the transfer matrix is a set of skin weights
------------------------------------------------
The transfer moves vertex i by ``Dv_i = sum_j B_ij t_j`` (B the N x M transfer matrix, t_j marker
j's displacement). Give marker j a translation-only joint animated by t_j and the head joint the
remaining weight ``1 - sum_j B_ij``: with linear blend skinning every marker joint's skinning
transform is ``p -> p + t_j`` and the head joint's is the identity, so

    skinned p_i = sum_j B_ij (p_i + t_j) + (1 - sum_j B_ij) p_i = p_i + (B t)_i,

exactly the (stabilised) point cache; the head motion is a transform of the whole face (the
skeleton layer's /Face prim), not a joint's. Weights must sum to one for this to hold (they do, by
construction of the remainder), and every weight of every marker matters: the N x (M + 1) matrix
(:func:`full_weights`) is exact.

Pruning to K influences
-----------------------
DCC importers and game engines take 4 or 8 influences per vertex. :func:`prune_weights` keeps the K
largest weights by magnitude among the M + 1 (the head remainder is one of them and is not
forced in) and then either

- ``fit="lsq"`` (default): refits the K weights by least squares over the take's own marker motion,
  keeping their sum at one: it minimises ``sum_f |sum_{k in S} w_k t_k(f) - (B t(f))_i|^2`` (the
  point-cache error over every frame) with a small ridge towards the truncated weights for
  directions the take never exercises. This needs the M x M Gram matrix of the marker motion once
  and one K x K solve per vertex. Weights are then specific to the take, though they stay close
  to the transfer's.
- ``fit="renormalize"``: truncates and rescales the K weights to sum to one.

Signs
-----
The interpolating transfer has negative entries (the Gaussian interpolant overshoots between
markers), and the head remainder is negative where the marker weights sum to more than one.
UsdSkel applies weights as authored and the exact reproduction needs them, but DCC importers do
not (Blender drops weights below 1e-5 and renormalises; Maya and game engines expect
non-negative weights): these "exact" weights are for UsdSkel consumers, the default deliverable
is the DCC-safe fit of :mod:`usdface.skel.dcc`.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import OptionError
from .modes import FIT_METHODS

#: ridge of the least-squares refit, relative to the mean diagonal of the motion's Gram matrix
LSQ_RIDGE = 1e-6


@dataclass(frozen=True)
class SkinWeights:
    """K influences per vertex (joint 0 = the root joint, joint j + 1 = marker j).

    Attributes
    ----------
    indices : ndarray (N, K) int32
        Joint indices into the skeleton's joint order.
    weights : ndarray (N, K) float64
        Weights, each row summing to one (up to rounding), strongest first.
    mode : str
        "exact" (signed, from the transfer matrix) or "dcc" (non-negative fit).
    fit : str
        How the weights were obtained: "exact" (nothing pruned), "lsq" or "renormalize" (exact
        weights pruned to K), "dcc".
    """

    indices: np.ndarray
    weights: np.ndarray
    mode: str = "exact"
    fit: str = "exact"

    @property
    def k(self) -> int:
        return self.indices.shape[1]

    def dense(self, n_joints: int) -> np.ndarray:
        """(N, n_joints) dense weight matrix."""
        out = np.zeros((self.indices.shape[0], n_joints))
        rows = np.repeat(np.arange(self.indices.shape[0]), self.k)
        np.add.at(out, (rows, self.indices.ravel()), self.weights.ravel())
        return out


def full_weights(transfer_matrix: np.ndarray) -> np.ndarray:
    """(N, M + 1) exact weights: column 0 the head remainder ``1 - sum_j B_ij``, then B."""
    b = np.asarray(transfer_matrix, dtype=np.float64)
    return np.concatenate([1.0 - b.sum(axis=1, keepdims=True), b], axis=1)


def motion_gram(displacements: np.ndarray) -> np.ndarray:
    """(M, M) Gram matrix ``sum_f,c t_j(f)_c t_k(f)_c`` of marker displacements (F, M, 3)."""
    d = np.asarray(displacements, dtype=np.float64)
    flat = d.reshape(d.shape[0], -1, 3).transpose(1, 0, 2).reshape(d.shape[1], -1)
    return flat @ flat.T


def prune_weights(full: np.ndarray, k: int | None, *, gram: np.ndarray | None = None, fit: str = "lsq") -> SkinWeights:
    """Keep K influences per vertex and make each row sum to one.

    Parameters
    ----------
    full : ndarray (N, M + 1)
        Exact weights from :func:`full_weights` (column 0 = head).
    k : int or None
        Influences per vertex (>= 1); None or >= M + 1 keeps them all (exact).
    gram : ndarray (M, M), optional
        :func:`motion_gram` of the take, for ``fit="lsq"`` (required then, unless nothing is pruned).
    fit : {"lsq", "renormalize"}
        How the kept weights are refitted (module docstring).

    Returns
    -------
    SkinWeights
    """
    if fit not in FIT_METHODS:
        raise OptionError(f"weight fit: expected one of {', '.join(FIT_METHODS)}; got {fit!r}")
    full = np.asarray(full, dtype=np.float64)
    n, j = full.shape
    if k is not None and (isinstance(k, bool) or not isinstance(k, (int, np.integer)) or k < 1):
        raise OptionError(f"--max-influences: expected an integer >= 1; got {k!r}")
    if k is None or k >= j:
        order = np.argsort(-np.abs(full), axis=1, kind="stable")
        return SkinWeights(order.astype(np.int32), np.take_along_axis(full, order, axis=1), "exact", "exact")
    order = np.argsort(-np.abs(full), axis=1, kind="stable")[:, :k]
    w = np.take_along_axis(full, order, axis=1)
    used_fit = fit
    if fit == "renormalize" or k == 1:
        s = w.sum(axis=1, keepdims=True)
        s[np.abs(s) < 1e-12] = 1.0
        w = w / s
        used_fit = "renormalize"
    else:
        if gram is None:
            raise OptionError("prune_weights(fit='lsq') needs the motion Gram matrix (gram=motion_gram(displacements))")
        w = _lsq_refit(full, order, np.asarray(gram, dtype=np.float64))
    return SkinWeights(order.astype(np.int32), w, "exact", used_fit)


def _lsq_refit(full: np.ndarray, order: np.ndarray, gram: np.ndarray) -> np.ndarray:
    """Refit the kept weights (sum one) by least squares over the take (see the module docstring)."""
    n, k = order.shape
    m = gram.shape[0]
    b = full[:, 1:]
    target = b @ gram  # (N, M): (G b_i)^T per vertex
    eps = LSQ_RIDGE * max(float(np.trace(gram)) / m, 1e-30)
    out = np.take_along_axis(full, order, axis=1).copy()
    has_head = (order == 0).any(axis=1)
    # rows with the head among the kept: marker weights free, head = 1 - their sum
    rows = np.flatnonzero(has_head)
    if rows.size and k > 1:
        pos = order[rows]
        keep = pos != 0
        mk = pos[keep].reshape(rows.size, k - 1) - 1  # marker indices
        g = gram[mk[:, :, None], mk[:, None, :]] + eps * np.eye(k - 1)
        rhs = np.take_along_axis(target[rows], mk, axis=1) + eps * np.take_along_axis(b[rows], mk, axis=1)
        wm = np.linalg.solve(g, rhs[:, :, None])[:, :, 0]
        res = np.empty((rows.size, k))
        res[keep] = wm.ravel()
        res[~keep] = 1.0 - wm.sum(axis=1)
        out[rows] = res
    # rows without the head: K marker weights with sum one (KKT system)
    rows = np.flatnonzero(~has_head)
    if rows.size:
        mk = order[rows] - 1
        a = np.zeros((rows.size, k + 1, k + 1))
        a[:, :k, :k] = gram[mk[:, :, None], mk[:, None, :]] + eps * np.eye(k)
        a[:, :k, k] = 1.0
        a[:, k, :k] = 1.0
        rhs = np.empty((rows.size, k + 1))
        rhs[:, :k] = np.take_along_axis(target[rows], mk, axis=1) + eps * np.take_along_axis(b[rows], mk, axis=1)
        rhs[:, k] = 1.0
        out[rows] = np.linalg.solve(a, rhs[:, :, None])[:, :k, 0]
    return out


def skinning_error(weights: SkinWeights, transfer_matrix: np.ndarray, displacements: np.ndarray,
                   rest_points: np.ndarray, *, chunk_frames: int = 256) -> dict:
    """How far linear blend skinning with exact-mode ``weights`` is from the point cache.

    The marker joints translate by the marker displacements t(f) and the root stays still.
    Skinned displacement of vertex i at frame f: ``(s_i - 1) p_i + sum_k w_ik t_{j_ik}(f)`` (s_i the
    row sum); the point cache moves it by ``(B t(f))_i``.

    Parameters
    ----------
    displacements : ndarray (F, M, 3)
        The marker joints' translations (finite).
    rest_points : ndarray (N, 3)

    Returns
    -------
    dict with ``max`` and ``rms`` (mesh units) over every vertex and frame, ``maxFrame``.
    """
    b = np.asarray(transfer_matrix, dtype=np.float64)
    n, m = b.shape
    dense = weights.dense(m + 1)
    e = dense[:, 1:] - b
    rest_err = (dense.sum(axis=1) - 1.0)[:, None] * np.asarray(rest_points, dtype=np.float64)
    d = np.asarray(displacements, dtype=np.float64)
    flat = np.ascontiguousarray(d.transpose(1, 0, 2).reshape(m, -1))  # (M, F*3), frame-major columns
    def chunks():
        for a in range(0, d.shape[0], chunk_frames):
            f = min(d.shape[0], a + chunk_frames) - a
            err = (e @ flat[:, 3 * a:3 * (a + f)]).reshape(n, f, 3) + rest_err[:, None, :]
            yield a, np.sqrt((err * err).sum(axis=2)).T  # (f, N)

    return error_summary(chunks())


def error_summary(norm_chunks) -> dict:
    """Largest and rms vertex error over chunks of frames.

    Parameters
    ----------
    norm_chunks : iterable of (first frame, ndarray (f, N))
        Vertex error norms (mesh units) of consecutive chunks of frames.

    Returns
    -------
    dict: ``max``, ``rms`` (mesh units), ``maxFrame`` (frame of the largest error), ``frames``.
    """
    worst, worst_f, sq, count, frames = 0.0, 0, 0.0, 0, 0
    for a, norm in norm_chunks:
        fmax = norm.max(axis=1)
        i = int(fmax.argmax())
        if fmax[i] > worst:
            worst, worst_f = float(fmax[i]), a + i
        sq += float((norm * norm).sum())
        count += norm.size
        frames += norm.shape[0]
    return {"max": worst, "rms": float(np.sqrt(sq / max(count, 1))), "maxFrame": int(worst_f), "frames": frames}
