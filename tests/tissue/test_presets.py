"""Every expression preset on both sample faces: stability, volume, and the right motion at landmarks.

The presets run once per session (``preset_runs`` in conftest.py): ramped 0 -> 1 over 3 frames at
24 fps, as in the paper, then held at the default (implicit, 1/240 s) step until the tissue is still.
"""
from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial import cKDTree

from usdface.tissue.expressions import PRESET_NAMES

FACES = ("realistic", "stylized")


def _lm(faces, preset_runs, face_name, preset):
    f = faces[face_name]
    run = preset_runs[face_name, preset]
    tree = cKDTree(f.mesh.points)
    return {k: run.displacement[tree.query(v)[1]] for k, v in f.rig.landmarks.items()}


@pytest.mark.parametrize("face_name", FACES)
def test_every_preset_reaches_equilibrium_with_bounded_energy(preset_runs, face_name):
    for preset in PRESET_NAMES:
        run = preset_runs[face_name, preset]
        assert run.converged, f"{face_name} {preset} did not come to rest"
        assert np.isfinite(run.energy).all()
        if preset != "neutral":
            # no blow-up: the energy never exceeds its final (equilibrium) value by more than 1%
            assert run.energy.max() <= 1.01 * run.final_energy, preset
        assert np.abs(run.displacement).max() < 3.0  # cm


@pytest.mark.parametrize("face_name", FACES)
def test_volume_change_bounds(preset_runs, face_name):
    """Stated bounds (relative volume change): skin prisms at full depth p99 <= 25%, max <= 110%;
    three-layer elements bound to the bone p99 <= 30%, max <= 130%."""
    for preset in PRESET_NAMES:
        v = preset_runs[face_name, preset].volume
        assert v["skin"]["p99"] <= 0.25, (preset, v["skin"])
        assert v["skin"]["maxAbs"] <= 1.1, (preset, v["skin"])
        assert v["element"]["p99"] <= 0.30, (preset, v["element"])
        assert v["element"]["maxAbs"] <= 1.3, (preset, v["element"])


def test_neutral_does_not_move(preset_runs):
    for face_name in FACES:
        assert np.abs(preset_runs[face_name, "neutral"].displacement).max() < 1e-6


def _mouth_width_change(d):
    return d["mouthCorner_L"][0] - d["mouthCorner_R"][0]


@pytest.mark.parametrize("face_name", FACES)
def test_joy_mouth_corners_up_and_back(faces, preset_runs, face_name):
    d = _lm(faces, preset_runs, face_name, "joy")
    for side, sign in (("L", 1), ("R", -1)):
        c = d[f"mouthCorner_{side}"]
        assert c[1] > 0.3                      # up
        assert sign * c[0] > 0.2 and c[2] < 0.05  # back toward the ear: outward, not forward
    assert _mouth_width_change(d) > 0.4
    assert d["browInner_L"][1] < 0.05          # the brows do not rise in a smile


@pytest.mark.parametrize("face_name", FACES)
def test_surprise_brows_up_and_jaw_open(faces, preset_runs, face_name):
    d = _lm(faces, preset_runs, face_name, "surprise")
    for side in "LR":
        assert d[f"browInner_{side}"][1] > 0.3 and d[f"browOuter_{side}"][1] > 0.3
    assert d["lowerLip"][1] < -0.8


@pytest.mark.parametrize("face_name", FACES)
def test_sadness_inner_brows_up_mouth_corners_down(faces, preset_runs, face_name):
    d = _lm(faces, preset_runs, face_name, "sadness")
    for side in "LR":
        assert d[f"browInner_{side}"][1] > 0.3
        assert d[f"browInner_{side}"][1] > d[f"browOuter_{side}"][1] + 0.2   # oblique brows
        assert d[f"mouthCorner_{side}"][1] < -0.3


@pytest.mark.parametrize("face_name", FACES)
def test_anger_brows_down_and_together_lips_pressed(faces, preset_runs, face_name):
    d = _lm(faces, preset_runs, face_name, "anger")
    assert d["browInner_L"][1] < -0.15 and d["browInner_R"][1] < -0.15
    assert d["browInner_L"][0] < 0 < d["browInner_R"][0]   # toward the midline
    assert _mouth_width_change(d) < -0.2


@pytest.mark.parametrize("face_name", FACES)
def test_fear_brows_up_mouth_stretched_open(faces, preset_runs, face_name):
    d = _lm(faces, preset_runs, face_name, "fear")
    assert d["browInner_L"][1] > 0.3 and d["browOuter_L"][1] > 0.2
    assert _mouth_width_change(d) > 0.1
    assert d["lowerLip"][1] < -0.3


@pytest.mark.parametrize("face_name", FACES)
def test_disgust_upper_lip_up_brows_down(faces, preset_runs, face_name):
    d = _lm(faces, preset_runs, face_name, "disgust")
    assert d["upperLip"][1] > 0.2
    assert d["browInner_L"][1] < -0.1 and d["browInner_R"][1] < -0.1


@pytest.mark.parametrize("face_name", FACES)
def test_pursed_lips_mouth_narrows_and_pushes_forward(faces, preset_runs, face_name):
    d = _lm(faces, preset_runs, face_name, "pursed_lips")
    assert _mouth_width_change(d) < -0.4
    assert d["mouthCorner_L"][2] > 0.1 and d["mouthCorner_R"][2] > 0.1
    assert abs(d["browInner_L"][1]) < 0.02
