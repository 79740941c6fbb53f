"""The transfer as the pipeline builds it: every default and check in one place.

:func:`build_transfer` turns precomputed distances and the transfer options into a fitted
:class:`~usdface.rbf.RBFTransfer`:

1. the polynomial term the kernel needs (:func:`~usdface.rbf.soundness.resolve_polynomial`);
2. the refusal of a kernel with no well-posed variant on the distance method
   (:func:`~usdface.rbf.soundness.check_kernel_method`);
3. the kernel widths: ``--stiffness`` or the default rule
   (:func:`~usdface.rbf.stiffness.transfer_widths`: per-marker and metric-aware for the decaying
   kernels of the interpolating solve, one width for the growing ones, the paper's 1.1 h for
   Eqs. 1-5);
4. the exact solve, or with ``regularization="auto"`` the least ridge term that keeps the
   amplification within bound (:func:`~usdface.rbf.stability.fit_stable`);
5. the amplification that slips through, reported as an
   :class:`~usdface.rbf.stability.AmplificationWarning`.

`usdface transfer` (and `skel`, `run`) and the quality evaluation (:mod:`usdface.evaluation`) both
call it, so the evaluation measures exactly what the pipeline writes.
"""
from __future__ import annotations

import math
import warnings
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..errors import OptionError
from .soundness import check_kernel_method, resolve_polynomial
from .stability import (DEFAULT_MAX_AMPLIFICATION, WARN_AMPLIFICATION, AmplificationWarning, amplification,
                        amplification_warning, fit_stable, marker_residual)
from .stiffness import WidthRule, default_width_rule, resolve_widths, transfer_widths
from .parameters import RBFCentres, RBFSettings
from .transfer import RBFTransfer

__all__ = ["TransferSettings", "TransferGeometry", "build_transfer"]


@dataclass(frozen=True)
class TransferSettings:
    """The options of the transfer (`usdface transfer`'s, with its defaults).

    Attributes
    ----------
    mode : {"interpolate", "paper"}
        ``--rbf``.
    kernel : str
        ``--kernel``.
    stiffness : None, float, sequence or dict
        ``--stiffness``: widths in mesh units (see :func:`usdface.rbf.stiffness.resolve_widths`);
        None: the mode's default rule.
    width_rule : WidthRule, optional
        Replace the default rule of the mode (benchmarks sweeping rules); None: the pipeline's.
    regularization : float or "auto"
        ``--regularization``.
    polynomial : "auto", True or False
        ``--polynomial`` / ``--no-polynomial``; "auto": exactly the kernels that need it.
    all_invalid : {"error", "hold", "zero"}
        Frames with no valid marker.
    max_amplification : float
        Bound of ``regularization="auto"``.
    warn_amplification : float
        Amplification above which an :class:`AmplificationWarning` is issued.
    check : bool
        Refuse the kernel and method pairs with no well-posed variant (False only for benchmarks
        that measure them).
    """

    mode: str = "interpolate"
    kernel: str = "gaussian"
    stiffness: Any = None
    width_rule: WidthRule | None = None
    regularization: Any = "auto"
    polynomial: Any = "auto"
    all_invalid: str = "error"
    max_amplification: float = DEFAULT_MAX_AMPLIFICATION
    warn_amplification: float = WARN_AMPLIFICATION
    check: bool = True

    def __post_init__(self) -> None:
        reg = self.regularization
        if not (reg == "auto" or (isinstance(reg, (int, float)) and not isinstance(reg, bool)
                                  and math.isfinite(reg) and reg >= 0)):
            raise OptionError(f"regularization: expected 'auto' or a number >= 0; got {reg!r}")
        if self.mode == "paper" and (self.polynomial is True or reg not in ("auto", 0, 0.0)):
            raise OptionError("--polynomial and --regularization apply to --rbf interpolate only "
                              "(paper mode solves nothing)")
        for name in ("max_amplification", "warn_amplification"):
            v = getattr(self, name)
            if not (isinstance(v, (int, float)) and math.isfinite(v) and v > 0):
                raise OptionError(f"{name}: expected a positive number; got {v!r}")


@dataclass(frozen=True)
class TransferGeometry:
    """Where the centres and vertices are.

    Attributes
    ----------
    marker_points : ndarray, shape (M, 3)
        Bound marker points (mesh units).
    centre_points : ndarray, shape (C, 3)
        Markers then constraint centres (mesh units): the polynomial term.
    vertex_points : ndarray, shape (N, 3)
        Mesh vertices (mesh units).
    marker_names : tuple of str, length M
    collocation : (ndarray (M, 3) int, ndarray (M, 3) float) or None
        The markers' bound triangles and barycentrics: interpolation conditions where the mesh
        shows the field (interpolate mode) and the marker residual.
    """

    marker_points: np.ndarray
    centre_points: np.ndarray
    vertex_points: np.ndarray
    marker_names: tuple
    collocation: tuple | None = None

    @property
    def n_markers(self) -> int:
        return len(self.marker_names)


def _widths(settings: TransferSettings, D_cc, geometry: TransferGeometry) -> tuple[np.ndarray, str]:
    """Per-centre widths and the name of the rule behind the defaulted ones."""
    names = geometry.marker_names
    M = geometry.n_markers
    if settings.width_rule is not None:
        rule = settings.width_rule
        return resolve_widths(settings.stiffness, D_cc, M, marker_names=names, rule=rule), rule.name
    rule = default_width_rule(settings.kernel, settings.mode)
    w = transfer_widths(settings.stiffness, D_cc, M, mode=settings.mode, kernel=settings.kernel, marker_names=names,
                        marker_points=geometry.marker_points)
    return w, rule.name


def build_transfer(D_vc, D_cc, method: str, *, settings: TransferSettings = TransferSettings(),
                   geometry: TransferGeometry, method_source: str | None = None) -> tuple[RBFTransfer, dict]:
    """The fitted transfer of the pipeline (see the module docstring).

    Parameters
    ----------
    D_vc : array_like, shape (N, C)
        Vertex-to-centre distances (mesh units).
    D_cc : array_like, shape (C, C)
        Centre-to-centre distances (mesh units), markers first.
    method : {"euclidean", "geodesic", "hybrid"}
        The distance method of ``D_vc`` / ``D_cc`` (the analysis layer's).
    settings : TransferSettings
    geometry : TransferGeometry
    method_source : str, optional
        Where ``method`` came from (e.g. the analysis layer's path), for the refusal message.

    Returns
    -------
    solver : RBFTransfer
        Fitted.
    info : dict
        ``kernel`` (canonical name), ``polynomial`` (bool), ``widthRule`` (name of the default rule
        used), ``regularization`` (the lambda used), ``choice``
        (:class:`~usdface.rbf.stability.RegularizationChoice` or None), ``amplification``,
        ``markerResidual`` (None without collocation), ``advice`` (conditioning advice or None),
        ``amplificationWarning`` (the warning text or None).

    Raises
    ------
    OptionError
        A kernel with no well-posed variant on ``method`` (``settings.check``), bad options.

    Warns
    -----
    AmplificationWarning
        The transfer amplifies marker motion more than ``settings.warn_amplification``.
    """
    mode = settings.mode
    polynomial = resolve_polynomial(settings.kernel, settings.polynomial) if mode == "interpolate" else False
    kernel = (check_kernel_method(settings.kernel, method, polynomial=polynomial, mode=mode, method_source=method_source)
              if settings.check else settings.kernel)
    widths, rule = _widths(settings, D_cc, geometry)
    colloc = geometry.collocation
    centres = RBFCentres(n_markers=geometry.n_markers, centre_points=geometry.centre_points,
                         vertex_points=geometry.vertex_points, marker_names=geometry.marker_names,
                         collocation=colloc if mode == "interpolate" else None)

    def make_solver(lam):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)  # conditioning: reported through info["advice"]
            return RBFTransfer(D_vc, D_cc, settings=RBFSettings(mode=mode, kernel=kernel, widths=widths,
                                                                polynomial=polynomial, regularization=lam,
                                                                all_invalid=settings.all_invalid),
                               centres=centres).fit()

    choice = None
    if mode == "interpolate" and settings.regularization == "auto":
        solver, choice = fit_stable(make_solver, max_amplification=settings.max_amplification)
        lam = choice.regularization
    else:
        lam = 0.0 if settings.regularization == "auto" else float(settings.regularization)
        solver = make_solver(lam)
    amp = amplification(solver.transfer_matrix)
    message = amplification_warning(amp, kernel=solver.kernel, method=method, regularization=lam,
                                    bound=settings.warn_amplification)
    if message:
        warnings.warn(message, AmplificationWarning, stacklevel=2)
    return solver, {
        "kernel": solver.kernel, "polynomial": polynomial, "widthRule": rule, "regularization": lam,
        "choice": choice, "amplification": amp,
        "markerResidual": None if colloc is None else marker_residual(solver, colloc[0], colloc[1]),
        "advice": solver.advice, "amplificationWarning": message,
    }
