"""Issue 19, item 6: a changed algorithm or default bumps a revision (usdface.revisions) that every
layer's provenance and the batch's cache keys carry, so `batch --resume` and the content cache
recompute what an older revision made instead of reusing it."""
from __future__ import annotations

import json
from pathlib import Path

import pytest

from usdface.options import BatchOptions


def _statuses(summary) -> list:
    return [r["status"] for r in summary["shots"]]


def test_resume_recomputes_a_shot_made_before_the_bump_and_skips_one_made_after(tmp_path, make_manifest,
                                                                                monkeypatch):
    from usdface import revisions
    from usdface.pipeline.batch.manifest import load_manifest
    from usdface.pipeline.batch.runner import run_batch
    from usdface.usd.layers import layer_provenance

    m = load_manifest(make_manifest(tmp_path, broken=False, trim=(0, 40)))
    m.shots = m.shots[:2]
    options = BatchOptions(workers=0, cache=False)
    # shot 0 made by the transfer of revision 1 (before the bump), shot 1 by the current one
    with monkeypatch.context() as before:
        before.setitem(revisions.REVISIONS, "transfer", 1)
        shot0 = load_manifest(make_manifest(tmp_path, broken=False, trim=(0, 40)))
        shot0.shots = shot0.shots[:1]
        assert _statuses(run_batch(shot0, options)) == ["ok"]
    anim0 = Path(m.shots[0].output) / "anim.usdc"
    assert "revision" not in layer_provenance(anim0)  # revision 1: nothing recorded (0.2's layers)
    m1 = load_manifest(make_manifest(tmp_path, broken=False, trim=(0, 40)))
    m1.shots = m1.shots[1:2]
    assert _statuses(run_batch(m1, options)) == ["ok"]
    anim1 = Path(m.shots[1].output) / "anim.usdc"
    assert layer_provenance(anim1)["revision"] == revisions.revision("transfer") > 1
    summary1 = json.loads((Path(m.shots[1].output) / "summary.json").read_text())
    assert json.loads(summary1["provenance"]["revisions"])["transfer"] == revisions.revision("transfer")
    # --resume: the older shot is recomputed, the current one skipped
    s = run_batch(m, BatchOptions(workers=0, cache=False, resume=True))
    assert _statuses(s) == ["ok", "skipped"]
    assert layer_provenance(anim0)["revision"] == revisions.revision("transfer")
    assert _statuses(run_batch(m, BatchOptions(workers=0, cache=False, resume=True))) == ["skipped", "skipped"]


def test_a_layer_made_by_an_older_revision_is_stale_even_with_a_current_summary(tmp_path, make_manifest,
                                                                              monkeypatch):
    """A shot without a shot record (made before records existed) is judged layer by layer."""
    from usdface import revisions
    from usdface.pipeline.batch import runner
    from usdface.pipeline.batch.manifest import load_manifest

    m = load_manifest(make_manifest(tmp_path, broken=False, trim=(0, 40)))
    m.shots = m.shots[:1]
    assert _statuses(runner.run_batch(m, BatchOptions(workers=0, cache=False))) == ["ok"]
    monkeypatch.setattr("usdface.usd.shot_record.read_shot_record", lambda path: None)
    assert runner.shot_is_current(m.shots[0]) == (True, "outputs current")
    # the transfer moves on while the run's recorded revisions are left as they were
    monkeypatch.setitem(revisions.REVISIONS, "transfer", 3)
    monkeypatch.setattr(revisions, "run_revisions", lambda: {"bind": 2, "import-capture": 2, "skel": 2,
                                                            "solve": 2, "transfer": 2})
    assert runner.shot_is_current(m.shots[0]) == (False, "anim.usdc: made by revision 2 of transfer, now 3")


def test_the_cache_key_carries_the_revision_of_the_processor_that_makes_the_entry(monkeypatch):
    from usdface import revisions
    from usdface.cache import content_key

    capture, distances = content_key("capture", "take.ma", "abc"), content_key("distances", [1, 2])
    monkeypatch.setitem(revisions.REVISIONS, "transfer", 3)  # not what makes either entry: keys kept
    assert (content_key("capture", "take.ma", "abc"), content_key("distances", [1, 2])) == (capture, distances)
    monkeypatch.setitem(revisions.REVISIONS, "import-capture", 3)
    assert content_key("capture", "take.ma", "abc") != capture
    monkeypatch.setitem(revisions.REVISIONS, "distances", 2)
    assert content_key("distances", [1, 2]) != distances
    monkeypatch.setitem(revisions.REVISIONS, "distances", 1)  # revision 1 keys are usdface 0.2's
    assert content_key("distances", [1, 2]) == distances


def test_the_capture_cache_recomputes_an_entry_made_by_an_older_revision(tmp_path, sample_assets, monkeypatch):
    """import-capture's cached layer (its key holds the file and the options, not the algorithm):
    after the bump the cache misses and the layer gets today's rest pose."""
    from usdface import registry, revisions
    from usdface.cache import ContentCache
    from usdface.options import CaptureOptions
    from usdface.usd.capture_layer import read_capture_layer

    cache = ContentCache(tmp_path / "cache")
    take = sample_assets / "capture" / "JawMoCap.ma"
    with monkeypatch.context() as before:
        before.setitem(revisions.REVISIONS, "import-capture", 1)
        first = registry.call("import-capture", take, options=CaptureOptions(trim=(0, 60)),
                              output=tmp_path / "a.usdc", cache=cache)
    assert first.summary["cache"]["status"] == "miss"
    again = registry.call("import-capture", take, options=CaptureOptions(trim=(0, 60)), output=tmp_path / "b.usdc",
                          cache=cache)
    assert again.summary["cache"]["status"] == "miss"
    third = registry.call("import-capture", take, options=CaptureOptions(trim=(0, 60)), output=tmp_path / "c.usdc",
                          cache=cache)
    assert third.summary["cache"]["status"] == "hit"
    assert read_capture_layer(tmp_path / "c.usdc").neutral_frames == read_capture_layer(tmp_path / "b.usdc").neutral_frames


@pytest.mark.parametrize("processor, recorded", [("transfer", {"revision": 2}), ("import-mesh", {}),
                                                 ("solve --apply", {})])
def test_provenance_records_the_revision_above_1(processor, recorded):
    from usdface.revisions import provenance_revision

    assert provenance_revision(processor) == recorded
