"""Units, time codes and options through the whole pipeline: the same motion in other units or
other layers gives the same animation; options reach the step they belong to."""
from __future__ import annotations

import json

import numpy as np
import pytest

from usdface.model.capture import Capture
from usdface.io.csv_format import write_csv
from usdface.io.maya_ascii import read_maya_ascii
from usdface.usd.capture_layer import read_capture_layer, write_capture_layer

LAYOUT = "makehuman_hm08_face.layout.json"
MESH = "makehuman_hm08_face_cm.obj"


@pytest.fixture(scope="module")
def jaw300(sample_assets):
    cap = read_maya_ascii(sample_assets / "capture" / "JawMoCap.ma")
    return Capture(names=cap.names, positions=cap.positions[:300], rate=cap.rate, units="cm", source="jaw300")


def _anim_points(out, frames=(0, 150, 299)):
    from pxr import Usd, UsdGeom

    stage = Usd.Stage.Open(str(out / "shot.usda"))
    attr = UsdGeom.Mesh(stage.GetPrimAtPath("/Face/Geom")).GetPointsAttr()
    return np.stack([np.asarray(attr.Get(f), dtype=np.float64) for f in frames])


def test_a_capture_in_mm_gives_the_same_animation_as_in_cm(jaw300, sample_assets, tmp_path, cli):
    cm_csv, mm_csv = tmp_path / "jaw_cm.csv", tmp_path / "jaw_mm.csv"
    write_csv(cm_csv, jaw300)
    write_csv(mm_csv, Capture(names=jaw300.names, positions=jaw300.positions * 10, rate=60.0, units="mm",
                              source="mm"))
    common = ["--mesh", sample_assets / "meshes" / MESH, "--layout", sample_assets / "layouts" / LAYOUT, "-q"]
    assert cli("run", "--capture", cm_csv, "-o", tmp_path / "cm", *common) == 0
    assert cli("run", "--capture", mm_csv, "-o", tmp_path / "mm", *common) == 0
    np.testing.assert_allclose(_anim_points(tmp_path / "mm"), _anim_points(tmp_path / "cm"), atol=2e-4)


def test_transfer_refuses_a_capture_in_other_units_than_the_bound_one(jaw300, sample_assets, tmp_path, capsys, cli):
    out = tmp_path / "cm"
    write_capture_layer(tmp_path / "cm.usdc", jaw300, prov={})
    assert cli("run", "--capture", tmp_path / "cm.usdc", "--mesh", sample_assets / "meshes" / MESH,
               "--layout", sample_assets / "layouts" / LAYOUT, "--no-stabilize", "-o", out, "-q") == 0
    mm = Capture(names=jaw300.names, positions=jaw300.positions * 10, rate=60.0, units="mm", source="mm")
    write_capture_layer(tmp_path / "mm.usdc", mm, prov={})
    code = cli("transfer", "--mesh", out / "mesh.usdc", "--capture", tmp_path / "mm.usdc", "--binding",
               out / "binding.usda", "--analysis", out / "analysis.usdc", "-o", tmp_path / "anim.usdc")
    assert code == 2
    err = capsys.readouterr().err
    assert "mm" in err and "bind this capture again" in err
    assert not (tmp_path / "anim.usdc").exists()


def test_a_composed_stage_reads_back_as_the_capture_it_holds(sample_assets, tmp_path, cli):
    """A binding stage references the capture under a placement transform, in the mesh's units:
    reading the capture from it gives the capture's own units and head motion."""
    out = tmp_path / "run"
    assert cli("run", "--capture", sample_assets / "capture" / "NoseMoCap.usdc", "--mesh",
               sample_assets / "meshes" / MESH, "--layout", sample_assets / "layouts" / LAYOUT,
               "--trim", "0", "200", "--method", "euclidean", "-o", out, "-q") == 0
    own = read_capture_layer(out / "capture.usdc")
    via_binding = read_capture_layer(out / "binding.usda")
    assert via_binding.units == own.units == "cm"
    np.testing.assert_allclose(via_binding.head_motion, own.head_motion, atol=1e-12)
    np.testing.assert_allclose(via_binding.positions, own.positions, atol=1e-6)


def test_neutral_time_zero_with_negative_start(sample_assets, tmp_path, cli):
    out = tmp_path / "neg.usdc"
    assert cli("import-capture", sample_assets / "capture" / "JawMoCap.ma", "-o", out, "--neutral", "10",
               "--start-frame", "-10", "-q") == 0
    cap = read_capture_layer(out)
    assert cap.start_frame == -10 and cap.neutral_frame == 10


def test_neutral_counts_frames_of_the_capture_before_resampling(sample_assets, tmp_path, cli):
    out = tmp_path / "r.usdc"
    assert cli("import-capture", sample_assets / "capture" / "JawMoCap.ma", "-o", out, "--neutral", "100",
               "--resample", "30", "-q") == 0
    cap = read_capture_layer(out)
    assert cap.rate == 30 and cap.neutral_frame == 50  # source frame 100 at 60 Hz


def test_run_passes_resample_and_start_frame(sample_assets, tmp_path, cli):
    out = tmp_path / "run"
    assert cli("run", "--capture", sample_assets / "capture" / "JawMoCap.ma", "--mesh",
               sample_assets / "meshes" / MESH, "--layout", sample_assets / "layouts" / LAYOUT,
               "--trim", "0", "240", "--resample", "30", "--start-frame", "1001", "--method", "euclidean",
               "-o", out, "-q") == 0
    summary = json.loads((out / "summary.json").read_text())
    assert summary["rate"] == 30 and summary["frames"] == 120
    from pxr import Usd

    stage = Usd.Stage.Open(str(out / "shot.usda"))
    assert (stage.GetStartTimeCode(), stage.GetEndTimeCode(), stage.GetTimeCodesPerSecond()) == (1001, 1120, 30)


@pytest.mark.parametrize("argv, message", [
    (["--rbf", "paper", "--kernel", "cubic"], "need a kernel that decays with distance"),
    (["--rbf", "paper", "--polynomial"], "interpolate only"),
    (["--stiffness", "no_such_widths.json"], "no_such_widths.json"),
    (["--stiffness", "-1"], "--stiffness -1: expected a number > 0"),  # a width, not a file named -1
])
def test_run_refuses_bad_transfer_options_before_work(argv, message, sample_assets, tmp_path, capsys, cli):
    code = cli("run", "--capture", sample_assets / "capture" / "JawMoCap.usdc", "--mesh",
               sample_assets / "meshes" / MESH, "--layout", sample_assets / "layouts" / LAYOUT,
               "-o", tmp_path / "out", *argv)
    assert code == 2 and message in capsys.readouterr().err
    assert not (tmp_path / "out").exists()


def test_usdz_output_and_frames_outside_the_range_are_refused(sample_assets, tmp_path, capsys, cli):
    assert cli("import-mesh", sample_assets / "meshes" / MESH, "-o", tmp_path / "m.usdz") == 2
    assert "expected a file ending in" in capsys.readouterr().err
    assert cli("preview", sample_assets / "capture" / "JawMoCap.usdc", "--frame", "5000", "-o",
               tmp_path / "x.png") == 2
    assert "outside the layer's time range" in capsys.readouterr().err
