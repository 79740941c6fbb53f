"""UsdSkel blend-shape layers: written and posed by UsdSkel's own queries; rigs read as DCCs export them."""
import numpy as np
import pytest
from pxr import Gf, Usd, UsdGeom, UsdSkel, Vt

from usdface.errors import FormatError, MeshError
from usdface.usd.blendshape_layer import (CurveSamples, evaluate_curves_layer, head_motion_of_layer,
                                          read_blendshape_rig, read_curves_layer, write_curves_layer)
from usdface.usd.layers import provenance


def _head(n):
    m = np.tile(np.eye(4), (n, 1, 1))
    a = np.linspace(0, 0.08, n)
    m[:, 0, 0] = m[:, 2, 2] = np.cos(a)
    m[:, 0, 2], m[:, 2, 0] = np.sin(a), -np.sin(a)
    m[:, :3, 3] = np.outer(np.linspace(0, 1, n), [0.5, -0.3, 0.2])
    return m


def test_curves_layer_poses_like_the_rig(makehuman, tmp_path):
    rig = makehuman["rig"]
    rng = np.random.default_rng(0)
    w = rng.random((6, 52)) * 0.7
    hm = _head(6)
    path = tmp_path / "curves.usdc"
    write_curves_layer(path, rig, makehuman["regions"],
                       CurveSamples(times=np.arange(6), weights=w, rate=30.0, start=0, end=5, head_motion=hm,
                                    head_times=np.arange(6)), prov=provenance("solve", options={}, inputs={}))
    stage = Usd.Stage.Open(str(path))
    assert stage.GetDefaultPrim().GetPath() == "/Face" and stage.GetDefaultPrim().IsA(UsdSkel.Root)
    assert stage.GetTimeCodesPerSecond() == 30.0 and stage.GetFramesPerSecond() == 30.0
    assert UsdGeom.GetStageMetersPerUnit(stage) == pytest.approx(0.01)
    assert not UsdGeom.Xformable(stage.GetPrimAtPath("/Face/Skeleton")).GetOrderedXformOps()  # D3
    assert not stage.GetRootLayer().subLayerPaths  # self-contained: imports alone
    times, local = evaluate_curves_layer(path, world=False)
    assert times.tolist() == list(range(6))
    assert np.abs(local - rig.evaluate(w)).max() < 1e-4  # float32 offsets and weights
    _, world = evaluate_curves_layer(path)
    want = np.einsum("fij,fnj->fni", hm[:, :3, :3], rig.evaluate(w)) + hm[:, None, :3, 3]
    assert np.abs(world - want).max() < 1e-4
    back = read_blendshape_rig(path)
    assert back.names == list(rig.names) and np.abs(back.deltas - rig.deltas).max() < 1e-6
    assert {r.name for r in back.regions} == {r.name for r in makehuman["regions"]}
    curves = read_curves_layer(path)
    assert np.abs(curves["weights"] - w).max() < 1e-6 and curves["rate"] == 30.0
    t, m = head_motion_of_layer(path)
    assert np.allclose(m, hm)


def _dcc_rig(path, *, zup=True, bad=None):
    """A rig as Blender / Maya-USD write it: Z-up metres, sparse offsets, an in-between."""
    stage = Usd.Stage.CreateNew(str(path))
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.z if zup else UsdGeom.Tokens.y)
    UsdGeom.SetStageMetersPerUnit(stage, 1.0)
    UsdSkel.Root.Define(stage, "/Char")
    mesh = UsdGeom.Mesh.Define(stage, "/Char/Head")
    pts = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [0.5, 0.5, 0.2]], dtype=np.float32)
    mesh.CreatePointsAttr(Vt.Vec3fArray.FromNumpy(pts))
    mesh.CreateFaceVertexCountsAttr([3, 3, 3, 3])
    mesh.CreateFaceVertexIndicesAttr([0, 1, 4, 1, 2, 4, 2, 3, 4, 3, 0, 4])
    binding = UsdSkel.BindingAPI.Apply(mesh.GetPrim())
    smile = UsdSkel.BlendShape.Define(stage, "/Char/Head/smile")
    smile.CreateOffsetsAttr([Gf.Vec3f(0, 0, 0.1), Gf.Vec3f(0.0, 0.0, float("nan") if bad == "nan" else 0.3)])
    smile.CreatePointIndicesAttr([4, 9] if bad == "index" else [4, 1])
    half = smile.CreateInbetween("half")
    half.SetWeight(0.5)
    half.SetOffsets(Vt.Vec3fArray([Gf.Vec3f(0, 0, 0.01), Gf.Vec3f(0, 0, 0.02)]))
    blink = UsdSkel.BlendShape.Define(stage, "/Char/Head/blink")
    blink.CreateOffsetsAttr(Vt.Vec3fArray.FromNumpy(np.full((5, 3), 0.05, dtype=np.float32)))
    names = ["smile", "smile"] if bad == "dup" else ["smile", "blink"]
    binding.CreateBlendShapesAttr(names)
    binding.CreateBlendShapeTargetsRel().SetTargets([smile.GetPath(), blink.GetPath()])
    stage.GetRootLayer().Save()
    return path


def test_reads_a_dcc_rig_with_sparse_offsets_and_inbetweens(tmp_path):
    rig = read_blendshape_rig(_dcc_rig(tmp_path / "dcc.usda"))
    assert rig.names == ["smile", "blink"] and rig.mesh.units == "m"
    # Z-up turned Y-up: (x, y, z) -> (x, z, -y)
    assert np.allclose(rig.mesh.points[2], [1, 0, -1])
    assert np.allclose(rig.deltas[0, 4], [0, 0.1, 0]) and np.allclose(rig.deltas[0, 1], [0, 0.3, 0])
    assert np.allclose(rig.deltas[0, [0, 2, 3]], 0)
    assert np.allclose(rig.deltas[1], [0.05, 0.05, -0.05], atol=1e-7)
    assert any("in-between shapes of 'smile' at weights 0.5 dropped" in n for n in rig.notes)


@pytest.mark.parametrize("bad,error,match", [
    ("index", MeshError, "shape 'smile' has another topology: pointIndices up to 9"),
    ("nan", FormatError, "NaN or infinite offsets in shape 'smile'"),
    ("dup", FormatError, "duplicate shape names smile"),
])
def test_bad_dcc_rigs_are_named(tmp_path, bad, error, match):
    with pytest.raises(error, match=match):
        read_blendshape_rig(_dcc_rig(tmp_path / f"{bad}.usda", bad=bad))
