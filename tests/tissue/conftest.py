"""Shared fixtures of the tissue tests: the two sample faces, their models and rigs, and one run of
every expression preset on each (session scoped: the presets are simulated once per test run)."""
from __future__ import annotations

import logging
import time
from dataclasses import dataclass

import numpy as np
import pytest

from usdface.io.meshes import read_mesh
from usdface.model.mesh import FaceMesh
from usdface.mesh.topology import find_hole_regions
from usdface.tissue.animation import animate
from usdface.tissue.expressions import PRESET_NAMES, expression_timeline
from usdface.tissue.integrators import Simulator
from usdface.tissue.model import build_tissue_model
from usdface.tissue.muscles import compile_muscles
from usdface.tissue.rig import default_rig

MESHES = {"realistic": "makehuman_hm08_face_cm.obj", "stylized": "makehuman_hm08_face_stylized_cm.obj"}


@dataclass
class Face:
    name: str
    mesh: FaceMesh
    regions: list
    rig: object
    model: object
    jaw: object
    muscles: object

    def simulator(self, **kw) -> Simulator:
        return Simulator(self.model, self.muscles, jaw=self.jaw, **kw)


def make_face(name, path) -> Face:
    mesh = read_mesh(path)
    regions = find_hole_regions(mesh)
    rig = default_rig(mesh, regions)
    model = build_tissue_model(mesh, regions=regions)
    jaw = rig.jaw_for(model.mesh, regions)
    return Face(name, mesh, regions, rig, model, jaw, compile_muscles(model, rig.muscles, jaw=jaw))


@pytest.fixture(scope="session")
def faces(sample_assets) -> dict:
    # quiet while the rigs are built, then the level back: tests elsewhere read usdface's warnings
    log = logging.getLogger("usdface")
    level = log.level
    log.setLevel(logging.ERROR)
    try:
        return {k: make_face(k, sample_assets / "meshes" / v) for k, v in MESHES.items()}
    finally:
        log.setLevel(level)


@pytest.fixture(scope="session")
def face(faces) -> Face:
    return faces["realistic"]


def grid_mesh(n=4, *, spacing=1.0, bulge=0.3, units="cm") -> FaceMesh:
    """An n x n vertex quad grid bulging toward +z (a tiny face-like patch)."""
    x, y = np.meshgrid(np.arange(n, dtype=float), np.arange(n, dtype=float))
    x, y = x * spacing, y * spacing
    c = (n - 1) * spacing / 2
    z = bulge * (1.0 - ((x - c) ** 2 + (y - c) ** 2) / (2 * c * c))
    pts = np.stack([x.ravel(), y.ravel(), z.ravel()], axis=1)
    i, j = np.meshgrid(np.arange(n - 1), np.arange(n - 1))
    v0 = (j * n + i).ravel()
    quads = np.stack([v0, v0 + 1, v0 + n + 1, v0 + n], axis=1)
    return FaceMesh(points=pts, face_vertex_counts=np.full(len(quads), 4), face_vertex_indices=quads.ravel(),
                    units=units, name="grid")


@dataclass
class PresetRun:
    converged: bool
    energy: np.ndarray          # total energy per animated frame, then per settle check
    final_energy: float
    displacement: np.ndarray    # (N, 3) skin displacement at equilibrium
    volume: dict
    seconds: float
    steps: int


@pytest.fixture(scope="session")
def preset_runs(faces) -> dict:
    """Every preset on both faces at the default (implicit) step: ramp 0 -> 1 over 3 frames at 24 fps
    (as in the paper), then held until the tissue is still. {(face, preset): PresetRun}."""
    from usdface.tissue.simulation import volume_stats

    out = {}
    for fname, f in faces.items():
        sim = f.simulator()
        for preset in PRESET_NAMES:
            sim.reset()
            t0, s0 = time.perf_counter(), sim.steps
            tl = expression_timeline(preset, f.rig.names, ramp_frames=3, hold_frames=0)
            energy = []
            for _ in animate(sim, tl):
                energy.append(sim.energy()["total"])
            rep = sim.run_to_equilibrium(max_time=3.0, tol=0.1)
            energy.append(sim.energy()["total"])
            out[fname, preset] = PresetRun(rep.converged, np.asarray(energy), energy[-1], sim.skin() - f.mesh.points,
                                           volume_stats(sim), time.perf_counter() - t0, sim.steps - s0)
    return out
