"""Muscle rig layers, simulated animation layers, and the muscles / simulate / fit-muscles commands."""
from __future__ import annotations

import json

import numpy as np
import pytest

import usdface.cli as cli
from usdface.errors import InputError
from usdface.usd.muscle_layer import read_animation_points, read_contractions, read_rig_layer, write_rig_layer


@pytest.fixture
def tissue_cli():
    """The usdface command, in-process."""
    def run(*argv):
        return cli.main([str(a) for a in argv])
    return run


@pytest.fixture(scope="module")
def mesh_layer(tmp_path_factory, sample_assets):
    out = tmp_path_factory.mktemp("tissue") / "face.usdc"
    assert cli.main(["import-mesh", str(sample_assets / "meshes" / "makehuman_hm08_face_cm.obj"), "-o", str(out),
                     "-q"]) == 0
    return out


def test_rig_layer_round_trip(face, mesh_layer, tmp_path):
    from pxr import Usd, UsdGeom

    from usdface.usd.layers import provenance
    from usdface.usd.validation import check_layer

    path = tmp_path / "rig.usda"
    write_rig_layer(path, face.rig, mesh_path=mesh_layer, prov=provenance("muscles", options={}, inputs={}))
    rig = read_rig_layer(path, units="cm")
    assert rig.names == face.rig.names
    for a, b in zip(rig.muscles, face.rig.muscles):
        assert a.type == b.type and a.max_force == b.max_force
        assert a.inner_radius == pytest.approx(b.inner_radius) and a.outer_radius == pytest.approx(b.outer_radius)
        for v in ("origin", "insertion", "centre", "semi_axes"):
            va, vb = getattr(a, v), getattr(b, v)
            assert (va is None and vb is None) or np.allclose(va, vb)
    assert np.allclose(rig.jaw_pivot, face.rig.jaw_pivot) and rig.jaw_max_angle == face.rig.jaw_max_angle
    assert rig.landmarks["mouthCorner_L"] == pytest.approx(face.rig.landmarks["mouthCorner_L"], abs=1e-5)
    stage = Usd.Stage.Open(str(path))
    prim = stage.GetPrimAtPath("/Face/Muscles/zygomaticMajor_L")
    assert prim.IsA(UsdGeom.BasisCurves) and prim.HasAPI("FaceMuscleAPI")
    assert prim.GetRelationship("usdface:muscle:mesh").GetTargets()[0] == "/Face/Geom"
    assert stage.GetPrimAtPath("/Face/Geom")  # the mesh layer is sublayered: the target resolves
    assert len(UsdGeom.BasisCurves(stage.GetPrimAtPath("/Face/Muscles/orbicularisOris")).GetPointsAttr().Get()) == 32
    assert not [f for f in check_layer(path) if f.severity == "error"]
    # rigs convert units to the mesh's
    mm = read_rig_layer(path, units="mm")
    assert np.allclose(mm.muscle("mentalis").origin, 10 * rig.muscle("mentalis").origin)


def test_muscles_simulate_commands(tissue_cli, mesh_layer, tmp_path, sample_assets, capsys):
    rig = tmp_path / "rig.usda"
    layout = sample_assets / "layouts" / "makehuman_hm08_face.layout.json"
    assert tissue_cli("muscles", "--mesh", mesh_layer, "--layout", layout, "--force", "zygomaticMajor=20000",
                      "-o", rig, "-q") == 0
    assert read_rig_layer(rig).muscle("zygomaticMajor_R").max_force == 20000
    timeline = tmp_path / "t.json"
    timeline.write_text(json.dumps({"rate": 24, "keys": {"zygomaticMajor_L": [[1, 0.0], [3, 1.0]],
                                                         "jawOpen": [[1, 0.0], [3, 0.3]]}}))
    anim = tmp_path / "anim.usdc"
    assert tissue_cli("simulate", "--mesh", mesh_layer, "--rig", rig, "--timeline", timeline, "-o", anim, "--json") == 0
    summary = json.loads(capsys.readouterr().out)
    # time codes are frame numbers from 0: the keys stay at frames 1..3 and frame 0 holds the first key
    assert summary["frames"] == 4 and summary["springs"] == 39380 and summary["elements"] == 3868
    times, pts = read_animation_points(anim)
    assert times.tolist() == [0.0, 1.0, 2.0, 3.0] and pts.shape == (4, 2020, 3)
    assert np.abs(pts[1] - pts[2]).max() > 0.05        # the face moves
    t, contr = read_contractions(anim)
    assert contr["zygomaticMajor_L"].tolist() == pytest.approx([0.0, 0.0, 0.5, 1.0])
    # the layer stands alone (mesh and muscles come with it); the shot stage sits beside it
    from pxr import Usd, UsdGeom

    alone = Usd.Stage.Open(str(anim))
    assert alone.GetPrimAtPath("/Face/Geom").GetTypeName() == "Mesh"
    assert UsdGeom.Mesh(alone.GetPrimAtPath("/Face/Geom")).GetPointsAttr().GetNumTimeSamples() == 4
    assert alone.GetPrimAtPath("/Face/Muscles/zygomaticMajor_L").GetTypeName() == "BasisCurves"
    assert summary["shot"] == str(tmp_path / "anim_shot.usda")
    shot = Usd.Stage.Open(summary["shot"])
    assert (shot.GetStartTimeCode(), shot.GetEndTimeCode(), shot.GetTimeCodesPerSecond()) == (0, 3, 24)
    assert not contr["zygomaticMajor_R"].any()
    # an expression preset, ramped and held
    anim2 = tmp_path / "surprise.usdc"
    assert tissue_cli("simulate", "--mesh", mesh_layer, "--rig", rig, "--expression", "surprise", "--ramp", "2",
                      "--hold", "1", "-o", anim2, "-q") == 0
    assert read_animation_points(anim2)[0].tolist() == [0.0, 1.0, 2.0, 3.0]  # ramp 0..2, hold to 3


def test_bad_inputs_exit_2_and_leave_nothing(tissue_cli, mesh_layer, tmp_path, sample_assets, capsys):
    rig = tmp_path / "rig.usda"
    assert tissue_cli("muscles", "--mesh", mesh_layer, "-o", rig, "-q") == 0
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps({"rate": 24, "keys": {"risorius_L": [[0, 0.0], [4, 1.5]]}}))
    out = tmp_path / "out.usdc"
    assert tissue_cli("simulate", "--mesh", mesh_layer, "--rig", rig, "--timeline", bad, "-o", out) == 2
    assert "risorius_L" in capsys.readouterr().err and not out.exists()
    bad.write_text(json.dumps({"rate": 24, "keys": {"buccinator_L": [[0, 0.0], [4, 1.0]]}}))
    assert tissue_cli("simulate", "--mesh", mesh_layer, "--rig", rig, "--timeline", bad, "-o", out) == 2
    assert "buccinator_L" in capsys.readouterr().err
    # a diverging simulation: stopped, frame and cause reported, nothing left behind
    assert tissue_cli("simulate", "--mesh", mesh_layer, "--rig", rig, "--expression", "surprise", "--integrator",
                      "explicit", "--dt", "0.004", "--ramp", "3", "--hold", "0", "-o", out) == 2
    err = capsys.readouterr().err
    assert "frame" in err and "diverged" in err and "stability limit" in err
    assert not out.exists() and not list(tmp_path.glob(".out.tmp-*"))
    with pytest.raises(InputError, match="no such file"):
        read_rig_layer(tmp_path / "missing.usda")


def test_far_origin_rig_is_refused(tissue_cli, mesh_layer, face, tmp_path, capsys):
    from usdface.usd.layers import provenance

    m = face.rig.muscle("procerus")
    rig = face.rig.replace(muscles=tuple(x if x.name != "procerus" else m.replace(origin=m.origin + [0, 0, -8.0])
                                         for x in face.rig.muscles))
    path = tmp_path / "far.usda"
    write_rig_layer(path, rig, mesh_path=mesh_layer, prov=provenance("test", options={}, inputs={}))
    assert tissue_cli("simulate", "--mesh", mesh_layer, "--rig", path, "--expression", "anger", "-o",
                      tmp_path / "a.usdc") == 2
    assert "procerus (origin" in capsys.readouterr().err


def test_fit_muscles_command(tissue_cli, mesh_layer, tmp_path, sample_assets, capsys):
    cap, bind, rig = tmp_path / "cap.usdc", tmp_path / "bind.usda", tmp_path / "rig.usda"
    layout = sample_assets / "layouts" / "makehuman_hm08_face.layout.json"
    assert cli.main(["import-capture", str(sample_assets / "capture" / "JawMoCap.ma"), "-o", str(cap), "-q"]) == 0
    assert cli.main(["bind", "--mesh", str(mesh_layer), "--capture", str(cap), "--layout", str(layout), "-o", str(bind),
                     "-q"]) == 0
    assert tissue_cli("muscles", "--mesh", mesh_layer, "--layout", layout, "-o", rig, "-q") == 0
    out, report = tmp_path / "fit.usdc", tmp_path / "fit.json"
    assert tissue_cli("fit-muscles", "--mesh", mesh_layer, "--rig", rig, "--capture", cap, "--binding", bind,
                      "--frames", "200", "260", "--step", "20", "--refine", "0", "--report", report, "-o", out,
                      "--json") == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary["frames"] == 3
    assert summary["errors"]["pass1"]["rms"] < summary["errors"]["still"]["rms"]
    data = json.loads(report.read_text())
    assert data["controls"]["timeCodes"] == [200.0, 220.0, 240.0]
    values = np.asarray(data["controls"]["values"])
    assert values.shape == (3, 24) and values.min() >= 0 and values.max() <= 1
    times, pts = read_animation_points(out)
    assert times.tolist() == [200.0, 220.0, 240.0]


def test_installed_command(tmp_path, sample_assets, repo_root):
    """The tissue subcommands through ``python -m usdface`` (a separate process, as users run it)."""
    import subprocess
    import sys

    out = tmp_path / "rig.usda"
    proc = subprocess.run([sys.executable, "-m", "usdface", "muscles", "--mesh",
                           str(sample_assets / "meshes" / "makehuman_hm08_face_cm.obj"), "-o", str(out), "--json"],
                          capture_output=True, text=True, timeout=120, cwd=str(repo_root))
    assert proc.returncode == 0, proc.stderr
    assert json.loads(proc.stdout)["muscles"][0] == "zygomaticMajor_L"
    assert read_rig_layer(out).placement == "mesh"


def test_tissue_commands_in_memory_write_nothing(mesh_layer, sample_assets, tmp_path, monkeypatch):
    """`usdface.api.muscles` and `simulate` on layers in memory (a DCC's scene): the same rig and the
    same animation as from files, and no file written anywhere."""
    from pxr import Sdf

    from usdface import api
    from usdface.options import MusclesOptions, SimulateOptions

    files = tmp_path / "files"
    files.mkdir()
    rig_file, anim_file = files / "rig.usda", files / "joy.usdc"
    options = MusclesOptions(force={"zygomaticMajor": 20000})
    assert api.muscles(mesh_layer, options, output=rig_file).layer == str(rig_file)
    sim_options = SimulateOptions(expression="joy", ramp=1, hold=0)
    from_files = api.simulate(mesh_layer, rig_file, sim_options, output=anim_file)
    assert from_files.summary["shot"] == str(files / "joy_shot.usda")

    work = tmp_path / "work"
    work.mkdir()
    monkeypatch.chdir(work)
    mesh = api.import_mesh(str(sample_assets / "meshes" / "makehuman_hm08_face_cm.obj")).layer
    rig = api.muscles(mesh, options).layer
    assert isinstance(rig, Sdf.Layer) and rig.anonymous
    assert read_rig_layer(rig).muscle("zygomaticMajor_R").max_force == 20000
    assert [m.name for m in read_rig_layer(rig).muscles] == [m.name for m in read_rig_layer(rig_file).muscles]
    result = api.simulate(mesh, rig, sim_options)
    assert result.summary["shot"] is None and "shot stage" not in result.text[0]
    assert list(work.iterdir()) == [] and sorted(p.name for p in files.iterdir()) == ["joy.usdc", "joy_shot.usda",
                                                                                      "rig.usda"]
    times, pts = read_animation_points(None, stage=api.new_stage(result.layer, rig, mesh))
    times_f, pts_f = read_animation_points(anim_file)
    assert times.tolist() == times_f.tolist() == [0.0, 1.0]
    np.testing.assert_array_equal(pts, pts_f)
    assert read_contractions(None, stage=api.new_stage(result.layer, rig))[1]["zygomaticMajor_L"].tolist() == [0.0, 1.0]


def test_tissue_options_parse_and_check_once():
    from usdface.errors import OptionError
    from usdface.options import FitMusclesOptions, MusclesOptions, SimulateOptions
    from usdface.tissue.fit import FitParameters

    o = MusclesOptions(force=["zygomaticMajor=20000", "risorius= 5", "zygomaticMajor=1"], tissue={"k_deep": 25})
    assert list(o.max_forces().items()) == [("zygomaticMajor", 1.0), ("risorius", 5.0)]
    assert o.tissue_settings() == {"k_deep": 25.0}
    assert o.replace(layout="face.layout.json").force == o.force  # a copy keeps the parsed values
    bad = [(MusclesOptions, {"force": ["zyg"]}, "--force: expected NAME=VALUE; got 'zyg'"),
           (MusclesOptions, {"force": ["zygomaticMajor=abc"]}, "--force: zygomaticMajor needs a number; got 'abc'"),
           (MusclesOptions, {"force": ["bogus=5"]}, "--force: unknown muscle(s) bogus; known: corrugator, "),
           (MusclesOptions, {"tissue": ["bogus=1"]}, "unknown tissue option(s) bogus; known: "),
           (SimulateOptions, {"tissue": ["k_deep=-1"]}, "tissue option k_deep must be a positive number; got -1.0"),
           (MusclesOptions, {"layout": "a.json", "binding": "b.usda"},
            "muscles: give at most one of --layout and --binding"),
           (SimulateOptions, {"dt": "fast"}, "--dt fast: expected a number"),
           (SimulateOptions, {"ramp": 1.5}, "--ramp 1.5: expected a whole number"),
           (FitMusclesOptions, {"step": 0}, "--step must be >= 1; got 0"),
           (FitMusclesOptions, {"refine": -1}, "--refine -1: expected a whole number >= 0"),
           (FitMusclesOptions, {"regularization": -1}, "--regularization -1: expected a number >= 0"),
           (FitMusclesOptions, {"frames": [3]}, "--frames [3]: expected two values (FIRST END)")]
    for cls, kwargs, message in bad:
        with pytest.raises(OptionError) as e:
            cls(**kwargs)
        assert str(e.value).startswith(message), (kwargs, str(e.value))
    f = FitMusclesOptions(frames=["200", 260], refine=0)
    assert f.frames == (200, 260) and f.parameters() == FitParameters(regularization=1e-3, refine=0)


def test_fit_muscles_refuses_negative_refinement_in_one_line(tissue_cli, tmp_path, capsys):
    """``--refine -1`` and ``--regularization -1`` used to end in a traceback (exit 1) after the
    capture was read; they are refused before any work, naming the option."""
    args = ["fit-muscles", "--mesh", tmp_path / "m.usdc", "--rig", tmp_path / "r.usda", "--capture",
            tmp_path / "c.usdc", "--binding", tmp_path / "b.usda", "-o", tmp_path / "fit.usdc"]
    assert tissue_cli(*args, "--refine", "-1") == 2
    assert capsys.readouterr().err.strip() == "usdface fit-muscles: error: --refine -1: expected a whole number >= 0"
    assert tissue_cli(*args, "--regularization", "-1") == 2
    assert capsys.readouterr().err.strip() == \
        "usdface fit-muscles: error: --regularization -1.0: expected a number >= 0"


def test_fit_muscles_checks_the_report_folder_first(tissue_cli, mesh_layer, tmp_path, capsys):
    """A report in a missing folder used to fail (exit 1) after the fit, with the layer already
    written; it is refused before any work."""
    out, report = tmp_path / "fit.usdc", tmp_path / "missing" / "fit.json"
    assert tissue_cli("fit-muscles", "--mesh", mesh_layer, "--rig", tmp_path / "r.usda", "--capture",
                      tmp_path / "c.usdc", "--binding", tmp_path / "b.usda", "--report", report, "-o", out) == 2
    assert capsys.readouterr().err.strip() == \
        f"usdface fit-muscles: error: --report {report}: folder {report.parent} does not exist"
    assert not out.exists()
