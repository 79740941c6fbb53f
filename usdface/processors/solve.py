"""`usdface solve`: marker capture -> weight curves on a blend-shape rig (CURVES.usdc, CSVs).

Also ``usdface solve --apply CURVES.csv --mesh OTHER_RIG -o OUT.usdc`` (the curves of one
character played on another whose shapes share the names) and :func:`solve_shot`, the step
``usdface run --output-kind blendshapes`` calls on the layers it wrote.

Every output of one call is written to a temporary name and renamed into place only when all of
them are complete (:class:`usdface.fileutil.StagedOutputs`): a failure leaves nothing new.
"""
from __future__ import annotations

import logging
import time
from pathlib import Path

import numpy as np

from ..errors import InputError, OptionError, list_names

log = logging.getLogger("usdface")

__all__ = ["load_rig", "solve", "apply_curves", "solve_shot", "write_deliverables", "register_cli"]


def solver_defaults() -> dict:
    """The solver's keyword arguments and their defaults (smoothing_hz, sparsity, symmetry, exclude,
    refit, max_iterations, tolerance). A function, not a constant: the solver module loads numba
    kernels, which the command line should not pay for at start-up."""
    from ..blendshape.solver import (DEFAULT_MAX_ITERATIONS, DEFAULT_SMOOTHING_HZ, DEFAULT_SPARSITY, DEFAULT_SYMMETRY,
                                     DEFAULT_TOLERANCE)
    from ..blendshape.take import DEFAULT_EXCLUDE

    return dict(smoothing_hz=DEFAULT_SMOOTHING_HZ, sparsity=DEFAULT_SPARSITY, symmetry=DEFAULT_SYMMETRY,
                exclude=DEFAULT_EXCLUDE, refit=True, max_iterations=DEFAULT_MAX_ITERATIONS, tolerance=DEFAULT_TOLERANCE)


# -- inputs -------------------------------------------------------------------------------------

def load_rig(mesh, shapes=None, *, mesh_units=None):
    """The rig and the mesh's regions from ``--mesh`` (and ``--shapes``).

    ``mesh``: a USD mesh with UsdSkel blend shapes (no ``shapes``), or a neutral mesh (OBJ/PLY/...
    or a USD mesh layer) with ``shapes`` = an ``.npz``, a folder of ``<shape>.obj`` or a USD rig
    whose neutral must match the mesh.

    Returns
    -------
    rig : BlendShapeRig
    regions : list of Region
        The mesh's regions (hole regions found when the mesh has none).
    """
    from ..blendshape.rig import BlendShapeRig, check_neutral, check_same_topology, load_mesh_folder_rig, load_npz_rig
    from ..mesh.topology import find_hole_regions
    from ..usd.layers import USD_SUFFIXES
    from .import_mesh import load_mesh

    mp = Path(mesh)
    if not mp.exists():
        raise InputError(f"--mesh {mp}: no such file")
    is_usd = mp.suffix.lower() in USD_SUFFIXES
    if shapes is None:
        if not is_usd:
            raise OptionError(f"--mesh {mp} is a plain mesh: give its blend shapes with --shapes DIR|NPZ|RIG.usd "
                              "(or a USD mesh with UsdSkel blend shapes as --mesh)")
        usd_rig = _read_usd_rig(mp, mesh_units)
        rig = BlendShapeRig(tuple(usd_rig.names), usd_rig.deltas, usd_rig.mesh, source=str(mp),
                            notes=tuple(usd_rig.notes))
        regions = usd_rig.regions
    else:
        sp = Path(shapes)
        if is_usd and _has_shapes(mp):
            raise OptionError(f"--mesh {mp} has blend shapes of its own; --shapes {sp} would replace them: give one")
        neutral, regions = load_mesh(mp, units=mesh_units)
        if sp.is_dir():
            rig = load_mesh_folder_rig(sp, neutral)
        elif sp.suffix.lower() == ".npz":
            rig = load_npz_rig(sp, neutral)
        elif sp.suffix.lower() in USD_SUFFIXES:
            usd_rig = _read_usd_rig(sp, mesh_units or neutral.units)
            check_same_topology(neutral, usd_rig.mesh, what=f"rig {sp}")
            check_neutral(usd_rig.mesh.points, neutral, source=str(sp))
            rig = BlendShapeRig(tuple(usd_rig.names), usd_rig.deltas, neutral, source=str(sp), notes=tuple(usd_rig.notes))
        elif not sp.exists():
            raise InputError(f"--shapes {sp}: no such file or folder")
        else:
            raise OptionError(f"--shapes {sp}: expected a folder of <shape>.obj, an .npz (names, deltas[, neutral]) or "
                              "a USD rig")
    if not regions:
        regions = find_hole_regions(rig.mesh)
    for note in rig.notes:
        log.warning("rig %s: %s", rig.source, note)
    return rig, regions


def _read_usd_rig(path, units):
    from ..usd.blendshape_layer import read_blendshape_rig

    return read_blendshape_rig(path, units=units)


def _has_shapes(path) -> bool:
    from ..usd.blendshape_layer import read_blendshape_rig

    try:
        read_blendshape_rig(path)
    except InputError:
        return False
    return True


def _check_outputs(inputs: dict, outputs: dict) -> dict:
    """Validate output paths before any work: suffixes, folders, no output is an input, no two alike."""
    from ..usd.layers import check_output_path

    checked = {}
    for option, (path, suffixes) in outputs.items():
        if path is None:
            continue
        if suffixes == "csv":
            p = Path(path)
            if p.suffix.lower() != ".csv":
                raise OptionError(f"{option} {p}: expected a file ending in .csv")
            folder = p.parent if str(p.parent) else Path(".")
            if not folder.is_dir():
                raise OptionError(f"{option} {p}: folder {folder} does not exist")
        else:
            p = check_output_path(path, option=option)
        checked[option] = p
    resolved = {}
    for option, p in checked.items():
        r = p.resolve()
        for in_opt, in_path in inputs.items():
            if in_path is not None and Path(in_path).exists() and Path(in_path).resolve() == r:
                raise OptionError(f"{option} {p} is the input {in_opt} {in_path}: outputs never replace inputs")
        if r in resolved:
            raise OptionError(f"{option} {p} and {resolved[r]} name the same file")
        resolved[r] = option
    return checked


# -- outputs ------------------------------------------------------------------------------------

def write_deliverables(curves, rig, regions, *, output, csv=None, livelink=None, livelink_fill_zeros=False,
                       start_frame=0, prov, report, staged) -> dict:
    """Write CURVES.usdc (+ CSVs) for :class:`usdface.blendshape.take.DeliverableCurves` into
    ``staged`` temporaries; returns what was written (paths are the final ones)."""
    from ..blendshape.csvio import curves_csv_text, live_link_face_text
    from ..usd.blendshape_layer import write_curves_layer

    n = curves.values.shape[0]
    frames = start_frame + np.arange(n)
    written = {"curves": str(output)}
    extra = {}
    if livelink is not None:  # before any file: a rig without ARKit names fails first
        text, ll_report = live_link_face_text(rig.names, curves.values, rate=curves.rate,
                                              head_motion=curves.head_motion, fill_missing=livelink_fill_zeros,
                                              source=f"the rig {rig.source}")
        extra["livelink"] = ll_report
    write_curves_layer(staged.path(output), mesh=rig.mesh, regions=regions, names=rig.names, deltas=rig.deltas,
                       times=start_frame + curves.sample_frames, weights=curves.sample_values, rate=curves.rate,
                       start=float(frames[0]), end=float(frames[-1]),
                       head_motion=curves.head_motion, head_times=frames if curves.head_motion is not None else None,
                       prov=prov, report=report)
    if csv is not None:
        staged.path(csv).write_text(curves_csv_text(rig.names, curves.values, rate=curves.rate,
                                                    start_frame=start_frame))
        written["csv"] = str(csv)
    if livelink is not None:
        staged.path(livelink).write_text(text)
        written["livelink"] = str(livelink)
    return {"files": written, **extra}


def _corrective_points(take, rig, regions, binding, *, method="hybrid"):
    """(F, N, 3) corrected points: the rig's pose plus the RBF transfer of the marker residual."""
    from ..units import scale_between
    from .distances import _compute
    from .transfer import build_transfer_solver

    cm = scale_between("cm", rig.units) if rig.units else 1.0
    dm, _ = _compute(rig.mesh, regions, binding, rig.source, method, "graph", "error", "auto", "upper", 1.0, 2.0,
                     0.6, cm)
    # frames without any valid marker: the curves bridge them; the corrective adds nothing there
    solver, info = build_transfer_solver(rig.mesh, binding, dm, all_invalid="zero")
    fit = np.einsum("fk,mkd->fmd", take.weights, take.basis)
    residual = take.displacements - fit  # NaN where invalid: the transfer re-solves those frames
    posed = rig.evaluate(take.weights)
    chunks = [solver.apply(residual[a:a + 256], dtype=np.float64) for a in range(0, residual.shape[0], 256)]
    return posed + np.concatenate(chunks), info


# -- the processors -----------------------------------------------------------------------------

def solve(mesh, capture, output, *, shapes=None, layout=None, auto=False, csv=None, livelink=None,
          livelink_fill_zeros=False, corrective=None, fps=None, key_tolerance=None, head_motion=True,
          retarget="displacement", mesh_units=None, units=None, rate=None, up_axis=None, stabilize="auto",
          fill_gaps=None, filter=None, cutoff=8.0, trim=None, neutral=None, resample=None, start_frame=None,
          allow=(), keep_zeros=False, drop_outliers=False,
          **solver_options) -> dict:
    """Solve a capture on a rig; write CURVES.usdc and the optional CSVs and corrective shot.

    Parameters
    ----------
    mesh, shapes : paths
        The rig (:func:`load_rig`).
    capture : path
        Raw capture (.ma .c3d .trc .csv) or a capture layer; conditioned like ``run`` (``stabilize``
        "auto" by default; None keeps the head motion in the markers).
    layout, auto : binding (a marker layout JSON, or automatic alignment).
    csv, livelink : paths, optional
        Curves CSV (``frame,time,<names>``) and Live Link Face CSV.
    livelink_fill_zeros : bool
        Zeros for ARKit shapes the rig lacks (otherwise an error).
    corrective : path, optional
        A points layer: the rig's pose plus the RBF transfer of the residual (markers hit exactly);
        its own shot, never layered over the curves.
    fps : float, optional
        Deliver at 24/25/30 (or any) frames per second instead of the capture rate.
    key_tolerance : float, optional
        Reduce keys: kept curves stay within this weight of the solved ones.
    head_motion : bool
        D1: the head motion as /Face's time-sampled transform (default when the capture had any).
    solver_options
        :func:`solver_defaults` (smoothing_hz, sparsity, symmetry, exclude, refit, max_iterations,
        tolerance).
    """
    from ..blendshape.take import deliverable_curves, solve_take
    from ..fileutil import StagedOutputs
    from ..usd.layers import provenance
    from .import_capture import condition_capture, load_capture

    t0 = time.perf_counter()
    defaults = solver_defaults()
    unknown = set(solver_options) - set(defaults)
    if unknown:
        raise OptionError(f"solve: unknown option(s) {', '.join(sorted(unknown))}")
    opts = {**defaults, **solver_options}
    if (layout is None) == (not auto):
        raise OptionError("solve: give exactly one of --layout LAYOUT.json or --auto")
    if corrective is True:
        corrective = Path(output).with_name(Path(output).stem + "_corrective.usdc")
    outs = _check_outputs({"--mesh": mesh, "--shapes": shapes, "--capture": capture, "--layout": layout},
                          {"-o": (output, "usd"), "--csv": (csv, "csv"), "--livelink": (livelink, "csv"),
                           "--corrective": (corrective, "usd")})
    for label, path in (("--capture", capture), ("--layout", layout)):
        if path is not None and not Path(path).is_file():
            raise InputError(f"{label} {path}: no such file")
    rig, regions = load_rig(mesh, shapes, mesh_units=mesh_units)
    if livelink is not None:  # fail before the work, not after it
        from ..blendshape.csvio import check_arkit_names

        check_arkit_names(rig.names, fill_missing=livelink_fill_zeros, source=f"the rig {rig.source}")
    cap = load_capture(capture, units=units, rate=rate, up_axis=up_axis, keep_zeros=keep_zeros)
    cap, reports = condition_capture(cap, trim=trim, fill_gaps=fill_gaps, filter=filter, cutoff=cutoff,
                                     resample=resample, neutral=neutral, stabilize=stabilize, start_frame=start_frame,
                                     allow=allow, drop_outliers=drop_outliers)
    from .bind import bind_and_judge

    # judged as `bind` judges a binding (face size, layout distance, fit residual, unit scale)
    binding, _, _ = bind_and_judge(rig.mesh, cap, layout=layout, retarget=retarget, allow=allow,
                                   mesh_name=f"mesh {mesh}", capture_name=f"capture {capture}")
    take = solve_take(rig, cap, binding, head_motion=head_motion, **opts)
    curves = deliverable_curves(rig.names, take.weights, rate=take.rate, fps=fps, key_tolerance=key_tolerance,
                                head_motion=take.head_motion)
    # D2: time code = frame index from 0 (a trimmed take too) unless --start-frame says otherwise
    start_out = 0 if start_frame is None else int(round(start_frame * curves.rate / take.rate))
    options = {**{k: (list(v) if isinstance(v, tuple) else v) for k, v in opts.items()}, "fps": fps,
               "key_tolerance": key_tolerance, "head_motion": take.head_motion is not None, "retarget": retarget,
               "stabilize": stabilize, "trim": trim, "fill_gaps": fill_gaps, "filter": filter, "resample": resample,
               "neutral": neutral, "start_frame": start_frame, "layout": Path(layout).name if layout else None,
               "auto": bool(auto)}
    prov = provenance("solve", options=options, inputs={"mesh": mesh, "shapes": shapes if shapes and Path(shapes).is_file() else None,
                                                        "capture": capture, "layout": layout})
    summary = _summary(take, curves, rig, binding, outs, reports)
    report = {k: summary[k] for k in ("residualMean", "stillResidualMean", "iterations", "mirror", "excludedShapes")}
    corrected = None
    if corrective is not None:
        corrected, cinfo = _corrective_points(take, rig, regions, binding)
        if fps is not None:  # the points shot plays at the curves' rate
            from ..blendshape.curves import resample_curves

            n = corrected.shape[1]
            corrected = resample_curves(corrected.reshape(corrected.shape[0], -1), take.rate, fps).reshape(-1, n, 3)
        summary["corrective"] = {"output": str(outs["--corrective"]), "amplification": cinfo["amplification"],
                                 "markerResidual": "0 at the bound points (the transfer interpolates them)"}
    with StagedOutputs() as staged:
        res = write_deliverables(curves, rig, regions, output=outs["-o"], csv=outs.get("--csv"),
                                 livelink=outs.get("--livelink"), livelink_fill_zeros=livelink_fill_zeros,
                                 start_frame=start_out, prov=prov, report=report, staged=staged)
        if corrected is not None:
            from ..usd.blendshape_layer import write_points_layer

            write_points_layer(staged.path(outs["--corrective"]), mesh=rig.mesh, regions=regions,
                               points=corrected, rate=curves.rate, start=start_out,
                               head_motion=curves.head_motion, prov=dict(prov, processor="solve --corrective"))
        staged.commit()
    summary.update(res)
    summary["seconds"] = round(time.perf_counter() - t0, 3)
    summary["_text"] = _text(summary, outs)
    return summary


def _summary(take, curves, rig, binding, outs, reports) -> dict:
    """The JSON summary; residuals in cm (the mesh's units converted)."""
    from ..units import scale_between

    sol = take.solution
    to_cm = scale_between(rig.units, "cm") if rig.units else 1.0
    residual, still, per_marker = sol.residual * to_cm, sol.still_residual * to_cm, sol.marker_rms * to_cm
    fin = np.isfinite(residual)
    units = "cm" if rig.units else "units"
    return {
        "output": str(outs["-o"]), "frames": int(sol.n_frames), "rate": take.rate, "deliveredFrames":
            int(curves.values.shape[0]), "deliveredRate": curves.rate, "shapes": rig.n_shapes,
        "markers": binding.n_markers, "units": units,  # of the residuals below
        "meshUnits": rig.units,
        "residual": [None if not np.isfinite(r) else round(float(r), 5) for r in residual],
        "residualMean": float(np.mean(residual[fin])) if fin.any() else None,
        "residualMax": float(np.max(residual[fin])) if fin.any() else None,
        "stillResidualMean": float(np.mean(still[fin])) if fin.any() else None,
        "markerResidual": {n: (None if not np.isfinite(v) else round(float(v), 5))
                           for n, v in zip(binding.names, per_marker)},
        "weightMax": {n: round(float(v), 4) for n, v in zip(rig.names, sol.weights.max(axis=0))},
        "iterations": int(sol.iterations), "converged": bool(sol.converged),
        "solveSeconds": round(float(sol.seconds), 4), "solver": sol.summary(),
        "mirror": take.mirror, "excludedShapes": sol.info.get("excludedShapes", []),
        "headMotion": take.head_motion is not None, "keys": curves.key_counts,
        "keyTolerance": curves.tolerance, "timeSamples": int(curves.sample_frames.size),
        "warnings": list(take.warnings), "rigNotes": list(rig.notes), "conditioning": reports,
    }


def _text(summary: dict, outs: dict) -> list[str]:
    u = summary["units"]
    lines = [f"wrote {summary['output']}: {summary['shapes']} shapes x {summary['deliveredFrames']} frames at "
             f"{summary['deliveredRate']:g} fps ({summary['timeSamples']} time samples), head motion "
             f"{'on /Face' if summary['headMotion'] else 'none'}, in {summary['seconds']:.2f} s",
             f"  solve: {summary['frames']} frames at {summary['rate']:g} Hz in {summary['solveSeconds']:.3f} s "
             f"({summary['iterations']} iterations); marker residual mean {summary['residualMean']:.3f} {u} "
             f"(still face {summary['stillResidualMean']:.3f} {u}), max {summary['residualMax']:.3f} {u}"]
    top = sorted(summary["weightMax"].items(), key=lambda kv: -kv[1])[:6]
    lines.append("  largest weights: " + ", ".join(f"{n} {v:.2f}" for n, v in top))
    pairs = summary["mirror"].get("prior", [])
    lines.append(f"  left/right prior on {len(pairs)} mirror pair(s); excluded: "
                 f"{', '.join(summary['excludedShapes']) or 'none'}")
    for key in ("csv", "livelink"):
        if key in summary.get("files", {}):
            lines.append(f"  {key}: {summary['files'][key]}")
    if "corrective" in summary:
        lines.append(f"  corrective points shot: {summary['corrective']['output']}")
    lines += [f"  warning: {w}" for w in summary["warnings"]]
    return lines


def apply_curves(curves, mesh, output, *, shapes=None, mesh_units=None, csv=None, livelink=None,
                 livelink_fill_zeros=False, fps=None, key_tolerance=None) -> dict:
    """Play solved curves (a curves CSV or a CURVES.usdc) on another rig whose shapes share names.

    Shapes of the curves the rig lacks are dropped (reported); rig shapes without a curve stay at
    0; no shared name is an error. A CURVES.usdc also brings its head motion along.
    """
    from ..blendshape.csvio import read_curves_csv
    from ..blendshape.take import deliverable_curves
    from ..fileutil import StagedOutputs
    from ..usd.blendshape_layer import head_motion_of_layer, read_curves_layer
    from ..usd.layers import USD_SUFFIXES, provenance

    t0 = time.perf_counter()
    outs = _check_outputs({"--apply": curves, "--mesh": mesh, "--shapes": shapes},
                          {"-o": (output, "usd"), "--csv": (csv, "csv"), "--livelink": (livelink, "csv")})
    cp = Path(curves)
    head = None
    start = 0
    if cp.suffix.lower() in USD_SUFFIXES:
        data = read_curves_layer(cp)
        names, times, values, rate = data["names"], data["times"], data["weights"], data["rate"]
        if times.size == 0:
            raise InputError(f"--apply {cp}: the curves have no time samples")
        frames = np.arange(int(round(times[0])), int(round(times[-1])) + 1)
        values = np.stack([np.interp(frames, times, values[:, k]) for k in range(len(names))], axis=1)
        hm = head_motion_of_layer(cp)
        if hm is not None:
            from ..blendshape.curves import interpolate_rigid

            head = interpolate_rigid(hm[0], hm[1], frames)
        start = int(frames[0])
    else:
        names, frames, values, rate = read_curves_csv(cp)
        start = int(frames[0])
    rig, regions = load_rig(mesh, shapes, mesh_units=mesh_units)
    if livelink is not None:
        from ..blendshape.csvio import check_arkit_names

        check_arkit_names(rig.names, fill_missing=livelink_fill_zeros, source=f"the rig {rig.source}")
    shared = [n for n in names if n in rig.names]
    if not shared:
        raise InputError(f"--apply {cp}: none of its {len(names)} curves ({list_names(names)}) names a shape of the "
                         f"rig {rig.source} ({list_names(rig.names)})")
    dropped = [n for n in names if n not in rig.names]
    if dropped:
        log.warning("curves for %s have no shape in %s: dropped", list_names(dropped), rig.source)
    w = np.zeros((values.shape[0], rig.n_shapes))
    for n in shared:
        w[:, rig.index(n)] = values[:, names.index(n)]
    if (w < -1e-6).any() or (w > 1 + 1e-6).any():
        log.warning("some weights of %s are outside [0, 1]; applied as they are", cp)
    delivered = deliverable_curves(rig.names, w, rate=rate, fps=fps, key_tolerance=key_tolerance, head_motion=head)
    prov = provenance("solve --apply", options={"fps": fps, "key_tolerance": key_tolerance},
                      inputs={"curves": curves, "mesh": mesh, "shapes": shapes if shapes and Path(shapes).is_file() else None})
    start_out = int(round(start * delivered.rate / rate))
    with StagedOutputs() as staged:
        res = write_deliverables(delivered, rig, regions, output=outs["-o"], csv=outs.get("--csv"),
                                 livelink=outs.get("--livelink"), livelink_fill_zeros=livelink_fill_zeros,
                                 start_frame=start_out, prov=prov, report={"appliedFrom": cp.name, "dropped": dropped},
                                 staged=staged)
        staged.commit()
    seconds = time.perf_counter() - t0
    summary = {"output": str(outs["-o"]), "frames": int(delivered.values.shape[0]), "rate": delivered.rate,
               "shared": shared, "dropped": dropped, "unanimated": [n for n in rig.names if n not in names],
               "headMotion": head is not None, "seconds": round(seconds, 3), **res}
    summary["_text"] = [f"wrote {outs['-o']}: {len(shared)} of {len(names)} curves applied to {rig.source} "
                        f"({rig.n_shapes} shapes), {summary['frames']} frames at {delivered.rate:g} fps"] + \
        ([f"  dropped (no such shape): {', '.join(dropped)}"] if dropped else [])
    return summary


def solve_shot(mesh_path, capture_path, binding_path, out_dir, *, shapes=None, mesh_units=None, fps=None,
               key_tolerance=None, head_motion=True, livelink=False, livelink_fill_zeros=False,
               files=("blendshapes.usdc", "shot_blendshapes.usda", "curves.csv"), **solver_options) -> dict:
    """The blend-shape step of ``usdface run --output-kind blendshapes``.

    Parameters
    ----------
    mesh_path, capture_path, binding_path : paths
        The mesh, capture and binding layers ``run`` wrote (the capture conditioned, the binding
        made on that mesh).
    out_dir : path
        Where ``files`` go: the curves layer, a shot stage composing it with the binding layer
        (markers shown with the face; None: not written, the summary's ``shotStage`` says its
        rate and range), and the curves CSV; ``livelink=True`` adds ``curves_livelink.csv``.
    shapes : path, optional
        The rig's shapes (``.npz``, folder of OBJs, or a USD rig matching the mesh); None when
        ``mesh_path`` itself has blend shapes.

    Time codes start at the capture layer's start frame (``run`` writes it from 0, or from its
    ``--start-frame``: decision D2).

    Returns
    -------
    dict
        The summary (as :func:`solve`'s), with ``files``.
    """
    from ..blendshape.take import deliverable_curves, solve_take
    from ..fileutil import StagedOutputs
    from ..usd.analysis_layer import write_shot_stage
    from ..usd.capture_layer import read_capture_layer
    from ..usd.layers import open_stage, provenance
    from ..usd.mesh_layer import read_binding

    t0 = time.perf_counter()
    opts = {**solver_defaults(), **solver_options}
    out = Path(out_dir)
    if not out.is_dir():
        raise OptionError(f"{out}: no such folder")
    curves_name, shot_name, csv_name = files
    rig, regions = load_rig(mesh_path, shapes, mesh_units=mesh_units)
    cap = read_capture_layer(capture_path)
    binding = read_binding(open_stage(binding_path, what="binding"), source=str(binding_path))
    if binding.triangle_vertices.max() >= rig.n_points:
        raise InputError(f"binding {binding_path} refers to vertex {int(binding.triangle_vertices.max())}, the rig "
                         f"{rig.source} has {rig.n_points} points")
    take = solve_take(rig, cap, binding, head_motion=head_motion, **opts)
    curves = deliverable_curves(rig.names, take.weights, rate=take.rate, fps=fps, key_tolerance=key_tolerance,
                                head_motion=take.head_motion)
    start_out = int(round(take.start_frame * curves.rate / take.rate))
    outs = {"-o": out / curves_name, "--csv": out / csv_name}
    if livelink:
        outs["--livelink"] = out / "curves_livelink.csv"
    prov = provenance("solve", options={**{k: (list(v) if isinstance(v, tuple) else v) for k, v in opts.items()},
                                        "fps": fps, "key_tolerance": key_tolerance, "head_motion": head_motion},
                      inputs={"mesh": mesh_path, "capture": capture_path, "binding": binding_path,
                              "shapes": shapes if shapes and Path(shapes).is_file() else None})
    summary = _summary(take, curves, rig, binding, outs, {})
    report = {k: summary[k] for k in ("residualMean", "stillResidualMean", "iterations", "mirror", "excludedShapes")}
    n = curves.values.shape[0]
    with StagedOutputs() as staged:
        res = write_deliverables(curves, rig, regions, output=outs["-o"], csv=outs["--csv"],
                                 livelink=outs.get("--livelink"), livelink_fill_zeros=livelink_fill_zeros,
                                 start_frame=start_out, prov=prov, report=report, staged=staged)
        # the shot names the final files (relative paths): written last, after the layers exist
        staged.commit()
    summary["shotStage"] = {"rate": curves.rate, "start": start_out, "end": start_out + n - 1, "units": rig.units,
                            "stabilizedCapture": cap.head_motion is not None and take.head_motion is None}
    if shot_name is not None:  # (`run` writes the shot itself, with the record of the whole commit)
        write_shot_stage(out / shot_name, layers=[outs["-o"], Path(binding_path)], rate=curves.rate, start=start_out,
                         end=start_out + n - 1, units=rig.units,
                         stabilized_capture=cap.head_motion is not None and take.head_motion is None)
        res["files"]["shot"] = str(out / shot_name)
    summary.update(res)
    summary["seconds"] = round(time.perf_counter() - t0, 3)
    summary["_text"] = _text(summary, outs)
    return summary


# -- CLI ----------------------------------------------------------------------------------------

#: options of `usdface run` that `solve` takes too (capture conditioning, binding, head motion)
_RUN_OPTIONS = ("units", "rate", "up_axis", "stabilize", "fill_gaps", "filter", "cutoff", "trim", "start_frame",
                "resample", "neutral", "allow", "keep_zeros", "drop_outliers", "retarget", "layout", "auto",
                "mesh_units", "head_motion")


def register_cli(sub) -> None:
    """Add `usdface solve` to the CLI."""
    from ..cliargs import add_common_options, add_options
    from ..options import RunOptions, SolveOptions

    p = sub.add_parser("solve", help="marker capture -> blend-shape weight curves on a rig (CURVES.usdc, CSV)",
                       description="Solve a capture's stabilised marker motion as blend-shape weights in [0, 1] for "
                                   "every frame of the take at once (smooth, sparse, left/right prior on mirrored "
                                   "pairs); write one layer with the mesh, its BlendShape prims and a UsdSkel "
                                   "animation that imports alone in DCCs. --apply plays curves on another rig.")
    p.add_argument("--mesh", required=True,
                   help="a USD mesh with UsdSkel blend shapes, or a neutral mesh (OBJ, USD...) given with --shapes")
    p.add_argument("--capture", help="capture (Maya ASCII, C3D, TRC, CSV or a capture layer)")
    p.add_argument("--apply", metavar="CURVES.csv|CURVES.usdc",
                   help="instead of solving: apply these curves to --mesh (shapes matched by name)")
    groups = add_options(p, RunOptions, only=set(_RUN_OPTIONS))
    add_options(p, SolveOptions, groups=groups)
    g = p.add_argument_group("outputs")
    g.add_argument("--csv", metavar="CURVES.csv", help="also write the curves as CSV: frame,time,<shape names>")
    g.add_argument("--livelink", dest="livelink_csv", metavar="FILE.csv",
                   help="also write the Live Link Face CSV layout (ARKit names)")
    g.add_argument("--corrective", nargs="?", const=True, metavar="POINTS.usdc",
                   help="also write a points shot: the rig's pose plus the RBF transfer of the residual (markers hit "
                        "exactly); default name <output>_corrective.usdc")
    p.add_argument("-o", "--output", required=True, help="curves layer to write (.usdc)")
    add_common_options(p)
    p.set_defaults(func=_cmd_solve)


def _cmd_solve(args) -> dict:
    from ..cliargs import options_from_args
    from ..options import CaptureOptions, RunOptions

    o = options_from_args(RunOptions, args)
    curves_out = dict(shapes=o.shapes, mesh_units=o.mesh_units, csv=args.csv, livelink=args.livelink_csv,
                      livelink_fill_zeros=o.livelink_fill_zeros, fps=o.fps, key_tolerance=o.key_tolerance)
    if args.apply is not None:
        extra = [flag for flag, given in (("--capture", args.capture), ("--layout", o.layout), ("--auto", o.auto),
                                          ("--corrective", args.corrective)) if given]
        if extra:
            raise OptionError(f"--apply plays existing curves: {', '.join(extra)} do not apply")
        return apply_curves(args.apply, args.mesh, args.output, **curves_out)
    if args.capture is None:
        raise OptionError("solve: give --capture CAPTURE (or --apply CURVES to play curves on a rig)")
    return solve(args.mesh, args.capture, args.output, layout=o.layout, auto=bool(o.auto),
                 corrective=args.corrective, head_motion=o.head_motion, retarget=o.retarget, **curves_out,
                 **o.group(CaptureOptions).to_dict(), **o.solver_kwargs())
