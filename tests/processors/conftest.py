"""Layers made once per test session from the sample assets, through the real CLI entry point."""
from __future__ import annotations

import pytest

from usdface.cli import main


def run_cli(*args) -> int:
    return main([str(a) for a in args])


@pytest.fixture(scope="session")
def cli():
    """Run `usdface ARGS...` in-process; returns the exit code."""
    return run_cli


@pytest.fixture(scope="session")
def layers(tmp_path_factory, sample_assets):
    d = tmp_path_factory.mktemp("layers")
    out = {"dir": d}
    for key, mesh in (("hm08", "makehuman_hm08_face_cm.obj"), ("stylized", "makehuman_hm08_face_stylized_cm.obj"),
                      ("mediapipe", "mediapipe_canonical_face_model_holes.obj")):
        out[f"mesh_{key}"] = d / f"{key}.usdc"
        assert run_cli("import-mesh", sample_assets / "meshes" / mesh, "-o", out[f"mesh_{key}"], "-q") == 0
    out["jaw"] = d / "jaw.usdc"
    assert run_cli("import-capture", sample_assets / "capture" / "JawMoCap.ma", "-o", out["jaw"], "-q") == 0
    out["jaw_stab"] = d / "jaw_stab.usdc"
    assert run_cli("import-capture", sample_assets / "capture" / "JawMoCap.ma", "-o", out["jaw_stab"],
                   "--stabilize", "-q") == 0
    out["binding_hm08"] = d / "binding_hm08.usda"
    assert run_cli("bind", "--mesh", out["mesh_hm08"], "--capture", out["jaw_stab"], "--layout",
                   sample_assets / "layouts" / "makehuman_hm08_face.layout.json", "-o", out["binding_hm08"], "-q") == 0
    return out
