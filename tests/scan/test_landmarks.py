"""Landmark files, the sample landmark files, landmarks of a hole mesh."""
import json

import numpy as np
import pytest

from usdface.errors import FormatError, InputError, MeshError
from usdface.scan.landmarks import (FACE_LANDMARKS, Landmarks, interocular_distance, mesh_face_landmarks,
                                    read_landmarks, read_pts, write_landmarks, write_pts)


def test_round_trip_and_features_file(tmp_path):
    lm = Landmarks(image={"a": (1.0, 2.0), "b": (3.5, 4.25)}, scan={"b": (1.0, 2.0, 3.0)})
    p = write_landmarks(tmp_path / "l.json", lm)
    back = read_landmarks(p)
    assert back.image == lm.image and back.scan == lm.scan and back.names == ("a", "b")
    (tmp_path / "f.json").write_text(json.dumps({"format": "usdface-features/1", "faces": [],
                                                 "landmarks": {"a": {"image": [5, 6]}}}))
    assert read_landmarks(tmp_path / "f.json").image == {"a": (5.0, 6.0)}
    pts = np.array([[1.5, 2.5], [3, 4]])
    assert np.allclose(read_pts(write_pts(tmp_path / "x.pts", pts)), pts)


@pytest.mark.parametrize("data, msg", [
    ({"a": {"image": [1]}}, "image must be 2 finite numbers"),
    ({"a": {"scan": [1, 2, float("nan")]}}, "the number 1e999 is beyond the range of a float"),
    ({"a": {"pixel": [1, 2]}}, "expected"),
    ({}, "non-empty"),
    ({"format": "usdface-layout/1", "markers": {}}, "is a marker layout"),
])
def test_bad_landmark_files(tmp_path, data, msg):
    p = tmp_path / "l.json"
    p.write_text(json.dumps(data).replace("NaN", "1e999"))
    with pytest.raises(FormatError, match=msg):
        read_landmarks(p)


def test_outside_the_image():
    lm = Landmarks(image={"a": (10.0, 10.0), "b": (-3.0, 4.0)}, scan={}, source="l.json")
    with pytest.raises(InputError, match=r"1 point\(s\) outside the 100x80 image: b"):
        lm.check_inside((100, 80))


def test_sample_landmark_files(sample_assets, shared_data):
    from usdface.io.meshes import read_mesh
    from usdface.mesh.closest import SurfaceLocator
    from usdface.mesh.layout import read_layout

    photo = read_landmarks(sample_assets / "landmarks" / "astronaut.landmarks.json")
    assert set(photo.image) == set(FACE_LANDMARKS)
    photo.check_inside((512, 512))
    pts = photo.image_array(FACE_LANDMARKS)
    # inside the Haar face box, right-eye landmarks on the image left
    assert (pts[:, 0] > 177).all() and (pts[:, 0] < 272).all() and (pts[:, 1] > 66).all() and (pts[:, 1] < 180).all()
    assert 35 < interocular_distance(pts) < 55
    mesh = read_mesh(sample_assets / "meshes" / "makehuman_hm08_face_cm.obj")
    lay = read_layout(sample_assets / "landmarks" / "makehuman_hm08_face.landmarks.layout.json")
    assert lay.names == FACE_LANDMARKS
    _, _, _, d = SurfaceLocator(mesh.points, mesh.triangles()).closest(lay.positions(mesh, FACE_LANDMARKS))
    assert d.max() < 0.01  # on the surface (cm)


def test_mesh_face_landmarks_symmetric(sample_assets):
    from usdface.io.meshes import read_mesh

    mesh = read_mesh(sample_assets / "meshes" / "makehuman_hm08_face_stylized_cm.obj")
    lm = mesh_face_landmarks(mesh)
    for n in FACE_LANDMARKS:
        if n.startswith(("L", "R")) and not n.startswith("Mouth"):
            other = ("R" if n[0] == "L" else "L") + n[1:]
            assert np.allclose(lm[n] * [-1, 1, 1], lm[other], atol=0.02)
    assert lm["Leye_Outside"][0] > lm["Leye_Inside"][0] > 0
    assert lm["Mouth_Up"][1] > lm["Mouth_Down"][1] > lm["Chin"][1]


def test_mesh_without_holes():
    from usdface.model.mesh import FaceMesh

    m = FaceMesh(points=[[0, 0, 0], [1, 0, 0], [0, 1, 0]], face_vertex_counts=[3], face_vertex_indices=[0, 1, 2])
    with pytest.raises(MeshError, match="leftEye"):
        mesh_face_landmarks(m, regions=[])
