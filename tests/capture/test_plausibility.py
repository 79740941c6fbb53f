"""Plausibility checks (usdface.capture.plausibility, usdface.mesh.judgement) on the real takes."""
from __future__ import annotations

import re

import numpy as np
import pytest

from usdface.capture.plausibility import check_capture, drop_outliers, face_size_finding, parse_allow, report
from usdface.errors import FormatError, OptionError, PlausibilityError


@pytest.fixture(scope="module")
def takes(sample_assets):
    from usdface.io.maya_ascii import read_maya_ascii

    return {t: read_maya_ascii(sample_assets / "capture" / f"{t}MoCap.ma") for t in ("Jaw", "Nose", "Eyebrows")}


def _codes(findings):
    return [f.code for f in findings]


def test_real_takes_have_no_finding(takes):
    for capture in takes.values():
        assert check_capture(capture) == []


def test_real_take_centred_at_the_origin_has_no_finding(takes):
    """A face near the origin is where dividing by a unit ratio lands markers next to others."""
    jaw = takes["Jaw"]
    centred = jaw.positions - np.nanmedian(jaw.positions.reshape(-1, 3), axis=0)
    assert check_capture(jaw.replace(positions=centred)) == []


@pytest.mark.parametrize("centred", [False, True])
def test_mixed_units_found_and_named(takes, centred):
    jaw = takes["Jaw"]
    pos = jaw.positions.copy()
    if centred:
        pos -= np.nanmedian(pos.reshape(-1, 3), axis=0)
    odd = np.zeros(jaw.n_markers, bool)
    odd[20:] = True  # the lower face in mm: a block of columns
    pos[:, odd] *= 10
    (f,) = [f for f in check_capture(jaw.replace(positions=pos)) if f.code == "mixed-units"]
    assert set(f.markers) == {n for n, o in zip(jaw.names, odd) if o}
    assert "10x larger" in f.message and "in mm and the others in cm" in f.message


def test_mixed_units_minority_in_metres(takes):
    jaw = takes["Jaw"]
    pos = jaw.positions.copy()
    pos[:, :5] /= 100
    findings = check_capture(jaw.replace(positions=pos))
    assert _codes(findings) == ["mixed-units"]  # judged after scaling: nothing else is wrong
    assert findings[0].markers == jaw.names[:5] and "in m and the others in cm" in findings[0].message


@pytest.mark.parametrize("factor, unit", [(0.01, "m"), (10.0, "mm"), (0.1, "dm")])
def test_face_size_suggests_the_unit(takes, factor, unit):
    jaw = takes["Jaw"]
    (f,) = check_capture(jaw.replace(positions=jaw.positions * factor))
    assert f.code == "face-size" and f"is it in {unit}?" in f.message and "18.8 cm" in f.message


def test_face_size_range_is_for_any_head():
    assert face_size_finding(12.0, "cm", what="x", kind="markers") is None  # a child
    assert face_size_finding(0.6, "m", what="x", kind="markers") is None  # a horse (60 cm)
    assert face_size_finding(2.0, "cm", what="x", kind="markers").code == "face-size"


def test_outliers_named_by_marker_and_frame_and_dropped(takes):
    jaw = takes["Jaw"]
    pos = jaw.positions.copy()
    pos[700, jaw.index("Mouth_UpL1")] += [0.0, 0.0, 8.0]  # 8 cm: 43% of the face's 18.8 cm
    pos[1000:1003, jaw.index("ForeHead_L")] = 0.0
    capture = jaw.replace(positions=pos)
    (f,) = check_capture(capture)
    assert f.code == "outliers" and set(f.markers) == {"Mouth_UpL1", "ForeHead_L"}
    assert "Mouth_UpL1 at frame 700" in f.message and "ForeHead_L at frame 1000-1002" in f.message
    assert f.samples.sum() == 4
    dropped, n = drop_outliers(capture, [f])
    assert n == 4 and (~dropped.valid).sum() == 4 and np.isnan(dropped.positions[700, jaw.index("Mouth_UpL1")]).all()
    assert check_capture(dropped) == []
    with pytest.raises(PlausibilityError, match="Mouth_UpL1 at frame 700"):
        report([f])
    assert report([f], allow=["outliers"])[0]["allowed"]


def test_speed_warning_on_a_jump(takes):
    jaw = takes["Jaw"]
    pos = jaw.positions.copy()
    pos[800:, jaw.index("Chin_L1")] += [2.5, 0.0, 0.0]  # a marker swap-like jump
    (f,) = check_capture(jaw.replace(positions=pos))
    assert f.code == "speed" and f.severity == "warning" and "Chin_L1 from frame 799->800 " in f.message


def test_parse_allow():
    assert parse_allow(["outliers,face-size", "speed"]) == {"outliers", "face-size", "speed"}
    with pytest.raises(OptionError, match="not a plausibility check"):
        parse_allow("outlier")


def test_maya_key_not_finite_is_a_format_error(sample_assets, tmp_path):
    from usdface.io.maya_ascii import read_maya_ascii

    text = (sample_assets / "capture" / "NoseMoCap.ma").read_text()
    i = text.index('createNode animCurveTL -n "NoseTop_translateX";')
    j = text.index('setAttr ".ktv[0:249]"', i) + len('setAttr ".ktv[0:249]"')
    value = list(re.finditer(r"\S+", text[j:j + 200]))[1]  # pairs "time value": key 0's value
    bad = tmp_path / "nose_inf.ma"
    bad.write_text(text[:j + value.start()] + "inf" + text[j + value.end():])
    with pytest.raises(FormatError, match=r"'NoseTop_translateX' \(driving NoseTop\.tx\): key 0 at time 0 \(line"):
        read_maya_ascii(bad)


def test_robust_similarity_recovers_the_transform_despite_a_far_marker(takes):
    from usdface.capture.rigid import fit_rigid
    from usdface.mesh.judgement import robust_similarity

    src = takes["Jaw"].positions[0]
    rng = np.random.default_rng(0)
    q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    rot = q * np.sign(np.linalg.det(q))
    dst = 0.87 * src @ rot.T + [1.0, -60.0, 4.0] + rng.normal(scale=0.05, size=src.shape)
    dst[7] += [0.0, 0.0, 45.0]
    r, s, t, res, kept = robust_similarity(src, dst, limit=4.0)
    assert not kept[7] and kept.sum() == len(src) - 1
    assert abs(s - 0.87) < 2e-3 and np.abs(r - rot).max() < 1e-2
    assert 44.0 < res[7] < 46.0 and np.delete(res, 7).max() < 0.25
    _, s_ls, _ = fit_rigid(src, dst, scale=True)  # least squares alone is dragged
    assert abs(s_ls - 0.87) > 0.01


def test_unit_scale_finding_names_the_mesh_unit():
    from usdface.mesh.judgement import unit_scale_finding

    f = unit_scale_finding(0.0093, capture_units="cm", mesh_units="cm", what="x")
    assert "0.0093" in f.message and "is the mesh in m?" in f.message
    assert unit_scale_finding(0.87, capture_units="cm", mesh_units="cm", what="x") is None
    assert unit_scale_finding(93.0, capture_units="cm", mesh_units="m", what="x").code == "unit-scale"
