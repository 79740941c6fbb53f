"""The USD layers in sample_assets/ are what the documented commands make from the raw files."""
from __future__ import annotations

import numpy as np
import pytest

from usdface.usd.capture_layer import read_capture_layer
from usdface.usd.mesh_layer import read_mesh_layer


@pytest.mark.parametrize("take", ["Jaw", "Nose", "Eyebrows"])
def test_sample_capture_layers_are_current(take, sample_assets, tmp_path, cli):
    fresh = tmp_path / "fresh.usdc"
    assert cli("import-capture", sample_assets / "capture" / f"{take}MoCap.ma", "-o", fresh, "--stabilize", "-q") == 0
    a, b = read_capture_layer(fresh), read_capture_layer(sample_assets / "capture" / f"{take}MoCap.usdc")
    assert a.names == b.names and a.rate == b.rate and a.units == b.units
    np.testing.assert_allclose(a.positions, b.positions, atol=1e-6)
    np.testing.assert_allclose(a.head_motion, b.head_motion, atol=1e-9)


@pytest.mark.parametrize("mesh", ["makehuman_hm08_face_cm", "makehuman_hm08_face_stylized_cm",
                                  "mediapipe_canonical_face_model_holes"])
def test_sample_mesh_layers_are_current(mesh, sample_assets, tmp_path, cli):
    fresh = tmp_path / "fresh.usdc"
    assert cli("import-mesh", sample_assets / "meshes" / f"{mesh}.obj", "-o", fresh, "-q") == 0
    (ma, ra), (mb, rb) = read_mesh_layer(fresh), read_mesh_layer(sample_assets / "meshes" / f"{mesh}.usdc")
    np.testing.assert_array_equal(ma.face_vertex_indices, mb.face_vertex_indices)
    np.testing.assert_allclose(ma.points, mb.points, atol=1e-6)
    assert [(r.name, r.role, r.indices.tolist()) for r in ra] == [(r.name, r.role, r.indices.tolist()) for r in rb]
