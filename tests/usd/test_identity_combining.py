"""Layers know what they belong to (issue 20, item 2), second part: the layers of track, lift, the
tissue commands, the shot stages, and the commands that combine or read them (lift, muscles,
simulate, fit-muscles, evaluate, run, playblast, report)."""
from __future__ import annotations

import dataclasses
import shutil

import pytest

from tests.hostile import assert_one_line, run_in_process
from tests.usd.identity_helpers import LAYOUTS, OBJS, recorded, short, stripped


def _layout(sa, key="mh"):
    return sa / "layouts" / f"{LAYOUTS[key]}.layout.json"


def _mesh_ids(fx):
    return recorded(fx["mh"])["mesh"], recorded(fx["mp"])["mesh"]


@pytest.fixture(scope="module")
def tracked(tmp_path_factory, sample_assets):
    """The sample video's dots tracked into a track layer."""
    from usdface import api

    d = tmp_path_factory.mktemp("tracked")
    video = sample_assets / "video"
    api.track(str(video / "animface_dots.mp4"), {"seeds": str(video / "animface_dots.seeds.json")},
              output=d / "tracks.usdc")
    return d / "tracks.usdc"


@pytest.fixture(scope="module")
def rig(fx, sample_assets):
    """A muscle rig placed on the MakeHuman face (by its layout)."""
    from usdface import api

    out = fx["dir"] / "rig_mh.usda"
    if not out.exists():
        api.muscles(fx["mh"], {"layout": str(_layout(sample_assets))}, output=out)
    return out


# -- what the new layers record -------------------------------------------------------------------

def test_a_track_layer_records_its_own_take_as_every_reader_reads_it(tracked):
    """A 2D track layer is a take: it records it, in pixels, equal to what `lift` reads from it and
    what `check` computes from it (which reads it as a capture layer: no metersPerUnit)."""
    from pxr import Sdf

    from usdface import api
    from usdface.usd.identity import capture_record, layer_capture_record
    from usdface.usd.track_layer import read_track_layer

    own = recorded(tracked)
    assert set(own) == {"version", "capture"}
    assert own["capture"] == capture_record(read_track_layer(tracked)[0]) == \
        layer_capture_record(Sdf.Layer.FindOrOpen(str(tracked)))
    assert own["capture"]["markers"] == 41 and own["capture"]["frames"] == 72
    assert not [f for f in api.check(tracked).summary["findings"] if f["rule"] == "usdface:LayerIdentity"]


def test_lift_refuses_a_binding_of_another_mesh(fx, tracked, tmp_path, capsys):
    out = tmp_path / "lifted.usdc"
    rc, lines = run_in_process(capsys, "lift", tracked, "--mesh", fx["mh"], "--binding", fx["bind_mp"], "-o", out)
    assert_one_line(rc, lines, code=2, command="lift")
    mh, mp = _mesh_ids(fx)
    assert lines[0] == (f"usdface lift: error: binding {fx['bind_mp']} was made for mesh {short(mp['sha256'])} (468 "
                        f"points), mesh {fx['mh']} is {short(mh['sha256'])} (2020 points); bind on this mesh "
                        "(`usdface bind`), or lift with --layout")
    assert not out.exists()


def test_lift_takes_a_binding_of_usdface_0_2_and_its_layer_is_a_take(fx, tracked, tmp_path, capsys):
    from usdface.usd.capture_layer import read_capture_layer
    from usdface.usd.identity import capture_record

    old = stripped(fx["bind_mh"], "bind_old_lift.usda")
    out = tmp_path / "lifted.usdc"
    rc, lines = run_in_process(capsys, "lift", tracked, "--mesh", fx["mh"], "--binding", old, "-o", out, "-q")
    assert rc == 0 and lines == [f"usdface: WARNING: binding {old} was written by usdface 0.2.0: its mesh cannot be "
                                 "verified"]
    # a capture: no mesh (it may be bound on another face, by layout or retargeted), its own take
    assert recorded(out) == {"version": 1, "capture": capture_record(read_capture_layer(out))}


# -- the tissue commands --------------------------------------------------------------------------

def test_muscles_refuses_a_binding_of_another_mesh_and_records_its_mesh(fx, rig, tmp_path, capsys):
    out = tmp_path / "rig.usda"
    rc, lines = run_in_process(capsys, "muscles", "--mesh", fx["mh"], "--binding", fx["bind_mp"], "-o", out)
    assert_one_line(rc, lines, code=2, command="muscles")
    mh, mp = _mesh_ids(fx)
    assert lines[0] == (f"usdface muscles: error: binding {fx['bind_mp']} was made for mesh {short(mp['sha256'])} "
                        f"(468 points), mesh {fx['mh']} is {short(mh['sha256'])} (2020 points); bind the capture on "
                        "this mesh (`usdface bind`), or place the muscles with --layout")
    assert not out.exists()
    assert recorded(rig) == {"version": 1, "mesh": mh}  # a rig serves every take and marker set


def test_muscles_takes_a_binding_of_usdface_0_2_with_a_warning(fx, tmp_path, capsys):
    old = stripped(fx["bind_mh"], "bind_old_muscles.usda")
    rc, lines = run_in_process(capsys, "muscles", "--mesh", fx["mh"], "--binding", old, "-o", tmp_path / "r.usda",
                               "-q")
    assert rc == 0 and lines == [f"usdface: WARNING: binding {old} was written by usdface 0.2.0: its mesh cannot be "
                                 "verified"]


def test_simulate_refuses_a_rig_placed_on_another_face(fx, rig, tmp_path, capsys):
    """The stylized face has the MakeHuman topology: the rig used to simulate on it silently."""
    out = tmp_path / "joy.usdc"
    rc, lines = run_in_process(capsys, "simulate", "--mesh", fx["sty"], "--rig", rig, "--expression", "joy",
                               "-o", out)
    assert_one_line(rc, lines, code=2, command="simulate")
    mh, sty = recorded(fx["mh"])["mesh"], recorded(fx["sty"])["mesh"]
    assert lines[0] == (f"usdface simulate: error: rig {rig} was made for mesh {short(mh['sha256'])} (2020 points), "
                        f"mesh {fx['sty']} is {short(sty['sha256'])} (2020 points); place the muscles on this mesh "
                        "(`usdface muscles`; --from-rig warps this rig onto it)")
    assert not out.exists() and not (tmp_path / "joy_shot.usda").exists()


def test_simulate_records_its_mesh_and_its_shot_the_identity_of_its_layers(fx, rig, tmp_path, capsys):
    """A rig of usdface 0.2 is accepted with one warning; the animation and the shot beside it
    record the mesh (no take: a preset drives it), and `check` finds them consistent."""
    from usdface import api

    old = stripped(rig, "rig_old.usda")
    out = tmp_path / "joy.usdc"
    rc, lines = run_in_process(capsys, "simulate", "--mesh", fx["mh"], "--rig", old, "--expression", "joy",
                               "--ramp", "1", "--hold", "0", "-o", out, "-q")
    assert rc == 0 and lines == [f"usdface: WARNING: rig {old} was written by usdface 0.2.0: its mesh cannot be "
                                 "verified"]
    mesh = recorded(fx["mh"])["mesh"]
    shot = tmp_path / "joy_shot.usda"
    assert recorded(out) == recorded(shot) == {"version": 1, "mesh": mesh}
    assert api.check(shot).exit_code == 0


def test_fit_muscles_refuses_a_rig_or_a_binding_of_another_mesh(fx, rig, sample_assets, tmp_path, capsys):
    from usdface import api

    mh, mp = _mesh_ids(fx)
    rig_mp = tmp_path / "rig_mp.usda"
    api.muscles(fx["mp"], {"layout": str(_layout(sample_assets, "mp"))}, output=rig_mp)
    out = tmp_path / "fit.usdc"
    rc, lines = run_in_process(capsys, "fit-muscles", "--mesh", fx["mh"], "--rig", rig_mp, "--capture", fx["jaw"],
                               "--binding", fx["bind_mh"], "-o", out)
    assert_one_line(rc, lines, code=2, command="fit-muscles")
    assert lines[0] == (f"usdface fit-muscles: error: rig {rig_mp} was made for mesh {short(mp['sha256'])} (468 "
                        f"points), mesh {fx['mh']} is {short(mh['sha256'])} (2020 points); place the muscles on this "
                        "mesh (`usdface muscles`; --from-rig warps this rig onto it)")
    rc, lines = run_in_process(capsys, "fit-muscles", "--mesh", fx["mh"], "--rig", rig, "--capture", fx["jaw"],
                               "--binding", fx["bind_mp"], "-o", out)
    assert_one_line(rc, lines, code=2, command="fit-muscles")
    assert lines[0] == (f"usdface fit-muscles: error: binding {fx['bind_mp']} was made for mesh "
                        f"{short(mp['sha256'])} (468 points), mesh {fx['mh']} is {short(mh['sha256'])} (2020 points); "
                        "bind the capture on this mesh (`usdface bind`)")
    assert not out.exists()


def test_fit_muscles_on_another_take_of_the_binding(fx, rig, tmp_path, capsys):
    """A binding serves every take: fitting the Nose take with the binding made on the Jaw take is
    right, and the layer records the Nose take. The shot beside it would show the Jaw markers over
    the Nose fit: it composes the animation alone, and says so."""
    from usdface import api

    out = tmp_path / "fit.usdc"
    rc, lines = run_in_process(capsys, "fit-muscles", "--mesh", fx["mh"], "--rig", rig, "--capture", fx["nose"],
                               "--binding", fx["bind_mh"], "--frames", "0", "40", "--step", "20", "--refine", "0",
                               "-o", out, "-q")
    jaw, nose = recorded(fx["jaw"])["capture"], recorded(fx["nose"])["capture"]
    shot = tmp_path / "fit_shot.usda"
    assert rc == 0 and lines == [
        f"usdface: WARNING: shot {shot}: binding {fx['bind_mh']} shows the markers of take {short(jaw['sha256'])} "
        f"(jaw.usdc), the fit is of take {short(nose['sha256'])} (capture {fx['nose']}): the shot holds the "
        "animation without markers; bind this take to see them"]
    assert recorded(out) == {"version": 1, "mesh": recorded(fx["mh"])["mesh"],
                             "markers": recorded(fx["bind_mh"])["markers"], "capture": nose}
    assert recorded(shot) == recorded(out) and api.check(shot).exit_code == 0
    from pxr import Sdf

    layer = Sdf.Layer.FindOrOpen(str(shot))
    assert list(layer.subLayerPaths) == ["./fit.usdc"]
    # with the binding of the take fitted, the shot shows its markers
    rc, lines = run_in_process(capsys, "fit-muscles", "--mesh", fx["mh"], "--rig", rig, "--capture", fx["nose"],
                               "--binding", fx["bind_mh_nose"], "--frames", "0", "40", "--step", "20", "--refine",
                               "0", "-o", tmp_path / "fit2.usdc", "-q")
    assert rc == 0 and lines == []
    layer = Sdf.Layer.FindOrOpen(str(tmp_path / "fit2_shot.usda"))
    subs = list(layer.subLayerPaths)
    assert subs[0] == "./fit2.usdc" and (tmp_path / subs[1]).resolve() == fx["bind_mh_nose"].resolve()
    assert api.check(tmp_path / "fit2_shot.usda").exit_code == 0


def test_evaluate_refuses_a_binding_of_another_mesh(fx, sample_assets, capsys):
    shapes = sample_assets / "meshes" / "makehuman_hm08_face_units_cm.npz"
    rc, lines = run_in_process(capsys, "evaluate", "--mesh", fx["mh"], "--shapes", shapes, "--binding", fx["bind_mp"])
    assert_one_line(rc, lines, code=2, command="evaluate")
    mh, mp = _mesh_ids(fx)
    assert lines[0] == (f"usdface evaluate: error: binding {fx['bind_mp']} was made for mesh {short(mp['sha256'])} "
                        f"(468 points), mesh {fx['mh']} is {short(mh['sha256'])} (2020 points); bind on this mesh "
                        "(`usdface bind`), or place the markers with --layout")
    old = stripped(fx["bind_mh"], "bind_old_evaluate.usda")
    rc, lines = run_in_process(capsys, "evaluate", "--mesh", fx["mh"], "--shapes", shapes, "--binding", old,
                               "--only", "jawOpen", "--methods", "euclidean", "--pins", "none", "-q")
    assert rc == 0 and lines == [f"usdface: WARNING: binding {old} was written by usdface 0.2.0: its mesh cannot be "
                                 "verified"]


# -- shot stages ------------------------------------------------------------------------------------

def test_shot_stage_refuses_an_animation_over_the_capture_of_another_take(fx, tmp_path):
    """The binding composes its capture: a shot of the Jaw animation over the binding made with the
    Nose take shows markers that do not follow the face, though no direct layer disagrees."""
    from usdface.errors import MixedLayersError
    from usdface.usd.analysis_layer import write_shot_stage

    out = tmp_path / "shot.usda"
    with pytest.raises(MixedLayersError) as err:
        write_shot_stage(out, layers=[fx["anim"], fx["an_mh"], fx["bind_mh_nose"]], rate=60, start=300, end=399,
                         units="cm", record={"runId": "x", "files": {}})
    jaw, nose = recorded(fx["jaw"])["capture"], recorded(fx["nose"])["capture"]
    assert str(err.value) == (f"shot {out}: layer {fx['anim']} was made from take {short(jaw['sha256'])} (41 markers, "
                              f"100 frames), layer {fx['dir'] / 'nose.usdc'} is take {short(nose['sha256'])} (41 "
                              "markers, 100 frames); they cannot be combined")
    assert err.value.exit_code == 2 and not out.exists()


def test_messages_say_whether_marker_names_or_bound_points_differ():
    from usdface.errors import MixedLayersError
    from usdface.usd.identity import Claims, verify

    names = {"names": "a" * 64, "boundPoints": "b" * 64, "count": 41}
    claims = Claims(label="analysis an.usdc", identity={"version": 1, "markers": names}, version="0.3.0",
                    processor="distances")
    with pytest.raises(MixedLayersError) as err:
        verify(claims, markers=("binding b.usda", {"names": "c" * 64, "boundPoints": "d" * 64, "count": 40}))
    assert str(err.value) == ("analysis an.usdc was made for marker names aaaaaaaaaaaa (41 markers), binding b.usda "
                              "has marker names cccccccccccc (40 markers)")
    with pytest.raises(MixedLayersError) as err:
        verify(claims, markers=("binding b.usda", {"names": "a" * 64, "boundPoints": "d" * 64, "count": 41}))
    assert str(err.value) == ("analysis an.usdc was made for bound points bbbbbbbbbbbb (41 markers), binding b.usda "
                              "has bound points dddddddddddd (41 markers)")


# -- run, and the commands that read its shot -------------------------------------------------------

_OTHER_TAKE = {}


def transfer_of_another_take(mesh, capture, binding, analysis, *, options, output):
    """`transfer` run on another take than the one given (a faulty step, for the test below)."""
    from usdface.processors.transfer import transfer

    return transfer(mesh, _OTHER_TAKE["capture"], binding, analysis, options=options, output=output)


def _run_args(sa, out, *, take="Jaw", trim=("300", "400")):
    return ("run", "--mesh", sa / "meshes" / OBJS["mh"], "--capture", sa / "capture" / f"{take}MoCap.ma",
            "--layout", _layout(sa), "--trim", *trim, "--method", "euclidean", "-o", out, "-q")


def test_run_refuses_a_shot_whose_layers_disagree(fx, sample_assets, tmp_path, capsys):
    """A step that wrote its layer from another take (a faulty plug-in step): the shot stage is
    refused, naming both files and both takes, and OUTDIR is left as it was."""
    from usdface import registry

    original = registry.find("transfer")
    _OTHER_TAKE["capture"] = fx["nose"]
    registry.register(dataclasses.replace(original, function=f"{__name__}:transfer_of_another_take"), replace=True)
    out = tmp_path / "shot"
    try:
        rc, lines = run_in_process(capsys, *_run_args(sample_assets, out))
    finally:
        registry.register(original, replace=True)
    assert_one_line(rc, lines, code=2, command="run")
    nose = recorded(fx["nose"])["capture"]
    assert lines[0].startswith(f"usdface run: error: shot step failed: shot {out / 'shot.usda'}: layer "
                               f"{out / 'anim.usdc'} was made from take {short(nose['sha256'])} (41 markers, 100 "
                               f"frames), layer {out / 'capture.usdc'} is take "), lines
    assert lines[0].endswith(" (41 markers, 100 frames); they cannot be combined")
    assert not out.exists()


@pytest.fixture(scope="module")
def run_shot(sample_assets, tmp_path_factory):
    d = tmp_path_factory.mktemp("runshot")
    from usdface.cli import main

    assert main([str(a) for a in _run_args(sample_assets, d / "shot")]) == 0
    return d / "shot"


def test_check_reports_a_run_shot_with_the_analysis_of_another_mesh(fx, run_shot, tmp_path):
    from usdface import api

    out = tmp_path / "shot"
    shutil.copytree(run_shot, out)
    assert api.check(out / "shot.usda").exit_code == 0
    shutil.copy(fx["an_mp"], out / "analysis.usdc")
    result = api.check(out / "shot.usda")
    assert result.exit_code == 1
    mh, mp = _mesh_ids(fx)
    errors = [(f["site"], f["message"]) for f in result.summary["findings"]
              if f["rule"] == "usdface:LayerIdentity" and f["severity"] == "error"]
    assert ("analysis.usdc", f"analysis.usdc was made for mesh {short(mp['sha256'])} (468 points), the stage's mesh "
                             f"/Face/Geom (points from mesh.usdc) is {short(mh['sha256'])} (2020 points)") in errors


@pytest.fixture(scope="module")
def mixed_shot(fx, run_shot, tmp_path_factory):
    """The run shot with its capture replaced by another take of the same character."""
    out = tmp_path_factory.mktemp("mixed") / "shot"
    shutil.copytree(run_shot, out)
    before = recorded(out / "capture.usdc")["capture"]
    shutil.copy(fx["nose"], out / "capture.usdc")
    return out, before, recorded(out / "capture.usdc")["capture"]


def _mixed_message(before, now) -> str:
    return (f"anim.usdc was made from take {short(before['sha256'])} (41 markers, 100 frames), capture capture.usdc "
            f"is take {short(now['sha256'])} (41 markers, 100 frames)")


def test_playblast_warns_about_a_mixed_shot_and_renders_it(mixed_shot, tmp_path, capsys):
    """A playblast is how one looks at a shot: it renders the mix, says so on one line and in its
    summary; `check` (exit 1) is the gate."""
    pytest.importorskip("av")
    from usdface import api

    out, before, now = mixed_shot
    shot = out / "shot.usda"
    movie = tmp_path / "mixed.mp4"
    rc, lines = run_in_process(capsys, "playblast", shot, "-o", movie, "--size", "160x96", "--range", "0", "5",
                               "--workers", "1", "-q")
    assert rc == 0 and movie.is_file()
    assert lines == [f"usdface: WARNING: shot {shot} mixes layers: {_mixed_message(before, now)} (and 1 more); "
                     f"`usdface check {shot}` lists every finding"]
    summary = api.playblast(str(shot), {"size": (160, 96), "frame_range": (0, 1), "workers": 1},
                            output=tmp_path / "again.mp4").summary
    assert summary["mixedLayers"][str(shot)][0] == _mixed_message(before, now)


def test_report_lists_a_mix_first(mixed_shot, tmp_path, capsys):
    pytest.importorskip("plotly")
    out, before, now = mixed_shot
    page = tmp_path / "report.html"
    rc, lines = run_in_process(capsys, "report", out, "-o", page, "--no-playblast", "-q")
    shot = out / "shot.usda"
    assert rc == 0 and lines == [f"usdface: WARNING: shot {shot} mixes layers: {_mixed_message(before, now)} (and 1 "
                                 f"more); `usdface check {shot}` lists every finding"]
    html = page.read_text()
    first = html.index('<div class="warn">')
    assert html[first:].startswith(f'<div class="warn">mixed layers: {_mixed_message(before, now)}</div>')


def test_two_takes_on_one_mesh_share_the_distance_cache_entry(sample_assets, tmp_path):
    """Through `run`: the Nose take's shot reuses the matrices computed for the Jaw take's, and
    their bindings and analyses record the same identity (no take), their animations their takes."""
    from usdface import registry
    from usdface.cache import ContentCache
    from usdface.options import RunOptions

    cache = ContentCache(tmp_path / "cache")
    sa = sample_assets
    summaries = {}
    for take, trim in (("Jaw", (300, 400)), ("Nose", (100, 200))):
        options = RunOptions(layout=str(_layout(sa)), trim=trim, method="euclidean")
        summaries[take] = registry.call("run", str(sa / "meshes" / OBJS["mh"]), str(sa / "capture" / f"{take}MoCap.ma"),
                                        options=options, output=tmp_path / take, cache=cache).summary
    status = {take: s["steps"]["distances"]["cache"] for take, s in summaries.items()}
    assert status["Jaw"]["status"] == "miss" and status["Nose"]["status"] == "hit"
    assert status["Jaw"]["key"] == status["Nose"]["key"]
    for name in ("binding.usda", "analysis.usdc"):
        assert recorded(tmp_path / "Jaw" / name) == recorded(tmp_path / "Nose" / name)
    assert recorded(tmp_path / "Jaw" / "anim.usdc")["capture"] != recorded(tmp_path / "Nose" / "anim.usdc")["capture"]
