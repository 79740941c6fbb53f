"""Rig input: NPZ and OBJ-folder loaders, their errors, and the mirror-pair check."""
import numpy as np
import pytest

from usdface.blendshape.mirror import find_mirror_pairs
from usdface.blendshape.rig import BlendShapeRig, load_mesh_folder_rig, load_npz_rig, marker_basis
from usdface.errors import FormatError, InputError, MeshError


def _write_obj(path, mesh, points):
    lines = [f"v {x:.6f} {y:.6f} {z:.6f}" for x, y, z in points]
    start = 0
    for c in mesh.face_vertex_counts:
        idx = mesh.face_vertex_indices[start:start + c] + 1
        lines.append("f " + " ".join(str(i) for i in idx))
        start += c
    path.write_text("\n".join(lines) + "\n")


def test_npz_rig_reads_and_evaluates(makehuman):
    rig = makehuman["rig"]
    assert rig.n_shapes == 52 and rig.n_points == 2020 and rig.units == "cm"
    w = np.zeros(52)
    w[rig.index("jawOpen")] = 0.5
    assert np.allclose(rig.evaluate(w), rig.neutral + 0.5 * rig.deltas[rig.index("jawOpen")])
    basis = marker_basis(rig, makehuman["binding"])
    assert basis.shape == (41, 52, 3)
    # the basis is the shape read at the bound points
    b = makehuman["binding"]
    k = rig.index("jawOpen")
    pts = b.surface_points(rig.neutral + rig.deltas[k]) - b.surface_points(rig.neutral)
    assert np.allclose(basis[:, k], pts)


def test_npz_errors_name_what_is_wrong(makehuman, tmp_path):
    mesh, rig = makehuman["mesh"], makehuman["rig"]
    bad = tmp_path / "neutral.npz"
    neutral = mesh.points.copy()
    neutral[100] += 0.5
    np.savez(bad, names=np.array(rig.names), deltas=rig.deltas, neutral=neutral)
    with pytest.raises(MeshError, match=r"neutral.npz.*does not match.*vertex 100"):
        load_npz_rig(bad, mesh)
    dup = tmp_path / "dup.npz"
    names = list(rig.names)
    names[3] = names[2]
    np.savez(dup, names=np.array(names), deltas=rig.deltas)
    with pytest.raises(FormatError, match="duplicate shape names browInnerUp"):
        load_npz_rig(dup, mesh)
    nan = tmp_path / "nan.npz"
    d = rig.deltas.copy()
    d[rig.index("cheekPuff"), 7, 1] = np.nan
    np.savez(nan, names=np.array(rig.names), deltas=d)
    with pytest.raises(FormatError, match="NaN or infinite offsets in shape.*cheekPuff"):
        load_npz_rig(nan, mesh)
    topo = tmp_path / "topo.npz"
    np.savez(topo, names=np.array(rig.names), deltas=rig.deltas[:, :2000])
    with pytest.raises(MeshError, match="2000 vertices.*another topology"):
        load_npz_rig(topo, mesh)


def test_obj_folder_rig_and_its_errors(makehuman, tmp_path):
    mesh, rig = makehuman["mesh"], makehuman["rig"]
    folder = tmp_path / "shapes"
    folder.mkdir()
    for name in ("jawOpen", "mouthSmileLeft"):
        _write_obj(folder / f"{name}.obj", mesh, mesh.points + rig.deltas[rig.index(name)])
    got = load_mesh_folder_rig(folder, mesh)
    assert got.names == ("jawOpen", "mouthSmileLeft")
    assert np.abs(got.deltas[0] - rig.deltas[rig.index("jawOpen")]).max() < 2e-6
    # a shape with another topology is named
    _write_obj(folder / "browInnerUp.obj", mesh, np.vstack([mesh.points, [[0.0, 0.0, 0.0]]]))
    with pytest.raises(MeshError, match="shape 'browInnerUp'.*another topology: 2021 vertices"):
        load_mesh_folder_rig(folder, mesh)
    from usdface.model.mesh import FaceMesh

    fewer = FaceMesh(mesh.points, mesh.face_vertex_counts[:-1], mesh.face_vertex_indices[:-int(mesh.face_vertex_counts[-1])])
    _write_obj(folder / "browInnerUp.obj", fewer, mesh.points)
    with pytest.raises(MeshError, match="shape 'browInnerUp'.*another topology: its polygons differ"):
        load_mesh_folder_rig(folder, mesh)
    (folder / "browInnerUp.obj").unlink()
    pts = mesh.points.copy()
    pts[5, 0] = np.nan
    _write_obj(folder / "cheekPuff.obj", mesh, pts)
    with pytest.raises(MeshError, match="cheekPuff"):
        load_mesh_folder_rig(folder, mesh)
    (folder / "cheekPuff.obj").unlink()
    _write_obj(folder / "jawOpen.OBJ", mesh, mesh.points)
    with pytest.raises(FormatError, match="duplicate shape names jawOpen"):
        load_mesh_folder_rig(folder, mesh)
    with pytest.raises(InputError, match="no such folder"):
        load_mesh_folder_rig(tmp_path / "nowhere", mesh)


def test_mirror_pairs_on_the_arkit_rig(makehuman):
    rep = find_mirror_pairs(makehuman["rig"])
    by = {p.left: p for p in rep.pairs}
    for opposite in ("jawLeft", "mouthLeft"):  # mirror images, but opposite motions of the same vertices
        assert by[opposite].mirror_error < 0.01 and not by[opposite].symmetric
        assert "opposite" in by[opposite].reason
    for one_sided in ("browDownLeft", "eyeBlinkLeft", "mouthSmileLeft", "noseSneerLeft", "mouthLowerDownLeft"):
        assert by[one_sided].symmetric, by[one_sided].reason
    assert len(rep.symmetric_pairs) == 18


def test_a_pair_that_does_not_mirror_gets_no_prior(makehuman):
    rig = makehuman["rig"]
    d = rig.deltas.copy()
    d[rig.index("browDownRight")] *= 0.5  # half the motion: not the mirror image any more
    broken = BlendShapeRig(rig.names, d, rig.mesh)
    by = {p.left: p for p in find_mirror_pairs(broken).pairs}
    assert not by["browDownLeft"].symmetric and "do not mirror" in by["browDownLeft"].reason
    assert by["eyeBlinkLeft"].symmetric
