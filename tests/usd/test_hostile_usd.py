"""Hostile USD inputs: USD's own parse message kept, composition problems said as what they are,
named pipes refused before USD opens them, file names USD cannot take refused up front."""
from __future__ import annotations

import os
import shutil

import pytest

from usdface.errors import InputError
from usdface.usd.layers import open_stage

from ..hostile import assert_one_line, digest, run_in_process, run_subprocess

SYNTAX = '#usda 1.0\n(\n    defaultPrim = "Face"\n)\n\ndef Xform "Face" {\n}\n}\n'


def _sublayering(path, *targets):
    path.write_text("#usda 1.0\n(\n    subLayers = [" + ", ".join(f"@./{t}@" for t in targets) + "]\n)\n")
    return path


def test_parse_error_keeps_usds_message_without_cpp_locations(tmp_path, capsys):
    # issue 20 (11): "cannot be read as USD (Error in '...UsdStage::Open' at line 1287 in file /opt/USD/...)"
    bad = tmp_path / "syntax.usda"
    bad.write_text(SYNTAX)
    rc, lines = run_in_process(capsys, "info", bad)
    line = assert_one_line(rc, lines, code=2, command="info",
                           contains=(f"file {bad}: cannot be read as USD ({bad}:8:1: parse error matching eof at '}}'",))
    assert "stage.cpp" not in line and "pxrInternal" not in line and "Failed to open layer" not in line


def test_parse_error_in_a_sublayer_names_the_sublayer(tmp_path):
    (tmp_path / "syntax.usda").write_text(SYNTAX)
    top = _sublayering(tmp_path / "top.usda", "syntax.usda")
    with pytest.raises(InputError, match=r"top\.usda: sublayer \./syntax\.usda of top\.usda cannot be read as USD "
                                         r"\(.*syntax\.usda:8:1: parse error"):
        open_stage(top)


def test_missing_sublayer_is_the_error_not_a_missing_prim(tmp_path, capsys):
    # issue 20 (12): USD's C++ warning, then "no Mesh prim (expected /Face/Geom)"
    top = _sublayering(tmp_path / "missing.usda", "nothere.usdc")
    rc, lines = run_in_process(capsys, "import-mesh", top, "-o", tmp_path / "m.usdc")
    assert_one_line(rc, lines, code=2, command="import-mesh",
                    contains=(f"mesh {top}: sublayer {tmp_path / 'nothere.usdc'} of {top} not found",))
    # `info` describes what is there, with one usdface warning instead of USD's raw one
    rc, lines = run_in_process(capsys, "info", top)
    assert rc == 0 and lines == [f"usdface: WARNING: file {top}: sublayer {tmp_path / 'nothere.usdc'} of {top} "
                                 f"not found"]


def test_cyclic_sublayers_are_named_as_a_cycle(tmp_path, capsys):
    # issue 20 (12): two raw warnings, then "has no units"
    one = _sublayering(tmp_path / "one.usda", "two.usda")
    _sublayering(tmp_path / "two.usda", "one.usda")
    rc, lines = run_in_process(capsys, "import-capture", one, "-o", tmp_path / "c.usdc")
    assert_one_line(rc, lines, code=2, command="import-capture",
                    contains=(f"capture {one}: its sublayers form a cycle (one.usda -> two.usda -> one.usda)",))


def test_missing_reference_warns_in_info(tmp_path, capsys):
    f = tmp_path / "ref.usda"
    f.write_text('#usda 1.0\ndef Xform "A" (references = @./gone.usda@) {}\n')
    rc, lines = run_in_process(capsys, "info", f)
    assert rc == 0 and lines == [f"usdface: WARNING: file {f}: reference {tmp_path / 'gone.usda'} of prim </A> in "
                                 f"{f} not found"]


@pytest.mark.parametrize("command", [["info"], ["check"]])
def test_named_pipe_is_refused_not_waited_on(tmp_path, command):
    # issue 20 (8): `info`, `check` and `bind --mesh` hung on a FIFO
    fifo = tmp_path / "shot.usda"
    os.mkfifo(fifo)
    rc, lines = run_subprocess(*command, fifo, timeout=60)
    assert_one_line(rc, lines, code=2, command=command[0],
                    contains=(f"file {fifo}: is a named pipe (FIFO), not a regular file",))


def test_named_pipe_as_bind_mesh_and_as_a_sublayer(sample_assets, tmp_path):
    fifo = tmp_path / "mesh.usda"
    os.mkfifo(fifo)
    rc, lines = run_subprocess("bind", "--mesh", fifo, "--capture", sample_assets / "capture" / "JawMoCap.usdc",
                               "--layout", sample_assets / "layouts" / "makehuman_hm08_face.layout.json",
                               "-o", tmp_path / "b.usda", timeout=60)
    assert_one_line(rc, lines, code=2, command="bind", contains=(f"mesh {fifo}: is a named pipe (FIFO)",))
    top = _sublayering(tmp_path / "top.usda", "mesh.usda")
    rc, lines = run_subprocess("info", top, timeout=60)
    assert_one_line(rc, lines, code=2, command="info",
                    contains=(f"file {top}: sublayer ./mesh.usda of top.usda: is a named pipe (FIFO)",))


def test_empty_and_truncated_files(sample_assets, tmp_path):
    empty = tmp_path / "empty.usdc"
    empty.write_bytes(b"")
    with pytest.raises(InputError, match=r"^layer .*empty\.usdc: the file is empty \(0 bytes\), not a USD layer$"):
        open_stage(empty)
    cut = tmp_path / "cut.usdc"
    cut.write_bytes((sample_assets / "capture" / "JawMoCap.usdc").read_bytes()[:3000])
    with pytest.raises(InputError, match=r"cut\.usdc: cannot be read as USD \(Sdf crate file corrupt, possibly "
                                         r"truncated: table of contents at offset \d+ but file size is 3000\)$"):
        open_stage(cut)
    latin = tmp_path / "latin.usda"
    latin.write_bytes(b'#usda 1.0\n(\n    defaultPrim = "A\xff"\n)\n')
    with pytest.raises(InputError, match=r"latin\.usda: cannot be read as USD \(the file holds bytes that are not "
                                         r"UTF-8 text"):
        open_stage(latin)


def test_non_utf8_input_and_output_names(sample_assets, tmp_path):
    # issue 20 (5): UnicodeEncodeError inside Sdf for a capture or output name with a non-UTF-8 byte
    cap = os.fsencode(tmp_path) + b"/cap\xff.usdc"
    shutil.copy(sample_assets / "capture" / "JawMoCap.usdc", cap)
    rc, lines = run_subprocess("import-capture", cap, "--trim", 0, 10, "-o", tmp_path / "o.usdc")
    assert_one_line(rc, lines, code=2, command="import-capture",
                    contains=("cap\\xff.usdc: the name holds the byte 0xff, which is not UTF-8",))
    rc, lines = run_subprocess("info", cap)
    assert_one_line(rc, lines, code=2, command="info", contains=("cap\\xff.usdc: the name holds the byte 0xff",))
    out = os.fsencode(tmp_path) + b"/out\xff.usdc"
    ma = sample_assets / "capture" / "JawMoCap.ma"
    before = digest(ma)
    rc, lines = run_subprocess("import-capture", ma, "--trim", 0, 10, "-o", out)
    assert_one_line(rc, lines, code=2, command="import-capture",
                    contains=("-o ", "out\\xff.usdc: the name holds the byte 0xff"))
    rc, lines = run_subprocess("import-mesh", sample_assets / "meshes" / "makehuman_hm08_face_cm.obj", "-o", out)
    assert_one_line(rc, lines, code=2, command="import-mesh", contains=("out\\xff.usdc: the name holds the byte",))
    assert digest(ma) == before and sorted(os.listdir(os.fsencode(tmp_path))) == [b"cap\xff.usdc"]


def test_a_non_utf8_capture_file_name_is_recorded_escaped(sample_assets, tmp_path, capsys):
    """A .ma read by usdface itself may have any name: USD only records it (escaped)."""
    ma = os.fsdecode(os.fsencode(tmp_path) + b"/jaw\xff.ma")
    shutil.copy(sample_assets / "capture" / "JawMoCap.ma", ma)
    rc, lines = run_in_process(capsys, "import-capture", ma, "--trim", 0, 10, "-o", tmp_path / "c.usdc", "-q")
    assert rc == 0 and lines == []
    from pxr import Usd
    stage = Usd.Stage.Open(str(tmp_path / "c.usdc"))
    prim = stage.GetPrimAtPath("/Capture/Markers")
    assert prim.GetAttribute("usdface:markerSet:sourceFile").Get() == "jaw\\xff.ma"


def test_capture_layer_with_a_ragged_points_array(sample_assets, tmp_path, capsys):
    # issue 20 (5): 10 points at one time and 41 at the others was an np.stack ValueError
    from pxr import Gf, Usd, Vt

    layer = tmp_path / "ragged.usda"
    Usd.Stage.Open(str(sample_assets / "capture" / "JawMoCap.usdc")).Export(str(layer))
    stage = Usd.Stage.Open(str(layer))
    stage.GetPrimAtPath("/Capture/Markers").GetAttribute("points").Set(Vt.Vec3fArray([Gf.Vec3f(0, 0, 0)] * 10), 5)
    stage.Save()
    del stage
    rc, lines = run_in_process(capsys, "import-capture", layer, "-o", tmp_path / "c.usdc")
    assert_one_line(rc, lines, code=2, command="import-capture",
                    contains=(f"capture {layer}: /Capture/Markers has 10 points at time 5 for its 41 marker names",))


def test_two_meshes_and_nothing_to_tell_the_face(sample_assets, tmp_path, capsys):
    """A character file with a head and an eye: refused, naming both (the first was taken silently)."""
    from pxr import Usd, UsdGeom

    face = Usd.Stage.Open(str(sample_assets / "meshes" / "makehuman_hm08_face_cm.usdc"))
    src = UsdGeom.Mesh(face.GetPrimAtPath("/Face/Geom"))
    path = tmp_path / "char.usda"
    stage = Usd.Stage.CreateNew(str(path))
    stage.SetDefaultPrim(UsdGeom.Xform.Define(stage, "/Char").GetPrim())
    UsdGeom.SetStageMetersPerUnit(stage, 0.01)  # a complete file: only the two meshes are wrong
    for name, pts, counts, idx in (("Head", src.GetPointsAttr().Get(), src.GetFaceVertexCountsAttr().Get(),
                                    src.GetFaceVertexIndicesAttr().Get()),
                                   ("EyeL", [(0, 0, 0), (1, 0, 0), (0, 1, 0)], [3], [0, 1, 2])):
        m = UsdGeom.Mesh.Define(stage, f"/Char/{name}")
        m.CreatePointsAttr(pts)
        m.CreateFaceVertexCountsAttr(counts)
        m.CreateFaceVertexIndicesAttr(idx)
    stage.Save()
    del stage
    rc, lines = run_in_process(capsys, "import-mesh", path, "-o", tmp_path / "m.usdc")
    assert_one_line(rc, lines, code=2, command="import-mesh",
                    contains=(f"mesh {path}: 2 Mesh prims under the default prim /Char and none marked as the face: "
                              "/Char/Head (2020 points), /Char/EyeL (3 points)", "export it alone"))
    from usdface.usd.mesh_layer import read_mesh_layer

    mesh, _ = read_mesh_layer(path, prim_path="/Char/Head")
    assert mesh.n_points == 2020
    with pytest.raises(InputError, match=r"/Char/Nose is not a Mesh prim; its Mesh prims: /Char/Head, /Char/EyeL"):
        read_mesh_layer(path, prim_path="/Char/Nose")
