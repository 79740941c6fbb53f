"""The skeleton `usdface skel` writes, fitted to a transfer (pure numpy; the processor reads and
writes the layers).

One static root joint plus one translation-only joint per marker, skinned in one of two modes
(:mod:`usdface.skel.modes`): "dcc" fits weights DCC importers take as they are, with corrective
blend shapes (:mod:`usdface.skel.dcc`); "exact" uses the transfer matrix itself, pruned to K and
refitted on the take (:mod:`usdface.skel.weights`).

Frames with missing markers: the transfer re-solves them with the valid markers. Its result is
still ``B @ D_eff`` for *effective* marker displacements (the values the re-solved field takes at
the missing markers' bound points), so the joints of missing markers follow those values (they
move with the surface the valid markers re-solve, no freeze, no jump) and the rig reproduces the
re-solved frames with the same skinning error as any frame; D_eff is recovered from the
transfer's own output by least squares on B (full column rank).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..errors import ComputeError
from .modes import (DEFAULT_FIT_METHOD, DEFAULT_MAX_INFLUENCES, DEFAULT_SHAPES, DEFAULT_SKIN_FIT,
                    DEFAULT_SKIN_WEIGHTS, REPORT_INFLUENCES, SKIN_FITS)

__all__ = ["apply_matrix", "effective_displacements", "gap_frames", "SkelInputs", "skel_inputs", "fit_dcc",
           "SkinParameters", "SkinFit", "fit_skin"]


def apply_matrix(b: np.ndarray, d: np.ndarray) -> np.ndarray:
    """B applied to every frame of ``d``, as one matrix product.

    Parameters
    ----------
    b : ndarray (N, M) float
        The transfer matrix (vertex displacement = B @ marker displacements).
    d : ndarray (F, M, 3) float
        Marker displacements (mesh units).

    Returns
    -------
    ndarray (F, N, 3): vertex displacements (mesh units).
    """
    f, m, _ = d.shape
    flat = np.ascontiguousarray(d.transpose(1, 0, 2).reshape(m, -1))
    return (b @ flat).reshape(b.shape[0], f, 3).transpose(1, 0, 2)


def effective_displacements(solver, disp: np.ndarray, *, chunk_frames: int = 64) -> tuple[np.ndarray, dict]:
    """Marker displacements that reproduce the transfer through B for every frame.

    Frames where every marker is valid keep their displacements; the others get
    ``D_eff = argmin |B D - transfer(frame)|`` (exact: the re-solved transfer is ``B @ D_eff``),
    solved by the QR factorisation of B (N x M, full column rank).

    Parameters
    ----------
    solver : usdface.rbf.transfer.RBFTransfer
        The fitted transfer (``transfer_matrix``, ``apply``).
    disp : ndarray (F, M, 3) float
        Marker displacements, mesh units; NaN where a marker is missing.
    chunk_frames : int
        Frames re-solved at once (memory: ``chunk_frames`` x N x 3 float64).

    Returns
    -------
    d_eff : ndarray (F, M, 3) float64, finite
    info : dict ``framesResolved`` and ``residual`` (largest |B D_eff - transfer| in mesh units)
    """
    d = np.array(disp, dtype=np.float64)
    bad = gap_frames(d)
    residual = 0.0
    if bad.size:
        b = solver.transfer_matrix
        q, r = np.linalg.qr(b)
        for a in range(0, bad.size, chunk_frames):
            idx = bad[a:a + chunk_frames]
            dv = solver.apply(disp[idx], dtype=np.float64)  # (f, N, 3): the re-solved transfer
            flat = dv.transpose(1, 0, 2).reshape(dv.shape[1], -1)  # (N, f*3)
            eff = np.linalg.solve(r, q.T @ flat).reshape(r.shape[0], idx.size, 3).transpose(1, 0, 2)
            residual = max(residual, float(np.abs(apply_matrix(b, eff) - dv).max()))
            d[idx] = eff
    return d, {"framesResolved": int(bad.size), "residual": residual}


def gap_frames(disp: np.ndarray) -> np.ndarray:
    """Indices (int64) of the frames of ``disp`` (F, M, 3) where some marker is invalid (NaN)."""
    return np.flatnonzero(~np.isfinite(disp).all(axis=(1, 2)))


@dataclass(frozen=True)
class SkelInputs:
    """What the skeleton is built from: the transfer's inputs and results (mesh space, mesh units).

    Attributes
    ----------
    mesh, capture, binding, dm : the inputs (:func:`usdface.usd.inputs.load_transfer_inputs`)
    solver, info : the fitted transfer (:func:`usdface.rbf.fitting.fit_transfer`)
    effective : ndarray (F, M, 3)
        Marker displacements reproducing every frame through B (:func:`effective_displacements`).
    effective_info : dict
    gap_frames : ndarray of int
        Frames where some marker is missing.
    bound_points : ndarray (M, 3)
    head_motion : ndarray (F, 4, 4) or None
        H_mesh(f) relative to the neutral frame (None: the capture was not stabilised).
    """

    mesh: object
    capture: object
    binding: object
    dm: object
    solver: object
    info: dict
    effective: np.ndarray
    effective_info: dict
    gap_frames: np.ndarray
    bound_points: np.ndarray
    head_motion: np.ndarray | None

    @property
    def transfer_matrix(self) -> np.ndarray:
        return self.solver.transfer_matrix

    def point_cache(self, frames=slice(None), *, world: bool = True) -> np.ndarray:
        """(F, N, 3) the transfer's point cache (float64), moved by the head motion when ``world``."""
        pts = self.mesh.points[None] + apply_matrix(self.transfer_matrix, self.effective[frames])
        if world and self.head_motion is not None:
            hm = self.head_motion[frames]
            pts = np.matmul(pts, hm[:, :3, :3].transpose(0, 2, 1)) + hm[:, None, :3, 3]
        return pts


def skel_inputs(mesh, capture, binding, dm, params=None) -> SkelInputs:
    """Fit the transfer (`usdface transfer`'s ``params``, :class:`usdface.rbf.fitting.TransferParameters`)
    and resolve the missing markers of ``capture``.

    ``mesh, capture, binding, dm`` as :func:`usdface.usd.inputs.load_transfer_inputs` returns them.
    Raises ComputeError when the re-solved frames are not reproduced through B (rank deficient).
    """
    from ..capture.retarget import marker_displacements
    from ..rbf.fitting import TransferParameters, fit_transfer
    from .joints import capture_head_motion

    disp = marker_displacements(capture, binding.names, binding.displacement_transform())
    solver, info = fit_transfer(mesh, binding, dm, TransferParameters() if params is None else params)
    d_eff, eff_info = effective_displacements(solver, disp)
    if eff_info["residual"] > 1e-6 * max(1.0, float(np.abs(d_eff).max())):
        raise ComputeError(f"skel: the re-solved frames are not reproduced through the transfer matrix "
                           f"(residual {eff_info['residual']:.3g} {mesh.units}); the transfer matrix is rank deficient")
    return SkelInputs(mesh=mesh, capture=capture, binding=binding, dm=dm, solver=solver, info=info,
                      effective=d_eff, effective_info=eff_info, gap_frames=gap_frames(disp),
                      bound_points=binding.surface_points(mesh.points),
                      head_motion=capture_head_motion(capture, binding.capture_to_mesh))


def fit_dcc(inputs: SkelInputs, k, *, skin_fit: str = DEFAULT_SKIN_FIT, n_shapes: int | None = None,
            covariance=None):
    """The DCC-safe rig of :mod:`usdface.skel.dcc` for these inputs (a :class:`usdface.skel.DccSkin`).

    ``k``: influences per vertex (None: every joint); ``skin_fit``: "rom" (the synthetic range of
    motion: the character's rig) or "take" (this take's marker motion); ``covariance`` (M, M)
    overrides both (e.g. another take's :func:`usdface.skel.take_covariance`). The starting weights
    are Gaussians of the transfer's own distances, with its widths when its kernel is Gaussian (else
    the default width rule).
    """
    from ..rbf.stiffness import DEFAULT_WIDTH_FACTOR, median_marker_spacing_from_points
    from .dcc import SHAPE_OFFSET_FACTOR, fit_dcc_skin, initial_weights, rom_covariance, take_covariance

    m = inputs.binding.n_markers
    bound = inputs.bound_points
    spacing = median_marker_spacing_from_points(bound)
    widths = (inputs.solver.widths[:m] if inputs.solver.kernel == "gaussian" else DEFAULT_WIDTH_FACTOR * spacing)
    w0 = initial_weights(inputs.dm.vertex_to_centre[:, :m], widths)
    if covariance is None:
        if skin_fit not in SKIN_FITS:
            raise ValueError(f"skin_fit: expected one of {', '.join(SKIN_FITS)}; got {skin_fit!r}")
        covariance = (rom_covariance(np.linalg.norm(bound[:, None] - bound[None], axis=2)) if skin_fit == "rom"
                      else take_covariance(inputs.effective))
    return fit_dcc_skin(inputs.transfer_matrix, w0, k, covariance,
                        n_shapes=DEFAULT_SHAPES if n_shapes is None else n_shapes,
                        shape_offset=SHAPE_OFFSET_FACTOR * spacing)


@dataclass(frozen=True)
class SkinParameters:
    """How the skin is fitted (the options of `usdface skel` build it:
    :meth:`usdface.options.SkelOptions.skin_parameters`).

    ``mode``: "dcc" or "exact" (:data:`usdface.skel.modes.SKIN_WEIGHTS`); ``max_influences``: K
    joints per vertex, root included, or None for every joint; ``skin_fit``: "rom" or "take" (dcc);
    ``corrective_shapes``: 0 or 2..16 (dcc; 0 for exact); ``weight_fit``: "lsq" or "renormalize"
    (exact); ``report_influences``: other K whose point-cache error is reported (each costs a fit
    in dcc mode).
    """

    mode: str = DEFAULT_SKIN_WEIGHTS
    max_influences: int | None = DEFAULT_MAX_INFLUENCES
    skin_fit: str = DEFAULT_SKIN_FIT
    corrective_shapes: int = DEFAULT_SHAPES
    weight_fit: str = DEFAULT_FIT_METHOD
    report_influences: tuple = REPORT_INFLUENCES


@dataclass
class SkinFit:
    """The fitted skin and its error against the point cache.

    Attributes
    ----------
    weights : SkinWeights
        K influences per vertex (joint 0 the root).
    translations : ndarray (F, M, 3)
        The marker joints' translations (mesh units).
    shapes : ndarray (S, N, 3) or None
        Corrective blend-shape offsets; ``shape_weights`` (F, S) their weights (dcc with S > 0).
    errors, gap_errors : dict
        {K ("4", "8", "all"): error summary (:func:`usdface.skel.weights.error_summary`)} over every
        frame and over the frames with missing markers (empty without any).
    """

    weights: object
    translations: np.ndarray
    shapes: np.ndarray | None = None
    shape_weights: np.ndarray | None = None
    errors: dict = field(default_factory=dict)
    gap_errors: dict = field(default_factory=dict)


def fit_skin(inputs: SkelInputs, params: SkinParameters = SkinParameters()) -> SkinFit:
    """Fit the skin of ``params.mode`` and measure it against the point cache, for K =
    ``params.max_influences`` and each of ``params.report_influences`` (the fitted K first)."""
    b, d_eff, gaps = inputs.transfer_matrix, inputs.effective, inputs.gap_frames
    k, report_ks = params.max_influences, list(params.report_influences or ())
    n_markers = b.shape[1]

    def key(kk):
        return "all" if kk is None or kk >= n_markers + 1 else str(kk)

    if params.mode == "dcc":
        from .dcc import dcc_skinning_error

        fits = {}
        for kk in [k] + report_ks:
            if key(kk) not in fits:
                fits[key(kk)] = fit_dcc(inputs, kk, skin_fit=params.skin_fit, n_shapes=params.corrective_shapes)
        out = SkinFit(weights=fits[key(k)].weights, translations=fits[key(k)].joint_translations(d_eff))
        for name, fitted in fits.items():
            out.errors[name] = dcc_skinning_error(fitted, b, d_eff)
            if gaps.size:
                out.gap_errors[name] = dcc_skinning_error(fitted, b, d_eff[gaps])
        if params.corrective_shapes:
            out.shapes, out.shape_weights = fits[key(k)].shapes, fits[key(k)].shape_weights(d_eff)
        return out
    from .weights import full_weights, motion_gram, prune_weights, skinning_error

    full = full_weights(b)
    gram = motion_gram(d_eff)
    chosen = prune_weights(full, k, gram=gram, fit=params.weight_fit)
    out = SkinFit(weights=chosen, translations=d_eff)
    for kk in [None] + report_ks + [k]:
        if key(kk) in out.errors:
            continue
        w = chosen if kk == k else prune_weights(full, kk, gram=gram, fit=params.weight_fit)
        out.errors[key(kk)] = skinning_error(w, b, d_eff, inputs.mesh.points)
        if gaps.size:
            out.gap_errors[key(kk)] = skinning_error(w, b, d_eff[gaps], inputs.mesh.points)
    return out
