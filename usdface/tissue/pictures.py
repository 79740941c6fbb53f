"""Pictures of the tissue model: every expression preset's held pose on one or more faces."""
from __future__ import annotations

import numpy as np

__all__ = ["preset_poses", "preset_contact_sheet"]


def preset_poses(mesh, regions, presets=None, *, integrator: str = "implicit") -> dict:
    """Each preset ramped in and held (:func:`usdface.tissue.expressions.expression_timeline`'s
    defaults) with the default rig on ``mesh``: ``{preset: skin points (N, 3)}`` at its last frame.

    Parameters
    ----------
    mesh : FaceMesh
        The face (units set).
    regions : list of Region
        Its hole regions.
    presets : sequence of str, optional
        Preset names (default :data:`usdface.tissue.expressions.PRESET_NAMES`).
    integrator : {"explicit", "symplectic", "implicit"}
    """
    from .animation import animate
    from .expressions import PRESET_NAMES, expression_timeline
    from .rig import default_rig
    from .simulation import build_simulator

    rig = default_rig(mesh, regions)
    sim = build_simulator(mesh, regions, rig, integrator=integrator)
    poses = {}
    for name in presets or PRESET_NAMES:
        sim.reset()
        for _ in animate(sim, expression_timeline(name, rig.names)):
            pass
        poses[name] = sim.skin()
    return poses


def preset_contact_sheet(faces, *, presets=None, size=(360, 420), integrator: str = "implicit") -> np.ndarray:
    """Every preset's held pose on each face (:func:`preset_poses`), software-rendered into one
    sheet: rows are faces, columns presets.

    Parameters
    ----------
    faces : sequence of (str, FaceMesh, list of Region)
        A label, the mesh (units set) and its hole regions, per face.
    presets : sequence of str, optional
        Preset names (default :data:`usdface.tissue.expressions.PRESET_NAMES`).
    size : (int, int)
        Width and height of one cell, pixels.
    integrator : {"explicit", "symplectic", "implicit"}

    Returns
    -------
    ndarray (H, W, 3) uint8, BGR
        The sheet (:func:`usdface.preview.contact_sheet`; write it with
        :func:`usdface.preview.write_png`).
    """
    from ..preview import Camera, contact_sheet, render_mesh
    from .expressions import PRESET_NAMES

    presets = list(presets or PRESET_NAMES)
    images, captions = [], []
    for label, mesh, regions in faces:
        cam = Camera.fit(mesh.points, view="front", size=size)
        for name, skin in preset_poses(mesh, regions, presets, integrator=integrator).items():
            images.append(render_mesh(skin, mesh.triangles(), camera=cam, title=name))
            captions.append(f"{label} {name}")
    return contact_sheet(images, captions, columns=len(presets), title="usdface tissue presets (seed 001 section 5)")
