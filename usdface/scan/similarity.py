"""Similarity transforms (rotation, uniform scale, translation) between point sets: stage 1 of the
registration (:mod:`usdface.scan.register`), and the rigid part of a blend-shape transfer."""
from __future__ import annotations

import numpy as np

from ..errors import ComputeError, OptionError

__all__ = ["similarity_fit", "apply_similarity"]


def similarity_fit(src, dst, *, scale: bool = True):
    """Least-squares similarity ``dst ~ s R src + t`` (Umeyama 1991).

    Parameters
    ----------
    src, dst : ndarray, shape (M, 3)

    Returns
    -------
    s : float
    R : ndarray, shape (3, 3)
    t : ndarray, shape (3,)
    """
    a = np.asarray(src, dtype=np.float64)
    b = np.asarray(dst, dtype=np.float64)
    if a.shape != b.shape or a.ndim != 2 or a.shape[1] != 3:
        raise OptionError(f"similarity fit: point sets must both be (M, 3); got {a.shape} and {b.shape}")
    if len(a) < 3:
        raise ComputeError(f"similarity fit: {len(a)} correspondences; at least 3 are needed")
    ma, mb = a.mean(axis=0), b.mean(axis=0)
    A, B = a - ma, b - mb
    cov = B.T @ A / len(a)
    u, sig, vt = np.linalg.svd(cov)
    d = np.sign(np.linalg.det(u @ vt)) or 1.0
    D = np.diag([1.0, 1.0, d])
    R = u @ D @ vt
    var = (A ** 2).sum() / len(a)
    if var <= 0:
        raise ComputeError("similarity fit: all source points coincide")
    s = float(np.trace(np.diag(sig) @ D) / var) if scale else 1.0
    return s, R, mb - s * R @ ma


def apply_similarity(points, s, R, t) -> np.ndarray:
    """``s R p + t`` for every row p of ``points`` (N, 3)."""
    return s * np.asarray(points, dtype=np.float64) @ R.T + t
