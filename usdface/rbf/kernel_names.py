"""The radial basis functions usdface offers, by name, without numpy: building the command line
(``--kernel``) reads these; :data:`usdface.rbf.kernels.KERNELS` maps them to the functions."""
from __future__ import annotations

__all__ = ["KERNEL_NAMES"]

KERNEL_NAMES = ("gaussian", "multiquadric", "inverse_multiquadric", "thin_plate_spline", "cubic")
