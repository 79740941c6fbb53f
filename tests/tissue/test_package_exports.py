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
    # a submodule named like the function left the package attribute bound to the module once
    # imported; the module is usdface.tissue.animation, and the function is loaded lazily
    out = _run("import usdface.tissue.animation\nfrom usdface.tissue import animate\nprint(callable(animate), "
               "type(animate).__name__)")
    assert out.split() == ["True", "function"]


def test_building_the_command_line_loads_no_numpy_numba_or_simulator():
    # the options read their choices from light constant modules (usdface.tissue.presets,
    # usdface.preview.choices, usdface.media.formats, usdface.rbf.kernel_names): `usdface --help`
    # loads neither numpy (as in 0.2: 75 ms of a 0.4 s start) nor the simulator, renderer or OpenCV
    out = _run("import sys, usdface.cli as c\nc.build_parser()\n"
               "print(sorted(m for m in ('numpy', 'numba', 'cv2', 'usdface.tissue.integrators', 'usdface.tissue.model', "
               "'usdface.preview.render', 'usdface.blendshape.solver') if m in sys.modules))")
    assert out.strip() == "[]"
