"""The README's Python API section: its table of functions is the registry's, it shows every
function at work, and its examples run as written (in a fresh process, from the repository root,
writing under a folder the test chooses) and print no USD warnings."""
from __future__ import annotations

import json
import os
import re
import subprocess
import sys
from pathlib import Path

from usdface import api, registry

ROOT = Path(__file__).resolve().parents[2]
SA = ROOT / "sample_assets"


def _section() -> str:
    text = (ROOT / "README.md").read_text()
    start = text.index("## Python API")
    return text[start:text.index("**Inside Blender's Python**", start)]


def test_the_function_table_is_the_registrys():
    section = _section()
    start, end = "<!-- api functions: generated from usdface.registry -->\n", "<!-- end of api functions -->"
    table = section.split(start, 1)[1].split(end, 1)[0]
    assert table == registry.api_table(), "paste the output of `python -m usdface.registry --api`"


def test_every_function_is_shown_at_work():
    code = "\n".join(re.findall(r"```python\n(.*?)```", _section(), re.S))
    missing = [name for name in api.commands() if f"api.{name}(" not in code]
    assert not missing, f"the README's examples never call {missing}"


def _acquisition_files(folder: Path, shared: Path) -> dict:
    """The files the acquisition example asks the reader for, made from the data: a stereo pair of
    the stylized face rendered with the photo's texture, its calibration and landmarks, and the
    photo with its hand-placed landmarks."""
    import cv2

    from usdface.scan.landmarks import FACE_LANDMARKS, Landmarks, write_landmarks
    from usdface.scan.synthetic import render_stereo_pair, sample_face

    _, _, _, scene = sample_face(SA, "stylized", photo=shared / "images" / "astronaut.png")
    pair = render_stereo_pair(scene, size=(400, 300))
    cv2.imwrite(str(folder / "left.png"), pair["first"])
    cv2.imwrite(str(folder / "right.png"), pair["second"])
    (folder / "rig.json").write_text(json.dumps(pair["calibration"]))
    uv, _ = pair["camera"].project(scene.landmarks())
    write_landmarks(folder / "scan.landmarks.json", Landmarks.from_image_points(FACE_LANDMARKS, uv))
    return {"face.png": shared / "images" / "astronaut.png",
            "face.landmarks.json": SA / "landmarks" / "astronaut.landmarks.json",
            "left.png": folder / "left.png", "right.png": folder / "right.png", "rig.json": folder / "rig.json",
            "scan.landmarks.json": folder / "scan.landmarks.json"}


def test_the_examples_run_as_written(tmp_path, shared_data):
    blocks = re.findall(r"```python\n(.*?)```", _section(), re.S)
    code = "\n".join(blocks)
    chosen = tmp_path / "api"
    assert 'out = Path("out/api")' in code
    code = code.replace('out = Path("out/api")', f"out = Path({str(chosen)!r})")
    for name, path in _acquisition_files(tmp_path, shared_data).items():
        code = code.replace(f'"{name}"', repr(str(path)))
    proc = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, timeout=1500,
                          env=dict(os.environ, PYTHONPATH=str(ROOT)))
    assert proc.returncode == 0, proc.stderr[-3000:]
    usd_warnings = [line for line in proc.stderr.splitlines()
                    if re.search(r"Warning|Tf|Sdf|Usd|anon:", line) and not line.startswith("usdface:")]
    assert not usd_warnings, proc.stderr
    out = proc.stdout.splitlines()
    assert out[0] == "300 frames; 0 check errors"
    assert out[2].endswith(str(chosen / "jaw" / "shot.usda"))
    # everything was written under the chosen folder, nothing in the repository
    assert (chosen / "jaw" / "shot.usda").is_file() and (chosen / "batch").is_dir()
    assert not (ROOT / "out" / "api").exists()

