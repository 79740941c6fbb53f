"""usdface.tissue.fit: recovering contractions from marker motion made by the simulator."""
from __future__ import annotations

import numpy as np
import pytest

from usdface.mesh.surface_points import project_to_surface
from usdface.mesh.layout import read_layout
from usdface.tissue.fit import (FitParameters, LinearResponse, bound_points, fit_frames, fit_sequence, linear_response,
                                marker_error, simulate_controls)


def test_bounded_least_squares_on_an_exact_linear_model():
    rng = np.random.default_rng(0)
    J = rng.normal(size=(30, 4))
    truth = np.array([[0.0, 0.5, 1.0, 0.2], [0.3, 0.0, 0.0, 0.9]])
    d = (truth @ J.T).reshape(2, 10, 3)
    d[1, 4] = np.nan  # a gap: that marker is left out of frame 1
    a, pred = fit_frames(LinearResponse(names=("a", "b", "c", "d"), J=J), d, regularization=1e-9)
    assert np.allclose(a, truth, atol=1e-4)
    # contractions stay in [0, 1] even when the data asks for more
    a2, _ = fit_frames(LinearResponse(names=("a", "b", "c", "d"), J=J), 3 * d, regularization=1e-9)
    assert a2.min() >= 0 and a2.max() <= 1


def test_marker_error_stats():
    e = marker_error(np.zeros((2, 2, 3)), np.array([[[3, 4, 0], [0, 0, 0]], [[np.nan] * 3, [0, 0, 1]]]))
    assert e["max"] == 5 and e["mean"] == pytest.approx(2.0) and e["rms"] == pytest.approx(np.sqrt(26 / 3))


@pytest.fixture(scope="module")
def markers(face, sample_assets):
    lay = read_layout(sample_assets / "layouts" / "makehuman_hm08_face.layout.json")
    sp = project_to_surface(face.mesh, lay.positions(face.mesh))
    return lay.names, sp.triangle_vertices, sp.barycentrics


def test_fit_recovers_simulated_contractions(face, markers):
    """Markers made by the simulator from known contractions (3 random muscles per frame plus the
    jaw) are fitted back; stated bounds: contraction error mean <= 0.06, marker RMS error under
    half the marker motion's RMS, and better than the first simulated pass."""
    names, tri, bary = markers
    sim = face.simulator()
    resp = linear_response(sim, tri, bary)
    assert resp.J.shape == (3 * len(names), face.muscles.n_muscles + 1) and resp.names[-1] == "jawOpen"
    assert np.isfinite(resp.J).all() and (np.linalg.norm(resp.J, axis=0) > 0).all()
    rng = np.random.default_rng(1)
    c = resp.n_controls
    truth = np.zeros((5, c))
    for f in range(1, 5):
        k = rng.choice(c, 3, replace=False)
        truth[f, k] = rng.uniform(0.2, 0.8, 3)
    rest = bound_points(face.model.rest[:sim.n], tri, bary)
    skins = np.stack(list(simulate_controls(sim, truth, list(resp.names), rate=24, settle_steps=2)))
    d = np.einsum("mk,fmkd->fmd", bary, skins[:, tri]) - rest
    res = fit_sequence(sim, tri, bary, d, rate=24, response=resp, parameters=FitParameters(refine=2),
                       marker_names=names)
    err = np.abs(res.controls - truth)
    assert err.mean() <= 0.06
    final = res.errors["pass3"]["rms"]
    assert final < 0.5 * res.errors["still"]["rms"]
    assert final <= res.errors["pass1"]["rms"]
    assert set(res.per_marker) == set(names)
    assert res.skin.shape == (5, face.mesh.n_points, 3)


def test_capture_displacements_start_from_the_rest_pose():
    """fit-muscles measures from the capture's rest pose (its neutral stretch, averaged robustly),
    as transfer, skel and solve do, not from the neutral frame alone."""
    from usdface.model.capture import Capture
    from usdface.model.mesh import Binding as MeshBinding
    from usdface.model.rest import robust_rest_pose
    from usdface.tissue.fit import capture_displacements

    rng = np.random.default_rng(5)
    names = ("a", "b", "c", "d")
    pos = rng.normal(0.0, 0.03, (40, 4, 3)) + np.arange(12.0).reshape(1, 4, 3)
    cap = Capture(names, pos, 60.0, units="cm", neutral_frame=3, neutral_window=(0, 20), head_motion=np.tile(
        np.eye(4), (40, 1, 1)))
    binding = MeshBinding(names=("c", "a"), face_indices=np.zeros(2, dtype=np.int64),
                          triangle_vertices=np.zeros((2, 3), dtype=np.int64), barycentrics=np.full((2, 3), 1 / 3),
                          nearest_vertices=np.zeros(2, dtype=np.int64), residuals=np.zeros(2),
                          capture_to_mesh=np.eye(4))
    d, _ = capture_displacements(cap, binding)
    rest = robust_rest_pose(pos[0:20])[0][[2, 0]]
    np.testing.assert_allclose(d, pos[:, [2, 0]] - rest[None], atol=1e-12)
    assert np.abs(d[3]).max() > 1e-3  # the neutral frame itself moves from the rest pose (noise)
