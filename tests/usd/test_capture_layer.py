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
