"""Capture layers: conventions, never NaN, composed world positions equal the input."""
import numpy as np
import pytest

import usdface  # noqa: F401
from usdface.capture import Capture
from usdface.errors import InputError
from usdface.usd.capture_layer import hold_invalid, read_capture_layer, write_capture_layer


def _capture(rng, with_motion=True):
    pos = rng.normal(size=(50, 4, 3)) * 5 + 70
    pos[3:9, 1] = np.nan
    pos[0:2, 2] = np.nan
    hm = None
    if with_motion:
        from scipy.spatial.transform import Rotation

        hm = np.tile(np.eye(4), (50, 1, 1))
        hm[:, :3, :3] = Rotation.from_euler("y", np.linspace(0, 5, 50)[:, None], degrees=True).as_matrix()
        hm[:, :3, 3] = np.linspace(0, 1.5, 50)[:, None]
    return Capture(names=["Chin", "NoseTop", "Mouth_Up", "ForeHead_M"], positions=pos, rate=60.0, units="cm",
                   start_frame=10, neutral_frame=4, source="take.ma", head_motion=hm)


def test_hold_invalid_holds_last_then_first_valid():
    pos = np.arange(5.0)[:, None, None] * np.ones((5, 1, 3))
    valid = np.array([[False], [True], [False], [False], [True]])
    held = hold_invalid(pos, valid)
    assert held[:, 0, 0].tolist() == [1, 1, 1, 1, 4]


def test_round_trip_and_conventions(tmp_path):
    from pxr import Usd, UsdGeom

    cap = _capture(np.random.default_rng(1))
    out = tmp_path / "cap.usdc"
    write_capture_layer(out, cap, prov={"processor": "test"})
    back = read_capture_layer(out)
    assert back.names == cap.names
    assert back.rate == 60 and back.units == "cm" and back.start_frame == 10 and back.neutral_frame == 4
    np.testing.assert_array_equal(np.isnan(back.positions), np.isnan(cap.positions))
    np.testing.assert_allclose(back.positions, cap.positions, atol=2e-5, equal_nan=True)
    np.testing.assert_allclose(back.head_motion, cap.head_motion, atol=1e-12)

    stage = Usd.Stage.Open(str(out))
    assert stage.GetRootLayer().defaultPrim == "Capture"
    assert stage.GetTimeCodesPerSecond() == 60 and stage.GetFramesPerSecond() == 60
    assert (stage.GetStartTimeCode(), stage.GetEndTimeCode()) == (10, 59)
    assert UsdGeom.GetStageMetersPerUnit(stage) == pytest.approx(0.01)
    markers = stage.GetPrimAtPath("/Capture/Markers")
    assert markers.IsA(UsdGeom.Points) and markers.HasAPI("FaceMarkerSetAPI")
    # never NaN in points; composed world positions equal the input world positions
    world_in = cap.world_positions()
    for f in range(cap.n_frames):
        t = 10 + f
        pts = np.asarray(UsdGeom.Points(markers).GetPointsAttr().Get(t), dtype=float)
        assert np.isfinite(pts).all()
        m = np.array(UsdGeom.Xformable(markers).ComputeLocalToWorldTransform(t))
        world = pts @ m[:3, :3] + m[3, :3]
        ok = cap.valid[f]
        np.testing.assert_allclose(world[ok], world_in[f][ok], atol=1e-4)
        assert np.asarray(markers.GetAttribute("primvars:usdface:valid").Get(t)).tolist() == ok.tolist()


def test_reading_a_layer_without_markers_names_the_file(tmp_path):
    from pxr import Usd, UsdGeom

    path = tmp_path / "empty.usda"
    stage = Usd.Stage.CreateNew(str(path))
    UsdGeom.Xform.Define(stage, "/Capture")
    stage.Save()
    with pytest.raises(InputError, match=r"empty\.usda.*no Points prim with FaceMarkerSetAPI"):
        read_capture_layer(path)


def test_the_neutral_stretch_and_rest_pose_round_trip(tmp_path):
    from pxr import Usd

    from usdface.capture.neutral import set_rest_pose
    from usdface.usd.info import describe, format_description

    rng = np.random.default_rng(2)
    base = _capture(rng, with_motion=False)
    still = np.repeat(base.positions[10:11], 50, axis=0) + rng.normal(0, 0.03, base.positions.shape)
    still[30:] += np.linspace(0, 2, 20)[:, None, None]  # the face moves from frame 30
    still[3:9, 1] = np.nan
    cap, report = set_rest_pose(base.replace(positions=still, neutral_frame=0))
    assert report.start == 0 and 25 <= report.end <= 31
    out = tmp_path / "cap.usdc"
    write_capture_layer(out, cap, prov={"processor": "test"})
    back = read_capture_layer(out)
    assert back.neutral_frame == 0 and back.neutral_frames == cap.neutral_frames
    np.testing.assert_allclose(back.neutral, cap.neutral, atol=2e-5)
    stage = Usd.Stage.Open(str(out))
    prim = stage.GetPrimAtPath("/Capture/Markers")
    assert prim.GetAttribute("usdface:markerSet:neutralStartTime").Get() == 10
    assert prim.GetAttribute("usdface:markerSet:neutralEndTime").Get() == 10 + report.end - 1
    np.testing.assert_allclose(np.asarray(prim.GetAttribute("usdface:markerSet:restPoints").Get()), cap.neutral,
                               atol=2e-5)
    assert prim.GetAttribute("usdface:markerSet:neutralMotionRms").Get() == pytest.approx(report.motion_rms)
    info = describe(out)["prims"][1]["markerSet"]
    assert info["neutralTimes"] == [10, 10 + report.end - 1]
    assert info["neutralMotionRmsCm"] == pytest.approx(report.motion_rms, abs=1e-5)
    text = "\n".join(format_description(describe(out)))
    assert (f"neutral times 10-{10 + report.end - 1} (around neutral frame 10), markers move {report.motion_rms:.3f} cm RMS "
            f"({report.motion_max:.3f} cm at most) there") in text


def test_layers_without_a_neutral_stretch_read_as_one_frame(tmp_path, sample_assets):
    """usdface 0.2 wrote the neutral time alone: the rest pose is that frame."""
    from pxr import Sdf

    from usdface.usd.info import describe, format_description

    old = sample_assets / "capture" / "JawMoCap.usdc"  # written before the stretch was recorded
    cap = read_capture_layer(old)
    assert cap.neutral_window is None and cap.neutral_frames == (cap.neutral_frame, cap.neutral_frame + 1)
    np.testing.assert_array_equal(cap.neutral, cap.positions[cap.neutral_frame])
    m = describe(old)["prims"][1]["markerSet"]
    assert m["neutralTimes"] == [m["neutralTime"]] * 2 and m["neutralMotionRmsCm"] is None
    assert f"neutral time {m['neutralTime']:g}\n" in "\n".join(format_description(describe(old))) + "\n"
    # the same with the new attributes removed from a new layer
    new = tmp_path / "cap.usda"
    write_capture_layer(new, _capture(np.random.default_rng(5)), prov={"processor": "test"})
    layer = Sdf.Layer.FindOrOpen(str(new))
    spec = layer.GetPrimAtPath("/Capture/Markers")
    for name in ("neutralStartTime", "neutralEndTime", "restPoints", "neutralMotionRms", "neutralMotionMax"):
        spec.RemoveProperty(spec.properties[f"usdface:markerSet:{name}"])
    layer.Save()
    back = read_capture_layer(new)
    assert back.neutral_window is None and back.neutral_frame == 4


def test_a_recorded_stretch_outside_the_layer_is_refused(tmp_path):
    from pxr import Sdf

    new = tmp_path / "cap.usda"
    write_capture_layer(new, _capture(np.random.default_rng(5)), prov={"processor": "test"})
    layer = Sdf.Layer.FindOrOpen(str(new))
    layer.GetAttributeAtPath("/Capture/Markers.usdface:markerSet:neutralEndTime").default = 99.0
    layer.Save()
    with pytest.raises(InputError, match=r"neutral stretch 14-99 must hold the neutral time 14 and lie within the "
                                         r"layer's time codes 10-59"):
        read_capture_layer(new)
