"""The tissue package loads its parts on first use; its public names must still be what they name."""
from __future__ import annotations

import subprocess
import sys


def _run(code: str) -> str:
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr[-3000:]
    return r.stdout


def test_every_public_name_is_its_submodules_object():
    out = _run("""
import importlib, usdface.tissue as t
bad = []
for name in t.__all__:
    obj = getattr(t, name)
    mod = t._EXPORTS.get(name)
    if mod is not None and obj is not getattr(importlib.import_module('usdface.tissue.' + mod), name):
        bad.append(name)
print(len(t.__all__), bad)
""")
    assert out.split(" ", 1)[1].strip() == "[]" and int(out.split()[0]) >= 28


def test_animate_is_the_function_whatever_was_imported_first():
    # importing the submodule first used to leave the package attribute bound to the module
    out = _run("import usdface.tissue.animate\nfrom usdface.tissue import animate\nprint(callable(animate), "
               "type(animate).__name__)")
    assert out.split() == ["True", "function"]


def test_building_the_command_line_loads_no_numba_or_simulator():
    # the options read their choices from light constant modules (usdface.tissue.expressions,
    # usdface.preview.camera and .colormap); the simulator, the renderer and OpenCV stay unloaded
    out = _run("import sys, usdface.cli as c\nc.build_parser()\n"
               "print(sorted(m for m in ('numba', 'cv2', 'usdface.tissue.integrators', 'usdface.tissue.model', "
               "'usdface.preview.render', 'usdface.blendshape.solver') if m in sys.modules))")
    assert out.strip() == "[]"
