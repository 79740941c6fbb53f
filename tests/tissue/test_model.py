"""usdface.tissue.model: the three-layer prism model of seed 001 §5.1, and bad meshes."""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from usdface.errors import MeshError, OptionError
from usdface.model.mesh import FaceMesh
from usdface.tissue.model import SPRING_KINDS, TissueOptions, build_tissue_model
from usdface.tissue.prisms import prism_volumes
from usdface.tissue.surface import inconsistent_faces, triangle_edges

from .conftest import grid_mesh


def test_sample_face_counts(face):
    m = face.model
    n = face.mesh.n_points
    assert face.mesh.n_faces == 1934
    assert m.n_elements == 3868                      # one prism element per triangle (quads split in two)
    assert m.prisms.shape == (2 * 3868, 6)            # dermal + deep sub-prisms
    assert m.n_nodes == 3 * n
    e = triangle_edges(m.triangles, n).shape[0]
    assert m.n_springs == 6 * e + 2 * n              # layer edges x2, verticals x2, cross-diagonals x4
    counts = np.bincount(m.spring_kind, minlength=4)
    assert dict(zip(SPRING_KINDS, counts)) == {"epidermis": e, "fascia": e, "dermis": 2 * e + n, "deep": 2 * e + n}
    # bone nodes are kinematic; the fascia and bone lie below the skin along the offset direction
    assert np.isinf(m.mass[2 * n:]).all() and np.isfinite(m.mass[:2 * n]).all()
    below = np.einsum("ij,ij->i", m.rest[:n] - m.rest[n:2 * n], m.direction)
    assert (below > 0).all()
    assert np.allclose(below, 0.3 * m.depth, atol=1e-9)        # fascia depth 0.3 cm (scaled at the rims)
    assert (m.depth[~np.isin(np.arange(n), m.triangles[np.isin(m.mesh.triangle_faces(), m.folded_faces)])] > 0).all()
    # all prisms positive at rest except the few folded mouth-corner faces, kept and named
    vol = m.rest_volume
    folded = np.isin(np.tile(m.mesh.triangle_faces(), 2), m.folded_faces)
    assert (vol[~folded] > 0).all()
    assert m.folded_faces.size <= 0.02 * face.mesh.n_faces
    assert (m.depth >= 0.1 - 1e-12).all() and np.mean(m.depth == 1.0) > 0.8


def test_rest_state_is_an_equilibrium(face):
    sim = face.simulator()
    F = sim.compute_forces()
    assert np.abs(F[:sim.n_free]).max() < 1e-9
    assert sim.energy()["total"] == pytest.approx(0.0, abs=1e-12)


def test_single_quad_springs():
    mesh = grid_mesh(2)
    m = build_tissue_model(mesh, regions=[])
    assert m.n_elements == 2 and m.triangles.tolist() == [[0, 1, 3], [0, 3, 2]]  # fixed v0-v2 split
    assert m.n_springs == 6 * 5 + 2 * 4
    assert (m.rest_volume > 0).all()
    # unit options: stiffness is force per cm, converted with the length scale
    mm = build_tissue_model(dataclasses.replace(mesh, points=mesh.points * 10, units="mm"), regions=[])
    assert mm.length_scale == pytest.approx(10.0)
    assert np.allclose(mm.rest_length, 10 * m.rest_length)
    assert np.allclose(mm.stiffness, m.stiffness / 10)


def test_prism_volume_of_a_right_prism():
    x = np.array([[0, 0, 1], [1, 0, 1], [0, 1, 1], [0, 0, 0], [1, 0, 0], [0, 1, 0]], dtype=float)
    assert prism_volumes(x, np.arange(6)[None]) == pytest.approx([0.5])


def test_inconsistent_normals_are_fixed_or_refused():
    mesh = grid_mesh(4)
    idx = mesh.face_vertex_indices.reshape(-1, 4).copy()
    idx[4] = idx[4][[0, 3, 2, 1]]  # wind face 4 the other way
    bad = dataclasses.replace(mesh, face_vertex_indices=idx.ravel())
    flip, non_orientable = inconsistent_faces(bad)
    assert flip.tolist() == [4] and non_orientable.size == 0
    m = build_tissue_model(bad, regions=[])
    assert m.flipped_faces.tolist() == [4]
    assert (m.rest_volume > 0).all()
    with pytest.raises(MeshError, match=r"wound against their neighbours.*faces 4"):
        build_tissue_model(bad, regions=[], orient="error")


def test_inside_out_mesh_is_rewound():
    mesh = grid_mesh(4)
    idx = mesh.face_vertex_indices.reshape(-1, 4)[:, [0, 3, 2, 1]]
    m = build_tissue_model(dataclasses.replace(mesh, face_vertex_indices=idx.ravel()), regions=[])
    assert m.flipped_faces.size == mesh.n_faces
    assert (m.rest_volume > 0).all()
    assert m.direction[:, 2].mean() > 0.5  # outward = toward the viewer again


def test_zero_area_face_is_named():
    mesh = grid_mesh(4)
    pts = mesh.points.copy()
    quad = mesh.face_vertex_indices.reshape(-1, 4)[7]
    pts[quad] = pts[quad[0]]  # collapse face 7 to a point
    with pytest.raises(MeshError, match=r"degenerate.*faces \[7"):
        build_tissue_model(dataclasses.replace(mesh, points=pts), regions=[])


def test_non_manifold_edge_is_refused():
    pts = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1]], dtype=float)
    mesh = FaceMesh(points=pts, face_vertex_counts=[3, 3, 3], face_vertex_indices=[0, 1, 2, 1, 0, 3, 0, 1, 4],
                    units="cm")
    with pytest.raises(MeshError, match="non-manifold"):
        build_tissue_model(mesh, regions=[])


def test_options_are_checked():
    with pytest.raises(OptionError, match="k_deep"):
        TissueOptions(k_deep=-1)
    with pytest.raises(OptionError, match="unknown tissue option"):
        TissueOptions().replace(k_bogus=1.0)
    assert TissueOptions().replace(k_deep=5.0, fascia_depth=None).k_deep == 5.0


def test_lips_and_eyelids_are_loosely_bound(face):
    from scipy.spatial import cKDTree

    m, pts = face.model, face.mesh.points
    by = {r.name: r for r in face.regions}
    o = m.options
    assert m.attachment[by["mouth"].loop].max() <= o.free_attachment + 1e-9
    assert m.attachment[by["leftEye"].loop].max() <= o.free_attachment + 1e-9
    d_mouth = cKDTree(pts[by["mouth"].loop]).query(pts)[0]
    d_eyes = np.minimum(cKDTree(pts[by["leftEye"].loop]).query(pts)[0], cKDTree(pts[by["rightEye"].loop]).query(pts)[0])
    bound = (d_mouth >= o.lip_free_radius) & (d_eyes >= o.eyelid_free_radius)
    assert bound.mean() > 0.5 and np.allclose(m.attachment[bound], 1.0)
