"""Manifests over the sample assets, written into tmp folders with absolute paths."""
from __future__ import annotations

from pathlib import Path

import pytest

from usdface import cli

TAKES = ("JawMoCap", "NoseMoCap", "EyebrowsMoCap")
MESHES = {"makehuman_hm08_face_cm": "makehuman_hm08_face", "mediapipe_canonical_face_model_holes": "mediapipe_face_holes"}


def write_manifest(folder: Path, sample_assets: Path, *, broken: bool = True, trim=(0, 120), extra: str = "",
                   batch: str = "") -> Path:
    """2 meshes x 3 takes (+ one broken take on the first mesh)."""
    sa = sample_assets
    text = [f"[batch]\n{batch}", "[defaults]", f"trim = [{trim[0]}, {trim[1]}]", 'output = "out/{mesh}/{capture}"',
            extra]
    for mesh, layout in MESHES.items():
        text += ["[[shots]]", f'mesh = "{sa}/meshes/{mesh}.obj"', f'layout = "{sa}/layouts/{layout}.layout.json"',
                 f'capture = "{sa}/capture/*MoCap.ma"']
    if broken:
        bad = folder / "BrokenMoCap.ma"
        bad.write_text("//Maya ASCII 2018 scene\nthis is not a Maya file at all {{{\n")
        mesh, layout = next(iter(MESHES.items()))
        text += ["[[shots]]", f'mesh = "{sa}/meshes/{mesh}.obj"', f'layout = "{sa}/layouts/{layout}.layout.json"',
                 f'capture = "{bad}"']
    path = folder / "shots.toml"
    path.write_text("\n".join(text) + "\n")
    return path


@pytest.fixture(scope="session")
def make_manifest(sample_assets):
    def make(folder, **kw):
        return write_manifest(Path(folder), sample_assets, **kw)
    return make
