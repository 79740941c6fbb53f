"""`usdface muscles`, `usdface simulate`, `usdface fit-muscles`: the muscle-driven tissue model.

- ``muscles``: a default rig of named anatomical muscles placed on a face (from its hole loops and
  surface, or from marker positions of a layout/binding, or warped from another face's rig)
  -> rig layer (.usda);
- ``simulate``: an expression preset (ramped 0 -> 1, as in seed 001) or a contraction timeline
  simulated on the layered tissue model -> animation layer (.usdc);
- ``fit-muscles``: contractions fitted to captured marker motion, simulated -> animation layer.
"""
from __future__ import annotations

import json
import logging
import math
import time
from pathlib import Path

import numpy as np

from ..fileutil import refuse_overwriting_inputs
from ..errors import InputError, MarkerError, OptionError, list_names
from ..usd.layers import check_output_path, provenance

log = logging.getLogger("usdface")

#: landmark displacements reported by ``simulate``
REPORT_LANDMARKS = ("mouthCorner_L", "mouthCorner_R", "upperLip", "lowerLip", "browInner_L", "browInner_R",
                    "browOuter_L", "browOuter_R", "eyeTop_L", "eyeTop_R", "chin", "noseTip")


# -- loading ------------------------------------------------------------------------------------

def _load_mesh(path):
    """(mesh, regions) from a mesh layer or a mesh file; hole regions found when not stored."""
    from ..mesh.topology import find_hole_regions
    from .import_mesh import load_mesh

    if not Path(path).exists():
        raise InputError(f"mesh {path}: no such file")
    mesh, regions = load_mesh(path)
    if mesh.units is None:
        import dataclasses

        mesh = dataclasses.replace(mesh, units="cm")
    if not any(r.role == "mouth" for r in regions):
        regions = find_hole_regions(mesh)
    return mesh, regions


def _parse_pairs(items, *, what: str) -> dict:
    out = {}
    for item in items or ():
        if "=" not in item:
            raise OptionError(f"{what}: expected NAME=VALUE; got {item!r}")
        k, v = item.split("=", 1)
        try:
            out[k.strip()] = float(v)
        except ValueError:
            raise OptionError(f"{what}: {k.strip()} needs a number; got {v!r}") from None
    return out


def tissue_options(rig_tissue: dict | None = None, overrides: dict | None = None):
    """TissueOptions from a rig's recorded settings and command-line overrides."""
    from ..tissue.model import TissueOptions

    return TissueOptions().replace(**(rig_tissue or {})).replace(**(overrides or {}))


def build_simulator(mesh, regions, rig, *, integrator="implicit", dt=None, tissue=None, backend="auto"):
    """Model, jaw, compiled muscles and Simulator for a mesh and a rig."""
    from ..tissue.integrators import Simulator
    from ..tissue.model import build_tissue_model
    from ..tissue.muscles import compile_muscles

    opts = tissue_options(rig.tissue, tissue)
    model = build_tissue_model(mesh, opts, regions=regions)
    jaw = rig.jaw_for(model.mesh, regions)
    muscles = compile_muscles(model, rig.muscles, jaw=jaw)
    sim = Simulator(model, muscles, jaw=jaw, integrator=integrator, dt="auto" if dt is None else dt, backend=backend)
    return sim


def _marker_positions(mesh, *, layout=None, binding=None) -> dict | None:
    if layout is not None and binding is not None:
        raise OptionError("muscles: give at most one of --layout and --binding")
    if layout is not None:
        from ..mesh.layout import read_layout

        lay = read_layout(layout)
        return dict(zip(lay.names, lay.positions(mesh)))
    if binding is not None:
        from ..usd.layers import open_stage
        from ..usd.mesh_layer import read_binding

        b = read_binding(open_stage(binding, what="binding"), source=str(binding))
        return dict(zip(b.names, b.surface_points(mesh.points)))
    return None


# -- muscles ------------------------------------------------------------------------------------

def muscles(mesh_path, output, *, layout=None, binding=None, from_rig=None, forces=None, tissue=None) -> dict:
    """Place the default muscle rig on a face and write a rig layer.

    Parameters
    ----------
    mesh_path : path
        Mesh layer (from `usdface import-mesh`) or mesh file.
    output : path
        Rig layer to write (.usda).
    layout, binding : path, optional
        Marker positions on this mesh (a layout JSON or a binding layer) to place the brows, nose
        tip, chin and forehead from (otherwise from the surface).
    from_rig : path, optional
        A rig layer built on another face: warp it onto this one through both faces' landmarks
        instead of placing the default rig (keeps hand edits).
    forces : dict {base muscle name: maxForce}, optional
    tissue : dict, optional
        Tissue options to record with the rig.
    """
    from ..tissue.rig import default_rig, face_landmarks, landmark_correspondence, warp_rig
    from ..usd.muscle_layer import read_rig_layer, write_rig_layer

    out = check_output_path(output, inputs={"--mesh": mesh_path, "--layout": layout, "--binding": binding,
                                            "--from-rig": from_rig})
    t0 = time.perf_counter()
    mesh, regions = _load_mesh(mesh_path)
    markers = _marker_positions(mesh, layout=layout, binding=binding)
    tissue_options(tissue)  # validate early
    from ..tissue.rig import DEFAULT_FORCES

    bad = sorted(set(forces or {}) - set(DEFAULT_FORCES))
    if bad:
        raise OptionError(f"--force: unknown muscle(s) {list_names(bad)}; known: {list_names(sorted(DEFAULT_FORCES))}")
    if from_rig is not None:
        src = read_rig_layer(from_rig, units=mesh.units)
        if not src.landmarks:
            raise InputError(f"rig {from_rig}: records no landmarks; cannot warp it to another face")
        _, lm = face_landmarks(mesh, regions, markers=markers)
        a, b = landmark_correspondence(src, lm)
        rig = warp_rig(src, a, b, target_mesh=mesh)
        rig = rig.replace(landmarks=lm, tissue={**src.tissue, **(tissue or {})})
    else:
        rig = default_rig(mesh, regions, markers=markers, forces=forces, tissue=tissue)
    # the rig must act on this mesh: compile it once (names far muscles, empty zones)
    build_simulator(mesh, regions, rig)
    prov = provenance("muscles", options={"layout": layout is not None, "binding": binding is not None,
                                          "fromRig": from_rig is not None, "forces": forces or {},
                                          "tissue": tissue or {}},
                      inputs={"mesh": mesh_path, "layout": layout, "binding": binding, "fromRig": from_rig})
    write_rig_layer(out, rig, mesh_path=mesh_path, prov=prov)
    lin = [m.name for m in rig.muscles if m.type == "linear"]
    sph = [m.name for m in rig.muscles if m.type == "sphincter"]
    summary = {"output": str(out), "muscles": list(rig.names), "linear": len(lin), "sphincter": len(sph),
               "placement": rig.placement, "jawPivot": [float(c) for c in rig.jaw_pivot],
               "jawMaxAngle": rig.jaw_max_angle, "units": mesh.units, "seconds": time.perf_counter() - t0}
    summary["_text"] = [
        f"wrote {out}: {len(rig.muscles)} muscles ({len(lin)} linear, {len(sph)} sphincter), placed from "
        f"{rig.placement}" + (" (warped from " + str(from_rig) + ")" if from_rig else ""),
        f"  {list_names(rig.names, 30)}",
    ]
    return summary


# -- simulate -----------------------------------------------------------------------------------

def _landmark_vertices(mesh, rig) -> dict:
    from scipy.spatial import cKDTree

    tree = cKDTree(mesh.points)
    return {k: int(tree.query(v)[1]) for k, v in rig.landmarks.items() if k in REPORT_LANDMARKS}


def volume_stats(sim) -> dict:
    """Relative volume change ``(V - V0) / V0`` statistics of the current state.

    ``skin``: the epidermis-fascia prisms where the tissue has its full depth; ``element``: the
    whole three-layer elements where the tissue is also bound to the bone (attachment 1);
    ``all``: every element, including the thinned slivers at the lip and eyelid rims whose tiny
    rest volume makes relative changes large. Folded faces (inverted at rest) are left out.
    """
    model = sim.model
    t = model.n_elements
    pv = sim.prism_volume_change()
    ev = sim.volume_change()
    ok = np.ones(t, bool)
    if model.folded_faces.size:
        ok &= ~np.isin(model.mesh.triangle_faces(), model.folded_faces)
    full = ok & (model.depth[model.triangles].min(axis=1) >= 1)
    bound = full & (model.attachment[model.triangles].min(axis=1) >= 0.999)

    def st(v):
        a = np.abs(v)
        return {"min": float(v.min()), "max": float(v.max()), "p99": float(np.percentile(a, 99)),
                "maxAbs": float(a.max()), "count": int(v.size)}

    return {"skin": st(pv[:t][full]), "element": st(ev[bound]), "all": st(ev[ok])}


def simulate(mesh_path, rig_path, output, *, expression=None, timeline=None, integrator="implicit", dt=None,
             rate=24.0, ramp=12, hold=12, intensity=1.0, start_frame=0, tissue=None, backend="auto") -> dict:
    """Simulate an expression preset or a contraction timeline and write an animation layer.

    The layer (``output``) stands alone (it sublayers the rig and the mesh); beside it,
    ``<stem>_shot.usda`` is the shot stage to open (:func:`shot_path_for`). Time codes are frame
    numbers from 0: a timeline's keys stay at their frames, and before its first key the timeline
    holds the first key's values.

    Returns the summary: frames, steps, wall time, whether the last frame is at equilibrium, the
    energy, the volume change, and the displacement of facial landmarks at the last frame.
    """
    from ..progress import progress
    from ..tissue.animate import animate
    from ..tissue.expressions import expression_timeline, read_timeline
    from ..usd.muscle_layer import read_rig_layer, write_tissue_animation_layer

    out = check_output_path(output, suffixes=(".usdc", ".usd"),
                            inputs={"--mesh": mesh_path, "--rig": rig_path, "--timeline": timeline})
    if (expression is None) == (timeline is None):
        raise OptionError("simulate: give exactly one of --expression NAME or --timeline T.json")
    t0 = time.perf_counter()
    mesh, regions = _load_mesh(mesh_path)
    rig = read_rig_layer(rig_path, units=mesh.units)
    sim = build_simulator(mesh, regions, rig, integrator=integrator, dt=dt, tissue=tissue, backend=backend)
    if expression is not None:
        tl = expression_timeline(expression, rig.names, rate=rate, ramp_frames=ramp, hold_frames=hold,
                                 intensity=intensity, start_frame=start_frame)
    else:
        tl = read_timeline(timeline)
    tl.check_names(rig.names, has_jaw=True)
    frames, contr, jaw = tl.sample(rig.names)
    n = frames.size
    energy = []
    bar = progress(total=n, desc="simulate", unit="frame")

    def chunks():
        it = animate(sim, tl, frames=frames)
        done = 0
        while done < n:
            block = []
            for _ in range(min(48, n - done)):
                _, skin = next(it)
                energy.append(sim.energy()["total"])
                block.append(skin)
            yield slice(done, done + len(block)), np.stack(block)
            done += len(block)

    prov = provenance("simulate", options={"expression": expression, "integrator": integrator, "dt": sim.dt,
                                           "rate": tl.rate, "ramp": ramp, "hold": hold, "intensity": intensity,
                                           "tissue": sim.model.options.to_dict()},
                      inputs={"mesh": mesh_path, "rig": rig_path, "timeline": timeline})
    try:
        write_tissue_animation_layer(out, chunks(), mesh_path=mesh_path, rig_path=rig_path,
                                     rest_points=sim.model.mesh.points, start=float(frames[0]), rate=tl.rate,
                                     n_frames=n, units=mesh.units, muscle_names=rig.names, contractions=contr,
                                     jaw=jaw, prov=prov, time_codes=frames, progress=bar, mesh=mesh)
    finally:
        bar.close()
    shot = _write_tissue_shot(out, [out], rate=tl.rate, start=float(frames[0]), end=float(frames[-1]),
                              units=mesh.units)
    # how still is the last frame: the net motion over one more frame interval
    before = sim.skin()
    sim.advance(1.0 / tl.rate)
    drift = float(np.linalg.norm(sim.skin() - before, axis=1).max()) * tl.rate / sim.model.length_scale
    skin = before
    disp = skin - mesh.points
    lmv = _landmark_vertices(mesh, rig)
    vol = volume_stats(sim)
    summary = {
        "output": str(out), "shot": shot, "frames": int(n), "rate": tl.rate, "integrator": integrator, "dt": sim.dt,
        "steps": int(sim.steps), "seconds": time.perf_counter() - t0, "springs": sim.model.n_springs,
        "elements": sim.model.n_elements, "finalSpeedCmPerS": drift, "atEquilibrium": drift < 0.05,
        "energyMax": float(max(energy)), "energyFinal": float(energy[-1]),
        "maxDisplacement": float(np.linalg.norm(disp, axis=1).max()), "volumeChange": vol,
        "landmarks": {k: [float(c) for c in disp[v]] for k, v in lmv.items()},
    }
    u = mesh.units or "units"
    summary["_text"] = [
        f"wrote {out}: {n} frames at {tl.rate:g} fps ({integrator} Euler, dt {sim.dt:.4g} s, {sim.steps} steps, "
        f"{summary['seconds']:.1f} s); shot stage {shot}",
        f"  model: {sim.model.n_springs} springs, {sim.model.n_elements} prism elements; max displacement "
        f"{summary['maxDisplacement']:.2f} {u}; last frame {'at equilibrium' if summary['atEquilibrium'] else 'moving'} "
        f"({drift:.3f} cm/s)",
        f"  volume change: skin prisms max {vol['skin']['maxAbs']:.1%} (p99 {vol['skin']['p99']:.1%}), bound "
        f"elements max {vol['element']['maxAbs']:.1%} (p99 {vol['element']['p99']:.1%})",
    ]
    return summary


def shot_path_for(output) -> Path:
    """The shot stage written beside a simulate / fit-muscles layer: ``<stem>_shot.usda``."""
    out = Path(output)
    return out.with_name(f"{out.stem}_shot.usda")


def _write_tissue_shot(output, layers, *, rate, start, end, units, stabilized_capture=False) -> str:
    from ..usd.analysis_layer import write_shot_stage

    shot = shot_path_for(output)
    write_shot_stage(shot, layers=list(layers), rate=rate, start=start, end=end, units=units,
                     stabilized_capture=stabilized_capture)
    return str(shot)


# -- fit-muscles --------------------------------------------------------------------------------

def capture_displacements(capture, binding, *, stabilize="auto"):
    """Marker displacements from the neutral frame in mesh space, in the binding's marker order.

    Returns (displacements (F, M, 3), capture used).
    """
    if stabilize not in ("auto", "none"):
        raise OptionError(f"stabilize must be 'auto' or 'none'; got {stabilize!r}")
    missing = [n for n in binding.names if n not in capture.names]
    if missing:
        raise MarkerError(f"binding markers not in the capture: {list_names(missing)}; capture has "
                          f"{list_names(capture.names)}")
    if stabilize == "auto" and capture.head_motion is None:
        from ..capture.stabilize import stabilize as stabilize_fn

        capture, _ = stabilize_fn(capture)
    idx = [capture.names.index(n) for n in binding.names]
    pos = capture.positions[:, idx]
    disp = pos - pos[capture.neutral_frame]
    return disp @ binding.displacement_transform().T, capture


def fit_muscles(mesh_path, rig_path, capture_path, binding_path, output, *, step=1, refine=2, regularization=1e-3,
                stabilize="auto", integrator="implicit", tissue=None, report=None, frames=None) -> dict:
    """Fit muscle contractions to a capture and write the simulated animation layer.

    Parameters
    ----------
    step : int
        Fit every ``step``-th capture frame (the layer keeps the capture's time codes).
    refine : int
        Refinement passes by simulation.
    frames : (int, int), optional
        Capture frame indices [first, last) to fit.
    report : path, optional
        JSON file with the fitted contractions per frame and the error statistics.
    """
    from ..progress import progress
    from ..tissue.fit import fit_sequence, linear_response
    from ..usd.capture_layer import read_capture_layer
    from ..usd.layers import open_stage
    from ..usd.mesh_layer import read_binding
    from ..usd.muscle_layer import read_rig_layer, write_tissue_animation_layer

    inputs = {"--mesh": mesh_path, "--rig": rig_path, "--capture": capture_path, "--binding": binding_path}
    out = check_output_path(output, suffixes=(".usdc", ".usd"), inputs=inputs)
    refuse_overwriting_inputs({"--report": report}, inputs)
    if int(step) < 1:
        raise OptionError(f"--step must be >= 1; got {step}")
    t0 = time.perf_counter()
    mesh, regions = _load_mesh(mesh_path)
    rig = read_rig_layer(rig_path, units=mesh.units)
    capture = read_capture_layer(capture_path)
    binding = read_binding(open_stage(binding_path, what="binding"), source=str(binding_path))
    disp, capture = capture_displacements(capture, binding, stabilize=stabilize)
    sel = np.arange(disp.shape[0])
    if frames is not None:
        a, b = int(frames[0]), int(frames[1])
        if not 0 <= a < b <= disp.shape[0]:
            raise OptionError(f"--frames {a} {b}: outside the capture's 0..{disp.shape[0]}")
        sel = sel[a:b]
    sel = sel[::int(step)]
    disp = disp[sel]
    sim = build_simulator(mesh, regions, rig, integrator=integrator, tissue=tissue)
    rate = capture.rate / int(step)
    resp = linear_response(sim, binding.triangle_vertices, binding.barycentrics)
    bar = progress(total=(refine + 1) * len(sel), desc="fit-muscles", unit="frame")
    try:
        res = fit_sequence(sim, binding.triangle_vertices, binding.barycentrics, disp, rate=rate,
                           marker_names=binding.names, regularization=regularization, refine=refine, response=resp,
                           progress=bar)
    finally:
        bar.close()
    names = list(res.names)
    muscle_idx = [names.index(n) for n in rig.names]
    contr = res.controls[:, muscle_idx]
    jaw = res.controls[:, names.index("jawOpen")] if "jawOpen" in names else np.zeros(len(sel))
    codes = capture.start_frame + sel.astype(np.float64)
    prov = provenance("fit-muscles", options={"step": step, "refine": refine, "regularization": regularization,
                                              "stabilize": stabilize, "integrator": integrator, "frames": frames,
                                              "tissue": sim.model.options.to_dict()},
                      inputs={"mesh": mesh_path, "rig": rig_path, "capture": capture_path, "binding": binding_path})
    skin = res.skin

    def chunks():
        for s in range(0, len(sel), 64):
            e = min(s + 64, len(sel))
            yield slice(s, e), skin[s:e]

    write_tissue_animation_layer(out, chunks(), mesh_path=mesh_path, rig_path=rig_path,
                                 rest_points=sim.model.mesh.points, start=float(codes[0]), rate=capture.rate,
                                 n_frames=len(sel), units=mesh.units, muscle_names=rig.names, contractions=contr,
                                 jaw=jaw, prov=prov, time_codes=codes, mesh=mesh)
    # the shot adds the binding layer: the captured markers beside the simulated face
    shot = _write_tissue_shot(out, [out, binding_path], rate=capture.rate, start=float(codes[0]),
                              end=float(codes[-1]), units=mesh.units, stabilized_capture=capture.head_motion is not None)
    final = res.errors[f"pass{refine + 1}"]
    summary = {"output": str(out), "shot": shot, "frames": int(len(sel)), "rate": rate, "errors": res.errors,
               "perMarkerRms": res.per_marker, "meanContraction": dict(zip(names, res.controls.mean(axis=0).tolist())),
               "maxContraction": dict(zip(names, res.controls.max(axis=0).tolist())),
               "seconds": time.perf_counter() - t0, "capture": str(capture_path)}
    if report is not None:
        data = {k: v for k, v in summary.items()}
        data["controls"] = {"names": names, "timeCodes": codes.tolist(), "values": np.round(res.controls, 5).tolist()}
        Path(report).write_text(json.dumps(data, indent=1, default=float) + "\n", encoding="utf-8")
    u = mesh.units or "units"
    worst = sorted(res.per_marker.items(), key=lambda kv: -kv[1] if math.isfinite(kv[1]) else 0)[:4]
    summary["_text"] = [
        f"wrote {out}: {len(sel)} frames fitted ({names.__len__()} controls, {refine} refinement pass(es), "
        f"{summary['seconds']:.1f} s); shot stage {shot}",
        f"  marker error RMS {final['rms']:.3f} {u} (median {final['median']:.3f}, p95 {final['p95']:.3f}); "
        f"a still face: RMS {res.errors['still']['rms']:.3f} {u}; linear fit: {res.errors['linear']['rms']:.3f} {u}",
        "  worst markers: " + ", ".join(f"{k} {v:.2f}" for k, v in worst),
    ]
    return summary


# -- contact sheet ------------------------------------------------------------------------------

def preset_contact_sheet(mesh_paths, output, *, presets=None, size=(360, 420), integrator="implicit") -> dict:
    """Render every preset's final pose on each mesh into one PNG (rows: meshes, columns: presets)."""
    from ..preview import Camera, contact_sheet, render_mesh, write_png
    from ..tissue.animate import animate
    from ..tissue.expressions import PRESET_NAMES, expression_timeline
    from ..tissue.rig import default_rig

    presets = list(presets or PRESET_NAMES)
    images, captions = [], []
    for mp in mesh_paths:
        mesh, regions = _load_mesh(mp)
        rig = default_rig(mesh, regions)
        sim = build_simulator(mesh, regions, rig, integrator=integrator)
        cam = Camera.fit(mesh.points, view="front", size=size)
        for name in presets:
            sim.reset()
            for _ in animate(sim, expression_timeline(name, rig.names)):
                pass
            images.append(render_mesh(sim.skin(), mesh.triangles(), camera=cam, title=name))
            captions.append(f"{Path(mp).stem} {name}")
    write_png(output, contact_sheet(images, captions, columns=len(presets),
                                    title="usdface tissue presets (seed 001 section 5)"))
    return {"output": str(output), "images": len(images)}


# -- command line -------------------------------------------------------------------------------

def register_cli(sub) -> None:
    """Add the ``muscles``, ``simulate`` and ``fit-muscles`` subcommands."""
    from ..cliargs import add_common_options
    from ..tissue.expressions import PRESET_NAMES
    from ..options import INTEGRATORS

    p = sub.add_parser("muscles", help="place the default muscle rig on a face -> rig layer (.usda)",
                       description="Place a rig of named anatomical muscles (zygomaticMajor_L, frontalisInner_R, "
                                   "orbicularisOris, ...) on a face from its eye and mouth loops and surface, or "
                                   "from marker positions; or warp another face's rig onto it.")
    p.add_argument("--mesh", required=True, help="mesh layer (from import-mesh) or mesh file")
    src = p.add_mutually_exclusive_group()
    src.add_argument("--layout", help="marker layout JSON: place brows, nose tip, chin, forehead from its markers")
    src.add_argument("--binding", help="binding layer: the same, from the bound markers")
    p.add_argument("--from-rig", metavar="RIG", help="warp this rig (built on another face) onto the mesh")
    p.add_argument("--force", action="append", metavar="MUSCLE=F",
                   help="maximum force of a muscle (base name, both sides), e.g. zygomaticMajor=30000")
    p.add_argument("--tissue", action="append", metavar="KEY=VALUE",
                   help="tissue option recorded with the rig (e.g. fascia_depth=0.4, k_deep=25)")
    p.add_argument("-o", "--output", required=True, help="rig layer to write (.usda)")
    add_common_options(p)
    p.set_defaults(func=lambda a: muscles(a.mesh, a.output, layout=a.layout, binding=a.binding, from_rig=a.from_rig,
                                          forces=_parse_pairs(a.force, what="--force"),
                                          tissue=_parse_pairs(a.tissue, what="--tissue")))

    p = sub.add_parser("simulate", help="simulate an expression or contraction timeline -> animation layer (.usdc)",
                       description="Simulate the layered mass-spring tissue model driven by the rig's muscles: an "
                                   "expression preset ramped from 0 to 1, or a timeline JSON "
                                   '({"rate": 24, "keys": {"zygomaticMajor_L": [[frame, contraction], ...]}}).')
    p.add_argument("--mesh", required=True, help="mesh layer or mesh file")
    p.add_argument("--rig", required=True, help="rig layer (from `usdface muscles`)")
    what = p.add_mutually_exclusive_group(required=True)
    what.add_argument("--expression", choices=PRESET_NAMES, help="expression preset")
    what.add_argument("--timeline", help="contraction timeline JSON")
    p.add_argument("--integrator", choices=INTEGRATORS, default="implicit",
                   help="implicit (stable, default), explicit (the paper's forward Euler) or symplectic Euler")
    p.add_argument("--dt", type=float, help="integration step in seconds (default: implicit 1/240; explicit "
                                            "and symplectic half their estimated stability limit)")
    p.add_argument("--rate", type=float, default=24.0, help="frames per second of an expression (default 24)")
    p.add_argument("--ramp", type=int, default=12, help="frames of the 0 -> 1 ramp of an expression (default 12)")
    p.add_argument("--hold", type=int, default=12, help="frames the expression is held after the ramp (default 12)")
    p.add_argument("--intensity", type=float, default=1.0, help="scale of the preset's contractions, 0..1")
    p.add_argument("--tissue", action="append", metavar="KEY=VALUE", help="override a tissue option")
    p.add_argument("-o", "--output", required=True,
                   help="animation layer to write (.usdc; stands alone); X_shot.usda is written beside it")
    add_common_options(p)
    p.set_defaults(func=lambda a: simulate(a.mesh, a.rig, a.output, expression=a.expression, timeline=a.timeline,
                                           integrator=a.integrator, dt=a.dt, rate=a.rate, ramp=a.ramp, hold=a.hold,
                                           intensity=a.intensity, tissue=_parse_pairs(a.tissue, what="--tissue")))

    p = sub.add_parser("fit-muscles", help="fit muscle contractions to captured markers -> animation layer (.usdc)",
                       description="Fit per-frame contractions in [0, 1] (and the jaw opening) that best reproduce "
                                   "the captured marker motion: bounded least squares on the model's linearised "
                                   "response, refined by simulation; write the simulated animation.")
    p.add_argument("--mesh", required=True, help="mesh layer or mesh file")
    p.add_argument("--rig", required=True, help="rig layer")
    p.add_argument("--capture", required=True, help="capture layer (from import-capture)")
    p.add_argument("--binding", required=True, help="binding layer (from bind) of this capture on this mesh")
    p.add_argument("--step", type=int, default=1, help="fit every N-th capture frame (default 1)")
    p.add_argument("--frames", type=int, nargs=2, metavar=("FIRST", "END"), help="capture frames FIRST..END-1 only")
    p.add_argument("--refine", type=int, default=2, help="refinement passes by simulation (default 2)")
    p.add_argument("--regularization", type=float, default=1e-3, help="Tikhonov weight of the fit (default 1e-3)")
    p.add_argument("--stabilize", choices=["auto", "none"], default="auto",
                   help="remove head motion first when the capture layer is not stabilised (default auto)")
    p.add_argument("--report", help="JSON file with the fitted contractions and error statistics")
    p.add_argument("-o", "--output", required=True,
                   help="animation layer to write (.usdc; stands alone); X_shot.usda (with the markers) is written "
                        "beside it")
    add_common_options(p)
    p.set_defaults(func=lambda a: fit_muscles(a.mesh, a.rig, a.capture, a.binding, a.output, step=a.step,
                                              refine=a.refine, regularization=a.regularization,
                                              stabilize=a.stabilize, report=a.report, frames=a.frames))
