"""RBF transfer of marker motion onto a face mesh (seed 000, Eqs. 1-5).

- :mod:`usdface.rbf.kernels`: radial kernels (gaussian = paper Eq. 3, multiquadrics, polyharmonic).
- :mod:`usdface.rbf.stiffness`: kernel widths (the per-marker, metric-aware default rule; the paper's
  rule; per-marker overrides).
- :mod:`usdface.rbf.soundness`: which kernel works with which distance; the polynomial term the
  conditionally positive definite kernels need.
- :mod:`usdface.rbf.stability`: the amplification guard (auto regularisation, warnings).
- :mod:`usdface.rbf.transfer`: :class:`RBFTransfer`, the paper mode and the interpolating solve,
  evaluated for whole sequences as one float32 matrix product, streamed in chunks of frames; its
  options (:mod:`usdface.rbf.parameters`: :class:`RBFSettings`, :class:`RBFCentres`) and its parts:
  the checked problem and system matrix (:mod:`usdface.rbf.system`), the fit and its diagnostics
  (:mod:`usdface.rbf.solver`), validity patterns (:mod:`usdface.rbf.patterns`), the chunked
  evaluation (:mod:`usdface.rbf.streaming`).
- :mod:`usdface.rbf.build`: :func:`build_transfer`, the transfer with the pipeline's defaults and
  checks (used by the transfer processor and the quality evaluation).

Pure numpy (no scipy in the solve or the per-frame loop); no pxr.
"""
from __future__ import annotations

from ..lazy import lazy_exports

#: public name -> submodule, loaded on first use
_EXPORTS = {
    "TransferGeometry": "build", "TransferSettings": "build", "build_transfer": "build",
    "CPD_ORDER": "kernels", "DECAYING_KERNELS": "kernels", "KERNELS": "kernels", "canonical_kernel_name": "kernels",
    "cubic": "kernels", "gaussian": "kernels", "get_kernel": "kernels", "inverse_multiquadric": "kernels",
    "multiquadric": "kernels", "thin_plate_spline": "kernels",
    "SOUND_KERNELS": "soundness", "check_kernel_method": "soundness", "resolve_polynomial": "soundness",
    "sound_kernels": "soundness",
    "WARN_AMPLIFICATION": "stability", "AmplificationWarning": "stability", "amplification_warning": "stability",
    "DEFAULT_WIDTH_FACTOR": "stiffness", "GROWING_WIDTH_RULES": "stiffness", "LOCAL_WIDTH_RULE": "stiffness",
    "PAPER_WIDTH_RULE": "stiffness", "WidthRule": "stiffness", "default_width": "stiffness",
    "default_width_rule": "stiffness", "local_marker_spacing": "stiffness", "median_marker_spacing": "stiffness",
    "median_marker_spacing_from_points": "stiffness", "resolve_widths": "stiffness", "transfer_widths": "stiffness",
    "RBFCentres": "parameters", "RBFSettings": "parameters",
    "ADVICE_CONDITION": "transfer", "RBFTransfer": "transfer", "transfer_motion": "transfer",
}
__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS, globals())

__all__ = [
    "ADVICE_CONDITION",
    "AmplificationWarning",
    "CPD_ORDER",
    "DECAYING_KERNELS",
    "DEFAULT_WIDTH_FACTOR",
    "GROWING_WIDTH_RULES",
    "KERNELS",
    "LOCAL_WIDTH_RULE",
    "PAPER_WIDTH_RULE",
    "RBFCentres",
    "RBFSettings",
    "RBFTransfer",
    "SOUND_KERNELS",
    "TransferGeometry",
    "TransferSettings",
    "WARN_AMPLIFICATION",
    "WidthRule",
    "amplification_warning",
    "build_transfer",
    "canonical_kernel_name",
    "check_kernel_method",
    "cubic",
    "default_width",
    "default_width_rule",
    "gaussian",
    "get_kernel",
    "inverse_multiquadric",
    "local_marker_spacing",
    "median_marker_spacing",
    "median_marker_spacing_from_points",
    "multiquadric",
    "resolve_polynomial",
    "resolve_widths",
    "sound_kernels",
    "thin_plate_spline",
    "transfer_motion",
    "transfer_widths",
]
