"""Thin-plate spline warps with an affine term (seed 001, section 4.2: RBF interpolation of the
generic model onto the raw data).

``f(x) = A x + b + sum_j w_j phi(|x - c_j|)`` with ``sum_j w_j = 0`` and ``sum_j w_j c_j^T = 0``
(Bookstein 1989). The kernel minimising the bending energy is ``phi(r) = r^2 log r`` in 2-D
(:func:`usdface.rbf.kernels.thin_plate_spline`) and ``phi(r) = -r`` in 3-D (the biharmonic
kernel, with the sign that makes it conditionally positive definite, so that a positive
``smoothing`` ridge regularises instead of destabilising); with the affine term the system is
solvable for any set of centres not all on one line (2-D) or plane (3-D).
"""
from __future__ import annotations

import numpy as np

from ..errors import ComputeError, OptionError

__all__ = ["ThinPlateSpline", "tps_kernel"]


def tps_kernel(r: np.ndarray, dim: int) -> np.ndarray:
    """Thin-plate kernel for ``dim`` dimensions: ``r^2 log r`` (2-D) or ``-r`` (3-D)."""
    if dim == 2:
        from ..rbf.kernels import thin_plate_spline

        return thin_plate_spline(r)
    if dim == 3:
        return -np.asarray(r, dtype=np.float64)
    raise OptionError(f"thin-plate spline: dimension must be 2 or 3; got {dim}")


class ThinPlateSpline:
    """A thin-plate spline mapping ``centres`` (M, D) onto ``targets`` (M, E).

    Parameters
    ----------
    centres : ndarray, shape (M, D), D in (2, 3)
    targets : ndarray, shape (M, E)
    smoothing : float
        Ridge ``lambda`` added to the kernel diagonal (0: exact interpolation), in the units of
        the kernel (length for 3-D).

    Examples
    --------
    >>> f = ThinPlateSpline(src, dst)      # doctest: +SKIP
    >>> moved = f(points)                   # doctest: +SKIP
    """

    def __init__(self, centres, targets, *, smoothing: float = 0.0):
        c = np.asarray(centres, dtype=np.float64)
        y = np.asarray(targets, dtype=np.float64)
        if c.ndim != 2 or c.shape[1] not in (2, 3):
            raise OptionError(f"thin-plate spline: centres must have shape (M, 2) or (M, 3); got {c.shape}")
        if y.ndim != 2 or y.shape[0] != c.shape[0]:
            raise OptionError(f"thin-plate spline: targets must have shape ({c.shape[0]}, E); got {y.shape}")
        m, d = c.shape
        if m < d + 1:
            raise ComputeError(f"thin-plate spline: {m} point pairs; at least {d + 1} are needed")
        self.dim = d
        self.centres = c
        r = np.linalg.norm(c[:, None, :] - c[None, :, :], axis=2)
        phi = tps_kernel(r, d) + smoothing * np.eye(m)
        P = np.hstack([np.ones((m, 1)), c])
        A = np.zeros((m + d + 1, m + d + 1))
        A[:m, :m] = phi
        A[:m, m:] = P
        A[m:, :m] = P.T
        rhs = np.vstack([y, np.zeros((d + 1, y.shape[1]))])
        if np.linalg.matrix_rank(P) < d + 1:
            raise ComputeError(f"thin-plate spline: the {m} centres are degenerate (all on one "
                               f"{'line' if d == 2 else 'plane'}); the affine part is undetermined")
        try:
            sol = np.linalg.solve(A, rhs)
        except np.linalg.LinAlgError:
            raise ComputeError("thin-plate spline: singular system (coincident centres?)") from None
        self.weights = sol[:m]
        self.affine = sol[m:]  # rows: constant, then one per input dimension

    def __call__(self, points, *, chunk: int = 20000) -> np.ndarray:
        """Evaluate at ``points`` (K, D) -> (K, E)."""
        x = np.asarray(points, dtype=np.float64)
        out = np.empty((x.shape[0], self.weights.shape[1]))
        for s in range(0, x.shape[0], chunk):
            xs = x[s:s + chunk]
            r = np.linalg.norm(xs[:, None, :] - self.centres[None, :, :], axis=2)
            out[s:s + chunk] = tps_kernel(r, self.dim) @ self.weights + self.affine[0] + xs @ self.affine[1:]
        return out
