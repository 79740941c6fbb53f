"""`usdface skel`: skeletal keyframes (UsdSkel) from a capture, skinned so they reproduce the transfer.

One static root joint plus one translation-only joint per marker (children of the root, at the
markers' bound surface points) and skin weights, in one of two modes:

- ``skin_weights="dcc"`` (default): weights Blender, Maya and game engines take as they are
  (non-negative, summing to one, at most K per vertex, none below 1e-5), fitted to the transfer
  over a range of motion (:mod:`usdface.skel.dcc`); the joints' translations are fitted blends of
  the marker displacements, and up to 16 time-invariant corrective blend shapes with per-frame
  weights take what skinning misses. Fitted on the synthetic range of motion (default), the
  weights, joint mapping and shapes depend on the character (mesh, binding, transfer) only: every
  take of one character gets the same ones.
- ``skin_weights="exact"``: the transfer matrix itself (signed; the root takes the remainder),
  joints translated by the marker displacements: with every weight kept, UsdSkel reproduces
  `usdface transfer`'s point cache (:mod:`usdface.skel.weights`); pruned to K and refitted on the
  take. Negative weights are dropped by DCC importers: this mode is for UsdSkel consumers.

Frames with missing markers: the transfer re-solves them with the valid markers. Its result is
still ``B @ D_eff`` for *effective* marker displacements (the values the re-solved field takes at
the missing markers' bound points), so the joints of missing markers follow those values (they
move with the surface the valid markers re-solve, no freeze, no jump) and the rig reproduces the
re-solved frames with the same skinning error as any frame; D_eff is recovered from the transfer's
own output by least squares on B (full column rank).

Head motion (decision D1): when the capture was stabilised, the SkelRoot /Face carries the head
motion removed by stabilisation as a time-sampled ``xformOp:transform``, mapped into mesh space by
the binding's capture-to-mesh similarity and taken relative to the neutral frame:
``H_mesh(f) = C H(n)^-1 H(f) C^-1`` (identity on the neutral frame). The skinned mesh stays in
stabilised mesh space, so the face in world space is the stabilised point cache moved by
H_mesh(f); ``head_motion=False`` (``--no-head-motion``) writes no op on /Face.
"""
from __future__ import annotations

import logging
import time
from dataclasses import dataclass

import numpy as np

from ..errors import ComputeError, OptionError
from ..progress import progress
from ..options import RunOptions, SkelOptions, TransferOptions
from ..rbf.stability import DEFAULT_MAX_AMPLIFICATION
from ..usd.layers import check_output_path, provenance
from .transfer import build_transfer_solver, load_transfer_inputs

log = logging.getLogger("usdface")

DEFAULT_MAX_INFLUENCES = 8
REPORT_INFLUENCES = (4, 8)
SKIN_WEIGHTS = ("dcc", "exact")
SKIN_FITS = ("rom", "take")
#: the deprecated --negative-weights values and the --skin-weights they map to
NEGATIVE_WEIGHTS_ALIAS = {"keep": "exact", "clamp": "dcc"}
#: frames deformed by UsdSkel at once when verifying the written layer
VERIFY_CHUNK = 128


def effective_displacements(solver, disp: np.ndarray, *, chunk_frames: int = 64) -> tuple[np.ndarray, dict]:
    """Marker displacements that reproduce the transfer through B for every frame.

    Frames where every marker is valid keep their displacements; the others get
    ``D_eff = argmin |B D - transfer(frame)|`` (exact: the re-solved transfer is ``B @ D_eff``).

    Returns
    -------
    d_eff : ndarray (F, M, 3) float64, finite
    info : dict ``framesResolved`` and ``residual`` (largest |B D_eff - transfer| in mesh units)
    """
    d = np.array(disp, dtype=np.float64)
    bad = np.flatnonzero(~np.isfinite(d).all(axis=(1, 2)))
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


def apply_matrix(b: np.ndarray, d: np.ndarray) -> np.ndarray:
    """(F, N, 3) = B (N, M) applied to every frame of d (F, M, 3), as one matrix product."""
    f, m, _ = d.shape
    flat = np.ascontiguousarray(d.transpose(1, 0, 2).reshape(m, -1))
    return (b @ flat).reshape(b.shape[0], f, 3).transpose(1, 0, 2)


def _parse_k(value):
    if value is None or value == "all":
        return None
    try:
        k = int(value)
    except (TypeError, ValueError):
        raise OptionError(f"--max-influences: expected an integer >= 1 or 'all'; got {value!r}") from None
    if k < 1 or isinstance(value, bool) or (isinstance(value, float) and value != k):
        raise OptionError(f"--max-influences: expected an integer >= 1 or 'all'; got {value!r}")
    return k


def resolve_skin_weights(skin_weights, negative_weights) -> str:
    """The weight mode from ``skin_weights`` and the deprecated ``negative_weights`` alias.

    ``negative_weights="keep"`` maps to "exact" (signed weights, as before) and ``"clamp"`` to
    "dcc" (the non-negative fit replaces clamping), with a warning; giving both with different
    meanings is an error.
    """
    if skin_weights is not None and skin_weights not in SKIN_WEIGHTS:
        raise OptionError(f"--skin-weights: expected one of {', '.join(SKIN_WEIGHTS)}; got {skin_weights!r}")
    if negative_weights is None:
        return skin_weights or "dcc"
    if negative_weights not in NEGATIVE_WEIGHTS_ALIAS:
        raise OptionError(f"--negative-weights (deprecated: use --skin-weights dcc|exact): expected keep or clamp; "
                          f"got {negative_weights!r}")
    mapped = NEGATIVE_WEIGHTS_ALIAS[negative_weights]
    if skin_weights is not None and skin_weights != mapped:
        raise OptionError(f"--negative-weights {negative_weights} (deprecated; means --skin-weights {mapped}) "
                          f"contradicts --skin-weights {skin_weights}: give --skin-weights only")
    log.warning("--negative-weights %s is deprecated: use --skin-weights %s", negative_weights, mapped)
    return mapped


def _gap_frames(disp: np.ndarray) -> np.ndarray:
    """Frames where some marker is invalid (NaN)."""
    return np.flatnonzero(~np.isfinite(disp).all(axis=(1, 2)))


@dataclass(frozen=True)
class SkelInputs:
    """What the skeleton is built from: the transfer's inputs and results (mesh space, mesh units).

    Attributes
    ----------
    mesh, capture, binding, dm : the loaded inputs (:func:`load_transfer_inputs`)
    solver, info : the fitted transfer (:func:`build_transfer_solver`)
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


def load_skel_inputs(mesh_path, capture_path, binding_path, analysis_path, *, rbf="interpolate",
                     kernel="gaussian", stiffness=None, regularization="auto", polynomial=False, method=None,
                     all_invalid="error", max_amplification=DEFAULT_MAX_AMPLIFICATION) -> SkelInputs:
    """Read the inputs, fit the transfer (`usdface transfer`'s options) and resolve missing markers."""
    from ..capture.retarget import marker_displacements
    from ..skel import head_motion_in_mesh_space

    mesh, capture, binding, dm = load_transfer_inputs(mesh_path, capture_path, binding_path, analysis_path,
                                                      method=method)
    disp = marker_displacements(capture, binding.names, binding.displacement_transform())
    solver, info = build_transfer_solver(mesh, binding, dm, rbf=rbf, kernel=kernel, stiffness=stiffness,
                                         regularization=regularization, polynomial=polynomial,
                                         all_invalid=all_invalid, max_amplification=max_amplification)
    d_eff, eff_info = effective_displacements(solver, disp)
    if eff_info["residual"] > 1e-6 * max(1.0, float(np.abs(d_eff).max())):
        raise ComputeError(f"skel: the re-solved frames are not reproduced through the transfer matrix "
                           f"(residual {eff_info['residual']:.3g} {mesh.units}); the transfer matrix is rank deficient")
    hm = None
    if capture.head_motion is not None:
        n = capture.neutral_frame
        rel = np.einsum("ij,fjk->fik", np.linalg.inv(capture.head_motion[n]), capture.head_motion)
        hm = head_motion_in_mesh_space(rel, binding.capture_to_mesh)
    return SkelInputs(mesh=mesh, capture=capture, binding=binding, dm=dm, solver=solver, info=info,
                      effective=d_eff, effective_info=eff_info, gap_frames=_gap_frames(disp),
                      bound_points=binding.surface_points(mesh.points), head_motion=hm)


def fit_dcc(inputs: SkelInputs, k, *, skin_fit="rom", n_shapes=None, covariance=None):
    """The DCC-safe rig of :mod:`usdface.skel.dcc` for these inputs (a :class:`usdface.skel.DccSkin`).

    ``skin_fit``: "rom" (the synthetic range of motion: the character's rig) or "take" (this
    take's marker motion); ``covariance`` (M, M) overrides both (e.g. another take's
    :func:`usdface.skel.take_covariance`). The starting weights are Gaussians of the transfer's own
    distances, with its widths when its kernel is Gaussian (else the default width rule).
    """
    from ..rbf.stiffness import DEFAULT_WIDTH_FACTOR, median_marker_spacing_from_points
    from ..skel import dcc, fit_dcc_skin, initial_weights, rom_covariance, take_covariance

    m = inputs.binding.n_markers
    bound = inputs.bound_points
    spacing = median_marker_spacing_from_points(bound)
    widths = (inputs.solver.widths[:m] if inputs.solver.kernel == "gaussian" else DEFAULT_WIDTH_FACTOR * spacing)
    w0 = initial_weights(inputs.dm.vertex_to_centre[:, :m], widths)
    if covariance is None:
        if skin_fit not in SKIN_FITS:
            raise OptionError(f"--skin-fit: expected one of {', '.join(SKIN_FITS)}; got {skin_fit!r}")
        covariance = (rom_covariance(np.linalg.norm(bound[:, None] - bound[None], axis=2)) if skin_fit == "rom"
                      else take_covariance(inputs.effective))
    return fit_dcc_skin(inputs.transfer_matrix, w0, k, covariance,
                        n_shapes=dcc.DEFAULT_SHAPES if n_shapes is None else n_shapes,
                        shape_offset=dcc.SHAPE_OFFSET_FACTOR * spacing)


def skel(mesh_path, capture_path, binding_path, analysis_path, output, *, skin_weights=None,
         max_influences=DEFAULT_MAX_INFLUENCES, skin_fit="rom", corrective_shapes=None, weight_fit="lsq",
         head_motion=True, negative_weights=None, report_influences=REPORT_INFLUENCES, verify=True,
         rbf="interpolate", kernel="gaussian", stiffness=None, regularization="auto", polynomial=False,
         method=None, all_invalid="error", max_amplification=DEFAULT_MAX_AMPLIFICATION) -> dict:
    """Write the skeleton layer (:mod:`usdface.usd.skel_layer`); returns the summary.

    Transfer options are `usdface transfer`'s (same defaults, same handling). Skinning options:

    skin_weights : {"dcc", "exact"}, default "dcc"
        Module docstring. None means "dcc".
    max_influences : int or "all", default 8
        K joints per vertex, root included (>= 1; "all"/None: every joint).
    skin_fit : {"rom", "take"}, default "rom"
        dcc only: the range of motion the weights are fitted on: "rom" the synthetic range (the
        character's weights, the same for every take), "take" this take's marker motion.
    corrective_shapes : int, default 16 (dcc)
        dcc only: corrective blend shapes, 0 or 2..16 (S shapes with weights in [0, 1] correct
        S - 1 signed directions, :mod:`usdface.skel.dcc`).
    weight_fit : {"lsq", "renormalize"}
        exact only: how weights pruned to K are refitted (:mod:`usdface.skel.weights`).
    head_motion : bool, default True
        Author the head motion on /Face (when the capture has one).
    negative_weights : {"keep", "clamp"}, optional
        Deprecated alias of ``skin_weights`` ("keep" -> "exact", "clamp" -> "dcc").
    report_influences : sequence of int
        Other K whose error is reported (each costs a fit in dcc mode).
    verify : bool
        Deform the written layer with UsdSkel (blend shapes and skinning) and report its world
        space error against the point cache moved by the head motion.
    """
    from ..skel import build_rig, dcc, full_weights, prune_weights, skinning_error
    from ..skel.weights import FIT_METHODS, motion_gram
    from ..usd.skel_layer import skinned_points, write_skel_layer

    out = check_output_path(output, inputs={"--mesh": mesh_path, "--capture": capture_path,
                                            "--binding": binding_path, "--analysis": analysis_path})
    k = _parse_k(max_influences)
    mode = resolve_skin_weights(skin_weights, negative_weights)
    if skin_fit not in SKIN_FITS:
        raise OptionError(f"--skin-fit: expected one of {', '.join(SKIN_FITS)}; got {skin_fit!r}")
    if weight_fit not in FIT_METHODS:
        raise OptionError(f"--weight-fit: expected one of {', '.join(FIT_METHODS)}; got {weight_fit!r}")
    n_shapes = dcc.check_shape_count(dcc.DEFAULT_SHAPES if corrective_shapes is None else corrective_shapes)
    if mode == "exact":
        n_shapes = 0
    report_ks = [_parse_k(v) for v in (report_influences or ())]
    t0 = time.perf_counter()
    inputs = load_skel_inputs(mesh_path, capture_path, binding_path, analysis_path, rbf=rbf, kernel=kernel,
                              stiffness=stiffness, regularization=regularization, polynomial=polynomial,
                              method=method, all_invalid=all_invalid, max_amplification=max_amplification)
    mesh, capture, binding, dm, info = inputs.mesh, inputs.capture, inputs.binding, inputs.dm, inputs.info
    B, d_eff, gaps, eff_info = inputs.transfer_matrix, inputs.effective, inputs.gap_frames, inputs.effective_info
    n_markers = B.shape[1]
    hm = inputs.head_motion if head_motion else None
    bound = inputs.bound_points

    def key(kk):
        return "all" if kk is None or kk >= n_markers + 1 else str(kk)

    errors, gap_errors = {}, {}
    shapes = shape_weights = None
    if mode == "dcc":
        fits = {}
        for kk in [k] + report_ks:
            if key(kk) not in fits:
                fits[key(kk)] = fit_dcc(inputs, kk, skin_fit=skin_fit, n_shapes=n_shapes)
        for name, fitted in fits.items():
            errors[name] = dcc.dcc_skinning_error(fitted, B, d_eff)
            if gaps.size:
                gap_errors[name] = dcc.dcc_skinning_error(fitted, B, d_eff[gaps])
        chosen_fit = fits[key(k)]
        chosen = chosen_fit.weights
        translations = chosen_fit.joint_translations(d_eff)
        if n_shapes:
            shapes, shape_weights = chosen_fit.shapes, chosen_fit.shape_weights(d_eff)
    else:
        full = full_weights(B)
        gram = motion_gram(d_eff)
        chosen = prune_weights(full, k, gram=gram, fit=weight_fit)
        for kk in [None] + report_ks + [k]:
            if key(kk) in errors:
                continue
            w = chosen if kk == k else prune_weights(full, kk, gram=gram, fit=weight_fit)
            errors[key(kk)] = skinning_error(w, B, d_eff, mesh.points)
            if gaps.size:
                gap_errors[key(kk)] = skinning_error(w, B, d_eff[gaps], mesh.points)
        translations = d_eff
    rig = build_rig(binding.names, bound, translations)
    k_used = chosen.k
    weight_stats = {"min": float(chosen.weights.min()), "negative": int((chosen.weights < 0).sum()),
                    "minNonZero": float(np.abs(chosen.weights[chosen.weights != 0]).min()),
                    "maxRowSumError": float(np.abs(chosen.weights.sum(axis=1) - 1.0).max())}
    report = {"skinWeights": mode, "maxInfluences": k_used, "weightFit": chosen.fit,
              "skinFit": skin_fit if mode == "dcc" else "take", "correctiveShapes": n_shapes,
              "pointCacheError": errors, "gapFrameError": gap_errors, "gapFrames": int(gaps.size),
              "weights": weight_stats, "headMotion": hm is not None,
              "framesResolved": eff_info["framesResolved"], "jointNameMapping": rig.name_mapping}
    options = {"rbf": rbf, "kernel": kernel, "stiffness": stiffness, "regularization": info["regularization"],
               "polynomial": polynomial, "method": dm.method, "all_invalid": all_invalid,
               "skin_weights": mode, "max_influences": k_used, "skin_fit": skin_fit,
               "corrective_shapes": n_shapes, "weight_fit": weight_fit, "head_motion": hm is not None}
    prov = provenance("skel", options=options, inputs={"mesh": mesh_path, "capture": capture_path,
                                                       "binding": binding_path, "analysis": analysis_path})
    bar = progress(total=capture.n_frames, desc="skel", unit="frame")
    try:
        write_skel_layer(out, rig, chosen, mesh_path=mesh_path, units=mesh.units, rate=capture.rate,
                         start=capture.start_frame, prov=prov, report=report, progress=bar, head_motion=hm,
                         shapes=shapes, shape_weights=shape_weights)
    finally:
        bar.close()
    usdskel_error = usdskel_gap_error = None
    if verify:
        from ..usd.layers import open_stage

        stage = open_stage(out, what="skeleton")
        err = np.empty(capture.n_frames)
        for a in range(0, capture.n_frames, VERIFY_CHUNK):  # memory: a chunk of frames at a time
            frames = np.arange(a, min(capture.n_frames, a + VERIFY_CHUNK))
            _, pts = skinned_points(out, times=(capture.start_frame + frames).tolist(), stage=stage, space="world")
            expected = inputs.point_cache(frames, world=hm is not None)
            err[frames] = np.sqrt(((pts - expected) ** 2).sum(axis=2)).max(axis=1)
        usdskel_error = float(err.max())
        usdskel_gap_error = float(err[gaps].max()) if gaps.size else None
    seconds = time.perf_counter() - t0
    summary = {
        "output": str(out), "frames": capture.n_frames, "vertices": mesh.n_points, "markers": binding.n_markers,
        "joints": rig.n_joints, "skinWeights": mode, "maxInfluences": k_used, "skinFit": report["skinFit"],
        "correctiveShapes": n_shapes, "weightFit": chosen.fit, "headMotion": hm is not None, "units": mesh.units,
        "pointCacheError": errors, "gapFrameError": gap_errors, "gapFrames": int(gaps.size),
        "usdSkelPointCacheError": usdskel_error, "usdSkelGapFrameError": usdskel_gap_error, "weights": weight_stats,
        "framesResolved": eff_info["framesResolved"], "jointNameMapping": rig.name_mapping,
        "mode": rbf, "kernel": inputs.solver.kernel, "distanceMethod": dm.method,
        "regularization": info["regularization"], "amplification": info["amplification"],
        "seconds": round(seconds, 3),
    }
    errs = ", ".join(f"K={name}: max {v['max']:.3g} rms {v['rms']:.3g}" for name, v in errors.items())
    gap_text = ", ".join(f"K={name}: max {v['max']:.3g}" for name, v in gap_errors.items())
    how = (f"DCC-safe weights fitted on the {'synthetic range of motion' if skin_fit == 'rom' else 'take'}, "
           f"{n_shapes} corrective shapes" if mode == "dcc" else f"exact signed weights ({chosen.fit})")
    summary["_text"] = [
        f"wrote {out}: {rig.n_joints} joints (root + {binding.n_markers} markers), {capture.n_frames} frames, "
        f"{k_used} influences per vertex, {how}, "
        f"head motion {'on /Face' if hm is not None else 'none'}, in {seconds:.2f} s",
        f"  skinning error against the point cache ({mesh.units}): {errs}",
    ] + ([f"  UsdSkel deformation of the written layer vs the point cache (world space): max {usdskel_error:.3g} "
          f"{mesh.units}"] if usdskel_error is not None else []) \
      + ([f"  {gaps.size} frames with missing markers (their joints follow the re-solved surface): {gap_text}"]
         if gaps.size else []) \
      + ([f"  joints renamed from markers: {rig.name_mapping}"] if rig.name_mapping else [])
    return summary


def register_cli(sub) -> None:
    """Add `usdface skel` to the CLI."""
    from ..cliargs import add_common_options, add_options

    p = sub.add_parser("skel", help="skeletal keyframes (UsdSkel): a joint per marker, skinned like the transfer",
                       description="Write a UsdSkel layer: one SkelRoot (carrying the head motion), a Skeleton with "
                                   "a static root joint and one joint per marker at its bound point, a SkelAnimation "
                                   "with the joints' motion, and skin weights that reproduce `usdface transfer`'s "
                                   "point cache: by default non-negative, summing to one, K per vertex, with "
                                   "corrective blend shapes (DCC-safe); or the exact signed transfer matrix. The "
                                   "error against the point cache is reported.")
    p.add_argument("--mesh", required=True, help="mesh layer")
    p.add_argument("--capture", required=True, help="capture layer")
    p.add_argument("--binding", required=True, help="binding layer")
    p.add_argument("--analysis", required=True, help="analysis layer (from `usdface distances`)")
    p.add_argument("--method", choices=["euclidean", "geodesic", "hybrid"],
                   help="which distance matrix of the analysis layer (default: its only one)")
    groups = add_options(p, TransferOptions)
    add_options(p, SkelOptions, groups=groups)
    add_options(p, RunOptions, only={"head_motion"}, groups=groups)
    g = groups["skeleton"]
    g.add_argument("--negative-weights", choices=sorted(NEGATIVE_WEIGHTS_ALIAS), default=None,
                   help="deprecated: keep = --skin-weights exact, clamp = --skin-weights dcc")
    g.add_argument("--no-verify", dest="verify", action="store_false",
                   help="skip deforming the written layer with UsdSkel to measure its error")
    p.add_argument("-o", "--output", required=True, help="skeleton layer to write (.usdc)")
    add_common_options(p)
    p.set_defaults(func=_cmd_skel)


def _cmd_skel(args) -> dict:
    from ..cliargs import options_from_args

    o = options_from_args(SkelOptions, args)
    # the deprecated alias decides only when --skin-weights was not given (resolve_skin_weights
    # refuses a contradiction)
    return skel(args.mesh, args.capture, args.binding, args.analysis, args.output,
                skin_weights=getattr(args, "skin_weights", None), negative_weights=args.negative_weights,
                max_influences=o.max_influences, skin_fit=o.skin_fit, corrective_shapes=o.corrective_shapes,
                weight_fit=o.weight_fit, head_motion=getattr(args, "head_motion", True), verify=args.verify,
                method=args.method, **options_from_args(TransferOptions, args).to_dict())
