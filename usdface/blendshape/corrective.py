"""The corrective points shot of `usdface solve --corrective`: the rig's pose plus the RBF transfer
(seed 000, Eqs. 1-5, interpolating) of the marker residual the curves leave, so the markers are hit
exactly at their bound points."""
from __future__ import annotations

import numpy as np

from ..distance.methods import DEFAULT_BACKEND

__all__ = ["corrective_points", "CORRECTIVE_METHOD", "CORRECTIVE_BACKEND", "CHUNK_FRAMES"]

#: the distances the residual is transferred over: hybrid (paper Eq. 8) on the pipeline's default
#: geodesics (fast marching)
CORRECTIVE_METHOD, CORRECTIVE_BACKEND = "hybrid", DEFAULT_BACKEND
#: frames transferred at once
CHUNK_FRAMES = 256


def corrective_points(take, rig, regions, binding) -> tuple[np.ndarray, dict]:
    """Corrected points for every frame of a solved take.

    Parameters
    ----------
    take : usdface.blendshape.take.TakeSolution
        Its weights (F, K), marker displacements (F, M, 3; NaN where invalid) and marker basis.
    rig : usdface.blendshape.rig.BlendShapeRig
    regions : list of Region
        The rig mesh's regions (the hybrid distances' geodesic regions and the pinned border).
    binding : usdface.model.mesh.Binding

    Returns
    -------
    points : ndarray (F, N, 3) float64
        ``rig.evaluate(w) + B @ (d - fit)``, mesh units; frames without any valid marker get the
        rig's pose alone (the curves bridge them).
    info : dict
        The transfer's (:func:`usdface.rbf.fitting.fit_transfer`): ``amplification`` ...
    """
    from ..distance.matrices import DistanceParameters, compute_distance_matrix
    from ..rbf.fitting import TransferParameters, fit_transfer

    distances = DistanceParameters(method=CORRECTIVE_METHOD, backend=CORRECTIVE_BACKEND)
    dm, _ = compute_distance_matrix(rig.mesh, regions, binding, distances, mesh_name=rig.source)
    # frames without any valid marker: the curves bridge them; the corrective adds nothing there
    solver, info = fit_transfer(rig.mesh, binding, dm, TransferParameters(all_invalid="zero"))
    fit = np.einsum("fk,mkd->fmd", take.weights, take.basis)
    residual = take.displacements - fit  # NaN where invalid: the transfer re-solves those frames
    posed = rig.evaluate(take.weights)
    chunks = [solver.apply(residual[a:a + CHUNK_FRAMES], dtype=np.float64)
              for a in range(0, residual.shape[0], CHUNK_FRAMES)]
    return posed + np.concatenate(chunks), info
