"""usdface.tissue.muscles: Waters-style linear muscles, sphincters, compiling against a model."""
from __future__ import annotations

import numpy as np
import pytest

from usdface.errors import InputError, OptionError
from usdface.tissue.muscles import (Muscle, check_contractions, compile_muscles, linear_muscle_weights,
                                    sphincter_weights)


def test_linear_weights_zone_and_falloff():
    o, ins = np.zeros(3), np.array([0.0, 4.0, 0.0])
    pts = np.array([
        [0.0, 4.0, 0.0],          # the insertion: full weight
        [0.0, 2.0, 0.0],          # half way up the muscle: the cubed ramp
        [0.0, 0.1, 0.0],          # near the bone: almost nothing
        [4.0, 0.1, 0.0],          # outside the angular zone
        [0.0, 6.0, 0.0],          # beyond the outer radius (5)
        [0.0, 4.5, 0.0],          # in the falloff
        [np.tan(np.radians(15)) * 4, 4.0, 0.0],   # 15 deg off axis with a 30 deg zone
    ])
    w = linear_muscle_weights(pts, o, ins, zone_angle=30.0, inner_radius=4.0, outer_radius=5.0)
    assert w[0] == pytest.approx(1.0)
    assert w[1] == pytest.approx(np.cos(np.pi / 4) ** 3)
    assert w[2] < 1e-4 and w[3] == 0.0 and w[4] == 0.0
    assert w[5] == pytest.approx(np.cos(0.5 * np.pi * 0.5))
    dist = np.linalg.norm(pts[6])
    assert w[6] == pytest.approx(np.cos(np.pi / 4) * np.cos(0.5 * np.pi * (dist - 4.0)), rel=1e-6)


def test_sphincter_weights_are_radial_only():
    c, s = np.zeros(3), np.array([2.0, 1.0, 0.5])
    pts = np.array([[0.5, 0, 0], [0, 0.25, 0], [1.5, 0, 0], [0, 0.75, 0], [2.5, 0, 0]])
    w = sphincter_weights(pts, c, s, inner_radius=1.0, outer_radius=2.0)
    assert w[0] == w[1] == 1.0                      # same elliptic radius 0.25: same weight
    assert w[2] == pytest.approx(w[3]) and 0 < w[2] < 1
    assert w[4] == 0.0


def test_muscle_validation():
    with pytest.raises(InputError, match="USD identifier"):
        Muscle(name="bad name", origin=[0, 0, 0], insertion=[1, 0, 0])
    with pytest.raises(InputError, match="coincide"):
        Muscle(name="m", origin=[0, 0, 0], insertion=[0, 0, 0])
    with pytest.raises(InputError, match="zoneAngle"):
        Muscle(name="m", origin=[0, 0, 0], insertion=[1, 0, 0], zone_angle=120)
    with pytest.raises(InputError, match="semi-axes"):
        Muscle(name="m", type="sphincter", centre=[0, 0, 0], semi_axes=[1, 0, 1])
    with pytest.raises(InputError, match="innerRadius < outerRadius"):
        Muscle(name="m", origin=[0, 0, 0], insertion=[1, 0, 0], inner_radius=2, outer_radius=1)
    m = Muscle(name="m", type="sphincter", centre=[0, 0, 0], semi_axes=[2.0, 1.0, 0.5])
    assert m.outer_radius == 2.0 and m.inner_radius == 1.0
    assert np.allclose(np.diag(m.squeeze_metric), [1.0, 1 / 16, 0.0])


def test_contractions_outside_unit_interval_are_named():
    with pytest.raises(OptionError, match=r"b=1\.5.*c=-0\.1|c=-0\.1.*b=1\.5"):
        check_contractions([0.2, 1.5, -0.1], ["a", "b", "c"])
    with pytest.raises(OptionError, match="expected 3"):
        check_contractions([0.2], ["a", "b", "c"])
    with pytest.raises(OptionError, match="nan"):
        check_contractions([np.nan, 0, 0], ["a", "b", "c"])


def test_rig_compiles_on_the_face(face):
    ms = face.muscles
    assert ms.n_muscles == len(face.rig.muscles) == 23
    for k in range(ms.n_muscles):  # every muscle acts on some fascia nodes with a full-weight peak
        sel = ms.muscle == k
        assert sel.sum() >= 5
        assert ms.base[sel].sum() == pytest.approx(face.rig.muscles[k].max_force)
    n = face.model.n_vertices
    assert ((ms.nodes >= n) & (ms.nodes < 2 * n)).all()  # muscles act on fascia nodes
    # mouth-corner depressors hang on the jaw, the zygomatics on the skull
    assert ms.on_jaw[ms.index("depressorAnguliOris_L")] == 1.0
    assert ms.on_jaw[ms.index("zygomaticMajor_L")] == 0.0


def test_far_and_empty_muscles_are_refused(face):
    good = face.rig.muscle("zygomaticMajor_L")
    far = good.replace(name="farMuscle", origin=good.origin + np.array([0.0, 0.0, -6.0]))
    with pytest.raises(InputError, match=r"farMuscle \(origin .* cm from the bone layer\)"):
        compile_muscles(face.model, [good, far])
    lost = Muscle(name="lost", type="sphincter", centre=[0.0, 0.0, 0.0], semi_axes=[1.0, 1.0, 1.0])
    with pytest.raises(InputError, match="lost"):
        compile_muscles(face.model, [lost])
    with pytest.raises(InputError, match="duplicate"):
        compile_muscles(face.model, [good, good])
