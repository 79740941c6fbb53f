"""The Python API on in-memory stages and layers: the same results as the command line's files,
nothing on disk, and a failed call leaves the target layer unchanged."""
from __future__ import annotations

import numpy as np
import pytest

import usdface  # noqa: F401  (schemas registered before any stage opens)
from usdface import api
from usdface.errors import UsdFaceError
from usdface.options import CaptureOptions, DistanceOptions, RunOptions, TransferOptions

MESH = "meshes/makehuman_hm08_face_cm.obj"
TAKE = "capture/JawMoCap.ma"
LAYOUT = "layouts/makehuman_hm08_face.layout.json"


@pytest.fixture(scope="module")
def in_memory(sample_assets):
    from pxr import Usd

    mesh = api.import_mesh(str(sample_assets / MESH)).layer
    capture = api.import_capture(str(sample_assets / TAKE), CaptureOptions(stabilize="auto", trim=(0, 200))).layer
    stage = api.new_stage(mesh)
    api.bind(stage, capture, layout=str(sample_assets / LAYOUT), into=stage)
    api.distances(stage, DistanceOptions(method="hybrid"), into=stage)
    result = api.transfer(stage, TransferOptions(), into=stage)
    return stage, result, mesh, capture


def test_in_memory_pipeline_matches_the_command_line(in_memory, sample_assets, tmp_path):
    from pxr import Usd, UsdGeom

    stage, result, _, _ = in_memory
    assert result.layer is stage.GetRootLayer() and result.summary["frames"] == 200
    assert stage.GetRootLayer().anonymous
    files = api.run(str(sample_assets / MESH), str(sample_assets / TAKE), tmp_path / "jaw",
                    RunOptions(layout=str(sample_assets / LAYOUT), trim=(0, 200)))
    shot = Usd.Stage.Open(files["shot"])
    for f in (0, 120, 199):
        a = np.asarray(UsdGeom.Mesh(stage.GetPrimAtPath("/Face/Geom")).GetPointsAttr().Get(f))
        b = np.asarray(UsdGeom.Mesh(shot.GetPrimAtPath("/Face/Geom")).GetPointsAttr().Get(f))
        np.testing.assert_allclose(a, b, atol=1e-4)
        ha = UsdGeom.Xformable(stage.GetPrimAtPath("/Face")).GetLocalTransformation(f)
        hb = UsdGeom.Xformable(shot.GetPrimAtPath("/Face")).GetLocalTransformation(f)
        np.testing.assert_allclose(np.array(ha), np.array(hb), atol=1e-9)


def test_the_evaluator_reads_what_the_api_wrote(in_memory):
    stage, _, _, _ = in_memory
    ev = api.evaluator(stage)
    assert ev.n_points == 2020 and len(ev.time_codes) == 200
    moved = np.linalg.norm(ev.points(120, space="mesh") - ev.rest_points(), axis=1).max()
    assert 0.5 < moved < 5.0  # the jaw opens a few cm


def test_results_check_clean(in_memory):
    stage, _, mesh, capture = in_memory
    for target in (stage, mesh, capture):
        assert not [f for f in api.check(target) if f.severity == "error"]


def test_a_failed_call_leaves_the_target_layer_unchanged(in_memory):
    from pxr import Sdf, Usd

    _, _, mesh, _ = in_memory
    into = Sdf.Layer.CreateAnonymous("mine.usda")
    Usd.Stage.Open(into).DefinePrim("/Mine", "Xform")
    before = into.ExportToString()
    # a stage with a face but no capture or binding: transfer cannot run
    with pytest.raises(UsdFaceError, match="no Points prim with FaceMarkerSetAPI"):
        api.transfer(Usd.Stage.Open(mesh), into=into)
    assert into.ExportToString() == before


def test_a_stage_without_a_face_mesh_is_refused_by_name():
    from pxr import Usd

    empty = Usd.Stage.CreateInMemory()
    empty.DefinePrim("/World", "Xform")
    with pytest.raises(UsdFaceError, match="no Mesh"):
        api.distances(empty)


def test_options_objects_are_checked():
    with pytest.raises(UsdFaceError, match="--max-influences 0"):
        RunOptions(max_influences=0)
    with pytest.raises(UsdFaceError, match="expected a CaptureOptions"):
        api.import_capture("x.ma", options=42)


def test_skeleton_in_memory_matches_the_point_cache(in_memory, sample_assets):
    """api.skel authors the skeleton into a layer of its own; the shared evaluator deforms it within
    the documented DCC-safe error of the point cache (head motion included). The skeleton is built
    on a scene without the point cache: two deliverables of one take must not be composed."""
    from pxr import Sdf

    from usdface.options import SkelOptions

    stage, _, mesh, capture = in_memory
    cache = api.evaluator(stage).points_range()
    scene = api.new_stage(mesh)
    api.bind(scene, capture, layout=str(sample_assets / LAYOUT), into=scene)
    api.distances(scene, into=scene)
    into = Sdf.Layer.CreateAnonymous("skel.usda")
    result = api.skel(scene, SkelOptions(max_influences=8), capture=capture, into=into)
    assert result.summary["skinWeights"] == "dcc" and result.summary["maxInfluences"] == 8
    shot = api.new_stage(into, scene.GetRootLayer())
    skinned = api.evaluator(shot).points_range()
    assert np.linalg.norm(skinned - cache, axis=2).max() < 0.25


def test_solve_on_files(sample_assets, tmp_path):
    summary = api.solve(str(sample_assets / MESH), str(sample_assets / TAKE), tmp_path / "curves.usdc",
                        RunOptions(layout=str(sample_assets / LAYOUT), trim=(0, 200),
                                   shapes=str(sample_assets / "meshes/makehuman_hm08_face_units_cm.npz")),
                        csv=tmp_path / "curves.csv")
    assert summary["residualMean"] < summary["stillResidualMean"]
    assert (tmp_path / "curves.csv").read_text().startswith("frame,time,")
