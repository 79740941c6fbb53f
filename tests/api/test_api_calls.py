"""How usdface.api functions are called (usdface 0.3): inputs, one options object, outputs by name;
the command line calls them; in-memory calls write no file; wrong types and unknown options are
OptionErrors naming them; usdface 0.2's calls still work with a DeprecationWarning."""
from __future__ import annotations

import os
import subprocess
import sys
import textwrap
import warnings
from pathlib import Path

import pytest

from usdface import api
from usdface.errors import OptionError
from usdface.options import BindOptions, CaptureOptions, DistanceOptions, NoOptions, RunOptions, TransferOptions
from usdface.registry import Result

ROOT = Path(__file__).resolve().parents[2]
SA = ROOT / "sample_assets"
MESH = SA / "meshes" / "makehuman_hm08_face_cm.obj"
TAKE = SA / "capture" / "JawMoCap.ma"
LAYOUT = SA / "layouts" / "makehuman_hm08_face.layout.json"


def test_the_command_line_calls_the_api_function_of_the_same_name(monkeypatch, capsys):
    from usdface.console import main

    seen = {}

    def fake_info(file, options=None):
        seen.update(file=file, options=options)
        return Result(summary={"fake": True}, text=["from the fake"], exit_code=3)

    monkeypatch.setattr(api, "info", fake_info, raising=False)
    assert main(["info", str(MESH)]) == 3
    assert capsys.readouterr().out == "from the fake\n"
    assert seen == {"file": str(MESH), "options": NoOptions()}

    def fake_distances(mesh, binding=None, options=None, *, output=None, into=None):
        seen.update(mesh=mesh, binding=binding, options=options, output=output)
        return Result(text=["fake distances"])

    monkeypatch.setattr(api, "distances", fake_distances, raising=False)
    assert main(["distances", "--mesh", "m.usdc", "--binding", "b.usda", "-o", "a.usdc", "--sigma", "3"]) == 0
    assert seen["options"] == DistanceOptions(sigma=3.0) and seen["output"] == "a.usdc"
    assert (seen["mesh"], seen["binding"]) == ("m.usdc", "b.usda")


def test_in_memory_calls_write_no_file(tmp_path):
    """The in-memory pipeline (every USD step) opens no file for writing (an audit hook sees every
    open), run from a read-only working folder."""
    work = tmp_path / "cwd"
    work.mkdir()
    script = textwrap.dedent(f"""
        import os, sys
        writes = []
        def audit(event, args):
            if event == "open" and args[1] is not None and any(c in str(args[1]) for c in "wax+"):
                writes.append(str(args[0]))
            elif event == "open" and args[2] and args[2] & (os.O_WRONLY | os.O_RDWR | os.O_CREAT):
                writes.append(str(args[0]))
        from usdface import api
        from usdface.options import CaptureOptions
        sys.addaudithook(audit)
        mesh = api.import_mesh({str(MESH)!r}).layer
        capture = api.import_capture({str(TAKE)!r}, CaptureOptions(stabilize="auto", trim=(0, 60))).layer
        stage = api.new_stage(mesh)
        api.bind(stage, capture, {{"layout": {str(LAYOUT)!r}}}, into=stage)
        api.distances(stage, {{"method": "euclidean"}}, into=stage)
        api.transfer(stage, capture, into=stage)
        api.info(stage)
        caches = ("__pycache__", ".nbi", ".nbc", "numba")
        print("\\n".join(w for w in writes if not any(c in w for c in caches)))
    """)
    os.chmod(work, 0o555)
    try:
        proc = subprocess.run([sys.executable, "-c", script], cwd=work, capture_output=True, text=True, timeout=300,
                              env=dict(os.environ, PYTHONPATH=str(ROOT)))
    finally:
        os.chmod(work, 0o755)
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.strip() == ""  # no file opened for writing
    assert list(work.iterdir()) == []


def test_wrong_types_and_unknown_options_name_what_is_wrong():
    with pytest.raises(OptionError, match=r"^transfer: mesh: expected a file path, an Sdf.Layer or a Usd.Stage; "
                                          r"got int$"):
        api.transfer(42)
    with pytest.raises(OptionError, match=r"distances options: unknown option 'sigmaa' \(did you mean 'sigma'\?\)"):
        api.distances("m.usdc", {"sigmaa": 3})
    with pytest.raises(OptionError, match=r"^bind: unknown argument 'layuot'"):
        api.bind("m.usdc", "c.usdc", layuot="x.json")
    with pytest.raises(OptionError, match=r"--sigma -1: expected a number > 0"):
        api.distances("m.usdc", {"sigma": -1})
    with pytest.raises(OptionError, match=r"import_capture: options: expected a CaptureOptions"):
        api.import_capture("x.ma", options=42)
    with pytest.raises(OptionError, match=r"^run: output: missing"):
        api.run(str(MESH), str(TAKE), RunOptions(layout=str(LAYOUT)))


def test_usdface_0_2_calls_work_with_a_deprecation_warning(tmp_path):
    mesh = api.import_mesh(str(MESH)).layer
    capture = api.import_capture(source=str(TAKE), options=CaptureOptions(trim=(0, 30))).layer  # unchanged
    stage = api.new_stage(mesh)
    with pytest.warns(DeprecationWarning, match=r"layout= .*fields of the options"):
        api.bind(stage, capture, layout=str(LAYOUT), into=stage)
    with pytest.warns(DeprecationWarning, match=r"options as a positional argument"):
        api.distances(stage, DistanceOptions(method="euclidean"), into=stage)
    with pytest.warns(DeprecationWarning, match=r"method=, head_motion="):
        r = api.transfer(stage, TransferOptions(), capture=capture, method="euclidean", head_motion=False,
                         into=stage)
    assert r.summary["distanceMethod"] == "euclidean" and r.summary["headMotion"] is False
    # the 0.2 return types: run returned its summary dict, check a list of findings
    with pytest.warns(DeprecationWarning):
        summary = api.run(str(MESH), str(TAKE), tmp_path / "jaw",
                          RunOptions(layout=str(LAYOUT), method="euclidean", trim=(0, 30)))
    with pytest.warns(DeprecationWarning, match="returns a Result since usdface 0.3"):
        assert summary["shot"] == str(tmp_path / "jaw" / "shot.usda")
    findings = api.check(stage)
    with pytest.warns(DeprecationWarning):
        assert not [f for f in findings if f.severity == "error"]


def test_the_new_calls_warn_nothing(tmp_path):
    with warnings.catch_warnings():
        warnings.simplefilter("error", DeprecationWarning)
        mesh = api.import_mesh(str(MESH)).layer
        capture = api.import_capture(str(TAKE), CaptureOptions(trim=(0, 30))).layer
        stage = api.new_stage(mesh)
        api.bind(stage, capture, BindOptions(layout=str(LAYOUT)), into=stage)
        api.distances(stage, options=DistanceOptions(method="euclidean"), into=stage)
        r = api.transfer(stage, capture, options=TransferOptions(head_motion=False), into=stage)
        assert r.layer is stage.GetRootLayer() and r.summary["frames"] == 30
        shot = api.run(str(MESH), str(TAKE), RunOptions(layout=str(LAYOUT), method="euclidean", trim=(0, 30)),
                       output=tmp_path / "jaw")
        assert shot.layers["shot.usda"] == str(tmp_path / "jaw" / "shot.usda") and shot.exit_code == 0
        assert shot.files["summary.json"] == str(tmp_path / "jaw" / "summary.json")
