"""Deliverables as DCC users get them: head motion on the face's root prim, animation layers that
stand alone, one time-code convention."""
from __future__ import annotations

import numpy as np
import pytest

LAYOUT = "makehuman_hm08_face.layout.json"
MESH = "makehuman_hm08_face_cm.obj"


@pytest.fixture(scope="module")
def shots(sample_assets, tmp_path_factory):
    from usdface.cli import main

    d = tmp_path_factory.mktemp("deliverables")
    common = ["--mesh", str(sample_assets / "meshes" / MESH), "--layout", str(sample_assets / "layouts" / LAYOUT),
              "--capture", str(sample_assets / "capture" / "EyebrowsMoCap.ma"), "--trim", "0", "300", "-q"]
    out = {}
    for name, extra in (("head", []), ("nohead", ["--no-head-motion"]), ("nostab", ["--no-stabilize"])):
        out[name] = d / name
        assert main(["run", *common, "-o", str(out[name]), *extra]) == 0
    return out


def _root_ops(path):
    from pxr import Usd, UsdGeom

    stage = Usd.Stage.Open(str(path))
    return stage, UsdGeom.Xformable(stage.GetPrimAtPath("/Face")).GetOrderedXformOps()


def test_head_motion_is_the_root_transform_and_moves_markers_and_face_together(shots):
    import usdface  # noqa: F401  (schemas)
    from pxr import Usd, UsdGeom

    from usdface.usd.mesh_layer import read_binding

    stage, ops = _root_ops(shots["head"] / "shot.usda")
    assert [op.GetOpName() for op in ops] == ["xformOp:transform"]
    face = stage.GetPrimAtPath("/Face")
    markers = stage.GetPrimAtPath("/Capture/Markers")
    binding = read_binding(stage)
    c = binding.capture_to_mesh
    names = list(markers.GetAttribute("usdface:markerSet:names").Get())
    idx = [names.index(n) for n in binding.names]
    cache = UsdGeom.XformCache()
    moved = 0.0
    for f in range(0, 300, 25):
        cache.SetTime(Usd.TimeCode(f))
        head = np.array(cache.GetLocalToWorldTransform(face), dtype=np.float64).T   # column vectors
        to_world = np.array(cache.GetLocalToWorldTransform(markers), dtype=np.float64).T
        local = np.c_[np.asarray(UsdGeom.Points(markers).GetPointsAttr().Get(f), dtype=np.float64)[idx],
                      np.ones(len(idx))].T
        # the face's root transform moves the face exactly as the capture's head moved the markers
        np.testing.assert_allclose((head @ c @ local)[:3], (to_world @ local)[:3], atol=1e-6)
        moved = max(moved, float(np.abs(head[:3, 3]).max()))
        if f == 0:  # the neutral frame: the face at rest
            np.testing.assert_allclose(head, np.eye(4), atol=1e-9)
    assert moved > 0.3  # the Eyebrows take's head moves about 1.5 cm


def test_no_head_motion_and_no_stabilize_leave_the_root_still(shots):
    for name in ("nohead", "nostab"):
        _, ops = _root_ops(shots[name] / "shot.usda")
        assert ops == [], name


def test_anim_layer_alone_is_the_animated_face(shots):
    from pxr import Usd, UsdGeom

    stage = Usd.Stage.Open(str(shots["head"] / "anim.usdc"))
    mesh = UsdGeom.Mesh(stage.GetPrimAtPath("/Face/Geom"))
    assert stage.GetPrimAtPath("/Face/Geom").GetTypeName() == "Mesh"
    assert len(mesh.GetFaceVertexCountsAttr().Get()) == 1934
    assert mesh.GetPointsAttr().GetNumTimeSamples() == 300
    assert stage.GetStartTimeCode() == 0 and stage.GetEndTimeCode() == 299
    assert [op.GetOpName() for op in UsdGeom.Xformable(stage.GetPrimAtPath("/Face")).GetOrderedXformOps()] == \
        ["xformOp:transform"]


def test_analysis_data_is_not_per_point_geometry(shots):
    """DCC importers turn vertex primvars into per-point attributes: the only usdface primvar
    left on the mesh is the one-value-per-vertex hybrid weight (usdview colours by it)."""
    from pxr import Usd, UsdGeom

    stage = Usd.Stage.Open(str(shots["head"] / "shot.usda"))
    prim = stage.GetPrimAtPath("/Face/Geom")
    usdface_primvars = [pv for pv in UsdGeom.PrimvarsAPI(prim).GetPrimvars() if "usdface" in pv.GetName()]
    assert [pv.GetName() for pv in usdface_primvars] == ["primvars:usdface:hybridWeight"]
    assert all(pv.GetElementSize() == 1 for pv in usdface_primvars)
    n = len(UsdGeom.Mesh(prim).GetPointsAttr().Get())
    assert len(prim.GetAttribute("usdface:distanceMatrix:hybrid:vertexDistances").Get()) == n * 70


def test_analysis_layers_of_usdface_0_1_still_work(shots, tmp_path, capsys):
    """Layers written before the move (N x C as an elementSize-C vertex primvar) read, check,
    preview and transfer the same."""
    import shutil

    from pxr import Sdf, Usd, UsdGeom

    from usdface.cli import main
    from usdface.usd.analysis_layer import read_distance_matrix

    d = tmp_path / "legacy"
    shutil.copytree(shots["head"], d)
    layer = Sdf.Layer.FindOrOpen(str(d / "analysis.usdc"))
    stage = Usd.Stage.Open(layer)
    prim = stage.GetPrimAtPath("/Face/Geom")
    attr = prim.GetAttribute("usdface:distanceMatrix:hybrid:vertexDistances")
    values = attr.Get()
    prim.RemoveProperty(attr.GetName())
    UsdGeom.PrimvarsAPI(prim).CreatePrimvar("usdface:distance:hybrid", Sdf.ValueTypeNames.FloatArray,
                                            UsdGeom.Tokens.vertex, 70).Set(values)
    layer.Save()
    new = read_distance_matrix(shots["head"] / "analysis.usdc")
    old = read_distance_matrix(d / "analysis.usdc")
    np.testing.assert_array_equal(new.vertex_to_centre, old.vertex_to_centre)
    assert main(["check", str(d / "analysis.usdc"), "-q"]) == 0
    assert main(["info", str(d / "analysis.usdc"), "-q"]) == 0
    assert main(["preview", str(d / "shot.usda"), "--color", "hybrid-weight", "--size", "128", "-o",
                 str(tmp_path / "w.png"), "-q"]) == 0
    assert main(["transfer", "--mesh", str(d / "mesh.usdc"), "--capture", str(d / "capture.usdc"), "--binding",
                 str(d / "binding.usda"), "--analysis", str(d / "analysis.usdc"), "-o", str(tmp_path / "a.usdc"),
                 "-q"]) == 0
