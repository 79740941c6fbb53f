"""Atomic layer writes, metadata and provenance."""
import os

import numpy as np
import pytest

import usdface  # noqa: F401
from usdface.errors import OptionError
from usdface.usd.layers import AtomicLayer, check_output_path, provenance, set_stage_metadata


def _write(path, value):
    from pxr import UsdGeom

    with AtomicLayer(path) as stage:
        set_stage_metadata(stage, units="cm", default_prim="X")
        UsdGeom.Xform.Define(stage, "/X").GetPrim().SetCustomDataByKey("v", value)


def test_atomic_layer_replaces_and_sets_permissions(tmp_path):
    out = tmp_path / "a.usda"
    _write(out, 1)
    _write(out, 2)
    assert "v = 2" in out.read_text()
    assert oct(os.stat(out).st_mode & 0o777) != oct(0o600)
    assert [p.name for p in tmp_path.iterdir()] == ["a.usda"]


def test_failure_leaves_previous_output_untouched(tmp_path):
    out = tmp_path / "a.usdc"
    _write(out, 1)
    before = out.read_bytes()
    with pytest.raises(RuntimeError):
        with AtomicLayer(out) as stage:
            stage.DefinePrim("/Y")
            stage.GetRootLayer().Save()  # a half-written temp file exists now
            raise RuntimeError("boom")
    assert out.read_bytes() == before
    assert [p.name for p in tmp_path.iterdir()] == ["a.usdc"]


def test_output_folder_must_exist(tmp_path):
    with pytest.raises(OptionError, match="does not exist"):
        check_output_path(tmp_path / "missing" / "x.usdc")
    with pytest.raises(OptionError, match="expected a file ending in"):
        check_output_path(tmp_path / "x.txt")


def test_provenance_has_no_absolute_paths_or_times(tmp_path):
    src = tmp_path / "input.bin"
    src.write_bytes(b"abc")
    prov = provenance("test", options={"a": 1}, inputs={"capture": src})
    text = repr(prov)
    assert str(tmp_path) not in text
    assert "input.bin" in text and "ba7816bf" in text  # sha256("abc")
    assert set(prov) == {"usdfaceVersion", "processor", "options", "inputs"}
