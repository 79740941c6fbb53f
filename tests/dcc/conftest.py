"""A real DCC in the test suite: Blender (the `bpy` wheel, `pip install ".[dcc]"`) run in a subprocess.

bpy carries its own USD libraries, which must never share an interpreter with usd-core's pxr,
so every import runs ``blender_import.py`` in a child process (this interpreter, or the one
$USDFACE_BLENDER_PYTHON names) and reads back an .npz. Without bpy the tests skip, except under CI=true, where a missing bpy fails the run.
"""
from __future__ import annotations

import importlib.util
import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from usdface.cli import main

SCRIPT = Path(__file__).with_name("blender_import.py")
EXTRA_HINT = ("bpy (Blender as a Python module) is not installed: pip install '.[dcc]' (Python 3.11), or point "
              "USDFACE_BLENDER_PYTHON at a Python that has it")


def blender_python() -> str | None:
    """The Python that runs Blender: $USDFACE_BLENDER_PYTHON (a Python with bpy in an environment
    of its own) or this interpreter, if it has bpy; None otherwise."""
    other = os.environ.get("USDFACE_BLENDER_PYTHON")
    if other:
        probe = "import importlib.util, sys; sys.exit(importlib.util.find_spec('bpy') is None)"
        ok = subprocess.run([other, "-c", probe], capture_output=True).returncode == 0
        return other if ok else None
    return sys.executable if importlib.util.find_spec("bpy") is not None else None  # does not import bpy


@pytest.fixture(scope="session")
def blender():
    """Import a USD file with Blender: ``blender(path, frames) -> BlenderImport``."""
    python = blender_python()
    if python is None:
        if os.environ.get("CI") == "true":
            pytest.fail(f"CI=true and {EXTRA_HINT}; the Blender tests must run in CI")
        pytest.skip(EXTRA_HINT)
    cache: dict = {}

    def run(path, frames, *, workdir: Path) -> BlenderImport:
        key = (str(path), tuple(frames))
        if key not in cache:
            out = workdir / f"{Path(path).stem}_{len(cache)}.npz"
            proc = subprocess.run([python, str(SCRIPT), str(path), str(out), "--frames",
                                   *[str(int(f)) for f in frames]], capture_output=True, text=True, timeout=900)
            assert proc.returncode == 0, f"Blender import of {path} failed:\n{proc.stderr[-3000:]}"
            cache[key] = BlenderImport(out)
        return cache[key]

    return run


class BlenderImport:
    """What Blender showed after importing one file (see blender_import.py)."""

    def __init__(self, npz: Path):
        with np.load(npz) as z:
            self.info = json.loads(str(z["info"]))
            self.points = [z[f"points_{i}"] for i in range(len(self.info["meshes"]))]
            self.rest = [z[f"rest_{i}"] for i in range(len(self.info["meshes"]))]
            self.shape_keys = [z[f"shape_keys_{i}"] if f"shape_keys_{i}" in z.files else None
                               for i in range(len(self.info["meshes"]))]

    def mesh_with(self, n_points: int) -> int | None:
        """Index of the one imported mesh with ``n_points`` vertices (None if there is none)."""
        found = [i for i, m in enumerate(self.info["meshes"]) if m["vertices"] == n_points]
        assert len(found) <= 1, f"several imported meshes have {n_points} vertices: {self.info['meshes']}"
        return found[0] if found else None

    def describe(self) -> str:
        return json.dumps({k: v for k, v in self.info.items() if k != "meshes"}
                          | {"meshes": [(m["name"], m["vertices"]) for m in self.info["meshes"]]})


@pytest.fixture(scope="session")
def jaw_outputs(tmp_path_factory, sample_assets):
    """`usdface run --output-kind all` on the Jaw take and the MakeHuman face with its 52-shape rig
    (first 300 frames): points, skeleton and blend-shape deliverables of one run."""
    out = tmp_path_factory.mktemp("dcc_jaw")
    code = main(["run", "--mesh", str(sample_assets / "meshes" / "makehuman_hm08_face_cm.obj"),
                 "--capture", str(sample_assets / "capture" / "JawMoCap.ma"),
                 "--layout", str(sample_assets / "layouts" / "makehuman_hm08_face.layout.json"),
                 "--shapes", str(sample_assets / "meshes" / "makehuman_hm08_face_units_cm.npz"),
                 "--output-kind", "all", "--trim", "0", "300", "-o", str(out), "-q"])
    assert code == 0
    return out
