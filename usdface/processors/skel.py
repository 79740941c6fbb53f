"""`usdface skel`: skeletal keyframes (UsdSkel) from a capture, skinned so they reproduce the transfer.

One head joint plus one translation-only joint per marker (children of the head, at the markers'
bound surface points), animated by the marker displacements the transfer uses, and skin weights
taken from the transfer matrix (the head joint gets the remainder): with every weight kept, linear
blend skinning reproduces `usdface transfer`'s point cache of the same inputs and settings
(:mod:`usdface.skel.weights` explains why). Pruned to K influences per vertex, the weights are
refitted to the take and the error against the point cache is reported.

Frames with missing markers: the transfer re-solves them with the valid markers. Its result is
still ``B @ D_eff`` for *effective* marker displacements (the values the re-solved field takes at
the missing markers' bound points), so the missing markers' joints follow those values and the
skeleton reproduces the re-solved frames as well; D_eff is recovered from the transfer's own
output by least squares on B (full column rank).

Head motion: when the capture was stabilised, the head joint carries the head motion removed by
stabilisation, mapped into mesh space by the binding's capture-to-mesh similarity and taken
relative to the neutral frame (the face is at its rest pose on the neutral frame):
``H_mesh(f) = C H(n)^-1 H(f) C^-1``. The skinned mesh is then the stabilised point cache moved by
H_mesh(f); ``--no-head-motion`` leaves the head joint still (the skinned mesh equals the point cache).
"""
from __future__ import annotations

import logging
import time

import numpy as np

from ..errors import ComputeError, OptionError
from ..progress import progress
from ..rbf.stability import DEFAULT_MAX_AMPLIFICATION
from ..usd.layers import check_output_path, provenance
from .transfer import build_transfer_solver, load_transfer_inputs

log = logging.getLogger("usdface")

DEFAULT_MAX_INFLUENCES = 8
REPORT_INFLUENCES = (4, 8)


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
    if k < 1:
        raise OptionError(f"--max-influences: expected an integer >= 1 or 'all'; got {value!r}")
    return k


def skel(mesh_path, capture_path, binding_path, analysis_path, output, *, max_influences=DEFAULT_MAX_INFLUENCES,
         negative_weights="keep", weight_fit="lsq", head_motion=True, report_influences=REPORT_INFLUENCES,
         verify=True, rbf="interpolate", kernel="gaussian", stiffness=None, regularization="auto",
         polynomial=False, method=None, all_invalid="error",
         max_amplification=DEFAULT_MAX_AMPLIFICATION) -> dict:
    """Write the skeleton layer (:mod:`usdface.usd.skel_layer`); returns the summary.

    Transfer options are `usdface transfer`'s (same defaults, same handling). ``max_influences``:
    K per vertex (None / "all": every joint, exact); ``negative_weights``: "keep" or "clamp";
    ``weight_fit``: "lsq" or "renormalize" (:mod:`usdface.skel.weights`); ``verify``: skin the
    written layer with UsdSkel and report its error against the point cache.
    """
    from ..capture.retarget import marker_displacements
    from ..skel import build_rig, full_weights, head_motion_in_mesh_space, prune_weights, skinning_error
    from ..skel.weights import FIT_METHODS, NEGATIVE_POLICIES, motion_gram
    from ..usd.skel_layer import skinned_points, write_skel_layer

    out = check_output_path(output, inputs={"--mesh": mesh_path, "--capture": capture_path,
                                            "--binding": binding_path, "--analysis": analysis_path})
    k = _parse_k(max_influences)
    if negative_weights not in NEGATIVE_POLICIES:
        raise OptionError(f"--negative-weights: expected one of {', '.join(NEGATIVE_POLICIES)}; got {negative_weights!r}")
    if weight_fit not in FIT_METHODS:
        raise OptionError(f"--weight-fit: expected one of {', '.join(FIT_METHODS)}; got {weight_fit!r}")
    report_ks = [_parse_k(v) for v in (report_influences or ())]
    t0 = time.perf_counter()
    mesh, capture, binding, dm = load_transfer_inputs(mesh_path, capture_path, binding_path, analysis_path,
                                                      method=method)
    disp = marker_displacements(capture, binding.names, binding.displacement_transform())
    solver, info = build_transfer_solver(mesh, binding, dm, rbf=rbf, kernel=kernel, stiffness=stiffness,
                                         regularization=regularization, polynomial=polynomial,
                                         all_invalid=all_invalid, max_amplification=max_amplification)
    B = solver.transfer_matrix
    d_eff, eff_info = effective_displacements(solver, disp)
    if eff_info["residual"] > 1e-6 * max(1.0, float(np.abs(d_eff).max())):
        raise ComputeError(f"skel: the re-solved frames are not reproduced through the transfer matrix "
                           f"(residual {eff_info['residual']:.3g} {mesh.units}); the transfer matrix is rank deficient")
    hm = None
    if head_motion and capture.head_motion is not None:
        n = capture.neutral_frame
        rel = np.einsum("ij,fjk->fik", np.linalg.inv(capture.head_motion[n]), capture.head_motion)
        hm = head_motion_in_mesh_space(rel, binding.capture_to_mesh)
    # skeleton space: mesh space moved to the face's centre (the head joint's place), which keeps
    # UsdSkel's float32 skinning arithmetic on small coordinates
    origin = 0.5 * (mesh.points.min(axis=0) + mesh.points.max(axis=0))
    hm_skel = None
    if hm is not None:
        shift = np.eye(4)
        shift[:3, 3] = origin
        hm_skel = np.einsum("ij,fjk,kl->fil", np.linalg.inv(shift), hm, shift)
    rig = build_rig(binding.names, binding.surface_points(mesh.points) - origin, d_eff, head_motion=hm_skel,
                    head_pivot=np.zeros(3))
    full = full_weights(B)
    gram = motion_gram(d_eff)
    chosen = prune_weights(full, k, gram=gram, fit=weight_fit, negative=negative_weights)
    errors = {}
    for kk in [None] + [x for x in report_ks if x is not None] + [k]:
        key = "all" if kk is None or kk >= B.shape[1] + 1 else str(kk)
        if key in errors:
            continue
        w = chosen if kk == k else prune_weights(full, kk, gram=gram, fit=weight_fit, negative=negative_weights)
        errors[key] = skinning_error(w, B, d_eff, mesh.points)
    negative = {"count": int((chosen.weights < 0).sum()), "min": float(chosen.weights.min()),
                "verticesWithNegative": int((chosen.weights < 0).any(axis=1).sum()),
                "inTransferMatrix": int((full < 0).sum())}
    k_used = chosen.k
    report = {"maxInfluences": k_used, "negativeWeights": negative_weights, "weightFit": chosen.fit,
              "pointCacheError": errors, "negative": negative, "headMotion": hm is not None,
              "framesResolved": eff_info["framesResolved"], "jointNameMapping": rig.name_mapping}
    options = {"rbf": rbf, "kernel": kernel, "stiffness": stiffness, "regularization": info["regularization"],
               "polynomial": polynomial, "method": dm.method, "all_invalid": all_invalid,
               "max_influences": k_used, "negative_weights": negative_weights, "weight_fit": weight_fit,
               "head_motion": hm is not None}
    prov = provenance("skel", options=options, inputs={"mesh": mesh_path, "capture": capture_path,
                                                       "binding": binding_path, "analysis": analysis_path})
    bar = progress(total=capture.n_frames, desc="skel", unit="frame")
    try:
        write_skel_layer(out, rig, chosen, mesh_path=mesh_path, units=mesh.units, rate=capture.rate,
                         start=capture.start_frame, prov=prov, report=report, progress=bar, origin=origin)
    finally:
        bar.close()
    usdskel_error = None
    if verify:
        times, pts = skinned_points(out)
        expected = mesh.points[None] + apply_matrix(B, d_eff)
        if hm is not None:
            expected = np.einsum("fij,fnj->fni", hm[:, :3, :3], expected) + hm[:, None, :3, 3]
        usdskel_error = float(np.sqrt(((pts - expected) ** 2).sum(axis=2)).max())
    seconds = time.perf_counter() - t0
    summary = {
        "output": str(out), "frames": capture.n_frames, "vertices": mesh.n_points, "markers": binding.n_markers,
        "joints": rig.n_joints, "maxInfluences": k_used, "negativeWeights": negative_weights,
        "weightFit": chosen.fit, "headMotion": hm is not None, "units": mesh.units,
        "pointCacheError": errors, "usdSkelPointCacheError": usdskel_error, "negative": negative,
        "framesResolved": eff_info["framesResolved"], "jointNameMapping": rig.name_mapping,
        "mode": rbf, "kernel": solver.kernel, "distanceMethod": dm.method,
        "regularization": info["regularization"], "amplification": info["amplification"],
        "seconds": round(seconds, 3),
    }
    errs = ", ".join(f"K={key}: max {v['max']:.3g} rms {v['rms']:.3g}" for key, v in errors.items())
    summary["_text"] = [
        f"wrote {out}: {rig.n_joints} joints (head + {binding.n_markers} markers), {capture.n_frames} frames, "
        f"{k_used} influences per vertex ({chosen.fit}, negative weights {negative_weights}), "
        f"head motion {'on the head joint' if hm is not None else 'none'}, in {seconds:.2f} s",
        f"  skinning error against the point cache ({mesh.units}): {errs}",
    ] + ([f"  UsdSkel skinning of the written layer vs the point cache: max {usdskel_error:.3g} {mesh.units}"]
         if usdskel_error is not None else []) \
      + ([f"  {eff_info['framesResolved']} frames with missing markers: their joints follow the re-solved surface"]
         if eff_info["framesResolved"] else []) \
      + ([f"  joints renamed from markers: {rig.name_mapping}"] if rig.name_mapping else [])
    return summary


def register_cli(sub) -> None:
    """Add `usdface skel` to the CLI."""
    from ..cliargs import add_common_options, add_options
    from ..options import TransferOptions

    p = sub.add_parser("skel", help="skeletal keyframes (UsdSkel): a joint per marker, skinned like the transfer",
                       description="Write a UsdSkel layer: one SkelRoot, a Skeleton with a head joint and one joint "
                                   "per marker at its bound point, a SkelAnimation with the marker (and head) "
                                   "motion, and skin weights from the transfer matrix, so that skinning reproduces "
                                   "`usdface transfer`'s point cache (exactly with every influence; the error for "
                                   "K influences is reported).")
    p.add_argument("--mesh", required=True, help="mesh layer")
    p.add_argument("--capture", required=True, help="capture layer")
    p.add_argument("--binding", required=True, help="binding layer")
    p.add_argument("--analysis", required=True, help="analysis layer (from `usdface distances`)")
    p.add_argument("--method", choices=["euclidean", "geodesic", "hybrid"],
                   help="which distance matrix of the analysis layer (default: its only one)")
    add_options(p, TransferOptions)
    g = p.add_argument_group("skinning")
    g.add_argument("--max-influences", default=str(DEFAULT_MAX_INFLUENCES), metavar="K|all",
                   help="joints per vertex, head included (default 8); 'all' keeps every weight (exact)")
    g.add_argument("--negative-weights", choices=["keep", "clamp"], default="keep",
                   help="keep (default: UsdSkel applies them; needed for an exact match) or clamp to zero and "
                        "renormalise (what some DCC importers do)")
    g.add_argument("--weight-fit", choices=["lsq", "renormalize"], default="lsq",
                   help="after pruning: refit the kept weights by least squares over the take (default) or "
                        "just rescale them to sum to one")
    g.add_argument("--no-head-motion", dest="head_motion", action="store_false",
                   help="leave the head joint still even when the capture has head motion")
    g.add_argument("--no-verify", dest="verify", action="store_false",
                   help="skip skinning the written layer with UsdSkel to measure its error")
    p.add_argument("-o", "--output", required=True, help="skeleton layer to write (.usdc)")
    add_common_options(p)
    p.set_defaults(func=_cmd_skel)


def _cmd_skel(args) -> dict:
    from ..cliargs import options_from_args
    from ..options import TransferOptions

    return skel(args.mesh, args.capture, args.binding, args.analysis, args.output,
                max_influences=args.max_influences, negative_weights=args.negative_weights,
                weight_fit=args.weight_fit, head_motion=args.head_motion, verify=args.verify, method=args.method,
                **options_from_args(TransferOptions, args).to_dict())
