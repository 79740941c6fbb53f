"""Batch scheduling: the longest shots are handed out first, and the summary shows where the time
went (seconds per step)."""
from __future__ import annotations

from usdface.pipeline.batch.manifest import Shot
from usdface.pipeline.batch.runner import shot_cost, step_times, summary_table


def test_longest_shots_first(tmp_path):
    small = tmp_path / "small.obj"
    small.write_text("v 0 0 0\n" * 10)
    big = tmp_path / "big.obj"
    big.write_text("v 0 0 0\n" * 1000)
    take = tmp_path / "take.ma"
    take.write_text("x" * 100)
    plan = [(small, [0, 300]), (big, [0, 100]), (big, [0, 300]), (small, [0, 10]), (big, None)]
    shots = [Shot(name=f"s{i}", mesh=str(m), capture=str(take), output=str(tmp_path / f"o{i}"),
                  options={} if trim is None else {"trim": trim}) for i, (m, trim) in enumerate(plan)]
    order = [s.name for s in sorted(shots, key=shot_cost, reverse=True)]
    # mesh size x frames: the big mesh's 300 frames, its 100 frames (and, without a trim, the take's
    # 100 bytes standing for its frames: a tie, kept in manifest order), the small one's 300, its 10
    assert order == ["s2", "s1", "s4", "s0", "s3"]
    assert shot_cost(shots[4]) == shot_cost(shots[1]) == shot_cost(shots[2]) / 3
    missing = Shot(name="x", mesh=str(tmp_path / "none.obj"), capture=str(take), output="o", options={})
    assert shot_cost(missing) > 0


def test_summary_table_shows_seconds_per_step():
    shots = [{"name": "makehuman/Jaw", "status": "ok", "seconds": 12.34,
              "cache": {"import-capture": "hit", "distances": "miss"},
              "steps": {"import-mesh": 0.41, "bind": 0.2, "distances": 3.96, "transfer": 7.1}},
             {"name": "broken", "status": "failed", "seconds": None, "error": "capture x: not a Maya file\nmore"}]
    summary = {"shots": shots, "counts": {"ok": 1, "skipped": 0, "failed": 1, "unsupported": 0}, "seconds": 13.0,
               "mode": "local", "workers": 2, "cache": {"steps": {}}, "summaryFile": "s.json"}
    lines = summary_table(summary)
    assert "steps (s)" in lines[0]
    row = next(l for l in lines if l.startswith("makehuman/Jaw"))
    assert "import-mesh 0.4, bind 0.2, distances 4.0, transfer 7.1" in row and "12.3" in row
    assert "capture x: not a Maya file" in next(l for l in lines if l.startswith("broken"))
    assert step_times(None) == "-" and step_times({"run": None}) == ""
    assert lines[-2] == "1 ok, 0 skipped, 1 failed in 13.0 s (local, 2 workers)"
    # --workers 0 runs the shots one after the other in this process: no worker count to show
    serial = summary_table({**summary, "mode": "serial", "workers": 0})
    assert serial[-2] == "1 ok, 0 skipped, 1 failed in 13.0 s (serial)"
    assert summary_table({**summary, "workers": 1})[-2].endswith("(local, 1 worker)")


def test_timed_calls_time_the_processors_called_through_the_registry():
    import pytest

    from usdface import registry
    from usdface.errors import UsdFaceError
    from usdface.options import BindOptions

    with registry.timed_calls() as times:
        with pytest.raises(UsdFaceError):        # a failing step is timed too
            registry.call("bind", "/nonexistent/mesh.usdc", "/nonexistent/capture.usdc",
                          options=BindOptions(auto=True), output="/tmp/x.usda")
    assert set(times) == {"bind"} and times["bind"] >= 0.0
    registry.call("plugin-path")  # outside the block: not timed
    assert set(times) == {"bind"}
