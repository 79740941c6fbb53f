"""The robust rest pose of a capture's markers: the estimator :attr:`usdface.model.capture.Capture.neutral`
averages the neutral stretch with (the stretch itself is found by :mod:`usdface.capture.rest`).
Pure numpy."""
from __future__ import annotations

import numpy as np

__all__ = ["robust_rest_pose", "HUBER_K"]

#: Huber threshold in robust standard deviations of a 3D sample (sqrt of chi2(3)'s 90% quantile)
HUBER_K = 2.5
#: median |n| of a 3D standard normal vector: turns a median distance into a per-coordinate scale
_MEDIAN_CHI3 = 1.5382


def robust_rest_pose(positions, *, iterations: int = 8) -> tuple[np.ndarray, np.ndarray]:
    """Per-marker Huber M-estimate of the position over the given frames.

    Parameters
    ----------
    positions : array_like, shape (F, M, D), float
        Positions (any units), NaN where a sample is invalid.
    iterations : int
        Reweighting rounds after the start from the per-coordinate median.

    Returns
    -------
    rest : ndarray, shape (M, D), float64
        NaN for a marker with no valid sample.
    count : ndarray, shape (M,), int64
        Valid samples per marker.
    """
    p = np.asarray(positions, dtype=np.float64)
    ok = np.isfinite(p).all(axis=2)
    count = ok.sum(axis=0)
    filled = np.where(ok[:, :, None], p, 0.0)
    with np.errstate(all="ignore"):
        if ok.all():
            rest = np.median(p, axis=0)
        else:
            import warnings

            with warnings.catch_warnings():
                warnings.simplefilter("ignore", RuntimeWarning)  # markers without samples stay NaN
                rest = np.nanmedian(np.where(ok[:, :, None], p, np.nan), axis=0)
        for _ in range(iterations):
            r = np.linalg.norm(filled - rest[None], axis=2)  # (F, M)
            r_nan = np.where(ok, r, np.nan)
            scale = _nanmedian_columns(r_nan) / _MEDIAN_CHI3  # (M,) per-coordinate sigma
            limit = HUBER_K * scale
            w = np.where(r > limit[None], limit[None] / np.maximum(r, 1e-300), 1.0) * ok
            w = np.where(scale[None] > 0, w, ok.astype(np.float64))
            total = w.sum(axis=0)
            # the weighted mean as a correction of the estimate: exact when every sample agrees
            step = (w[:, :, None] * (filled - rest[None])).sum(axis=0) / np.where(total > 0, total, 1.0)[:, None]
            new = rest + step
            rest = np.where((total > 0)[:, None], new, np.nan)
    return rest, count.astype(np.int64)


def _nanmedian_columns(x: np.ndarray) -> np.ndarray:
    """Median over axis 0 ignoring NaN; NaN for an all-NaN column, without a warning."""
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        return np.nanmedian(x, axis=0)
