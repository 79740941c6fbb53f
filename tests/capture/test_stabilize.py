"""Rigid head stabilisation on synthetic captures with a known head motion (real takes: test_conditioning_real.py)."""
from __future__ import annotations

import json

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from usdface.model.capture import Capture
from usdface.capture.rigid import rotation_angle
from usdface.capture.stabilize import rank_rigid_markers, residual_rigid_motion, stabilize
from usdface.errors import MarkerError, OptionError

SKULL = [f"Skull{i}" for i in range(6)]
EXPR = [f"Expr{i}" for i in range(6)]
JAW = [f"Jaw{i}" for i in range(3)]


def synthetic(n_frames=240, seed=0):
    """A face-like capture: 6 skull markers, 6 expressive markers, 3 jaw markers; known head motion."""
    rng = np.random.default_rng(seed)
    skull = np.array([[0, 10, 0], [4, 9, -1], [-4, 9, -1], [6, 4, -2], [-6, 4, -2], [0, 3, 3]], float)
    expr = rng.normal(size=(6, 3)) * 3 + [0, 0, 2]
    jaw = np.array([[0, -7, 1], [3, -6, 0], [-3, -6, 0]], float)
    f = np.arange(n_frames)
    # expressions: large non-rigid offsets (up to 1 cm) with different phases
    expr_t = expr[None] + 1.0 * np.sin(2 * np.pi * f[:, None, None] / 80 + rng.uniform(0, 6, (1, 6, 3)))
    expr_t[0] = expr  # starts neutral
    # jaw opens: rotation about a hinge at y=-2, z=-4 (rigid among itself, not with the skull)
    ang = np.radians(12) * np.sin(np.pi * f / n_frames) ** 2
    hinge = np.array([0, -2, -4.0])
    jr = Rotation.from_rotvec(np.c_[ang, 0 * ang, 0 * ang]).as_matrix()
    jaw_t = np.einsum("fij,kj->fki", jr, jaw - hinge) + hinge
    local = np.concatenate([np.repeat(skull[None], n_frames, 0), expr_t, jaw_t], axis=1) + [0, 70, 0]
    # head motion: smooth, up to ~5 deg and 1.5 cm, identity at frame 0, rotating about the neck
    rv = np.radians(5) * np.c_[np.sin(f / 37.0), 0.6 * np.sin(f / 23.0), 0.4 * np.sin(f / 51.0)]
    rot = Rotation.from_rotvec(rv).as_matrix()
    pivot = np.array([0, 60.0, -5])
    trans = 1.5 * np.c_[np.sin(f / 29.0), 0.5 * np.sin(f / 41.0), 0.3 * np.sin(f / 17.0)]
    world = np.einsum("fij,fkj->fki", rot, local - pivot) + pivot + trans[:, None, :]
    world = world + rng.normal(scale=1e-3, size=world.shape)
    head = np.zeros((n_frames, 4, 4))
    head[:, :3, :3] = rot
    head[:, :3, 3] = pivot - np.einsum("fij,j->fi", rot, pivot) + trans
    head[:, 3, 3] = 1
    cap = Capture(names=SKULL + EXPR + JAW, positions=world, rate=60.0, units="cm", source="synthetic")
    return cap, head


def test_auto_selection_finds_the_skull_and_recovers_head_motion():
    cap, head = synthetic()
    before = cap.positions.copy()
    out, rep = stabilize(cap, n_auto=6)
    np.testing.assert_array_equal(cap.positions, before)  # input untouched
    assert set(rep.markers) == set(SKULL) and rep.auto
    assert rep.interpolated_frames.size == 0
    # head motion equals the truth (frame 0 is the reference and the head starts at identity)
    err_rot = rotation_angle(np.einsum("fji,fjk->fik", head[:, :3, :3], out.head_motion[:, :3, :3]))
    assert err_rot.max() < 0.1  # degrees (10 um marker noise)
    # (translations compared where they matter, at the face: the origin is 70 cm away)
    c = np.r_[cap.positions[0, :6].mean(0), 1.0]
    np.testing.assert_allclose(out.head_motion @ c, head @ c, atol=0.005)
    # the world positions are reproduced exactly
    np.testing.assert_allclose(out.world_positions(), cap.positions, atol=1e-10)
    # skull markers stand still in the local frame
    assert np.abs(out.positions[:, :6] - out.positions[0, :6]).max() < 0.01
    step = out.history[-1]
    assert step["step"] == "stabilize" and step["auto"] and sorted(step["markers"]) == sorted(SKULL)
    json.dumps(list(out.history))
    json.dumps(rep.summary())
    # the rigidity ranking puts the skull first and the expressive markers last
    ranked = [n for n, _ in rank_rigid_markers(cap, n_auto=6)]
    assert set(ranked[:6]) == set(SKULL)


def test_named_markers_and_holdout_report():
    cap, _ = synthetic()
    out, rep = stabilize(cap, markers=SKULL[::2], holdout=SKULL[1::2])
    assert rep.markers == tuple(SKULL[::2]) and not rep.auto
    assert rep.holdout == tuple(SKULL[1::2])
    assert rep.before.max_angle_deg > 4.0 and rep.before.max_translation > 1.0
    assert rep.after.max_angle_deg < 0.3 and rep.after.max_translation < 0.02
    summary = json.loads(json.dumps(rep.summary()))
    assert summary["holdout"]["markers"] == SKULL[1::2]
    assert summary["holdout"]["after"]["max_angle_deg"] == pytest.approx(rep.after.max_angle_deg)
    # residual_rigid_motion on the stored positions gives the same numbers
    again = residual_rigid_motion(out, SKULL[1::2])
    np.testing.assert_allclose(again.angle_deg, rep.after.angle_deg, atol=1e-9)
    # default holdout: non-fit markers ranked most rigid after the fact
    _, rep2 = stabilize(cap, markers=SKULL[:4])
    assert set(rep2.holdout[:2]) == set(SKULL[4:])


def test_frames_without_three_stable_markers_are_interpolated_and_reported():
    cap, head = synthetic()
    pos = cap.positions.copy()
    pos[100:106, 1:6] = np.nan  # only Skull0 valid among the skull markers
    pos[0:1, 7] = np.nan  # a non-stable marker invalid at the reference frame
    cap = cap.replace(positions=pos)
    out, rep = stabilize(cap, markers=SKULL)
    np.testing.assert_array_equal(rep.interpolated_frames, np.arange(100, 106))
    assert np.isnan(rep.fit_rms[100:106]).all() and np.isfinite(rep.fit_rms[:100]).all()
    # the interpolated head motion is close to the (smooth) truth
    err_rot = rotation_angle(np.einsum("fji,fjk->fik", head[95:111, :3, :3], out.head_motion[95:111, :3, :3]))
    assert err_rot.max() < 0.1
    c = np.r_[cap.positions[0, :6].mean(0), 1.0]
    np.testing.assert_allclose(out.head_motion[95:111] @ c, head[95:111] @ c, atol=0.02)
    # invalid samples stay invalid, valid ones round-trip
    assert np.array_equal(np.isnan(out.positions), np.isnan(pos))
    world = out.world_positions()
    ok = ~np.isnan(pos)
    np.testing.assert_allclose(world[ok], pos[ok], atol=1e-10)
    assert out.history[-1]["interpolated_frames"] == 6


def test_stabilising_twice_composes_head_motion():
    cap, _ = synthetic()
    once, _ = stabilize(cap, markers=SKULL[:4])
    twice, _ = stabilize(once, markers=SKULL)
    np.testing.assert_allclose(twice.world_positions(), cap.positions, atol=1e-9)
    assert [h["step"] for h in twice.history] == ["stabilize", "stabilize"]


def test_reference_frame_option():
    cap, _ = synthetic()
    out, rep = stabilize(cap, markers=SKULL, reference=50)
    assert rep.reference_frame == 50
    np.testing.assert_allclose(out.head_motion[50], np.eye(4), atol=1e-9)
    np.testing.assert_allclose(out.world_positions(), cap.positions, atol=1e-10)


def test_errors_name_the_problem():
    cap, _ = synthetic()
    with pytest.raises(MarkerError, match=r"'Nope' not in capture.*Skull0"):
        stabilize(cap, markers=["Skull0", "Skull1", "Nope"])
    with pytest.raises(OptionError, match="at least 3"):
        stabilize(cap, markers=["Skull0", "Skull1"])
    with pytest.raises(OptionError, match="n_auto"):
        stabilize(cap, n_auto=2)
    with pytest.raises(OptionError, match="reference"):
        stabilize(cap, reference=10_000)
    with pytest.raises(OptionError, match="also stable"):
        stabilize(cap, markers=SKULL[:3], holdout=SKULL[2:5])
    with pytest.raises(OptionError, match="list of marker names"):
        stabilize(cap, markers="Skull0")
    pos = cap.positions.copy()
    pos[0, 0] = np.nan
    with pytest.raises(MarkerError, match="invalid at reference frame 0"):
        stabilize(cap.replace(positions=pos), markers=SKULL)
    few = Capture(names=["a", "b", "c"], positions=np.where(np.arange(5)[:, None, None] < 3, np.nan, np.ones((5, 3, 3))), rate=30)
    with pytest.raises(MarkerError, match="only 0 marker"):
        stabilize(few)
