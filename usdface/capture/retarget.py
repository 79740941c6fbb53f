"""Capture motion expressed as marker displacements in mesh space (the RBF transfer's input)."""
from __future__ import annotations

import numpy as np

from ..errors import MarkerError, list_names
from .model import Capture


def marker_displacements(capture: Capture, names, transform: np.ndarray) -> np.ndarray:
    """Displacement of each named marker from the neutral frame, in mesh space.

    Parameters
    ----------
    capture : Capture
        Positions (F, M', 3) in capture units (head-local when stabilised), NaN where invalid.
    names : sequence of str, length M
        Markers to take, in this order (the binding's order).
    transform : ndarray, shape (3, 3)
        Capture displacement -> mesh displacement (rotation times unit conversion, and the fitted
        scale for similarity retargeting): :meth:`usdface.mesh.Binding.displacement_transform`.

    Returns
    -------
    ndarray, shape (F, M, 3), float64
        ``transform @ (p_f - p_neutral)`` per marker, mesh units; NaN where the sample is invalid.

    Raises
    ------
    MarkerError
        A named marker is missing from the capture, or invalid at the neutral frame.
    """
    missing = [n for n in names if n not in capture.names]
    if missing:
        raise MarkerError(
            f"binding and capture have different marker sets: {list_names(missing)} not in capture "
            f"{capture.source}; capture has {capture.n_markers} markers: {list_names(capture.names)}"
        )
    idx = np.array([capture.names.index(n) for n in names], dtype=np.int64)
    pos = capture.positions[:, idx]
    neutral = pos[capture.neutral_frame]
    bad = [names[j] for j in np.flatnonzero(~np.isfinite(neutral).all(axis=1))]
    if bad:
        raise MarkerError(
            f"capture {capture.source}: marker(s) {list_names(bad)} invalid at the neutral frame "
            f"{capture.neutral_frame}; fill gaps (--fill-gaps N) or choose another neutral frame (--neutral)"
        )
    return (pos - neutral[None]) @ np.asarray(transform, dtype=np.float64).T
