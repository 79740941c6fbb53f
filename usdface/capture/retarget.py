"""Capture motion expressed as marker displacements in mesh space (the RBF transfer's input)."""
from __future__ import annotations

import numpy as np

from ..errors import MarkerError, list_names
from ..model.capture import Capture


def marker_displacements(capture: Capture, names, transform: np.ndarray) -> np.ndarray:
    """Displacement of each named marker from the rest pose, in mesh space.

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
        ``transform @ (p_f - rest)`` per marker, mesh units, with ``rest`` the capture's rest pose
        (:attr:`Capture.neutral`: averaged over the neutral window, or the neutral frame); NaN
        where the sample is invalid.

    Raises
    ------
    MarkerError
        A named marker is missing from the capture, or has no valid sample in the neutral frames.
    """
    missing = [n for n in names if n not in capture.names]
    if missing:
        raise MarkerError(
            f"binding and capture have different marker sets: {list_names(missing)} not in capture "
            f"{capture.source}; capture has {capture.n_markers} markers: {list_names(capture.names)}"
        )
    idx = np.array([capture.names.index(n) for n in names], dtype=np.int64)
    pos = capture.positions[:, idx]
    neutral = capture.neutral[idx]
    bad = [names[j] for j in np.flatnonzero(~np.isfinite(neutral).all(axis=1))]
    if bad:
        raise MarkerError(
            f"capture {capture.source}: marker(s) {list_names(bad)} invalid at the {capture.describe_neutral()}; "
            "fill gaps (--fill-gaps N) or choose other neutral frames (--neutral)"
        )
    return (pos - neutral[None]) @ np.asarray(transform, dtype=np.float64).T


def mesh_head_motion(capture: Capture, capture_to_mesh: np.ndarray) -> np.ndarray | None:
    """The head motion removed by stabilisation, as rigid motions of the face in mesh space.

    ``H_mesh(f) = C H(n)^-1 H(f) C^-1`` with H the capture's head motion (capture space), n the
    neutral frame and C the binding's capture-to-mesh similarity: the actor's head rotation about
    the (mapped) head, the translation scaled like the face, identity at the neutral frame (where
    the face is at its rest pose). The similarity's scale cancels in the rotation, so H_mesh is
    rigid. H(n), not the head pose averaged over the neutral stretch: the conditioning stabilises
    on the neutral frame (H(n) = I) or on the rest pose of named frames, so the positions are
    head-local in that pose; the binding maps them to the mesh and the shot places the markers with
    C alone, and any other reference would move the face off its markers.

    Returns
    -------
    ndarray (F, 4, 4) float64 (column vectors), or None when the capture was not stabilised.
    """
    if capture.head_motion is None:
        return None
    h = np.asarray(capture.head_motion, dtype=np.float64)
    rel = np.einsum("ij,fjk->fik", np.linalg.inv(h[capture.neutral_frame]), h)
    c = np.asarray(capture_to_mesh, dtype=np.float64)
    out = np.einsum("ij,fjk,kl->fil", c, rel, np.linalg.inv(c))
    out[:, 3] = (0.0, 0.0, 0.0, 1.0)  # exact affine rows (no rounding into the projective part)
    return out
