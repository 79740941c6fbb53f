"""Fitting the RBF transfer of a binding's markers over a distance matrix, as every processor that
transfers does it (`usdface transfer`, `skel`, the blend-shape corrective): the checks and defaults
of :func:`usdface.rbf.build.build_transfer` (kernel and method soundness, the polynomial term, the
width rule, the regularisation of indefinite kernels, the amplification guard) on the pipeline's
data, with its findings logged once."""
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
    :data:`usdface.rbf.kernels.KERNELS`; ``stiffness``: None (the mode's default width rule:
    :mod:`usdface.rbf.stiffness`), a width in mesh units, a {marker: width} dict or a JSON file of
    one; ``regularization``: "auto" or lambda >= 0; ``polynomial``: "auto" (exactly the kernels
    that need the linear polynomial term get it: :func:`usdface.rbf.soundness.resolve_polynomial`),
    True or False; ``all_invalid``: what a frame with no valid marker gets ("error", "zero",
    "hold"); ``max_amplification``: the bound of ``regularization="auto"``.
    """

    rbf: str = "interpolate"
    kernel: str = "gaussian"
    stiffness: Any = None
    regularization: Any = "auto"
    polynomial: Any = "auto"
    all_invalid: str = "error"
    max_amplification: float = DEFAULT_MAX_AMPLIFICATION


def fit_transfer(mesh, binding, dm, params: TransferParameters = TransferParameters(), *,
                 method_source: str | None = None):
    """The fitted RBF transfer of ``binding``'s markers over the distance matrix ``dm``.

    Parameters
    ----------
    mesh : FaceMesh
    binding : Binding
    dm : DistanceMatrix
        As :func:`usdface.usd.inputs.load_transfer_inputs` returns them; ``dm.method`` is the
        method the kernel is checked against.
    params : TransferParameters
    method_source : str, optional
        Where ``dm`` came from (the analysis layer), named when the kernel is refused.

    Returns
    -------
    solver : RBFTransfer
        Fitted; ``solver.transfer_matrix`` is the N x M matrix B (vertex displacement = B @ marker
        displacements when every marker is valid).
    info : dict
        ``regularization`` (the lambda used), ``choice`` (RegularizationChoice or None),
        ``amplification``, ``markerResidual``, ``advice``, ``polynomial`` (resolved),
        ``widthRule`` (the default rule's name), ``amplificationWarning`` (text or None),
        ``settings`` (FaceTransferAPI values).

    Raises
    ------
    OptionError
        (exit 2) A kernel with no well-posed variant on ``dm.method`` (one line naming ``--kernel``
        and ``--method`` and the kernels that work), or bad widths.
    """
    from .build import TransferGeometry, TransferSettings, build_transfer
    from .stability import AmplificationWarning
    from .stiffness import parse_stiffness

    rbf = params.rbf
    marker_points = binding.surface_points(mesh.points)
    centre_points = np.concatenate([marker_points, mesh.points[dm.constraint_vertices]])
    settings = TransferSettings(mode=rbf, kernel=params.kernel, stiffness=parse_stiffness(params.stiffness),
                                regularization=params.regularization, polynomial=params.polynomial,
                                all_invalid=params.all_invalid, max_amplification=params.max_amplification)
    geometry = TransferGeometry(marker_points=marker_points, centre_points=centre_points, vertex_points=mesh.points,
                                marker_names=tuple(binding.names),
                                collocation=(binding.triangle_vertices, binding.barycentrics))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", AmplificationWarning)  # logged below, once
        solver, info = build_transfer(dm.vertex_to_centre, dm.centre_to_centre, dm.method, settings=settings,
                                      geometry=geometry, method_source=method_source)
    choice, regularization, amp = info["choice"], info["regularization"], info["amplification"]
    if choice is not None and choice.regularized:
        log.warning("the exact interpolant on %s distances amplifies marker motion %.0fx (the kernel matrix is "
                    "not positive definite on these distances); regularization %.3g chosen automatically "
                    "(amplification %.1fx; markers are then reproduced approximately)", dm.method,
                    choice.exact_amplification, choice.regularization, choice.amplification)
    if info["amplificationWarning"]:
        log.warning("%s", info["amplificationWarning"])
    if info["advice"]:
        log.warning("%s", info["advice"])
    miss = info["markerResidual"]
    settings_record = {
        "mode": rbf, "kernel": schema_kernel(solver.kernel), "distanceMethod": dm.method,
        "markerNames": list(binding.names), "widths": solver.widths[: binding.n_markers],
        "regularization": regularization, "polynomial": info["polynomial"],
        "conditionNumber": solver.condition_number,
        "parameters": {"constraintVertices": int(dm.constraint_vertices.size), "allInvalid": params.all_invalid,
                       "amplification": amp, "markerResidual": miss, "widthRule": info["widthRule"],
                       "regularizationAuto": None if choice is None else {
                           "exactAmplification": choice.exact_amplification,
                           "tried": {str(k): v for k, v in choice.tried.items()}},
                       "retarget": binding.retarget, "distanceBackend": dm.backend},
    }
    return solver, {"regularization": regularization, "choice": choice, "amplification": amp,
                    "markerResidual": miss, "advice": info["advice"], "polynomial": info["polynomial"],
                    "widthRule": info["widthRule"], "amplificationWarning": info["amplificationWarning"],
                    "settings": settings_record}


def schema_kernel(name: str) -> str:
    """RBF engine kernel name -> the FaceTransferAPI token."""
    return {"inverse_multiquadric": "inverseMultiquadric", "thin_plate_spline": "thinPlate",
            "thin_plate": "thinPlate"}.get(name, name)
