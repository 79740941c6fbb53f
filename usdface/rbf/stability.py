"""Guarding the interpolating solve against kernels that amplify marker motion.

A Gaussian kernel is positive definite on Euclidean distances, but not on geodesic (or hybrid)
distances: the kernel matrix can be indefinite with eigenvalues near zero, and the exact
interpolant then swings far from the markers (on the sample faces, 1 cm of marker motion moved
some geodesic-transferred vertices by metres). The condition number does not show it reliably;
the amplification does.

Amplification (the Lebesgue constant of the transfer): ``max_i sum_j |B_ij|`` for the N x M
transfer matrix B (vertex displacement = B @ marker displacements). It bounds how far any vertex
can move per unit of marker motion: about 1-5 for a well-behaved interpolant.

Two bounds: above :data:`DEFAULT_MAX_AMPLIFICATION` (25x) ``regularization="auto"`` trades exact
interpolation for a ridge term (:func:`fit_stable`); above :data:`WARN_AMPLIFICATION` (6x) whatever
is left is reported (:func:`amplification_warning`). The warning bound was read off the tuning
shapes of ``benchmarks/heldout_split.json`` (``python benchmarks/rbf_heldout.py``, section 1):
every Gaussian or inverse multiquadric transfer (Euclidean, geodesic or hybrid, widths 1.5-4 cm)
whose mesh error exceeded 1.25x the default Euclidean Gaussian's amplified marker motion 6.6x or
more, and every one within it 4.7x or less.
"""
from __future__ import annotations

import warnings
from dataclasses import dataclass, field

import numpy as np

#: regularisation values tried, in kernel units (phi(0) = 1 for the gaussian)
LAMBDA_GRID = (0.0, 1e-3, 3e-3, 1e-2, 3e-2, 0.1, 0.3, 1.0)
#: amplification above which "auto" regularises
DEFAULT_MAX_AMPLIFICATION = 25.0
#: amplification above which the transfer is reported as unreliable (see the module docstring)
WARN_AMPLIFICATION = 6.0


class AmplificationWarning(RuntimeWarning):
    """The transfer moves some vertex more than :data:`WARN_AMPLIFICATION` times the marker motion."""


def amplification_warning(amp: float, *, kernel: str, method: str, regularization: float = 0.0,
                          bound: float = WARN_AMPLIFICATION) -> str | None:
    """The one-line warning for a transfer amplifying marker motion ``amp`` times, or None.

    Parameters
    ----------
    amp : float
        :func:`amplification` of the transfer matrix.
    kernel, method : str
        Kernel and distance method, named in the message.
    regularization : float
        The ridge term used (named when > 0: it did not bring the amplification down enough).
    bound : float
        Warn above this (default :data:`WARN_AMPLIFICATION`).
    """
    if not amp > bound:
        return None
    ridge = f" even with regularization {regularization:.3g}" if regularization > 0 else ""
    fixes = ["a smaller --stiffness"] + (["--method euclidean"] if method != "euclidean" else []) \
        + (["--kernel gaussian"] if kernel != "gaussian" else [])
    return (f"the {kernel} transfer on {method} distances amplifies marker motion {amp:.1f}x at some vertices"
            f"{ridge} (a sound transfer stays under {bound:g}x): expect errors well above the markers' motion there; "
            f"try {' or '.join(fixes)}")


def amplification(transfer_matrix: np.ndarray) -> float:
    """Lebesgue constant ``max_i sum_j |B_ij|`` of an (N, M) transfer matrix (dimensionless)."""
    return float(np.abs(np.asarray(transfer_matrix)).sum(axis=1).max())


@dataclass
class RegularizationChoice:
    """What ``regularization="auto"`` decided.

    Attributes
    ----------
    regularization : float
        The lambda used.
    amplification : float
        Amplification with that lambda.
    exact_amplification : float
        Amplification of the exact (lambda = 0) interpolant.
    tried : dict float -> float
        Amplification per lambda tried.
    """

    regularization: float
    amplification: float
    exact_amplification: float
    tried: dict = field(default_factory=dict)

    @property
    def regularized(self) -> bool:
        return self.regularization > 0


def fit_stable(make_solver, *, max_amplification: float = DEFAULT_MAX_AMPLIFICATION,
               lambdas=LAMBDA_GRID):
    """Fit the exact interpolant; if it amplifies more than ``max_amplification``, use the smallest
    lambda of ``lambdas`` that brings the amplification within the bound (the least smoothing that
    does), or, when none does, the one with the smallest amplification.

    Parameters
    ----------
    make_solver : callable lambda -> fitted RBFTransfer (interpolate mode)
    max_amplification : float
    lambdas : sequence of float, starting with 0

    Returns
    -------
    solver, RegularizationChoice
    """
    tried = {}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        exact = make_solver(0.0)
        tried[0.0] = amplification(exact.transfer_matrix)
        if tried[0.0] <= max_amplification:
            return exact, RegularizationChoice(0.0, tried[0.0], tried[0.0], tried)
        best, best_lam = exact, 0.0
        for lam in sorted(lambdas):
            if lam == 0.0:
                continue
            solver = make_solver(lam)
            tried[lam] = amplification(solver.transfer_matrix)
            if tried[lam] < tried[best_lam]:
                best, best_lam = solver, lam
            if tried[lam] <= max_amplification:
                break
    return best, RegularizationChoice(best_lam, tried[best_lam], tried[0.0], tried)


def marker_residual(solver, marker_points_tri, marker_bary) -> float:
    """Largest |B_bound - I| entry: how far a unit marker displacement misses its own bound point
    (0 for an exact interpolant evaluated at the vertices of the markers' triangles, up to the
    barycentric evaluation)."""
    b = solver.transfer_matrix
    at_markers = np.einsum("mk,mkj->mj", marker_bary, b[marker_points_tri])
    return float(np.abs(at_markers - np.eye(at_markers.shape[0])).max())
