"""usdface.tissue.rig: landmarks, the default rig, the jaw, carrying a rig to another face."""
from __future__ import annotations

import numpy as np
import pytest

from usdface.errors import MeshError
from usdface.mesh.layout import read_layout
from usdface.mesh.topology import find_hole_regions
from usdface.tissue.rig import DEFAULT_FORCES, default_rig, face_landmarks, jaw_weights, landmark_correspondence, warp_rig

EXPECTED = {"zygomaticMajor", "risorius", "depressorAnguliOris", "depressorLabiiInferioris", "levatorLabiiSuperioris",
            "levatorLabiiAlaeque", "frontalisInner", "frontalisOuter", "corrugator", "orbicularisOculi"}


def test_default_rig_names_and_types(face):
    names = set(face.rig.names)
    for base in EXPECTED:
        assert {f"{base}_L", f"{base}_R"} <= names
    assert {"mentalis", "procerus", "orbicularisOris"} <= names
    types = {m.name: m.type for m in face.rig.muscles}
    assert types["orbicularisOris"] == types["orbicularisOculi_L"] == "sphincter"
    assert types["zygomaticMajor_L"] == "linear"
    assert set(DEFAULT_FORCES) == EXPECTED | {"mentalis", "procerus", "orbicularisOris"}


def test_landmarks_are_anatomical(face):
    lm = face.rig.landmarks
    assert lm["mouthCorner_L"][0] > 2 > -2 > lm["mouthCorner_R"][0]          # +x is the performer's left
    assert lm["mouthCorner_L"] == pytest.approx(lm["mouthCorner_R"] * [-1, 1, 1], abs=1e-6)   # symmetric face
    for s in "LR":
        assert lm[f"browMid_{s}"][1] > lm[f"eyeTop_{s}"][1] + 1.0
        assert lm[f"eyeCentre_{s}"][1] > lm["noseTip"][1] > lm["mouthCentre"][1] > lm["chin"][1]
    assert lm["noseTip"][2] == pytest.approx(face.mesh.points[:, 2].max(), abs=0.1)


def test_muscles_sit_where_they_should(face):
    r, lm = face.rig, face.rig.landmarks
    zyg = r.muscle("zygomaticMajor_L")
    assert np.linalg.norm(zyg.insertion - lm["mouthCorner_L"]) < 1.0
    assert zyg.origin[0] > zyg.insertion[0] and zyg.origin[1] > zyg.insertion[1]     # up and out, on the cheekbone
    front = r.muscle("frontalisInner_R")
    assert front.origin[1] > front.insertion[1] > lm["eyeTop_R"][1]
    dao = r.muscle("depressorAnguliOris_L")
    assert dao.origin[1] < dao.insertion[1]
    oris = r.muscle("orbicularisOris")
    assert np.linalg.norm(oris.centre[:2] - lm["mouthCentre"][:2]) < 0.5


def test_jaw_is_below_the_mouth(face):
    w = face.jaw.weights
    lm = face.rig.landmarks
    idx = lambda p: int(np.argmin(np.linalg.norm(face.mesh.points - p, axis=1)))  # noqa: E731
    assert w[idx(lm["chin"])] == 1.0 and w[idx(lm["lowerLip"])] == 1.0
    assert w[idx(lm["upperLip"])] == 0.0 and w[idx(lm["noseTip"])] == 0.0
    assert 0.0 <= w[idx(lm["mouthCorner_L"])] < 0.5           # the corners ride mostly with the skull
    # the pivot sits behind and above the mouth corners
    assert face.rig.jaw_pivot[2] < lm["mouthCorner_L"][2] - 5 and face.rig.jaw_pivot[1] > lm["mouthCentre"][1]


def test_markers_place_the_brows(face, sample_assets):
    lay = read_layout(sample_assets / "layouts" / "makehuman_hm08_face.layout.json")
    markers = dict(zip(lay.names, lay.positions(face.mesh)))
    rig = default_rig(face.mesh, face.regions, markers=markers)
    assert rig.placement == "markers"
    assert rig.landmarks["browInner_L"] == pytest.approx(markers["Leyebrow_Inside"], abs=1e-3)
    assert rig.landmarks["chin"] == pytest.approx(markers["Chin"], abs=1e-3)


def test_rig_carries_over_to_the_stylized_face(faces):
    src, dst = faces["realistic"], faces["stylized"]
    _, lm = face_landmarks(dst.mesh, dst.regions)
    a, b = landmark_correspondence(src.rig, lm)
    warped = warp_rig(src.rig, a, b, target_mesh=dst.mesh)
    assert warped.placement == "warp" and warped.names == src.rig.names
    # the warp lands the muscles where the default placement on that face puts them
    for name in ("zygomaticMajor_L", "frontalisInner_R", "depressorAnguliOris_L"):
        assert np.linalg.norm(warped.muscle(name).insertion - dst.rig.muscle(name).insertion) < 0.6
    assert np.linalg.norm(warped.muscle("orbicularisOris").centre - dst.rig.muscle("orbicularisOris").centre) < 0.6
    # identity warp changes nothing
    same = warp_rig(src.rig, a, a)
    assert np.allclose(same.muscle("risorius_L").origin, src.rig.muscle("risorius_L").origin, atol=1e-6)


def test_mesh_without_holes_is_refused(face):
    from usdface.model.mesh import Region

    with pytest.raises(MeshError, match="open eyes and mouth"):
        default_rig(face.mesh, [Region("outerBorder", "outerBorder", [0, 1, 2], loop=[0, 1, 2])])
    with pytest.raises(MeshError, match="missing mouth"):
        jaw_weights(face.mesh, [r for r in find_hole_regions(face.mesh) if r.name != "mouth"])
