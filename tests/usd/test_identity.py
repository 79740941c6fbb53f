"""Layers know what they belong to (issue 20, item 2): the identities of a mesh, a take and bound
markers, recorded in every layer and compared wherever layers are combined."""
from __future__ import annotations

import json
import shutil

import numpy as np
import pytest

from tests.hostile import assert_one_line, run_in_process

from tests.usd.identity_helpers import LAYOUTS, OBJS, composed, recorded, short, stripped


# -- the identities themselves --------------------------------------------------------------------

def _quad_mesh():
    points = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [2, 0, 0], [2, 1, 0]], dtype=np.float64) * 0.1
    return np.array([4, 4]), np.array([0, 1, 2, 3, 1, 4, 5, 2]), points


def test_mesh_identity_is_the_documented_bytes():
    """A golden digest: the identity is a contract between layers written by different versions
    (a change of the hashed bytes must bump IDENTITY_VERSION, never pass silently)."""
    import hashlib

    from usdface.model.identity import mesh_identity

    counts, indices, points = _quad_mesh()
    by_hand = hashlib.sha256(b"usdface-identity-1/mesh")
    for part in (np.float64(0.01).tobytes(), np.int32([4, 4]).tobytes(), np.int32(indices).tobytes(),
                 points.astype(np.float32).tobytes()):
        by_hand.update(len(part).to_bytes(8, "little") + part)
    assert mesh_identity(counts, indices, points, 0.01) == by_hand.hexdigest() == \
        "594c8f79abdc54c4e00adcec881e02203320dea6f252bcacdf2adc759d30943e"


def test_mesh_identity_sees_units_order_points_and_topology_not_precision():
    from usdface.model.identity import mesh_identity

    counts, indices, points = _quad_mesh()
    base = mesh_identity(counts, indices, points, 0.01)
    # a float64 copy of float32 points (what readers make) is the same mesh
    assert mesh_identity(counts.astype(np.int64), indices, points.astype(np.float32).astype(np.float64), 0.01) == base
    assert mesh_identity(counts, indices, points, 0.001) != base          # same numbers in mm: 10x smaller
    assert mesh_identity(counts, indices, points, None) != base           # units unknown
    moved = points.astype(np.float32)
    moved[5, 1] = np.nextafter(moved[5, 1], np.float32(2))                # one float32 ulp
    assert mesh_identity(counts, indices, moved, 0.01) != base
    order = np.array([5, 4, 3, 2, 1, 0])                                  # same surface, points reordered
    inverse = np.argsort(order)
    assert mesh_identity(counts, inverse[indices], points[order], 0.01) != base
    assert mesh_identity(np.array([3, 3, 3, 3]), np.array([0, 1, 2, 0, 2, 3, 1, 4, 5, 1, 5, 2]), points, 0.01) != base


def test_mesh_identity_ignores_uvs_and_names():
    from usdface.model.identity import mesh_identity
    from usdface.model.mesh import FaceMesh
    from usdface.usd.identity import mesh_record

    counts, indices, points = _quad_mesh()
    plain = FaceMesh(points=points, face_vertex_counts=counts, face_vertex_indices=indices, units="cm")
    uvs = FaceMesh(points=points, face_vertex_counts=counts, face_vertex_indices=indices, units="cm",
                   uvs=np.random.default_rng(0).random((8, 2)), uv_indices=np.arange(8), name="Other", source="x.obj")
    assert mesh_record(plain) == mesh_record(uvs) == {
        "sha256": mesh_identity(counts, indices, points, 0.01), "points": 6, "faces": 2}


def test_recorded_identities_equal_the_content_read_back(fx, tmp_path, sample_assets):
    """What a layer records of itself is what any reader computes from it: the mesh layer (read as a
    FaceMesh, or composed on a stage), the capture layer (invalid samples and head motion included)."""
    from pxr import Usd

    from usdface.model import Capture
    from usdface.usd.capture_layer import read_capture_layer, write_capture_layer
    from usdface.usd.identity import capture_record, identity, mesh_record, prim_mesh_record
    from usdface.usd.layers import provenance
    from usdface.usd.mesh_layer import find_mesh, read_mesh_layer

    for key in OBJS:
        mesh, _ = read_mesh_layer(fx[key])
        stage = Usd.Stage.Open(str(fx[key]))
        prim = find_mesh(stage)
        assert recorded(fx[key])["mesh"] == mesh_record(mesh) == prim_mesh_record(prim)[0]
    assert recorded(fx["jaw"])["capture"] == capture_record(read_capture_layer(fx["jaw"]))
    # a take with gaps (held samples) and a head motion
    take = read_capture_layer(fx["nose"])
    pos = take.positions.copy()
    pos[10:20, 3] = np.nan
    pos[0:5, 7] = np.nan
    motion = np.repeat(np.eye(4)[None], take.n_frames, axis=0)
    motion[:, 0, 3] = np.linspace(0, 1.5, take.n_frames)
    gappy = Capture(names=take.names, positions=pos, rate=take.rate, units=take.units, start_frame=take.start_frame,
                    neutral_frame=take.neutral_frame, head_motion=motion)
    rec = capture_record(gappy)
    write_capture_layer(tmp_path / "gappy.usdc", gappy,
                        prov=provenance("import-capture", options={}, inputs={}, identity=identity(capture=rec)))
    back = read_capture_layer(tmp_path / "gappy.usdc")
    assert (~back.valid).sum() == 15 and back.head_motion is not None
    assert recorded(tmp_path / "gappy.usdc")["capture"] == capture_record(back) == rec
    assert capture_record(take) != rec


def test_what_each_layer_records(fx):
    """Meshes their own mesh, captures their own take; bindings and analyses the mesh and bound
    markers but no take (they serve every take); the animation all three."""
    ids = {k: recorded(fx[k]) for k in ("mh", "jaw", "bind_mh", "bind_mh_nose", "an_mh", "anim")}
    assert set(ids["mh"]) == {"version", "mesh"} and set(ids["jaw"]) == {"version", "capture"}
    assert set(ids["bind_mh"]) == set(ids["an_mh"]) == {"version", "mesh", "markers"}
    assert set(ids["anim"]) == {"version", "mesh", "markers", "capture"}
    assert ids["bind_mh"]["mesh"] == ids["an_mh"]["mesh"] == ids["anim"]["mesh"] == ids["mh"]["mesh"]
    assert ids["bind_mh"]["markers"] == ids["an_mh"]["markers"] == ids["anim"]["markers"]
    # a layout binds the same points whatever the take it was bound with
    assert ids["bind_mh_nose"] == ids["bind_mh"]
    assert ids["anim"]["capture"] == ids["jaw"]["capture"] and ids["anim"]["capture"]["frames"] == 100
    # reproducible: no paths, no time, no host in what is recorded
    text = json.dumps(ids)
    assert str(fx["dir"]) not in text and "/" not in text


# -- processors refuse a mix ------------------------------------------------------------------------

def test_distances_refuses_a_binding_made_on_another_mesh(fx, tmp_path, capsys):
    """Issue 20, case 2: the MakeHuman mesh (2020 points) with a binding made on the MediaPipe face
    (468 points) exited 0; `check` on the result said no problems."""
    out = tmp_path / "an.usdc"
    rc, lines = run_in_process(capsys, "distances", "--mesh", fx["mh"], "--binding", fx["bind_mp"], "-o", out)
    assert_one_line(rc, lines, code=2, command="distances")
    mh, mp = recorded(fx["mh"])["mesh"], recorded(fx["mp"])["mesh"]
    assert lines[0] == (f"usdface distances: error: binding {fx['bind_mp']} was made for mesh {short(mp['sha256'])} "
                        f"(468 points), mesh {fx['mh']} is {short(mh['sha256'])} (2020 points); bind the capture on "
                        "this mesh (`usdface bind`)")
    assert not out.exists()


def test_a_binding_on_the_makehuman_face_is_refused_on_the_stylized_one(fx, tmp_path, capsys):
    """Same topology, other points: nothing but the identity tells them apart."""
    rc, lines = run_in_process(capsys, "distances", "--mesh", fx["sty"], "--binding", fx["bind_mh"],
                               "-o", tmp_path / "an.usdc")
    assert rc == 2, lines
    mh, sty = recorded(fx["mh"])["mesh"], recorded(fx["sty"])["mesh"]
    assert mh["points"] == sty["points"] and mh["faces"] == sty["faces"] and mh["sha256"] != sty["sha256"]
    assert_one_line(rc, lines, code=2, command="distances",
                    contains=(f"binding {fx['bind_mh']} was made for mesh {short(mh['sha256'])} (2020 points), "
                              f"mesh {fx['sty']} is {short(sty['sha256'])} (2020 points)",))


def test_transfer_refuses_the_issue_case(fx, tmp_path, capsys):
    """`transfer` exited 0 ("markers reproduced within 558%", amplification 3e11x) with the analysis
    `distances` wrote for the MakeHuman mesh and the MediaPipe binding (made here as usdface 0.2
    would, from a binding without identity)."""
    from usdface import api

    mixed = tmp_path / "an_mixed.usdc"
    api.distances(fx["mh"], stripped(fx["bind_mp"], "bind_mp_old.usda"), {"method": "euclidean"}, output=mixed)
    out = tmp_path / "anim.usdc"
    rc, lines = run_in_process(capsys, "transfer", "--mesh", fx["mh"], "--capture", fx["jaw"], "--binding",
                               fx["bind_mp"], "--analysis", mixed, "-o", out)
    assert_one_line(rc, lines, code=2, command="transfer")
    mh, mp = recorded(fx["mh"])["mesh"], recorded(fx["mp"])["mesh"]
    assert lines[0] == (f"usdface transfer: error: binding {fx['bind_mp']} was made for mesh {short(mp['sha256'])} "
                        f"(468 points), mesh {fx['mh']} is {short(mh['sha256'])} (2020 points); bind the capture on "
                        "this mesh (`usdface bind`)")
    assert not out.exists()


def test_transfer_refuses_an_analysis_of_another_mesh(fx, tmp_path, capsys):
    rc, lines = run_in_process(capsys, "transfer", "--mesh", fx["mh"], "--capture", fx["jaw"], "--binding",
                               fx["bind_mh"], "--analysis", fx["an_mp"], "-o", tmp_path / "anim.usdc")
    assert_one_line(rc, lines, code=2, command="transfer")
    mh, mp = recorded(fx["mh"])["mesh"], recorded(fx["mp"])["mesh"]
    assert lines[0] == (f"usdface transfer: error: analysis {fx['an_mp']} was made for mesh {short(mp['sha256'])} "
                        f"(468 points), mesh {fx['mh']} is {short(mh['sha256'])} (2020 points); compute the distances "
                        "again (`usdface distances`)")


def test_transfer_refuses_an_analysis_of_other_bound_points(fx, tmp_path, capsys):
    """Same mesh, same marker names, other bound points (an automatic binding): the distance
    matrix's centres are not the binding's points (this passed every earlier check)."""
    from usdface import api

    auto = tmp_path / "bind_auto.usda"
    api.bind(fx["mh"], fx["jaw"], {"auto": True}, output=auto)
    rc, lines = run_in_process(capsys, "transfer", "--mesh", fx["mh"], "--capture", fx["jaw"], "--binding", auto,
                               "--analysis", fx["an_mh"], "-o", tmp_path / "anim.usdc")
    assert_one_line(rc, lines, code=2, command="transfer")
    have, made_for = recorded(auto)["markers"], recorded(fx["an_mh"])["markers"]
    assert have["names"] == made_for["names"] and have["boundPoints"] != made_for["boundPoints"]
    assert lines[0] == (f"usdface transfer: error: analysis {fx['an_mh']} was made for bound points "
                        f"{short(made_for['boundPoints'])} (41 markers), binding {auto} has bound points "
                        f"{short(have['boundPoints'])} (41 markers); compute the distances again (`usdface distances`)")


def test_shot_stage_refuses_layers_of_two_meshes(fx, tmp_path):
    from usdface.errors import MixedLayersError
    from usdface.usd.analysis_layer import write_shot_stage

    out = tmp_path / "shot.usda"
    with pytest.raises(MixedLayersError) as err:
        write_shot_stage(out, layers=[fx["anim"], fx["an_mp"], fx["bind_mh"]], rate=60, start=300, end=399, units="cm",
                         record={"runId": "x", "files": {}})
    mh, mp = recorded(fx["mh"])["mesh"], recorded(fx["mp"])["mesh"]
    assert str(err.value) == (f"shot {out}: layer {fx['anim']} was made for mesh {short(mh['sha256'])} (2020 points), "
                              f"layer {fx['an_mp']} for mesh {short(mp['sha256'])} (468 points); they cannot be "
                              "combined")
    assert err.value.exit_code == 2 and not out.exists()
    write_shot_stage(out, layers=[fx["anim"], fx["an_mh"], fx["bind_mh"]], rate=60, start=300, end=399, units="cm",
                     record={"runId": "x", "files": {}})
    assert recorded(out) == recorded(fx["anim"])


# -- layers of usdface 0.2 ----------------------------------------------------------------------------

def test_layers_of_usdface_0_2_are_accepted_with_one_warning(fx, tmp_path, capsys):
    old_binding = stripped(fx["bind_mh"], "bind_old_distances.usda")
    rc, lines = run_in_process(capsys, "distances", "--mesh", fx["mh"], "--binding", old_binding, "--method",
                               "euclidean", "-o", tmp_path / "an.usdc", "-q")
    assert rc == 0, lines
    assert lines == [f"usdface: WARNING: binding {old_binding} was written by usdface 0.2.0: its mesh cannot be "
                     "verified"]
    # the layer written from it still records what it was computed for (from the inputs' content)
    assert recorded(tmp_path / "an.usdc") == recorded(fx["an_mh"])
    old_analysis = stripped(fx["an_mh"], "an_old.usdc")
    rc, lines = run_in_process(capsys, "transfer", "--mesh", fx["mh"], "--capture", fx["jaw"], "--binding",
                               fx["bind_mh"], "--analysis", old_analysis, "-o", tmp_path / "anim.usdc", "-q")
    assert rc == 0
    assert lines == [f"usdface: WARNING: analysis {old_analysis} was written by usdface 0.2.0: its mesh and its "
                     "bound markers cannot be verified"]


def test_check_warns_about_a_layer_without_identity(fx, tmp_path, capsys):
    old = stripped(fx["bind_mh"], "bind_old.usda")
    from usdface import api

    rc, lines = run_in_process(capsys, "check", old)
    assert rc == 0
    findings = api.check(old).summary["findings"]
    assert [f for f in findings if f["rule"] == "usdface:LayerIdentity"] == [
        {"severity": "warning", "rule": "usdface:LayerIdentity", "site": "bind_old.usda",
         "message": "bind_old.usda was written by usdface 0.2.0: its mesh cannot be verified"}]


# -- check --------------------------------------------------------------------------------------

def test_check_reports_an_analysis_composed_with_a_binding_of_another_mesh(fx):
    from usdface import api

    stage = composed(fx["dir"] / "mixed.usda", [fx["an_mh"], fx["bind_mp"]])
    result = api.check(stage)
    assert result.exit_code == 1, [str(f) for f in result.legacy]
    mh, mp = recorded(fx["mh"])["mesh"], recorded(fx["mp"])["mesh"]
    marks_mh, marks_mp = recorded(fx["an_mh"])["markers"], recorded(fx["bind_mp"])["markers"]
    errors = [(f["site"], f["message"]) for f in result.summary["findings"]
              if f["rule"] == "usdface:LayerIdentity" and f["severity"] == "error"]
    assert errors == [
        ("an_mh.usdc", f"an_mh.usdc was made for mesh {short(mh['sha256'])} (2020 points), the stage's mesh /Face/Geom "
                       f"(points from mp.usdc) is {short(mp['sha256'])} (468 points)"),
        ("an_mh.usdc", f"an_mh.usdc was made for bound points {short(marks_mh['boundPoints'])} (41 markers), the "
                       f"stage's binding on /Face/Geom (bind_mp.usda) has bound points "
                       f"{short(marks_mp['boundPoints'])} (41 markers)")]
    # the layers of one character compose clean
    clean = composed(fx["dir"] / "clean.usda", [fx["anim"], fx["an_mh"], fx["bind_mh"]])
    assert api.check(clean).exit_code == 0


def test_check_reports_an_animation_over_another_take(fx):
    """A hand-composed shot (no run record): the animation of the Jaw take over a binding that
    references the Nose take; only the identities tell."""
    from usdface import api

    stage = composed(fx["dir"] / "swapped.usda", [fx["anim"], fx["an_mh"], fx["bind_mh_nose"]])
    result = api.check(stage)
    assert result.exit_code == 1, [str(f) for f in result.legacy]
    jaw, nose = recorded(fx["jaw"])["capture"], recorded(fx["nose"])["capture"]
    assert [f["message"] for f in result.summary["findings"] if f["severity"] == "error"] == [
        f"anim.usdc was made from take {short(jaw['sha256'])} (41 markers, 100 frames), capture nose.usdc is take "
        f"{short(nose['sha256'])} (41 markers, 100 frames)"]


def test_check_reports_a_take_swapped_under_a_run_shot(tmp_path, sample_assets, fx, capsys):
    from usdface import api

    sa = sample_assets
    out = tmp_path / "shot"
    rc = run_in_process(capsys, "run", "--mesh", sa / "meshes" / OBJS["mh"], "--capture",
                        sa / "capture" / "JawMoCap.ma",
                        "--layout", sa / "layouts" / "makehuman_hm08_face.layout.json", "--trim", "300", "400",
                        "--method", "euclidean", "-o", out, "-q")[0]
    assert rc == 0 and api.check(out / "shot.usda").exit_code == 0
    before = out / "capture_before.usdc"
    shutil.copy(out / "capture.usdc", before)
    nose = tmp_path / "nose.usdc"
    api.import_capture(str(sa / "capture" / "NoseMoCap.ma"), {"trim": (100, 200), "stabilize": "auto"}, output=nose)
    shutil.copy(nose, out / "capture.usdc")  # another take of the same character, same markers and length
    result = api.check(out / "shot.usda")
    assert result.exit_code == 1
    identity = [(f["site"], f["message"]) for f in result.summary["findings"] if f["rule"] == "usdface:LayerIdentity"]
    assert identity, [str(f) for f in result.legacy]
    take, other = recorded(before)["capture"], recorded(out / "capture.usdc")["capture"]
    seen = f"take {short(take['sha256'])} (41 markers, 100 frames), capture capture.usdc is take " \
           f"{short(other['sha256'])} (41 markers, 100 frames)"
    assert identity == [("anim.usdc", f"anim.usdc was made from {seen}"),
                        ("shot.usda", f"shot.usda was made from {seen}")]


def test_check_reports_a_mesh_layer_changed_after_it_was_written(fx, tmp_path):
    from pxr import Sdf, Vt

    from usdface import api

    mesh = tmp_path / "mh.usdc"
    shutil.copy(fx["mh"], mesh)
    layer = Sdf.Layer.FindOrOpen(str(mesh))
    attr = layer.GetAttributeAtPath("/Face/Geom.points")
    pts = np.asarray(attr.default).copy()
    pts[0] += 0.5
    attr.default = Vt.Vec3fArray.FromNumpy(pts)
    layer.Save()
    found = api.check(mesh).summary["findings"]
    mh = recorded(fx["mh"])["mesh"]
    from usdface.usd.identity import prim_mesh_record
    from pxr import Usd

    stage = Usd.Stage.Open(str(mesh))
    now = prim_mesh_record(stage.GetPrimAtPath("/Face/Geom"))[0]
    assert [f["message"] for f in found if f["rule"] == "usdface:LayerIdentity"] == [
        f"mh.usdc records mesh {short(mh['sha256'])} (2020 points) but holds mesh {short(now['sha256'])} (2020 points) "
        "(changed after usdface wrote it)"]


# -- units, re-imports, info, cache -------------------------------------------------------------------

def test_units_preserving_reimport_keeps_the_identity_other_units_change_it(fx, tmp_path, sample_assets, capsys):
    """A re-import that keeps the numbers and the units (the mesh layer itself, the OBJ into .usda)
    keeps the identity, though the files' bytes differ; the OBJ declared in mm is a face ten times
    smaller: bindings, distances and widths made in cm do not fit it, so it is refused."""
    from usdface import api

    api.import_mesh(fx["mh"], output=tmp_path / "again.usdc")
    api.import_mesh(str(sample_assets / "meshes" / OBJS["mh"]), output=tmp_path / "again.usda")
    api.import_mesh(str(sample_assets / "meshes" / OBJS["mh"]), {"units": "mm"}, output=tmp_path / "mm.usdc")
    mh = recorded(fx["mh"])["mesh"]
    assert recorded(tmp_path / "again.usdc")["mesh"] == recorded(tmp_path / "again.usda")["mesh"] == mh
    mm = recorded(tmp_path / "mm.usdc")["mesh"]
    assert mm["sha256"] != mh["sha256"] and mm["points"] == mh["points"]
    rc, lines = run_in_process(capsys, "distances", "--mesh", tmp_path / "again.usda", "--binding", fx["bind_mh"],
                               "--method", "euclidean", "-o", tmp_path / "an.usdc", "-q")
    assert rc == 0 and lines == []
    rc, lines = run_in_process(capsys, "distances", "--mesh", tmp_path / "mm.usdc", "--binding", fx["bind_mh"],
                               "-o", tmp_path / "an_mm.usdc")
    assert_one_line(rc, lines, code=2, command="distances",
                    contains=(f"mesh {tmp_path / 'mm.usdc'} is {short(mm['sha256'])} (2020 points)",))


def test_info_shows_identities_to_compare_by_eye(fx, capsys):
    from usdface import api

    mh, mp = recorded(fx["mh"])["mesh"], recorded(fx["bind_mp"])
    text = api.info(fx["bind_mp"]).text
    assert f"  belongs to: mesh {short(mp['mesh']['sha256'])} (468 points); bound points " \
           f"{short(mp['markers']['boundPoints'])} (41 markers)" in text
    # the mesh composed under it is computed, not read from metadata
    assert f"      mesh {short(mp['mesh']['sha256'])}" in text
    assert f"      take {short(recorded(fx['jaw'])['capture']['sha256'])}" in text
    mesh_text = api.info(fx["mh"]).text
    assert f"      mesh {short(mh['sha256'])}" in mesh_text and \
        f"  belongs to: mesh {short(mh['sha256'])} (2020 points)" in mesh_text
    summary = api.info(fx["anim"]).summary
    assert summary["provenance"]["identity"] == recorded(fx["anim"])


def test_info_names_the_revision_a_layer_was_made_by(fx):
    """A layer of a processor whose algorithms changed since usdface 0.2 says which revision made it
    (usdface.revisions); one of a processor at revision 1 records none and says none."""
    from usdface import __version__, api
    from usdface.revisions import revision

    assert f"  written by usdface {__version__} (transfer, revision {revision('transfer')})" in api.info(fx["anim"]).text
    assert revision("import-mesh") == 1
    assert f"  written by usdface {__version__} (import-mesh)" in api.info(fx["mh"]).text


def test_distance_cache_is_shared_across_takes_of_one_character(fx, tmp_path):
    """The identities add no take to a binding or an analysis: the matrices computed for the Jaw
    take's binding serve the Nose take's, and both analyses record the same identity."""
    from usdface import registry
    from usdface.cache import ContentCache
    from usdface.options import DistanceOptions

    cache = ContentCache(tmp_path / "cache")
    first = registry.call("distances", fx["mh"], fx["bind_mh"], options=DistanceOptions(method="euclidean"),
                          output=tmp_path / "jaw.usdc", cache=cache)
    second = registry.call("distances", fx["mh"], fx["bind_mh_nose"], options=DistanceOptions(method="euclidean"),
                           output=tmp_path / "nose.usdc", cache=cache)
    assert first.summary["cache"]["status"] == "miss" and second.summary["cache"]["status"] == "hit"
    assert recorded(tmp_path / "jaw.usdc") == recorded(tmp_path / "nose.usdc") == recorded(fx["an_mh"])


def test_in_memory_layers_carry_their_identity(fx):
    """The Python API's in-memory outputs record the identity too, and are checked like files."""
    from pxr import Sdf

    from usdface import api
    from usdface.errors import MixedLayersError

    binding = Sdf.Layer.CreateAnonymous("binding.usda")
    api.bind(fx["mp"], fx["jaw"], {"layout": str(_layout("mp"))}, into=binding)
    assert binding.customLayerData["usdface"]["identity"] == recorded(fx["bind_mp"])
    with pytest.raises(MixedLayersError, match="was made for mesh .* \\(468 points\\), mesh .* \\(2020 points\\)"):
        api.distances(fx["mh"], binding, {"method": "euclidean"})


def _layout(key):
    from tests.conftest import SAMPLE_ASSETS

    return SAMPLE_ASSETS / "layouts" / f"{LAYOUTS[key]}.layout.json"
