"""Layers made once per test session from the sample assets, through the real CLI entry point."""
from __future__ import annotations

import pytest



@pytest.fixture(scope="session")
def layers(tmp_path_factory, sample_assets, cli):
    d = tmp_path_factory.mktemp("layers")
    out = {"dir": d}
    for key, mesh in (("hm08", "makehuman_hm08_face_cm.obj"), ("stylized", "makehuman_hm08_face_stylized_cm.obj"),
                      ("mediapipe", "mediapipe_canonical_face_model_holes.obj")):
        out[f"mesh_{key}"] = d / f"{key}.usdc"
        assert cli("import-mesh", sample_assets / "meshes" / mesh, "-o", out[f"mesh_{key}"], "-q") == 0
    out["jaw"] = d / "jaw.usdc"
    assert cli("import-capture", sample_assets / "capture" / "JawMoCap.ma", "-o", out["jaw"], "-q") == 0
    out["jaw_stab"] = d / "jaw_stab.usdc"
    assert cli("import-capture", sample_assets / "capture" / "JawMoCap.ma", "-o", out["jaw_stab"],
                   "--stabilize", "-q") == 0
    out["binding_hm08"] = d / "binding_hm08.usda"
    assert cli("bind", "--mesh", out["mesh_hm08"], "--capture", out["jaw_stab"], "--layout",
                   sample_assets / "layouts" / "makehuman_hm08_face.layout.json", "-o", out["binding_hm08"], "-q") == 0
    return out
