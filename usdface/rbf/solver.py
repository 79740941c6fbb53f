"""Fitting the RBF transfer and judging it: the transfer matrix B, the condition number, the advice.

:func:`fit_system` factorises the system of an :class:`~usdface.rbf.system.RBFSystem` once and
folds it into the N x M transfer matrix B (see :mod:`usdface.rbf.transfer` for the two modes);
:func:`conditioning_advice` and :func:`nearly_coincident` say what is wrong with a badly
conditioned system. Numpy's linear algebra only (one SVD, one LU solve).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import ComputeError, list_names
from .system import RBFSystem

__all__ = ["ADVICE_CONDITION", "SINGULAR_CONDITION", "COINCIDENT_RTOL", "FittedTransfer", "fit_system",
           "conditioning_advice", "nearly_coincident"]

#: condition number above which :attr:`RBFTransfer.advice` speaks up (and fit() warns)
ADVICE_CONDITION = 1e10
#: condition number (or an exactly singular LU) at which fit() refuses: the result is meaningless
SINGULAR_CONDITION = 1e15
#: centres closer than this fraction of their (smaller) kernel width count as nearly coincident
COINCIDENT_RTOL = 1e-2

_SETUP_BLOCK_BYTES = 32 << 20  # kernel evaluation block during fit()


@dataclass(frozen=True)
class FittedTransfer:
    """What :func:`fit_system` computes.

    Attributes
    ----------
    B64 : ndarray, shape (N, M), float64, read-only
        The transfer matrix: vertex displacements = B @ marker displacements (mesh units).
    B32 : ndarray, shape (N, M), float32, read-only
        B for the float32 evaluation.
    condition : float or None
        2-norm condition number of the full system (interpolate mode); None in paper mode.
    Z_mm : ndarray, shape (M, M), or None
        Interpolate mode: the marker block of A^-1 (the reduced solves of validity patterns).
    phi_mm : ndarray, shape (M, M), or None
        Paper mode: the marker-to-marker kernel matrix (Eq. 4 sums of validity patterns).
    r : ndarray, shape (M,), or None
        Paper mode: the Eq. 4 sums ``sum_k phi_k(d_jk)`` over all markers.
    """

    B64: np.ndarray
    B32: np.ndarray
    condition: float | None
    Z_mm: np.ndarray | None = None
    phi_mm: np.ndarray | None = None
    r: np.ndarray | None = None


def nearly_coincident(system: RBFSystem, rtol: float = COINCIDENT_RTOL) -> list[tuple[str, str, float]]:
    """Pairs of centres closer than ``rtol`` times the smaller of their kernel widths.

    Returns
    -------
    list of (str, str, float)
        (label of centre j, label of centre k, distance in mesh units), closest first; labels are
        marker names (quoted) or ``constraint centre #p``. Distance is ``min(D_cc[j, k], D_cc[k, j])``.
    """
    d = np.minimum(system.D_cc, system.D_cc.T)
    w = system.widths
    tol = rtol * np.minimum(w[:, None], w[None, :])
    j, k = np.nonzero(np.triu(d < tol, k=1))
    order = np.argsort(d[j, k], kind="stable")
    return [(system.marker_label(int(j[o])), system.marker_label(int(k[o])), float(d[j[o], k[o]])) for o in order]


def conditioning_advice(system: RBFSystem, cond: float | None) -> str:
    """What to do about a system of condition number ``cond`` (None or inf: singular): nearly
    coincident centres, the widths against the nearest-centre distances, dense constraint centres."""
    parts = []
    if cond is None or not np.isfinite(cond):
        parts.append("the interpolation matrix is singular")
    else:
        parts.append(f"the interpolation matrix has condition number {cond:.3g} (> {ADVICE_CONDITION:.0e}): "
                     "the solve amplifies noise and round-off")
    pairs = nearly_coincident(system)
    if pairs:
        shown = [f"{a} and {b} ({d:.3g} apart)" for a, b, d in pairs]
        parts.append(f"nearly coincident centres (closer than {COINCIDENT_RTOL:g} x kernel width): {list_names(shown, limit=8)}; "
                     "remove or merge duplicates (check the marker binding)")
    w = system.widths
    d = np.minimum(system.D_cc, system.D_cc.T).astype(np.float64)
    np.fill_diagonal(d, np.inf)
    nearest = d.min(axis=1)
    ratio = nearest / w
    parts.append(
        f"kernel widths {w.min():.3g}..{w.max():.3g} mesh units vs nearest-centre distances down to "
        f"{nearest.min():.3g}: try a smaller width, regularization > 0 (e.g. 1e-8..1e-3)"
        + (", or a polynomial term with a polyharmonic kernel" if not system.settings.polynomial else "")
    )
    M = system.n_markers
    if system.n_centres > M and np.median(ratio[M:]) < 0.5 * np.median(ratio[:M]):
        parts.append("constraint centres are much denser than the markers: subsample them to about the marker spacing")
    return "; ".join(parts) + "."


def _refusal(system: RBFSystem, what: str, cond: float | None) -> ComputeError:
    """The error of a fit that cannot be used, with the advice; ``.condition`` is the condition
    number measured (None in paper mode), which the transfer still reports."""
    err = ComputeError(f"{what} {conditioning_advice(system, cond)}")
    err.condition = cond
    return err


def _fit_interpolate(system: RBFSystem) -> FittedTransfer:
    """``B = [Phi_vc, P_v] @ A^-1[:, :M]``: one SVD (condition number), one LU solve, kernel rows in
    blocks of vertices."""
    N, C, M = system.n_vertices, system.n_centres, system.n_markers
    A = system.matrix()
    try:
        cond = float(np.linalg.cond(A))  # 2-norm, SVD: O(C^3), once
    except np.linalg.LinAlgError:  # pragma: no cover - SVD did not converge
        cond = float("inf")
    if not cond < SINGULAR_CONDITION:
        raise _refusal(system, "RBF system is singular; cannot transfer.", cond)
    E = np.zeros((A.shape[0], M))
    E[np.arange(M), np.arange(M)] = 1.0
    try:
        Z = np.linalg.solve(A, E)  # LU with partial pivoting (LAPACK gesv); Z = A^-1[:, :M]
    except np.linalg.LinAlgError:  # pragma: no cover - guarded by the condition check
        raise _refusal(system, "RBF system is singular; cannot transfer.", cond) from None
    Z_mm = np.ascontiguousarray(Z[:M, :M])
    Zc = np.ascontiguousarray(Z[:C])
    Zp = Z[C:] if system.settings.polynomial else None
    B = np.empty((N, M))
    step = max(1, _SETUP_BLOCK_BYTES // (8 * C))
    for a in range(0, N, step):
        b = min(N, a + step)
        np.matmul(system.kernel_rows(slice(a, b)), Zc, out=B[a:b])
        if Zp is not None:
            pv = (system.vertex_points[a:b] - system.poly_origin) / system.poly_scale
            B[a:b] += Zp[0] + pv @ Zp[1:]
    return _finish(system, B, cond, Z_mm=Z_mm)


def _fit_paper(system: RBFSystem) -> FittedTransfer:
    """``B[:, j] = Phi_vc[:, j] / sum_k Phi_cc[j, k]`` (Eqs. 4-5, k over the markers)."""
    N, M = system.n_vertices, system.n_markers
    phi_mm = system.phi(system.D_cc[:M, :M], system.widths[:M])
    r = phi_mm.sum(axis=1)
    bad = ~(np.isfinite(r) & (r > 0))
    if bad.any():
        labels = [system.marker_label(j) for j in np.flatnonzero(bad)]
        raise ComputeError(
            f"paper mode: Eq. 4 sums sum_k phi(d_jk) are not positive for {list_names(labels)}; "
            f"kernel {system.settings.kernel!r} cannot be used in paper mode here (use gaussian)"
        )
    B = np.empty((N, M))
    step = max(1, _SETUP_BLOCK_BYTES // (8 * M))
    for a in range(0, N, step):
        b = min(N, a + step)
        np.divide(system.kernel_rows(slice(a, b), slice(0, M)), r, out=B[a:b])
    return _finish(system, B, None, phi_mm=phi_mm, r=r)


def _finish(system: RBFSystem, B: np.ndarray, cond: float | None, *, Z_mm=None, phi_mm=None, r=None) -> FittedTransfer:
    if not np.isfinite(B).all():
        raise _refusal(system, "RBF transfer matrix has non-finite entries.", cond)
    B.setflags(write=False)
    B32 = B.astype(np.float32)
    B32.setflags(write=False)
    return FittedTransfer(B64=B, B32=B32, condition=cond, Z_mm=Z_mm, phi_mm=phi_mm, r=r)


def fit_system(system: RBFSystem) -> FittedTransfer:
    """Factorise ``system`` once and build its transfer matrix B (N x M).

    Interpolate mode: the 2-norm condition number of the (C [+ 4]) system (one SVD), one LU solve
    (partial pivoting) for ``Z = A^-1[:, :M]`` and ``B = [Phi_vc, P_v] @ Z`` (kernel evaluated in
    blocks of vertices). Paper mode: ``B[:, j] = Phi_vc[:, j] / sum_k Phi_cc[j, k]`` (Eqs. 4-5, k
    over the markers).

    Raises
    ------
    ComputeError
        Singular or numerically singular system (the message carries the advice; ``.condition``
        the condition number), non-finite B, or non-positive Eq. 4 sums in paper mode.
    """
    return _fit_interpolate(system) if system.settings.mode == "interpolate" else _fit_paper(system)
