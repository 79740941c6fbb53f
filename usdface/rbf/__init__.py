"""RBF transfer of marker motion onto a face mesh (seed 000, Eqs. 1-5).

- :mod:`usdface.rbf.kernels`: radial kernels (gaussian = paper Eq. 3, multiquadrics, polyharmonic).
- :mod:`usdface.rbf.stiffness`: kernel widths (default rule on marker spacing, per-marker overrides).
- :mod:`usdface.rbf.transfer`: :class:`RBFTransfer`, the paper mode and the interpolating solve,
  evaluated for whole sequences as one float32 matrix product, streamed in chunks of frames.

Pure numpy (no scipy in the solve or the per-frame loop); no pxr.
"""
from __future__ import annotations

from .kernels import (
    DECAYING_KERNELS,
    KERNELS,
    canonical_kernel_name,
    cubic,
    gaussian,
    get_kernel,
    inverse_multiquadric,
    multiquadric,
    thin_plate_spline,
)
from .stiffness import (
    DEFAULT_WIDTH_FACTOR,
    default_width,
    median_marker_spacing,
    median_marker_spacing_from_points,
    resolve_widths,
)
from .transfer import ADVICE_CONDITION, RBFTransfer, transfer_motion

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
