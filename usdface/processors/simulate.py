"""`usdface simulate`: an expression preset (ramped 0 -> 1, as in seed 001) or a contraction timeline
simulated on the layered tissue model -> animation layer (.usdc), with a shot stage beside it."""
from __future__ import annotations

import time

import numpy as np

from ..errors import OptionError
from ..options import SimulateOptions
from ..registry import Result
from ..usd.layers import check_output_path, provenance

#: frames simulated between two saves of the animation layer
_CHUNK = 48


def simulate(mesh_path, rig_path, *, options: SimulateOptions, output) -> Result:
    """Simulate an expression preset or a contraction timeline and write an animation layer.

    The layer (``output``) stands alone (it sublayers the rig and the mesh); beside it,
    ``<stem>_shot.usda`` is the shot stage to open (:func:`usdface.usd.muscle_layer.shot_path_for`;
    none for an in-memory output). Time codes are frame numbers from 0: a timeline's keys stay at
    their frames, and before its first key the timeline holds the first key's values.

    The summary gives frames, steps, wall time, whether the last frame is at equilibrium, the
    energy, the volume change, and the displacement of facial landmarks at the last frame.
    """
    from ..progress import progress
    from ..tissue.animation import ControlSamples
    from ..tissue.simulation import build_simulator
    from ..usd.identity import identity
    from ..usd.muscle_layer import read_rig_layer, write_tissue_animation_layer, write_tissue_shot
    from ..usd.tissue_inputs import check_rig_mesh, load_tissue_mesh

    out = check_output_path(output, suffixes=(".usdc", ".usd"),
                            inputs={"--mesh": mesh_path, "--rig": rig_path, "--timeline": options.timeline})
    if (options.expression is None) == (options.timeline is None):
        raise OptionError("simulate: give exactly one of --expression NAME or --timeline T.json")
    t0 = time.perf_counter()
    mesh, regions = load_tissue_mesh(mesh_path)
    on_mesh = check_rig_mesh(rig_path, mesh_path, mesh)
    rig = read_rig_layer(rig_path, units=mesh.units)
    sim = build_simulator(mesh, regions, rig, integrator=options.integrator, dt=options.dt,
                          tissue=options.tissue_settings())
    tl = _timeline(options, rig)
    frames, contr, jaw = tl.sample(rig.names)
    n = frames.size
    energy = []
    prov = provenance("simulate", options={"expression": options.expression, "integrator": options.integrator,
                                           "dt": sim.dt, "rate": tl.rate, "ramp": options.ramp, "hold": options.hold,
                                           "intensity": options.intensity, "tissue": sim.model.options.to_dict()},
                      inputs={"mesh": mesh_path, "rig": rig_path, "timeline": options.timeline},
                      identity=identity(mesh=on_mesh))  # no take: a timeline or a preset drives it
    controls = ControlSamples(time_codes=frames, rate=tl.rate, muscle_names=rig.names, contractions=contr, jaw=jaw)
    bar = progress(total=n, desc="simulate", unit="frame")
    try:
        write_tissue_animation_layer(out, _simulated_chunks(sim, tl, frames, energy), mesh_path=mesh_path,
                                     rig_path=rig_path, mesh=mesh, controls=controls, prov=prov, progress=bar)
    finally:
        bar.close()
    shot = write_tissue_shot(out, [out], rate=tl.rate, start=float(frames[0]), end=float(frames[-1]),
                             units=mesh.units, processor="simulate")
    summary = _summary(sim, mesh, rig, tl.rate, energy)
    summary = {"output": str(out), "shot": shot, "frames": int(n), "rate": tl.rate, "integrator": options.integrator,
               "dt": sim.dt, "steps": int(sim.steps), "seconds": time.perf_counter() - t0, **summary}
    return Result(layers={"output": out}, summary=summary, text=_text(summary, sim, mesh.units))


def _timeline(options: SimulateOptions, rig):
    """The expression preset's timeline (ramped, held) or the timeline file's, checked against the rig."""
    from ..tissue.expressions import expression_timeline, read_timeline

    if options.expression is not None:
        tl = expression_timeline(options.expression, rig.names, rate=options.rate, ramp_frames=options.ramp,
                                 hold_frames=options.hold, intensity=options.intensity)
    else:
        tl = read_timeline(options.timeline)
    tl.check_names(rig.names, has_jaw=True)
    return tl


def _simulated_chunks(sim, tl, frames, energy: list):
    """``(frames slice, skin points (f, N, 3))`` blocks of the simulated timeline; the total energy
    of every frame is appended to ``energy``."""
    from ..tissue.animation import animate

    n = frames.size
    it = animate(sim, tl, frames=frames)
    done = 0
    while done < n:
        block = []
        for _ in range(min(_CHUNK, n - done)):
            _, skin = next(it)
            energy.append(sim.energy()["total"])
            block.append(skin)
        yield slice(done, done + len(block)), np.stack(block)
        done += len(block)


def _summary(sim, mesh, rig, rate: float, energy: list) -> dict:
    """How still the last frame is, the displacements and the volume change (the summary's
    simulation part)."""
    from ..tissue.simulation import landmark_vertices, volume_stats

    # how still is the last frame: the net motion over one more frame interval
    before = sim.skin()
    sim.advance(1.0 / rate)
    drift = float(np.linalg.norm(sim.skin() - before, axis=1).max()) * rate / sim.model.length_scale
    disp = before - mesh.points
    lmv = landmark_vertices(mesh, rig)
    return {"springs": sim.model.n_springs, "elements": sim.model.n_elements, "finalSpeedCmPerS": drift,
            "atEquilibrium": drift < 0.05, "energyMax": float(max(energy)), "energyFinal": float(energy[-1]),
            "maxDisplacement": float(np.linalg.norm(disp, axis=1).max()), "volumeChange": volume_stats(sim),
            "landmarks": {k: [float(c) for c in disp[v]] for k, v in lmv.items()}}


def _text(summary: dict, sim, units) -> list:
    u = units or "units"
    vol, drift = summary["volumeChange"], summary["finalSpeedCmPerS"]
    shot = f"; shot stage {summary['shot']}" if summary["shot"] is not None else ""
    return [
        f"wrote {summary['output']}: {summary['frames']} frames at {summary['rate']:g} fps ({summary['integrator']} "
        f"Euler, dt {sim.dt:.4g} s, {sim.steps} steps, {summary['seconds']:.1f} s){shot}",
        f"  model: {sim.model.n_springs} springs, {sim.model.n_elements} prism elements; max displacement "
        f"{summary['maxDisplacement']:.2f} {u}; last frame "
        f"{'at equilibrium' if summary['atEquilibrium'] else 'moving'} ({drift:.3f} cm/s)",
        f"  volume change: skin prisms max {vol['skin']['maxAbs']:.1%} (p99 {vol['skin']['p99']:.1%}), bound "
        f"elements max {vol['element']['maxAbs']:.1%} (p99 {vol['element']['p99']:.1%})",
    ]
