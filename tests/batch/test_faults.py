"""Batch under faults, the short version of benchmarks/batch_faults.py (issue 20, item 4): a real
`dask scheduler` and two `dask worker` processes; (b) a worker SIGKILLed while it writes a shot,
(e) the batch process SIGKILLed, then --resume while the killed batch's task still holds a shot.

The benchmark's own checks apply: every shot accounted for (good ones complete and check-clean,
bad ones failed with their manifest line), never two writers in one shot folder (the lock audit
log), the cache never seen partial or corrupted, a complete shot never recomputed by --resume,
the inputs unchanged."""
from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def faults():
    spec = importlib.util.spec_from_file_location("batch_faults", ROOT / "benchmarks" / "batch_faults.py")
    module = importlib.util.module_from_spec(spec)
    sys.modules["batch_faults"] = module  # dataclasses look their module up
    spec.loader.exec_module(module)
    if module.DASK is None:
        pytest.skip("the dask command is not installed (pip install \"dask[distributed]\")")
    return module


@pytest.mark.parametrize("scenario", ["b", "e"])
def test_batch_faults(faults, tmp_path, scenario):
    rows = faults.run([scenario], tmp_path / "work", shots=8, shots_a=8, frames=30, bad_fraction=0.25)
    row = rows[0]
    assert not row.problems, "\n".join(row.problems)
    assert (row.shots, row.ok, row.failed_expected) == (8, 6, 2)
    if scenario == "b":
        assert row.recomputed >= 1 and "SIGKILLed" in row.notes[0]  # the killed worker's shot ran again
    else:
        assert any("still held the long shot" in n for n in row.notes), row.notes
