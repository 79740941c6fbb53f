"""Hostile inputs to every reader (issue 20, items 3-5, 7, 8, 11-15, and more of the same classes),
for benchmarks/fault_attempts.py.

Each attempt builds its files in a scratch folder, records their sha256, runs the real command
(``python -m usdface``) with a timeout and at most 4 GB of address space (a reader that trusts a
lying header would otherwise allocate tens of GB on a shared machine), and reports: exit code,
stderr lines, inputs unchanged, and files left behind (temporaries or a partial output).
Handled: the expected exit code, the expected number of stderr lines (one for an error), no
traceback, inputs unchanged, nothing left behind, and, where the issue is about the message (wrong
diagnosis, USD's own text lost, a raw USD warning), what the message says.
"""
from __future__ import annotations

import hashlib
import json
import os
import shutil
import signal
import struct
import subprocess
import sys
import time
import zipfile
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

import numpy as np
from hostile_harness import COMPILE_NOTICE

REPO = Path(__file__).resolve().parents[1]
SA = REPO / "sample_assets"
MESH_OBJ, MESH_USD = SA / "meshes" / "makehuman_hm08_face_cm.obj", SA / "meshes" / "makehuman_hm08_face_cm.usdc"
TAKE_MA, TAKE_USD = SA / "capture" / "JawMoCap.ma", SA / "capture" / "JawMoCap.usdc"
LAYOUT = SA / "layouts" / "makehuman_hm08_face.layout.json"
SEEDS, MOVIE = SA / "video" / "animface_dots.seeds.json", SA / "video" / "animface_dots.mp4"
MEMORY_LIMIT = 4 * 1024**3


@dataclass
class Hostile:
    klass: str
    what: str
    make: Callable[[Path], tuple[list, list]]   # folder -> (command arguments, input files)
    code: int = 2
    lines: int = 1
    timeout: float = 60.0
    says: Callable[[str], bool] | None = None   # what the message must (not) say, where the issue is about it


# -- file makers -----------------------------------------------------------------------------------

def _csv(d: Path, name="take.csv", declaration="# units=cm rate=60", last=None, cell=None) -> Path:
    rng = np.random.default_rng(0)
    base = np.array([[0, 0, 0], [15, 0, 0], [0, 15, 0], [15, 15, 3.0]])
    rows = [declaration, "frame," + ",".join(f"{m}_{a}" for m in "ABCD" for a in "xyz")]
    for f in range(200):
        rows.append(",".join([str(f)] + [f"{v:.4f}" for v in (base + rng.normal(0, 0.01, base.shape)).ravel()]))
    if last is not None:
        rows[-1] = f"{last}," + rows[-1].split(",", 1)[1]
    if cell is not None:
        cells = rows[11].split(",")
        cells[1] = cell
        rows[11] = ",".join(cells)
    (d / name).write_text("\n".join(rows) + "\n")
    return d / name


def _obj_with(d: Path, value: str) -> Path:
    lines = MESH_OBJ.read_text().splitlines()
    k = [i for i, line in enumerate(lines) if line.startswith("v ")][17]
    lines[k] = f"v {value} 70 10"
    (d / "face.obj").write_text("\n".join(lines) + "\n")
    return d / "face.obj"


def _write(d: Path, name: str, data) -> Path:
    p = d / name
    p.write_bytes(data if isinstance(data, bytes) else data.encode())
    return p


def _fifo(d: Path, name: str) -> Path:
    os.mkfifo(d / name)
    return d / name


def _sublayers(d: Path, name: str, *targets) -> Path:
    return _write(d, name, "#usda 1.0\n(\n    subLayers = [" + ", ".join(f"@./{t}@" for t in targets) + "]\n)\n")


SYNTAX = '#usda 1.0\n(\n    defaultPrim = "Face"\n)\n\ndef Xform "Face" {\n}\n}\n'
PLY = ("ply\nformat {fmt} 1.0\nelement vertex 1000000000\nproperty float x\nproperty float y\nproperty float z\n"
       "element face 1000000000\nproperty list uchar int vertex_indices\nend_header\n")


def _c3d(d: Path, group: str, name: str, fmt: str, value) -> Path:
    """A small valid C3D (written by usdface from a CSV), one parameter patched."""
    import sys

    if str(REPO) not in sys.path:
        sys.path.insert(0, str(REPO))
    from usdface.io.captures import read_capture, write_capture  # this tree writes the (valid) seed file

    path = d / "take.c3d"
    write_capture(path, read_capture(_csv(d, "seed.csv")))
    (d / "seed.csv").unlink()
    data = bytearray(path.read_bytes())
    base = (data[0] - 1) * 512
    pos, groups = base + 4, {}
    while True:  # walk the parameter section to the entry (C3D layout: usdface.io.c3d_header)
        nchar, gid = struct.unpack_from("bb", data, pos)
        label = bytes(data[pos + 2:pos + 2 + abs(nchar)]).decode()
        step = struct.unpack_from("<h", data, pos + 2 + abs(nchar))[0]
        if gid < 0:
            groups[-gid] = label
        elif groups.get(gid) == group and label == name:
            body = pos + 4 + abs(nchar)
            struct.pack_into("<" + fmt, data, body + 2 + data[body + 1], value)
            break
        pos = pos + 2 + abs(nchar) + step
    path.write_bytes(bytes(data))
    return path


def _ragged_usda(d: Path) -> Path:
    from pxr import Gf, Usd, Vt

    path = d / "ragged.usda"
    Usd.Stage.Open(str(TAKE_USD)).Export(str(path))
    stage = Usd.Stage.Open(str(path))
    stage.GetPrimAtPath("/Capture/Markers").GetAttribute("points").Set(Vt.Vec3fArray([Gf.Vec3f(0, 0, 0)] * 10), 5)
    stage.Save()
    return path


def _two_meshes(d: Path) -> Path:
    from pxr import Usd, UsdGeom

    face = Usd.Stage.Open(str(MESH_USD))
    src = UsdGeom.Mesh(face.GetPrimAtPath("/Face/Geom"))
    path = d / "char.usda"
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
    return path


def _layout(d: Path, change) -> Path:
    data = json.loads(LAYOUT.read_text())
    change(data["markers"])
    return _write(d, "l.json", json.dumps(data))


def _bind(layout) -> list:
    return ["bind", "--mesh", MESH_USD, "--capture", TAKE_USD, "--layout", layout, "-o", "b.usda"]


def _maya_fast(d: Path) -> Path:
    """Three markers whose keys are 1e-9 film frame apart (2.4e10 Hz)."""
    lines = ["//Maya ASCII 2017 scene", "//Name: fast.ma", "currentUnit -l centimeter -a degree -t film;",
             'createNode transform -n "Grp";']
    for m, base in (("A", 0.0), ("B", 5.0), ("C", 9.0)):
        keys = " ".join(f"{1 + 1e-9 * k:.12g} {base + k}" for k in range(4))
        lines += [f'createNode transform -n "{m}" -p "Grp";', f'createNode animCurveTL -n "{m}_tx";',
                  '\tsetAttr -s 4 ".ktv[0:3]"  ' + keys + ";", f'connectAttr "{m}_tx.o" "{m}.tx";']
    lines.append("// End of fast.ma")
    return _write(d, "fast.ma", "\n".join(lines) + "\n")


def _npz_bomb(d: Path) -> Path:
    """An .npz whose member announces a 80 GB array in 128 bytes."""
    header = {"descr": "<f8", "fortran_order": False, "shape": (100000, 100000)}
    buf = bytearray(b"\x93NUMPY\x01\x00")
    text = repr(header).encode()
    text += b" " * (-(len(buf) + 2 + len(text) + 1) % 64) + b"\n"
    buf += struct.pack("<H", len(text)) + text + b"\0" * 64
    with zipfile.ZipFile(d / "model.npz", "w") as z:
        z.writestr("meta.npy", bytes(buf))
    return d / "model.npz"


def _shapes(d: Path) -> Path:
    folder = d / "shapes"
    folder.mkdir()
    for k in range(2):
        lines = [f"v {float(t[1]) + 0.1 * (k + 1)} {t[2]} {t[3]}" if t and t[0] == "v" else line
                 for line, t in ((line, line.split()) for line in MESH_OBJ.read_text().splitlines())]
        (folder / f"s{k}.obj").write_text("# units: furlongs\n" + "\n".join(lines) + "\n")
    return folder


def _non_utf8(d: Path, name: bytes, source: Path) -> bytes:
    path = os.fsencode(d) + b"/" + name
    shutil.copy(source, path)
    return path


# -- the attempts ----------------------------------------------------------------------------------

def _cases() -> list[Hostile]:
    h = Hostile
    return [
        h("mesh (7)", "binary STL: count 1e6, 50 bytes of data", lambda d: (["import-mesh", _write(
            d, "lie.stl", b"\0" * 80 + struct.pack("<I", 10**6) + b"\1" * 50), "-o", "m.usdc"], None), timeout=30),
        h("mesh (new)", "binary STL with 10 trailing bytes", lambda d: (["import-mesh", _write(
            d, "t.stl", b"\0" * 80 + struct.pack("<I", 1) + b"\0" * 60), "-o", "m.usdc"], None)),
        h("mesh (new)", "ASCII STL cut mid-facet", lambda d: (["import-mesh", _write(
            d, "cut.stl", "solid x\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\n"), "-o", "m.usdc"], None), timeout=30),
        h("mesh (7)", "ASCII PLY announcing 1e9 vertices and faces", lambda d: (["import-mesh", _write(
            d, "lie.ply", PLY.format(fmt="ascii") + "0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n"), "-o", "m.usdc"], None), timeout=30),
        h("mesh (7)", "binary PLY announcing 1e9 vertices and faces", lambda d: (["import-mesh", _write(
            d, "lie.ply", PLY.format(fmt="binary_little_endian").encode() + b"\1" * 50), "-o", "m.usdc"], None),
          timeout=30),
        h("mesh (5)", "OFF header '-3 -1 0'", lambda d: (["import-mesh", _write(d, "neg.off", "OFF\n-3 -1 0\n"),
                                                          "-o", "m.usdc"], None)),
        h("mesh (7)", "binary OFF announcing 1e9 vertices", lambda d: (["import-mesh", _write(
            d, "lie.off", b"OFF BINARY\n" + struct.pack(">iii", 10**9, 10**9, 0) + b"\1" * 50), "-o", "m.usdc"],
            None), timeout=30),
        h("mesh (15)", "OBJ vertex at 1e39", lambda d: (["import-mesh", _obj_with(d, "1e39"), "-o", "m.usdc"], None),
          says=lambda e: "vertex 17" in e),  # the corrupt vertex named, not only its faces
        h("mesh (new)", "OBJ vertex at 1e30", lambda d: (["import-mesh", _obj_with(d, "1e30"), "-o", "m.usdc"], None),
          says=lambda e: "vertex 17" in e),  # the corrupt vertex named, not only its faces
        h("mesh (new)", "empty .ply", lambda d: (["import-mesh", _write(d, "e.ply", b""), "-o", "m.usdc"], None)),
        h("mesh (8)", "named pipe as mesh", lambda d: (["import-mesh", _fifo(d, "p.obj"), "-o", "m.usdc"], None),
          timeout=20),
        h("mesh (new)", "folder named face.obj", lambda d: ((d / "face.obj").mkdir() or
                                                             ["import-mesh", d / "face.obj", "-o", "m.usdc"], None)),
        h("mesh (15)", "USD file with two meshes", lambda d: (["import-mesh", _two_meshes(d), "-o", "m.usdc"], None)),
        h("chatter (13)", "`solve --shapes` of OBJs with a units comment", lambda d: (
            ["solve", "--mesh", MESH_OBJ, "--shapes", _shapes(d), "--capture", TAKE_USD, "--layout", LAYOUT,
             "--trim", 0, 20, "-o", "solve.usdc", "-q"], None), code=0, lines=0, timeout=300),
        h("usd (11)", "`info` of a .usda syntax error", lambda d: (["info", _write(d, "syntax.usda", SYNTAX)], None),
          says=lambda e: "syntax.usda:8:1: parse error" in e and "stage.cpp" not in e),
        h("usd (new)", "parse error in a sublayer", lambda d: (
            _write(d, "syntax.usda", SYNTAX) and ["info", _sublayers(d, "top.usda", "syntax.usda")], None),
          says=lambda e: "parse error" in e and "stage.cpp" not in e),
        h("usd (12)", "`import-mesh` of a layer with a missing sublayer", lambda d: (
            ["import-mesh", _sublayers(d, "missing.usda", "nothere.usdc"), "-o", "m.usdc"], None),
          says=lambda e: "nothere.usdc" in e and "no Mesh prim" not in e and "stage.cpp" not in e),
        h("usd (12)", "`info` of a layer with a missing sublayer (a warning)", lambda d: (
            ["info", _sublayers(d, "missing.usda", "nothere.usdc")], None), code=0, lines=1,
          says=lambda e: e.startswith("usdface") and "nothere.usdc" in e and "stage.cpp" not in e),
        h("usd (12)", "cyclic sublayers to `import-capture`", lambda d: (
            _sublayers(d, "two.usda", "one.usda") and ["import-capture", _sublayers(d, "one.usda", "two.usda"),
                                                       "-o", "c.usdc"], None),
          says=lambda e: "cycle" in e and "has no units" not in e and "stage.cpp" not in e),
        h("usd (8)", "`info` of a named pipe", lambda d: (["info", _fifo(d, "p.usda")], None), timeout=20),
        h("usd (8)", "`check` of a named pipe", lambda d: (["check", _fifo(d, "p.usda")], None), timeout=20),
        h("usd (8)", "`bind --mesh` a named pipe", lambda d: (
            ["bind", "--mesh", _fifo(d, "p.usda"), "--capture", TAKE_USD, "--layout", LAYOUT, "-o", "b.usda"], None),
          timeout=20),
        h("usd (new)", "a named pipe as a sublayer", lambda d: (
            _fifo(d, "p.usda") and ["info", _sublayers(d, "top.usda", "p.usda")], None), timeout=20),
        h("usd (new)", "empty .usdc", lambda d: (["info", _write(d, "e.usdc", b"")], None)),
        h("usd (new)", "truncated .usdc", lambda d: (["info", _write(d, "cut.usdc", TAKE_USD.read_bytes()[:3000])],
                                                     None)),
        h("usd (new)", ".usda with a Latin-1 byte", lambda d: (
            ["info", _write(d, "latin.usda", b'#usda 1.0\n(\n    defaultPrim = "A\xff"\n)\n')], None)),
        h("usd (5)", "capture name with a non-UTF-8 byte", lambda d: (
            ["import-capture", _non_utf8(d, b"cap\xff.usdc", TAKE_USD), "--trim", 0, 10, "-o", "o.usdc"], None)),
        h("usd (5)", "output name with a non-UTF-8 byte", lambda d: (
            ["import-capture", TAKE_MA, "--trim", 0, 10, "-o", os.fsencode(d) + b"/out\xff.usdc"], [TAKE_MA])),
        h("usd (5)", "capture .usda: 10 points at one time, 41 at others", lambda d: (
            ["import-capture", _ragged_usda(d), "-o", "c.usdc"], None)),
        h("layout (5)", "100000 nested '['", lambda d: (_bind(_write(d, "deep.json", "[" * 100000)), None)),
        h("layout (5)", "layout point [1e308, 1e308, 1e308]", lambda d: (_bind(_layout(
            d, lambda m: m.update(ForeHead_M={"point": [1e308] * 3}))), None)),
        h("layout (15)", "every layout point at one vertex", lambda d: (_bind(_layout(
            d, lambda m: m.update({k: {"vertex": 5} for k in m}))), None), says=lambda e: "0 cm" not in e),
        h("layout (new)", "a marker twice in one layout", lambda d: (_bind(_write(
            d, "dup.json", '{"format": "usdface-layout/1", "markers": {"Chin": {"vertex": 1}, "Chin": {"vertex": 2}}}')),
            None)),
        h("capture (3)", "CSV cell 1e308", lambda d: (["import-capture", _csv(d, cell="1e308"), "-o", "c.usdc"], None)),
        h("capture (new)", "CSV cell -inf", lambda d: (["import-capture", _csv(d, cell="-inf"), "-o", "c.usdc"], None)),
        h("capture (4)", "CSV last frame 2000000000", lambda d: (
            ["import-capture", _csv(d, last=2000000000), "-o", "c.usdc"], None), timeout=120),
        h("capture (new)", "CSV frame 1e300", lambda d: (["import-capture", _csv(d, last="1e300"), "-o", "c.usdc"],
                                                         None), timeout=120),
        h("capture (14)", "CSV rate=1e300", lambda d: (
            ["import-capture", _csv(d, declaration="# units=cm rate=1e300"), "-o", "c.usdc"], None)),
        h("capture (14)", ".ma keys 1e-9 frame apart (2.4e10 Hz)", lambda d: (
            ["import-capture", _maya_fast(d), "-o", "c.usdc"], None)),
        h("capture (14)", "`import-capture --resample 1e-9`", lambda d: (
            ["import-capture", TAKE_MA, "--trim", 0, 200, "--resample", "1e-9", "-o", "c.usdc"], [TAKE_MA])),
        h("capture (7)", "C3D ANALOG:RATE 1e9 (ezc3d allocated 12 GB)", lambda d: (
            ["import-capture", _c3d(d, "ANALOG", "RATE", "f", 1e9), "-o", "c.usdc"], None), timeout=60),
        h("capture (7)", "C3D POINT:USED 30000 in 15 kB", lambda d: (
            ["import-capture", _c3d(d, "POINT", "USED", "H", 30000), "-o", "c.usdc"], None)),
        h("capture (8)", "named pipe as a CSV capture", lambda d: (["import-capture", _fifo(d, "p.csv"), "-o", "c.usdc"],
                                                                   None), timeout=20),
        h("video (13)", "empty .mp4 to `track`", lambda d: (
            ["track", _write(d, "e.mp4", b""), "--seeds", SEEDS, "-o", "t.usdc"], None)),
        h("video (13)", "text .mp4 to `track`", lambda d: (
            ["track", _write(d, "t.mp4", "hello\n"), "--seeds", SEEDS, "-o", "t.usdc"], None)),
        h("video (13)", "truncated .mp4 to `track`", lambda d: (
            ["track", _write(d, "cut.mp4", MOVIE.read_bytes()[:20000]), "--seeds", SEEDS, "-o", "t.usdc"], None)),
        h("video (8)", "named pipe as the video", lambda d: (
            ["track", _fifo(d, "p.mp4"), "--seeds", SEEDS, "-o", "t.usdc"], None), timeout=20),
        h("json (new)", "seeds {\"Chin\": \"12\"} (read as (1, 2))", lambda d: (
            ["track", MOVIE, "--seeds", _write(d, "s.json", '{"Chin": "12"}'), "-o", "t.usdc"], None), timeout=120),
        h("npz (new)", "AAM .npz announcing an 80 GB array", lambda d: (
            ["detect", REPO.parent / "shared" / "data" / "images" / "astronaut.png", "--aam", _npz_bomb(d),
             "-o", "f.json"], None), timeout=60),
    ]


# -- running -------------------------------------------------------------------------------------------

def _limit():
    import resource

    resource.setrlimit(resource.RLIMIT_AS, (MEMORY_LIMIT, MEMORY_LIMIT))


def _digest(path) -> str:
    return hashlib.sha256(Path(os.fsdecode(path)).read_bytes()).hexdigest()


def _inputs(args, given) -> list:
    if given is not None:
        return list(given)
    return [a for a in args if isinstance(a, (Path, bytes)) and os.path.isfile(a)]


def run_one(code: Path, scratch: Path, case: Hostile, index: int) -> dict:
    """Run one attempt; returns the row's fields."""
    d = scratch / f"r{index:02d}"
    shutil.rmtree(d, ignore_errors=True)
    d.mkdir(parents=True)
    env = dict(os.environ, PYTHONPATH=str(code), OMP_NUM_THREADS="1", NUMBA_CACHE_DIR=str(scratch / "numba"))
    args, given = case.make(d)
    inputs = _inputs(args, given)
    before = {os.fsdecode(p): _digest(p) for p in inputs}
    present = set(os.listdir(d))
    argv = [sys.executable, "-m", "usdface", *[a if isinstance(a, bytes) else os.fsencode(str(a)) for a in args]]
    t0 = time.perf_counter()
    p = subprocess.Popen(argv, cwd=d, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                         preexec_fn=_limit, start_new_session=True)
    try:
        _, err = p.communicate(timeout=case.timeout)
        rc = p.returncode
    except subprocess.TimeoutExpired:
        os.killpg(p.pid, signal.SIGKILL)  # SIGTERM cannot stop a C++ loop (issue 20, item 7)
        _, err = p.communicate()
        rc = None
    seconds = time.perf_counter() - t0
    text = err.decode("utf-8", "backslashreplace")
    lines = [line for line in text.splitlines() if line.strip() and not COMPILE_NOTICE.match(line)]
    same = all(_digest(Path(k)) == v for k, v in before.items())
    left = sorted(os.fsdecode(n) for n in set(os.listdir(d)) - present)
    if case.code == 0:
        left = [n for n in left if n.startswith(".") or ".tmp-" in n]  # a success writes its output
    first = next((line for line in lines if "error" in line.lower() or "warning" in line.lower()),
                 lines[-1] if lines else "")
    ok = (rc == case.code and len(lines) == case.lines and "Traceback" not in text and same and not left
          and (case.says is None or case.says(text)))
    return {"rc": rc, "lines": len(lines), "same": same, "left": left, "seconds": seconds,
            "first": first if len(first) < 170 else first[:167] + "...", "ok": ok,
            "traceback": "Traceback" in text}


def table(code: Path, scratch: Path, only: str | None = None) -> list[dict]:
    """Print the readers' table; returns its rows (klass, what, ok, ...)."""
    if str(REPO) not in sys.path:  # this tree writes some inputs; its schemas register before pxr opens stages
        sys.path.insert(0, str(REPO))
    import usdface  # noqa: F401
    print("| class (issue 20 item) | attempt | exit | stderr lines | traceback | inputs unchanged | left behind | "
          "first line | handled |")
    print("|---|---|---|---|---|---|---|---|---|")
    rows = []
    for i, case in enumerate(_cases()):
        if only and only not in case.what:
            continue
        try:
            r = run_one(code, scratch, case, i)
        except Exception as exc:  # noqa: BLE001 - the attempt itself broke: report it
            print(f"| {case.klass} | {case.what} | attempt failed: {type(exc).__name__}: {str(exc)[:100]} ||||||**no**|")
            rows.append({"klass": case.klass, "what": case.what, "ok": False})
            continue
        rows.append(dict(r, klass=case.klass, what=case.what))
        rc = "killed after %.0f s" % r["seconds"] if r["rc"] is None else str(r["rc"])
        first = r["first"].replace("|", "/").replace("`", "'")
        print(f"| {case.klass} | {case.what} | {rc} | {r['lines']} | {'**yes**' if r['traceback'] else 'no'} | "
              f"{'yes' if r['same'] else '**CHANGED**'} | {', '.join(r['left']) or 'nothing'} | `{first}` | "
              f"{'yes' if r['ok'] else '**no**'} |", flush=True)
    return rows
