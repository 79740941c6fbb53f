"""Skeleton placement far from the origin: no offset transform, and UsdSkel's float32 skinning holds.

The same face (MakeHuman, the Jaw take's DCC-safe rig) is placed with its centre at the origin, at
y = 170 cm (a standing actor's head) and at y = 10 m (a set), written as mesh + skeleton layers
exactly as `usdface skel` writes them, skinned by UsdSkel (blend shapes + ComputeSkinnedPoints) and
moved back: every frame must land within 1e-3 cm of the face at the origin.
"""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest

TOL_CM = 1e-3


@pytest.fixture(scope="module")
def jaw_rig(jaw):
    from usdface.skel import fit_dcc, skel_inputs
    from usdface.usd.inputs import load_transfer_inputs

    inputs = skel_inputs(*load_transfer_inputs(jaw["mesh"], jaw["capture"], jaw["binding"], jaw["analysis"]))
    fit = fit_dcc(inputs, 8)
    # the neutral frame, the largest Chin displacement and a spread of others
    chin = inputs.binding.names.index("Chin")
    frames = sorted({0, inputs.capture.neutral_frame,
                     int(np.argmax(np.linalg.norm(inputs.effective[:, chin], axis=1))), *range(5, 1590, 97)})
    return inputs, fit, frames


def _skin_at(tmp_path, inputs, fit, frames, offset):
    """Write the face moved by ``offset`` (cm) and return UsdSkel's deformed points moved back by it."""
    from usdface.skel import SkinFit, build_rig
    from usdface.usd.mesh_layer import read_mesh_layer, write_mesh_layer
    from usdface.usd.skel_layer import skinned_points, write_skel_layer

    mesh, regions = read_mesh_layer(inputs.mesh.source)
    shift = np.asarray(offset, dtype=np.float64)
    tag = "_".join(f"{v:g}" for v in offset)
    mesh_path = tmp_path / f"mesh_{tag}.usdc"
    write_mesh_layer(mesh_path, dataclasses.replace(mesh, points=mesh.points + shift), regions,
                     prov={"processor": "test"})
    d = inputs.effective[frames]
    rig = build_rig(inputs.binding.names, inputs.bound_points + shift, fit.joint_translations(d))
    skel_path = tmp_path / f"skel_{tag}.usdc"
    skin = SkinFit(fit.weights, fit.joint_translations(d), fit.shapes, fit.shape_weights(d))
    write_skel_layer(skel_path, rig, skin, mesh_path=mesh_path, rate=60.0, start=0.0, prov={"processor": "test"})
    _, pts = skinned_points(skel_path)
    return pts - shift


def test_far_from_the_origin_skins_like_at_the_origin(jaw_rig, tmp_path):
    inputs, fit, frames = jaw_rig
    centre = 0.5 * (inputs.mesh.points.min(axis=0) + inputs.mesh.points.max(axis=0))
    at_origin = _skin_at(tmp_path, inputs, fit, frames, -centre)
    model = inputs.mesh.points[None] + fit.displacements(inputs.effective[frames])
    assert np.linalg.norm(at_origin - model, axis=2).max() < 1e-4  # UsdSkel = the float64 rig at the origin
    moved = np.linalg.norm(at_origin - inputs.mesh.points[None], axis=2).max()
    assert moved > 3.0  # the frames really deform the face (cm)
    for height in (170.0, 1000.0):
        far = _skin_at(tmp_path, inputs, fit, frames, np.array([0.0, height, 0.0]) - centre)
        err = np.linalg.norm(far - at_origin, axis=2).max()
        print(f"face centred at y = {height:g} cm vs at the origin: max {err:.2e} cm over {len(frames)} frames")
        assert err < TOL_CM
