"""RBF transfer of marker motion onto a face mesh (seed 000, Eqs. 1-5).

- :mod:`usdface.rbf.kernels`: radial kernels (gaussian = paper Eq. 3, multiquadrics, polyharmonic).
- :mod:`usdface.rbf.stiffness`: kernel widths (default rule on marker spacing, per-marker overrides).
- :mod:`usdface.rbf.transfer`: :class:`RBFTransfer`, the paper mode and the interpolating solve,
  evaluated for whole sequences as one float32 matrix product, streamed in chunks of frames.

Pure numpy (no scipy in the solve or the per-frame loop); no pxr.
"""
from __future__ import annotations

from ..lazy import lazy_exports

#: public name -> submodule, loaded on first use
_EXPORTS = {
    "DECAYING_KERNELS": "kernels", "KERNELS": "kernels", "canonical_kernel_name": "kernels", "cubic": "kernels",
    "gaussian": "kernels", "get_kernel": "kernels", "inverse_multiquadric": "kernels", "multiquadric": "kernels",
    "thin_plate_spline": "kernels", "DEFAULT_WIDTH_FACTOR": "stiffness", "default_width": "stiffness",
    "median_marker_spacing": "stiffness", "median_marker_spacing_from_points": "stiffness",
    "resolve_widths": "stiffness", "ADVICE_CONDITION": "transfer", "RBFTransfer": "transfer",
    "transfer_motion": "transfer",
}
__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS, globals())

__all__ = [
    "ADVICE_CONDITION",
    "DECAYING_KERNELS",
    "DEFAULT_WIDTH_FACTOR",
    "KERNELS",
    "RBFTransfer",
    "canonical_kernel_name",
    "cubic",
    "default_width",
    "gaussian",
    "get_kernel",
    "inverse_multiquadric",
    "median_marker_spacing",
    "median_marker_spacing_from_points",
    "multiquadric",
    "resolve_widths",
    "thin_plate_spline",
    "transfer_motion",
]
