"""Registration of the generic face: similarity, thin-plate warp, closest-point projection."""
import numpy as np
import pytest

from usdface.errors import ComputeError, MeshError
from usdface.scan.register import GenericRegistration, RegistrationParameters, apply_similarity, similarity_fit
from usdface.scan.synthetic import rotation_matrix
from usdface.scan.warp import ThinPlateSpline


def test_similarity_fit_recovers_a_transform():
    rng = np.random.default_rng(0)
    a = rng.normal(size=(20, 3))
    R = rotation_matrix(20, -35, 50)
    b = 1.7 * a @ R.T + [1, 2, 3]
    s, R2, t = similarity_fit(a, b)
    assert s == pytest.approx(1.7) and np.allclose(R2, R) and np.allclose(apply_similarity(a, s, R2, t), b)
    with pytest.raises(ComputeError):
        similarity_fit(a[:2], b[:2])


@pytest.mark.parametrize("dim", [2, 3])
def test_thin_plate_interpolates_and_keeps_affine(dim):
    rng = np.random.default_rng(1)
    c = rng.normal(size=(15, dim))
    A = rng.normal(size=(dim, dim)) + 2 * np.eye(dim)
    tps = ThinPlateSpline(c, c @ A.T + 1.0)
    q = rng.normal(size=(30, dim))
    assert np.allclose(tps(q), q @ A.T + 1.0, atol=1e-8)  # an affine map is reproduced exactly
    y = rng.normal(size=(15, 2))
    assert np.allclose(ThinPlateSpline(c, y)(c), y, atol=1e-8)
    smooth = ThinPlateSpline(c, y, smoothing=10.0)(c)
    assert np.abs(smooth - y).max() > 1e-3  # the ridge smooths


@pytest.fixture(scope="module")
def faces(sample_assets):
    from usdface.io.meshes import read_mesh
    from usdface.mesh.layout import read_layout
    from usdface.mesh.topology import find_hole_regions
    from usdface.scan.landmarks import FACE_LANDMARKS

    g = read_mesh(sample_assets / "meshes" / "makehuman_hm08_face_cm.obj")
    st = read_mesh(sample_assets / "meshes" / "makehuman_hm08_face_stylized_cm.obj")
    lay = read_layout(sample_assets / "landmarks" / "makehuman_hm08_face.landmarks.layout.json")
    return g, find_hole_regions(g), lay.positions(g, FACE_LANDMARKS), st


def test_register_stylized_face_from_20_landmarks(faces):
    g, regions, glm, st = faces
    reg = GenericRegistration(g, regions, glm)
    rng = np.random.default_rng(7)
    s, R, t = rng.uniform(0.5, 2.0), rotation_matrix(*rng.uniform(-30, 30, 3)), rng.uniform(-40, 40, 3)
    truth = apply_similarity(st.points, s, R, t)
    slm = reg.landmark_positions(truth)  # same topology: the same surface points on the stylized face
    s2, R2, t2 = similarity_fit(g.points, truth)  # the best similarity, knowing every correspondence
    e_sim = np.linalg.norm(apply_similarity(g.points, s2, R2, t2) - truth, axis=1).mean()
    plain = reg.register(truth, st.triangles(), slm)
    cropped = reg.register(truth, st.triangles(), slm, RegistrationParameters(border_weight=1.0, field_iterations=8))
    e_rbf = np.linalg.norm(plain.rbf_points - truth, axis=1).mean()
    e_plain = np.linalg.norm(plain.points - truth, axis=1).mean()
    e_crop = np.linalg.norm(cropped.points - truth, axis=1).mean()
    assert plain.similarity[0] == pytest.approx(s, rel=0.1)
    assert e_rbf < 0.8 * e_sim and e_plain < e_rbf
    assert e_crop <= 0.30 * e_sim  # the bar: <= 30% of the best similarity alignment's error
    assert np.nanmedian(plain.surface_distance) < 0.01 * s  # on the scan (cm)
    assert plain.landmark_residuals.max() < 0.05 * s
    # holes excluded from the data term, topology kept
    assert not plain.data_vertices[reg.excluded].any() and plain.points.shape == g.points.shape


def test_register_needs_regions(faces):
    g, _, glm, _ = faces
    with pytest.raises(MeshError, match="no regions"):
        GenericRegistration(g, [], glm)
