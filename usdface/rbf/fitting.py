"""Fitting the RBF transfer of a binding's markers over a distance matrix, with the option
handling every processor that transfers shares (width rule, per-marker widths, regularisation of
indefinite kernels, the amplification guard)."""
from __future__ import annotations

import logging
import warnings
from dataclasses import dataclass
from typing import Any

import numpy as np

from .stability import DEFAULT_MAX_AMPLIFICATION

log = logging.getLogger("usdface")

__all__ = ["TransferParameters", "fit_transfer", "schema_kernel"]


@dataclass(frozen=True)
class TransferParameters:
    """How the transfer is fitted (the options of `usdface transfer` build it:
    :meth:`usdface.options.TransferOptions.parameters`).

    ``rbf``: "paper" (Eqs. 1-5) or "interpolate" (the exact solve); ``kernel``: a name of
    :data:`usdface.rbf.kernels.KERNELS`; ``stiffness``: None (the default width rule), a width in
    mesh units, a {marker: width} dict or a JSON file of one; ``regularization``: "auto" or lambda
    >= 0; ``polynomial``: add the linear polynomial term; ``all_invalid``: what a frame with no
    valid marker gets ("error", "zero", "hold"); ``max_amplification``: the guard's threshold.
    """

    rbf: str = "interpolate"
    kernel: str = "gaussian"
    stiffness: Any = None
    regularization: Any = "auto"
    polynomial: bool = False
    all_invalid: str = "error"
    max_amplification: float = DEFAULT_MAX_AMPLIFICATION


def fit_transfer(mesh, binding, dm, params: TransferParameters = TransferParameters()):
    """The fitted RBF transfer of ``binding``'s markers over the distance matrix ``dm``, as
    `usdface transfer`, `skel` and the blend-shape corrective use it (one place for it): the
    default width rule, per-marker widths, the automatic regularisation of indefinite kernels and
    the amplification guard.

    Parameters
    ----------
    mesh : FaceMesh
    binding : Binding
    dm : DistanceMatrix
        As :func:`usdface.usd.inputs.load_transfer_inputs` returns them.
    params : TransferParameters

    Returns
    -------
    solver : RBFTransfer
        Fitted; ``solver.transfer_matrix`` is the N x M matrix B (vertex displacement = B @ marker
        displacements when every marker is valid).
    info : dict
        ``regularization`` (the lambda used), ``choice`` (RegularizationChoice or None),
        ``amplification``, ``markerResidual``, ``advice``, ``settings`` (FaceTransferAPI values).
    """
    from .stability import amplification, fit_stable, marker_residual
    from .stiffness import DEFAULT_WIDTH_FACTOR, median_marker_spacing_from_points, parse_stiffness
    from .transfer import RBFTransfer

    rbf, kernel, stiffness, regularization = params.rbf, params.kernel, params.stiffness, params.regularization
    polynomial, all_invalid, max_amplification = params.polynomial, params.all_invalid, params.max_amplification
    centre_points = np.concatenate([binding.surface_points(mesh.points), mesh.points[dm.constraint_vertices]])
    widths = parse_stiffness(stiffness)
    # the default rule on Euclidean marker spacing, whatever the distance method; a partial
    # {marker: width} dict keeps that default for every other centre
    default = DEFAULT_WIDTH_FACTOR * median_marker_spacing_from_points(binding.surface_points(mesh.points))
    if widths is None:
        widths = default
    elif isinstance(widths, dict):
        from .stiffness import resolve_widths

        n_centres = dm.vertex_to_centre.shape[1]
        widths = resolve_widths(widths, np.full((n_centres, n_centres), default / DEFAULT_WIDTH_FACTOR),
                                binding.n_markers, marker_names=binding.names)

    def make_solver(lam):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)  # the same advice is logged once below
            return RBFTransfer(dm.vertex_to_centre, dm.centre_to_centre, mode=rbf, kernel=kernel, widths=widths,
                               polynomial=polynomial, regularization=lam, n_markers=binding.n_markers,
                               centre_points=centre_points, vertex_points=mesh.points,
                               marker_names=binding.names, all_invalid=all_invalid,
                               collocation=(binding.triangle_vertices, binding.barycentrics)
                               if rbf == "interpolate" else None).fit()

    choice = None
    if rbf == "interpolate" and regularization == "auto":
        solver, choice = fit_stable(make_solver, max_amplification=max_amplification)
        regularization = choice.regularization
        if choice.regularized:
            log.warning("the exact interpolant on %s distances amplifies marker motion %.0fx (the kernel matrix is "
                        "not positive definite on these distances); regularization %.3g chosen automatically "
                        "(amplification %.1fx; markers are then reproduced approximately)", dm.method,
                        choice.exact_amplification, choice.regularization, choice.amplification)
    else:
        regularization = 0.0 if regularization == "auto" else float(regularization)
        solver = make_solver(regularization)
    amp = amplification(solver.transfer_matrix)
    miss = marker_residual(solver, binding.triangle_vertices, binding.barycentrics)
    if amp > max_amplification and (choice is None or not choice.regularized):
        log.warning("the transfer amplifies marker motion up to %.0fx at some vertices; consider "
                    "--regularization auto, a smaller --stiffness, or --method euclidean", amp)
    advice = solver.advice
    if advice:
        log.warning("%s", advice)
    settings = {
        "mode": rbf, "kernel": schema_kernel(solver.kernel), "distanceMethod": dm.method,
        "markerNames": list(binding.names), "widths": solver.widths[: binding.n_markers],
        "regularization": regularization, "polynomial": polynomial,
        "conditionNumber": solver.condition_number,
        "parameters": {"constraintVertices": int(dm.constraint_vertices.size), "allInvalid": all_invalid,
                       "amplification": amp, "markerResidual": miss,
                       "regularizationAuto": None if choice is None else {
                           "exactAmplification": choice.exact_amplification,
                           "tried": {str(k): v for k, v in choice.tried.items()}},
                       "retarget": binding.retarget, "distanceBackend": dm.backend},
    }
    return solver, {"regularization": regularization, "choice": choice, "amplification": amp,
                    "markerResidual": miss, "advice": advice, "settings": settings}


def schema_kernel(name: str) -> str:
    """RBF engine kernel name -> the FaceTransferAPI token."""
    return {"inverse_multiquadric": "inverseMultiquadric", "thin_plate_spline": "thinPlate",
            "thin_plate": "thinPlate"}.get(name, name)
