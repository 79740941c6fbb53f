"""`usdface solve`, `solve --apply` and the run step on real captures, through the CLI entry point."""
import json

import numpy as np
import pytest

from usdface.cli import main


def cli(*args):
    return main([str(a) for a in args])


@pytest.fixture(scope="module")
def rig_args(sample_assets):
    return ["--mesh", sample_assets / "meshes" / "makehuman_hm08_face_cm.obj",
            "--shapes", sample_assets / "meshes" / "makehuman_hm08_face_units_cm.npz",
            "--layout", sample_assets / "layouts" / "makehuman_hm08_face.layout.json"]


@pytest.fixture(scope="module")
def jaw(tmp_path_factory, sample_assets, rig_args):
    out = tmp_path_factory.mktemp("jaw")
    import contextlib
    import io

    buf = io.StringIO()
    with contextlib.redirect_stdout(buf):
        code = cli("solve", *rig_args, "--capture", sample_assets / "capture" / "JawMoCap.ma", "-o", out / "jaw.usdc",
                   "--csv", out / "jaw.csv", "--livelink", out / "jaw_ll.csv", "--json", "-q")
    assert code == 0
    return out, json.loads(buf.getvalue())


def test_jaw_take_curves(jaw):
    from usdface.blendshape.csvio import read_curves_csv
    from usdface.usd.blendshape_layer import evaluate_curves_layer, read_curves_layer

    out, summary = jaw
    assert summary["frames"] == 1590 and len(summary["residual"]) == 1590
    assert summary["residualMean"] < 0.6 * summary["stillResidualMean"]
    names, frames, w, rate = read_curves_csv(out / "jaw.csv")
    assert rate == pytest.approx(60.0) and frames[0] == 0 and w.shape == (1590, 52)
    assert w.min() >= 0 and w.max() <= 1
    layer = read_curves_layer(out / "jaw.usdc")
    assert np.abs(layer["weights"] - w).max() < 1e-5  # one set of curves in every output
    assert summary["headMotion"] is True
    ll = (out / "jaw_ll.csv").read_text().splitlines()
    assert ll[0].startswith("Timecode,BlendShapeCount,EyeBlinkLeft") and len(ll) == 1591
    times, pts = evaluate_curves_layer(out / "jaw.usdc", times=[0.0, 400.0])
    assert np.abs(pts[0] - pts[1]).max() > 2.0  # the jaw opens by centimetres in UsdSkel's evaluation


@pytest.mark.parametrize("take", ["Jaw", "Eyebrows", "Nose"])
def test_real_takes_beat_a_still_face(sample_assets, makehuman, take):
    from usdface.blendshape.take import solve_take
    from usdface.mesh.binding import bind_layout
    from usdface.mesh.layout import read_layout
    from usdface.usd.capture_layer import read_capture_layer

    cap = read_capture_layer(sample_assets / "capture" / f"{take}MoCap.usdc")
    binding = bind_layout(makehuman["mesh"], read_layout(sample_assets / "layouts" / "makehuman_hm08_face.layout.json"),
                          cap)
    res = solve_take(makehuman["rig"], cap, binding)
    sol = res.solution
    assert np.nanmean(sol.residual) < 0.8 * np.nanmean(sol.still_residual)
    rig = makehuman["rig"]
    d = res.displacements
    if take == "Jaw":
        chin = np.linalg.norm(d[:, binding.names.index("Chin")], axis=1)
        hold = chin > 0.8 * chin.max()
        assert hold[np.argmax(sol.weights[:, rig.index("jawOpen")])]
    if take == "Eyebrows":
        inner = [binding.names.index("Leyebrow_Inside"), binding.names.index("Reyebrow_Inside")]
        up = d[:, inner, 1].mean(axis=1)
        raised = up > 0.25 * up.max()
        w = sol.weights[:, rig.index("browInnerUp")]
        at_max = w >= w.max() - 1e-3
        assert raised[np.argmax(w)] and raised[at_max].mean() > 0.99


def test_bad_inputs_write_nothing(tmp_path, sample_assets, rig_args, capsys):
    from usdface.io.captures import read_capture
    from usdface.io.csv_format import write_csv

    cap = read_capture(sample_assets / "capture" / "NoseMoCap.ma")
    short = cap.replace(positions=cap.positions[:60])
    renamed = short.replace(names=tuple("Chin_X" if n == "Chin" else n for n in short.names))
    write_csv(tmp_path / "renamed.csv", renamed)
    out = tmp_path / "out"
    out.mkdir()
    assert cli("solve", *rig_args, "--capture", tmp_path / "renamed.csv", "-o", out / "c.usdc", "--csv",
               out / "c.csv", "-q") == 2
    err = capsys.readouterr().err
    assert "Chin" in err and err.count("\n") == 1
    assert list(out.iterdir()) == []
    # NaN offsets: named, nothing written
    z = np.load(sample_assets / "meshes" / "makehuman_hm08_face_units_cm.npz")
    d = z["deltas"].copy()
    d[5, 3, 0] = np.nan
    np.savez(tmp_path / "nan.npz", names=z["names"], deltas=d)
    args = list(rig_args)
    args[3] = tmp_path / "nan.npz"
    assert cli("solve", *args, "--capture", sample_assets / "capture" / "NoseMoCap.ma", "-o", out / "c.usdc", "-q") == 2
    assert "cheekPuff" in capsys.readouterr().err and list(out.iterdir()) == []
    # a rig lacking ARKit names with --livelink: an error before anything is written
    names = z["names"].copy()
    names[0] = "frownL"
    np.savez(tmp_path / "renamed.npz", names=names, deltas=z["deltas"])
    args[3] = tmp_path / "renamed.npz"
    write_csv(tmp_path / "short.csv", short)
    assert cli("solve", *args, "--capture", tmp_path / "short.csv", "-o", out / "c.usdc", "--livelink",
               out / "ll.csv", "-q") == 2
    assert "lacks 1 of the 52 ARKit shapes" in capsys.readouterr().err
    # the output may not replace an input
    assert cli("solve", *rig_args, "--capture", tmp_path / "short.csv", "-o", out / "c.usdc",
               "--csv", tmp_path / "short.csv", "-q") == 2
    assert "would overwrite the input" in capsys.readouterr().err
    assert list(out.iterdir()) == []


def test_still_capture_and_unmoved_markers(tmp_path, sample_assets, rig_args, caplog):
    from usdface.io.captures import read_capture
    from usdface.io.csv_format import write_csv

    cap = read_capture(sample_assets / "capture" / "JawMoCap.ma")
    still = cap.replace(positions=np.repeat(cap.positions[:1], 40, axis=0))
    write_csv(tmp_path / "still.csv", still)
    z = np.load(sample_assets / "meshes" / "makehuman_hm08_face_units_cm.npz")
    from usdface.io.meshes import read_mesh
    from usdface.mesh.layout import read_layout
    from usdface.mesh.layout_binding import binding_from_layout

    mesh = read_mesh(sample_assets / "meshes" / "makehuman_hm08_face_cm.obj")
    b = binding_from_layout(mesh, read_layout(sample_assets / "layouts" / "makehuman_hm08_face.layout.json"))
    d = z["deltas"].copy()
    d[:, b.triangle_vertices[b.names.index("ForeHead_M")]] = 0.0  # no shape moves that marker any more
    np.savez(tmp_path / "rig.npz", names=z["names"], deltas=d)
    args = list(rig_args)
    args[3] = tmp_path / "rig.npz"
    import contextlib
    import io

    buf = io.StringIO()
    with contextlib.redirect_stdout(buf):
        assert cli("solve", *args, "--capture", tmp_path / "still.csv", "-o", tmp_path / "still.usdc", "--csv",
                   tmp_path / "still_curves.csv", "--json", "--no-stabilize") == 0
    s = json.loads(buf.getvalue())
    assert max(s["weightMax"].values()) == 0.0 and s["residualMax"] == 0.0
    assert any("ForeHead_M" in w and "moved by no shape" in w for w in s["warnings"])
    assert "ForeHead_M" in caplog.text


def test_apply_curves_to_the_stylized_face(jaw, tmp_path, sample_assets):
    from usdface.usd.blendshape_layer import evaluate_curves_layer, read_curves_layer

    out, _ = jaw
    z = np.load(sample_assets / "meshes" / "makehuman_hm08_face_units_cm.npz")
    keep = [i for i, n in enumerate(z["names"]) if n != "cheekPuff"]
    np.savez(tmp_path / "stylized.npz", names=z["names"][keep], deltas=z["deltas"][keep])  # no neutral: the mesh's
    for src in (out / "jaw.csv", out / "jaw.usdc"):
        dst = tmp_path / f"applied_{src.suffix[1:]}.usdc"
        assert cli("solve", "--apply", src, "--mesh", sample_assets / "meshes" / "makehuman_hm08_face_stylized_cm.obj",
                   "--shapes", tmp_path / "stylized.npz", "-o", dst, "--fps", "24", "-q") == 0
        got = read_curves_layer(dst)
        assert got["rate"] == 24.0 and len(got["names"]) == 51 and got["weights"].shape[0] == 636
    src_w = read_curves_layer(out / "jaw.usdc")
    j = src_w["names"].index("jawOpen")
    applied = read_curves_layer(tmp_path / "applied_usdc.usdc")
    # frame 200 at 24 fps is frame 500 at 60 Hz
    assert applied["weights"][200, applied["names"].index("jawOpen")] == pytest.approx(src_w["weights"][500, j], abs=1e-5)
    _, pts = evaluate_curves_layer(tmp_path / "applied_usdc.usdc", times=[200.0])
    assert np.isfinite(pts).all()


def test_blendshapes_step_on_run_layers(tmp_path, sample_assets):
    """`run`'s blend-shape step (the registry's `blendshapes`) on the layers run writes; the shot
    stage run composes from its summary plays the curves as the curves layer alone does."""
    from usdface import api, registry
    from usdface.options import CaptureOptions, SolveOptions
    from usdface.usd.analysis_layer import write_shot_stage
    from usdface.usd.blendshape_layer import evaluate_curves_layer

    api.import_mesh(str(sample_assets / "meshes" / "makehuman_hm08_face_cm.obj"), output=tmp_path / "mesh.usdc")
    api.import_capture(str(sample_assets / "capture" / "JawMoCap.ma"),
                       CaptureOptions(stabilize="auto", trim=(300, 500)), output=tmp_path / "capture.usdc")
    api.bind(tmp_path / "mesh.usdc", tmp_path / "capture.usdc",
             {"layout": str(sample_assets / "layouts" / "makehuman_hm08_face.layout.json")},
             output=tmp_path / "binding.usda")
    r = registry.call("blendshapes", tmp_path / "mesh.usdc", tmp_path / "capture.usdc", tmp_path / "binding.usda",
                      options=SolveOptions(shapes=str(sample_assets / "meshes" / "makehuman_hm08_face_units_cm.npz")),
                      output=tmp_path / "blendshapes.usdc", csv=tmp_path / "curves.csv")
    for name in ("blendshapes.usdc", "curves.csv"):
        assert (tmp_path / name).is_file()
    assert not (tmp_path / "curves_livelink.csv").exists()
    assert r.layers == {"output": str(tmp_path / "blendshapes.usdc")}
    assert r.files == {"csv": str(tmp_path / "curves.csv")}
    s = r.summary
    assert s["frames"] == 200 and s["residualMean"] < s["stillResidualMean"]
    assert s["shotStage"] == {"rate": 60.0, "start": 0, "end": 199, "units": "cm", "stabilizedCapture": False}
    st = s["shotStage"]
    write_shot_stage(tmp_path / "shot_blendshapes.usda",
                     layers=[tmp_path / "blendshapes.usdc", tmp_path / "binding.usda"], rate=st["rate"],
                     start=st["start"], end=st["end"], units=st["units"], stabilized_capture=st["stabilizedCapture"])
    _, shot = evaluate_curves_layer(tmp_path / "shot_blendshapes.usda", times=[100.0])
    _, alone = evaluate_curves_layer(tmp_path / "blendshapes.usdc", times=[100.0])
    assert np.allclose(shot, alone)


def test_capture_markers_must_match_the_binding(sample_assets, makehuman):
    from usdface.blendshape.take import solve_take
    from usdface.errors import MarkerError
    from usdface.mesh.binding import bind_layout
    from usdface.mesh.layout import read_layout
    from usdface.usd.capture_layer import read_capture_layer

    cap = read_capture_layer(sample_assets / "capture" / "NoseMoCap.usdc")
    binding = bind_layout(makehuman["mesh"], read_layout(sample_assets / "layouts" / "makehuman_hm08_face.layout.json"),
                          cap)
    extra = cap.replace(names=cap.names + ("Ear_L",),
                        positions=np.concatenate([cap.positions, cap.positions[:, :1]], axis=1))
    with pytest.raises(MarkerError, match="not in the binding: Ear_L"):
        solve_take(makehuman["rig"], extra, binding)
    fewer = cap.replace(names=cap.names[1:], positions=cap.positions[:, 1:])
    with pytest.raises(MarkerError, match=f"not in the capture: {cap.names[0]}"):
        solve_take(makehuman["rig"], fewer, binding)


def test_reduced_keys_are_the_same_curves_in_every_output(tmp_path, sample_assets, rig_args):
    from usdface.blendshape.csvio import read_curves_csv
    from usdface.usd.blendshape_layer import head_motion_of_layer, read_curves_layer

    out = tmp_path / "k.usdc"
    assert cli("solve", *rig_args, "--capture", sample_assets / "capture" / "NoseMoCap.ma", "-o", out, "--csv",
               tmp_path / "k.csv", "--fps", "25", "--key-tolerance", "0.02", "--no-head-motion", "-q") == 0
    layer = read_curves_layer(out)
    names, frames, w, rate = read_curves_csv(tmp_path / "k.csv")
    assert rate == pytest.approx(25.0) and layer["rate"] == 25.0
    assert layer["times"].size < frames.size  # fewer samples than frames
    interp = np.stack([np.interp(frames, layer["times"], layer["weights"][:, k]) for k in range(len(names))], axis=1)
    assert np.abs(interp - w).max() < 2e-6  # USD's linear interpolation gives the CSV's curves
    assert head_motion_of_layer(out) is None


def test_corrective_points_shot_hits_the_markers(tmp_path, sample_assets):
    from pxr import Usd, UsdGeom

    from usdface.blendshape.rig import load_npz_rig
    from usdface.blendshape.take import solve_take
    from usdface.capture.retarget import marker_displacements
    from usdface.io.meshes import read_mesh
    from usdface.mesh.binding import bind_layout
    from usdface.mesh.layout import read_layout
    from usdface import api
    from usdface.capture.conditioning import Conditioning, condition_capture
    from usdface.options import SolveOptions
    from usdface.usd.inputs import load_capture

    layout = sample_assets / "layouts" / "makehuman_hm08_face.layout.json"
    r = api.solve(str(sample_assets / "meshes" / "makehuman_hm08_face_cm.obj"),
                  str(sample_assets / "capture" / "NoseMoCap.ma"),
                  options=SolveOptions(shapes=str(sample_assets / "meshes" / "makehuman_hm08_face_units_cm.npz"),
                                       layout=str(layout), trim=(400, 560)),
                  output=tmp_path / "nose.usdc", corrective=True)
    shot = tmp_path / "nose_corrective.usdc"
    assert r.summary["corrective"]["output"] == str(shot)
    assert r.layers == {"output": str(tmp_path / "nose.usdc"), "corrective": str(shot)}
    cap, _ = condition_capture(load_capture(sample_assets / "capture" / "NoseMoCap.ma"),
                               Conditioning(trim=(400, 560), stabilize="auto"))
    mesh = read_mesh(sample_assets / "meshes" / "makehuman_hm08_face_cm.obj")
    binding = bind_layout(mesh, read_layout(layout), cap)
    rig = load_npz_rig(sample_assets / "meshes" / "makehuman_hm08_face_units_cm.npz", mesh)
    # the displacements the solve fitted: the stabilised ones with the pose refit's corrections
    d = solve_take(rig, cap, binding).displacements
    raw = marker_displacements(cap, binding.names, binding.displacement_transform())
    assert np.nanmax(np.abs(d - raw)) > 1e-3  # the refit moved them (the head motion carries the rest)
    stage = Usd.Stage.Open(str(shot))
    assert not stage.GetRootLayer().subLayerPaths and stage.GetStartTimeCode() == 0
    pts = UsdGeom.Mesh(stage.GetPrimAtPath("/Face/Geom")).GetPointsAttr()
    worst = 0.0
    for f in (0, 60, 120, 159):
        p = np.asarray(pts.Get(Usd.TimeCode(f)), dtype=np.float64)
        hit = binding.surface_points(p) - binding.surface_points(mesh.points)
        worst = max(worst, float(np.abs(hit - d[f]).max()))
    assert worst < 1e-3  # the residual the rig leaves (up to ~0.5 cm) is transferred: markers hit


def test_solve_in_memory_writes_no_file(tmp_path, sample_assets, monkeypatch):
    """api.solve without an output path authors the curves into a new in-memory layer (or ``into``);
    nothing touches the disk (the working folder is read-only), and the layer holds the curves the
    files would."""
    from pxr import Sdf

    from usdface import api
    from usdface.errors import OptionError
    from usdface.options import SolveOptions
    from usdface.usd.blendshape_layer import read_curves_layer

    options = SolveOptions(shapes=str(sample_assets / "meshes" / "makehuman_hm08_face_units_cm.npz"),
                           layout=str(sample_assets / "layouts" / "makehuman_hm08_face.layout.json"), trim=(0, 120))
    mesh = str(sample_assets / "meshes" / "makehuman_hm08_face_cm.obj")
    take = str(sample_assets / "capture" / "NoseMoCap.ma")
    work = tmp_path / "ro"
    work.mkdir()
    work.chmod(0o555)
    monkeypatch.chdir(work)
    try:
        result = api.solve(mesh, take, options=options)
        into = Sdf.Layer.CreateAnonymous("curves.usda")
        again = api.solve(mesh, take, options=options, into=into)
        with pytest.raises(OptionError, match="--corrective: name the points shot"):
            api.solve(mesh, take, options=options, corrective=True)
    finally:
        work.chmod(0o755)
    assert list(work.iterdir()) == []
    assert isinstance(result.layer, Sdf.Layer) and result.layer.anonymous and again.layer is into
    curves = read_curves_layer(result.layer)
    assert curves["weights"].shape == (120, 52) and curves["rate"] == 60.0
    assert np.array_equal(read_curves_layer(into)["weights"], curves["weights"])
    assert result.summary["output"].startswith("in-memory layer") and result.summary["residualMean"] > 0


def test_blend_shapes_belong_to_the_rig_and_the_take(tmp_path, sample_assets, jaw):
    """`run`'s blend-shape step refuses a binding made on another face than the rig's (the stylized
    MakeHuman: same topology, other points), naming both; `solve`'s curves layer records the rig's
    mesh, the bound markers and the take conditioned as `import-capture` would write it."""
    from usdface import api, registry
    from usdface.errors import InputError
    from usdface.options import SolveOptions
    from usdface.usd.layers import layer_provenance

    sa = sample_assets
    api.import_mesh(str(sa / "meshes" / "makehuman_hm08_face_cm.obj"), output=tmp_path / "mesh.usdc")
    api.import_mesh(str(sa / "meshes" / "makehuman_hm08_face_stylized_cm.obj"), output=tmp_path / "stylized.usdc")
    api.import_capture(str(sa / "capture" / "JawMoCap.ma"), {"stabilize": "auto", "trim": (300, 400)},
                       output=tmp_path / "capture.usdc")
    api.bind(tmp_path / "stylized.usdc", tmp_path / "capture.usdc",
             {"layout": str(sa / "layouts" / "makehuman_hm08_face_stylized.layout.json")},
             output=tmp_path / "binding.usda")
    with pytest.raises(InputError) as err:
        registry.call("blendshapes", tmp_path / "mesh.usdc", tmp_path / "capture.usdc", tmp_path / "binding.usda",
                      options=SolveOptions(shapes=str(sa / "meshes" / "makehuman_hm08_face_units_cm.npz")),
                      output=tmp_path / "never.usdc", csv=tmp_path / "never.csv")
    assert err.value.exit_code == 2 and not (tmp_path / "never.usdc").exists()
    assert str(err.value).startswith(f"binding {tmp_path / 'binding.usda'} was made for mesh ") and \
        f"(2020 points), the rig's mesh {tmp_path / 'mesh.usdc'} is " in str(err.value)
    # solve (default conditioning: stabilised) records what the curves belong to
    out, _ = jaw
    made = layer_provenance(out / "jaw.usdc")["identity"]
    api.import_capture(str(sa / "capture" / "JawMoCap.ma"), {"stabilize": "auto"}, output=tmp_path / "jaw.usdc")
    assert made["capture"] == layer_provenance(tmp_path / "jaw.usdc")["identity"]["capture"]
    assert made["mesh"] == layer_provenance(tmp_path / "mesh.usdc")["identity"]["mesh"]
    assert made["markers"]["count"] == 41


def test_pose_refit_is_on_by_default_recorded_and_printed(jaw, sample_assets, rig_args, tmp_path, capsys):
    """Issue 19: the solve refits the head stabilisation and the rest pose (4 rounds at most by
    default), says so, and records the rounds in the layer's provenance; --pose-refit 0 is the
    solve of usdface 0.2 (nothing refitted)."""
    from usdface.usd.layers import layer_provenance

    def read_provenance(path):
        return {**layer_provenance(path), "options": json.loads(layer_provenance(path)["options"])}

    out, summary = jaw
    refit = summary["poseRefit"]
    assert 1 <= refit["rounds"] <= 4 and refit["headAngleDegMax"] > 0
    assert read_provenance(out / "jaw.usdc")["options"]["pose_refit"] == 4
    assert cli("solve", *rig_args, "--capture", sample_assets / "capture" / "JawMoCap.ma", "--trim", "0", "300",
               "--pose-refit", "0", "-o", tmp_path / "off.usdc") == 0
    text = capsys.readouterr().out.splitlines()
    assert text[2].startswith("  rest pose: frames 0-") and not any("pose refit" in line for line in text)
    assert read_provenance(tmp_path / "off.usdc")["options"]["pose_refit"] == 0
    assert cli("solve", *rig_args, "--capture", sample_assets / "capture" / "JawMoCap.ma", "--trim", "0", "300",
               "-o", tmp_path / "on.usdc") == 0
    text = capsys.readouterr().out.splitlines()
    assert text[3].startswith("  pose refit: ") and "round(s); rest pose corrected by " in text[3]


@pytest.mark.parametrize("value", ["-1", "1.5", "many"])
def test_pose_refit_takes_a_whole_number(value, sample_assets, rig_args, tmp_path, capsys):
    assert cli("solve", *rig_args, "--capture", sample_assets / "capture" / "JawMoCap.ma", f"--pose-refit={value}",
               "-o", tmp_path / "c.usdc") == 2
    assert capsys.readouterr().err.splitlines() == [f"usdface solve: error: --pose-refit {value}: expected a whole "
                                                    "number >= 0"]
