"""Curves CSV round trip and the Live Link Face layout."""
import numpy as np
import pytest

from usdface.blendshape.csvio import (LIVE_LINK_FACE_SHAPES, head_angles, live_link_face_text, live_link_timecode,
                                      read_curves_csv, write_curves_csv)
from usdface.errors import FormatError, InputError


def test_curves_csv_round_trip(tmp_path, makehuman):
    names = makehuman["rig"].names
    w = np.random.default_rng(0).random((30, len(names)))
    p = write_curves_csv(tmp_path / "c.csv", names, w, rate=24.0, start_frame=10)
    header = p.read_text().splitlines()[0]
    assert header == "frame,time," + ",".join(names)
    got_names, frames, values, rate = read_curves_csv(p)
    assert got_names == list(names) and frames[0] == 10 and rate == pytest.approx(24.0, rel=1e-5)
    assert np.abs(values - w).max() <= 5e-7
    (tmp_path / "bad.csv").write_text("frame,time,a\n0,0.0,0.1\n2,0.1,0.2\n")
    with pytest.raises(FormatError, match="consecutive"):
        read_curves_csv(tmp_path / "bad.csv")


def _rot(yaw, pitch, roll):
    def ry(a):
        return np.array([[np.cos(a), 0, np.sin(a)], [0, 1, 0], [-np.sin(a), 0, np.cos(a)]])

    def rx(a):
        return np.array([[1, 0, 0], [0, np.cos(a), -np.sin(a)], [0, np.sin(a), np.cos(a)]])

    def rz(a):
        return np.array([[np.cos(a), -np.sin(a), 0], [np.sin(a), np.cos(a), 0], [0, 0, 1]])

    m = np.eye(4)
    m[:3, :3] = ry(yaw) @ rx(pitch) @ rz(roll)
    return m


def test_live_link_face_layout(makehuman):
    names = makehuman["rig"].names
    w = np.zeros((3, len(names)))
    w[1, names.index("jawOpen")] = 0.75
    w[2, names.index("jawLeft")] = 0.5
    head = np.stack([_rot(0, 0, 0), _rot(0.1, -0.05, 0.02), _rot(-0.2, 0.1, 0.0)])
    text, rep = live_link_face_text(names, w, rate=60.0, head_motion=head)
    lines = text.splitlines()
    cols = lines[0].split(",")
    assert cols[:4] == ["Timecode", "BlendShapeCount", "EyeBlinkLeft", "EyeLookDownLeft"]
    assert cols.index("JawRight") < cols.index("JawLeft") and cols.index("MouthRight") < cols.index("MouthLeft")
    assert cols[-9:] == ["HeadYaw", "HeadPitch", "HeadRoll", "LeftEyeYaw", "LeftEyePitch", "LeftEyeRoll",
                         "RightEyeYaw", "RightEyePitch", "RightEyeRoll"]
    assert len(cols) == 2 + 52 + 9 and rep["missing"] == [] and rep["unused"] == []
    row1 = lines[2].split(",")
    assert row1[0] == "00:00:00:01.000" and row1[1] == "61"
    assert float(row1[cols.index("JawOpen")]) == 0.75 and float(lines[3].split(",")[cols.index("JawLeft")]) == 0.5
    assert [float(x) for x in row1[-9:-6]] == pytest.approx([0.1, -0.05, 0.02], abs=1e-6)
    assert live_link_timecode(3725 * 30 + 7, 30.0) == "01:02:05:07.000"


def test_head_angles_round_trip():
    rng = np.random.default_rng(2)
    ang = rng.uniform(-0.5, 0.5, (20, 3))
    m = np.stack([_rot(*a) for a in ang])
    assert np.allclose(head_angles(m), ang, atol=1e-12)


def test_rig_without_arkit_names(makehuman):
    names = ["smile", "jawOpen"]
    w = np.zeros((2, 2))
    with pytest.raises(InputError, match=r"lacks 51 of the 52 ARKit shapes.*--livelink-fill-zeros"):
        live_link_face_text(names, w, rate=30.0)
    text, rep = live_link_face_text(names, w, rate=30.0, fill_missing=True)
    assert len(rep["missing"]) == 51 and rep["unused"] == ["smile"]
    assert len(text.splitlines()[1].split(",")) == 63
    assert len(LIVE_LINK_FACE_SHAPES) == 52
