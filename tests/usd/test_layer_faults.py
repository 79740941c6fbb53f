"""AtomicLayer under injected file-system faults (USDFACE_TEST_FAULT): EACCES, EROFS and ENOSPC when
the temporary is created, saved and renamed, and inside the block (a long .usdc's intermediate
saves). The destination keeps its old bytes, no temporary is left, and the error is one
WriteError naming the destination and the cause."""
from __future__ import annotations

import errno

import pytest
from pxr import UsdGeom

import usdface  # noqa: F401
from usdface.errors import WriteError
from usdface.fileutil import FAULT_ENV
from usdface.usd.layers import AtomicLayer, set_stage_metadata

CAUSES = {"EACCES": "permission denied", "EROFS": "read-only file system", "ENOSPC": "disk full"}


def _write(path, value):
    with AtomicLayer(path) as stage:
        set_stage_metadata(stage, units="cm", default_prim="X")
        UsdGeom.Xform.Define(stage, "/X").GetPrim().SetCustomDataByKey("v", value)


@pytest.mark.parametrize("code", sorted(CAUSES))
@pytest.mark.parametrize("point", ["create", "save", "replace"])
@pytest.mark.parametrize("suffix", [".usdc", ".usda"])
def test_injected_fault_keeps_old_layer(tmp_path, monkeypatch, code, point, suffix):
    out = tmp_path / f"anim{suffix}"
    _write(out, 1)
    before = out.read_bytes()
    monkeypatch.setenv(FAULT_ENV, f"{code}:{point}:anim{suffix}")
    with pytest.raises(WriteError) as info:
        _write(out, 2)
    assert str(info.value).startswith(f"cannot write {out}: {CAUSES[code]}"), str(info.value)
    assert "\n" not in str(info.value)
    assert out.read_bytes() == before
    assert [p.name for p in tmp_path.iterdir()] == [out.name]


def test_failure_inside_the_block_is_a_write_error(tmp_path):
    out = tmp_path / "anim.usdc"
    _write(out, 1)
    before = out.read_bytes()
    with pytest.raises(WriteError, match=r"anim\.usdc: disk full"):
        with AtomicLayer(out) as stage:
            stage.DefinePrim("/Y")
            raise OSError(errno.ENOSPC, "No space left on device", None)  # an intermediate Save ran out of space
    assert out.read_bytes() == before and [p.name for p in tmp_path.iterdir()] == ["anim.usdc"]


def test_other_errors_inside_the_block_pass_through(tmp_path):
    out = tmp_path / "anim.usdc"
    with pytest.raises(KeyError):
        with AtomicLayer(out) as stage:
            stage.DefinePrim("/Y")
            raise KeyError("not a file-system failure")
    assert list(tmp_path.iterdir()) == []
