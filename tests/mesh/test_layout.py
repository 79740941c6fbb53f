"""usdface.mesh.layout: the layout file format, and the sample layouts' placements."""
from __future__ import annotations

import json

import numpy as np
import pytest

from usdface.errors import FormatError, InputError, MeshError
from usdface.io.meshes import read_mesh
from usdface.mesh.surface_points import project_to_surface
from usdface.mesh.layout import LAYOUT_FORMAT, Layout, LayoutMarker, read_layout, write_layout
from usdface.mesh.topology import find_hole_regions

ANIMFACE = (
    "ForeHead_M ForeHead_L ForeHead_R Leyebrow_M Leyebrow_Inside Leyebrow_Outside Eyebrow_Center "
    "Reyebrow_M Reyebrow_Inside Reyebrow_Outside NoseTop NoseHead NoseHead_L NoseHead_R Leye_Up Leye_Down "
    "Leye_Inside Leye_Outside Reye_Up Reye_Down Reye_Inside Reye_Outside Lcheek_Up Lcheek_Down "
    "Lcheek_Outside Rcheek_Up Rcheek_Down Rcheek_Outside Mouth_Up Mouth_Down Mouth_UpL1 Mouth_Lend "
    "Mouth_UpR1 Mouth_Rend Mouth_DownL Mouth_DownR Chin Chin_R1 Chin_R2 Chin_L1 Chin_L2"
).split()
LEFT = {"ForeHead_L", "NoseHead_L", "Mouth_UpL1", "Mouth_Lend", "Mouth_DownL", "Chin_L1", "Chin_L2"}
RIGHT = {"ForeHead_R", "NoseHead_R", "Mouth_UpR1", "Mouth_Rend", "Mouth_DownR", "Chin_R1", "Chin_R2"}
MOUTH = {n for n in ANIMFACE if n.startswith("Mouth_")}

SAMPLES = [
    ("makehuman_hm08_face.layout.json", "makehuman_hm08_face_cm.obj"),
    ("makehuman_hm08_face_stylized.layout.json", "makehuman_hm08_face_stylized_cm.obj"),
    ("mediapipe_face_holes.layout.json", "mediapipe_canonical_face_model_holes.obj"),
]


def side(name):
    if name.startswith("L") or name in LEFT:
        return 1
    if name.startswith("R") or name in RIGHT:
        return -1
    return 0


def write_json(path, data):
    path.write_text(json.dumps(data))
    return path


# -- format ---------------------------------------------------------------------------------------
def test_round_trip(tmp_path):
    lay = Layout((LayoutMarker("Chin", vertex=812), LayoutMarker("NoseHead", point=(0.0, 70.91, 16.52))), units="cm")
    p = write_layout(tmp_path / "a.layout.json", lay)
    data = json.loads(p.read_text())
    assert data == {"format": LAYOUT_FORMAT, "units": "cm",
                    "markers": {"Chin": {"vertex": 812}, "NoseHead": {"point": [0.0, 70.91, 16.52]}}}
    back = read_layout(p)
    assert back == lay and back.source == str(p)
    assert back.names == ("Chin", "NoseHead") and back["Chin"].vertex == 812


def test_units_optional_and_converted(tmp_path, shared_data):
    mesh = read_mesh(shared_data / "meshes" / "mediapipe_canonical_face_model_holes.obj")
    v = mesh.points[10]
    no_units = read_layout(write_json(tmp_path / "a.json", {"format": LAYOUT_FORMAT, "markers": {"A": {"point": list(v)}}}))
    assert no_units.units is None
    np.testing.assert_allclose(no_units.positions(mesh), [v])  # mesh units
    mm = read_layout(write_json(tmp_path / "b.json", {"format": LAYOUT_FORMAT, "units": "mm",
                                                      "markers": {"A": {"point": list(v * 10)}, "B": {"vertex": 3}}}))
    np.testing.assert_allclose(mm.positions(mesh), [v, mesh.points[3]])  # mm -> cm; vertices unscaled


@pytest.mark.parametrize(
    "data, match",
    [
        ({"format": "usdface-layout/2", "markers": {"A": {"vertex": 1}}}, r"format tag is 'usdface-layout/2'; expected 'usdface-layout/1'"),
        ({"markers": {"A": {"vertex": 1}}}, r"format tag is None"),
        ({"format": LAYOUT_FORMAT, "comment": "x", "markers": {"A": {"vertex": 1}}}, r"unknown key\(s\) comment"),
        ({"format": LAYOUT_FORMAT, "units": "furlong", "markers": {"A": {"vertex": 1}}}, r"unknown units 'furlong'"),
        ({"format": LAYOUT_FORMAT, "markers": {}}, r"'markers' must be a non-empty object"),
        ({"format": LAYOUT_FORMAT, "markers": [1]}, r"'markers' must be a non-empty object"),
        ({"format": LAYOUT_FORMAT, "markers": {"A": {"vertex": -1}}}, r"marker 'A': vertex must be an integer >= 0; got -1"),
        ({"format": LAYOUT_FORMAT, "markers": {"A": {"vertex": 1.5}}}, r"marker 'A': vertex must be an integer"),
        ({"format": LAYOUT_FORMAT, "markers": {"A": {"vertex": True}}}, r"marker 'A': vertex must be an integer"),
        ({"format": LAYOUT_FORMAT, "markers": {"A": {"point": [1, 2]}}}, r"marker 'A': point must be a list of 3 finite numbers"),
        ({"format": LAYOUT_FORMAT, "markers": {"A": {"point": [1, "2", 3]}}}, r"marker 'A': point must be a list of 3"),
        ({"format": LAYOUT_FORMAT, "markers": {"A": {"vertex": 1, "point": [1, 2, 3]}}}, r"marker 'A': entry must be"),
        ({"format": LAYOUT_FORMAT, "markers": {"A": {"vertx": 1}}}, r"marker 'A': entry must be"),
        ({"format": LAYOUT_FORMAT, "markers": {"A": 3}}, r"marker 'A': entry must be"),
        ([1, 2], r"top level must be a JSON object"),
    ],
)
def test_bad_layouts(tmp_path, data, match):
    p = write_json(tmp_path / "bad.layout.json", data)
    with pytest.raises(FormatError, match=match) as e:
        read_layout(p)
    assert "bad.layout.json" in str(e.value)


def test_not_json_and_missing(tmp_path):
    p = tmp_path / "x.json"
    p.write_text('{"format": "usdface-layout/1",\n "markers": {"A": {"point": [1, 2, 3}}}')
    with pytest.raises(FormatError, match=r"x\.json: not valid JSON: .* line 2"):
        read_layout(p)
    p.write_text('{"format": "usdface-layout/1", "markers": {"A": {"point": [1, 2, NaN]}}}')
    with pytest.raises(FormatError, match=r"x\.json: NaN is not a number JSON allows"):
        read_layout(p)
    with pytest.raises(InputError, match=r"layout file .*nope\.json: no such file"):
        read_layout(tmp_path / "nope.json")


def test_vertex_out_of_range(tmp_path, shared_data):
    mesh = read_mesh(shared_data / "meshes" / "mediapipe_canonical_face_model_holes.obj")
    lay = read_layout(write_json(tmp_path / "v.json", {"format": LAYOUT_FORMAT, "markers": {"Chin": {"vertex": 468}, "Nose": {"vertex": 4}}}))
    with pytest.raises(MeshError, match=r"v\.json: vertex index out of range for mesh .*holes\.obj \(468 vertices, 0\.\.467\): Chin \(vertex 468\)"):
        lay.positions(mesh)


def test_duplicate_names_rejected():
    with pytest.raises(FormatError, match="duplicate markers: A"):
        Layout((LayoutMarker("A", vertex=1), LayoutMarker("A", vertex=2)))


# -- the sample layouts ---------------------------------------------------------------------------
@pytest.mark.parametrize("layout_name, mesh_name", SAMPLES)
def test_sample_layout_placements(sample_assets, shared_data, layout_name, mesh_name):
    lay = read_layout(sample_assets / "layouts" / layout_name)
    mesh = read_mesh(shared_data / "meshes" / mesh_name)
    assert sorted(lay.names) == sorted(ANIMFACE) and len(ANIMFACE) == 41
    assert lay.units == "cm" and all(m.point is not None for m in lay.markers)  # points survive remeshing
    pos = lay.positions(mesh)
    names = lay.names
    # on the surface
    sp = project_to_surface(mesh, pos)
    assert sp.distances.max() < 1e-3
    regions = {r.name: mesh.points[r.loop] for r in find_hole_regions(mesh)}

    def dist_to(loop):
        return np.linalg.norm(pos[:, None] - loop[None], axis=2).min(axis=1)

    x0 = 0.5 * (mesh.points[:, 0].min() + mesh.points[:, 0].max())
    s = np.array([side(n) for n in names])
    assert (pos[s == 1, 0] > x0 + 0.5).all() and (pos[s == -1, 0] < x0 - 0.5).all()
    np.testing.assert_allclose(pos[s == 0, 0], x0, atol=1e-3)
    # not in (or on the rim of) an eye hole; only the lip corners on the mouth loop
    assert dist_to(np.vstack([regions["leftEye"], regions["rightEye"]])).min() > 0.3
    d_mouth = dist_to(regions["mouth"])
    is_mouth = np.array([n in MOUTH for n in names])
    corners = np.array([n in ("Mouth_Lend", "Mouth_Rend") for n in names])
    assert (d_mouth[is_mouth] < 1.5).all()
    assert (d_mouth[~corners] > 0.15).all()
    np.testing.assert_allclose(d_mouth[corners], 0.0, atol=1e-3)
    mouth = regions["mouth"]
    np.testing.assert_allclose(pos[names.index("Mouth_Lend")], mouth[np.argmax(mouth[:, 0])], atol=1e-3)
    np.testing.assert_allclose(pos[names.index("Mouth_Rend")], mouth[np.argmin(mouth[:, 0])], atol=1e-3)
    # away from the outer border, and apart from each other
    assert dist_to(regions["outerBorder"]).min() > 0.5
    d = np.linalg.norm(pos[:, None] - pos[None], axis=2) + np.eye(len(pos)) * 1e9
    assert d.min() > 0.8
    # lids above/below their eye, brows above the lids, chin below the mouth, nose between
    y = dict(zip(names, pos[:, 1]))
    for e, eye in (("L", regions["leftEye"]), ("R", regions["rightEye"])):
        assert y[f"{e}eye_Up"] > eye[:, 1].max() > eye[:, 1].min() > y[f"{e}eye_Down"]
        assert y[f"{e}eyebrow_M"] > y[f"{e}eye_Up"] + 1.0
    assert y["Mouth_Up"] > mouth[:, 1].max() and y["Mouth_Down"] < mouth[:, 1].min()
    assert y["Chin"] < y["Mouth_Down"] - 1.0
    assert y["Mouth_Up"] < y["NoseHead"] < y["NoseTop"] < y["Eyebrow_Center"] < y["ForeHead_M"]
