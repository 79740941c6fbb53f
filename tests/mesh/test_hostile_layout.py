"""Hostile layouts: deep nesting, points beyond float32, markers on one point, duplicate keys."""
from __future__ import annotations

import json

import numpy as np
import pytest

from usdface.errors import FormatError, OptionError
from usdface.io.meshes import read_mesh
from usdface.mesh.closest import SurfaceLocator
from usdface.mesh.layout import read_layout

from ..hostile import assert_one_line, digest, run_in_process

LAYOUT = "makehuman_hm08_face.layout.json"


@pytest.fixture
def bind_args(sample_assets, tmp_path):
    def args(layout):
        return ["bind", "--mesh", sample_assets / "meshes" / "makehuman_hm08_face_cm.usdc", "--capture",
                sample_assets / "capture" / "JawMoCap.usdc", "--layout", layout, "-o", tmp_path / "b.usda"]
    return args


def _layout(sample_assets, tmp_path, change) -> object:
    data = json.loads((sample_assets / "layouts" / LAYOUT).read_text())
    change(data["markers"])
    out = tmp_path / "l.json"
    out.write_text(json.dumps(data))
    return out


def test_deeply_nested_layout_is_one_line(tmp_path, capsys, bind_args):
    # issue 20 (5): 100000 nested '[' was a RecursionError traceback in read_layout
    deep = tmp_path / "deep.json"
    deep.write_text("[" * 100000)
    before = digest(deep)
    rc, lines = run_in_process(capsys, *bind_args(deep))
    assert_one_line(rc, lines, code=2, command="bind",
                    contains=(f"layout file {deep}: nested deeper than 64 levels; not a usdface JSON file",))
    assert digest(deep) == before and not (tmp_path / "b.usda").exists()


def test_layout_point_beyond_float32_is_one_line(sample_assets, tmp_path, capsys, bind_args):
    # issue 20 (5): a point [1e308, 1e308, 1e308] was an IndexError in mesh/closest.py
    def far(markers):
        markers["ForeHead_M"] = {"point": [1e308, 1e308, 1e308]}
    layout = _layout(sample_assets, tmp_path, far)
    rc, lines = run_in_process(capsys, *bind_args(layout))
    assert_one_line(rc, lines, code=2, command="bind",
                    contains=(f"layout file {layout}, marker 'ForeHead_M': point [1e+308, 1e+308, 1e+308] is beyond "
                              "the range of the float32 coordinates USD stores",))


def test_layout_whose_points_coincide_says_so(sample_assets, tmp_path, capsys, bind_args):
    # issue 20 (15): every point at one place reported a face of "0 cm"
    def one_vertex(markers):
        for name in markers:
            markers[name] = {"vertex": 5}
    layout = _layout(sample_assets, tmp_path, one_vertex)
    rc, lines = run_in_process(capsys, *bind_args(layout))
    assert_one_line(rc, lines, code=2, command="bind",
                    contains=(f"layout {layout}: all 41 markers are at one point (-3.08, 73.566, 14.103) cm",))


def test_two_markers_on_one_point_are_named(sample_assets, tmp_path):
    def copy(markers):
        markers["Chin"] = dict(markers["Mouth_Down"])
    layout = read_layout(_layout(sample_assets, tmp_path, copy))
    mesh = read_mesh(sample_assets / "meshes" / "makehuman_hm08_face_cm.obj")
    with pytest.raises(FormatError, match=r"l\.json: markers at the same point on mesh .*: (Mouth_Down and Chin|"
                                          r"Chin and Mouth_Down); each marker needs its own place"):
        layout.positions(mesh)


def test_every_sample_layout_spreads_its_markers(sample_assets):
    for name, mesh in (("makehuman_hm08_face", "makehuman_hm08_face_cm.obj"),
                       ("makehuman_hm08_face_stylized", "makehuman_hm08_face_stylized_cm.obj"),
                       ("mediapipe_face_holes", "mediapipe_canonical_face_model_holes.obj")):
        m = read_mesh(sample_assets / "meshes" / mesh)
        for path in (sample_assets / "layouts" / f"{name}.layout.json",
                     sample_assets / "landmarks" / f"{name}.landmarks.layout.json"):
            assert read_layout(path).positions(m).shape[1] == 3


@pytest.mark.parametrize("text, match", [
    ('{"format": "usdface-layout/1", "markers": {"A": {"vertex": 1}, "A": {"vertex": 2}}}',
     r"the key 'A' appears twice in one object"),
    ('{"format": "usdface-layout/1", "markers": {"A": {"point": [1, 2, Infinity]}}}',
     r"Infinity is not a number JSON allows"),
    ('{"format": "usdface-layout/1", "markers": {"A": {"point": [1e400, 2, 3]}}}',
     r"the number 1e400 is beyond the range of a float"),
    ('{"format": "usdface-layout/1", "markers": {"A": {"vertex": 123456789012345678901234567890}}}',
     r"the integer 123456789012345678901234\.\.\. is too large"),
    ("", r"the file is empty"),
])
def test_json_that_python_reads_but_no_layout_holds(tmp_path, text, match):
    p = tmp_path / "l.json"
    p.write_text(text)
    with pytest.raises(FormatError, match=r"layout file .*l\.json: " + match):
        read_layout(p)
    p.write_bytes(b'{"format": "usdface-layout/1", "units": "c\xe9"}')
    with pytest.raises(FormatError, match=r"not UTF-8 text \(byte 0xe9 at line 1\)"):
        read_layout(p)


def test_surface_locator_refuses_coordinates_beyond_float32():
    loc = SurfaceLocator(np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0]]), np.array([[0, 1, 2]]))
    with pytest.raises(OptionError, match="beyond float32's range"):
        loc.closest(np.array([[1e308, 1e308, 1e308]]))
    tri, _, _, dist = loc.closest(np.array([[3e38, 0, 0]]))  # within range: still exact
    assert tri[0] == 0 and dist[0] == pytest.approx(3e38 - 1, rel=1e-12)
