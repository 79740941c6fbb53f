"""The content-addressed cache: atomic entries, racing writers, a full disk, corrupt entries."""
from __future__ import annotations

from usdface.options import BatchOptions

import errno
import shutil
import threading

import numpy as np
import pytest

from usdface.cache import ContentCache, content_key
from usdface.errors import ResourceError


def test_key_depends_on_content_not_identity():
    a = np.arange(6.0).reshape(2, 3)
    assert content_key("d", a.copy(), "x") == content_key("d", a, "x")
    assert content_key("d", a, "x") != content_key("d", a + 1e-12, "x")
    assert content_key("d", a, "x") != content_key("d", a.astype(np.float32), "x")
    assert content_key("d", {"b": 1, "a": 2}) == content_key("d", {"a": 2, "b": 1})


def test_put_get_roundtrip_and_counts(tmp_path):
    c = ContentCache(tmp_path / "c")
    key = content_key("t", 1)
    assert c.get("t", key) is None
    e = c.put("t", key, arrays={"x": np.arange(5)}, meta={"hello": "world"})
    assert e.meta["hello"] == "world" and np.array_equal(c.get("t", key).arrays()["x"], np.arange(5))
    assert (c.stats.hits, c.stats.misses, c.stats.stores) == (1, 1, 1)
    assert not list((tmp_path / "c" / "t").glob(".tmp-*"))


def test_concurrent_writers_leave_one_whole_entry(tmp_path):
    c = ContentCache(tmp_path / "c", lock="none")  # no lock: writers really race
    key = content_key("t", "race")
    data = np.random.default_rng(0).random((200, 200))
    errors = []

    def write():
        try:
            c.put("t", key, arrays={"x": data}, meta={})
        except Exception as exc:  # noqa: BLE001
            errors.append(exc)

    threads = [threading.Thread(target=write) for _ in range(8)]
    [t.start() for t in threads]
    [t.join() for t in threads]
    assert not errors
    assert len(c.entries("t")) == 1 and np.array_equal(c.get("t", key).arrays()["x"], data)
    assert not list((tmp_path / "c" / "t").glob(".tmp-*"))


def test_disk_filling_up_while_writing_leaves_no_entry(tmp_path, monkeypatch):
    c = ContentCache(tmp_path / "c")
    key = content_key("t", "full")

    def full(*a, **k):
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(np, "savez", full)
    with pytest.raises(ResourceError, match=r"filled up while writing.*no entry was written.*--no-cache"):
        c.put("t", key, arrays={"x": np.zeros(10)}, meta={})
    assert c.get("t", key) is None and not list((tmp_path / "c" / "t").iterdir())[1:] and \
        not list((tmp_path / "c" / "t").glob(".tmp-*"))


def test_too_little_free_space_is_refused_up_front(tmp_path, monkeypatch):
    c = ContentCache(tmp_path / "c")
    real = shutil.disk_usage
    monkeypatch.setattr(shutil, "disk_usage", lambda p: real(p)._replace(free=1000))
    with pytest.raises(ResourceError, match=r"too little free space.*1\.0 kB|too little free space"):
        c.put("t", content_key("t", 2), arrays={"x": np.zeros(1000)}, meta={})
    assert c.entries("t") == []


def test_corrupt_entry_is_a_miss_and_removed(tmp_path):
    c = ContentCache(tmp_path / "c")
    key = content_key("t", 3)
    e = c.put("t", key, arrays={"x": np.arange(100)}, meta={})
    with open(e.file("arrays.npz"), "r+b") as f:
        f.seek(-8, 2)
        f.write(b"garbage!")
    assert c.get("t", key) is None
    assert c.entries("t") == []


def test_full_cache_fails_the_shot_clearly(tmp_path, make_manifest, monkeypatch):
    """A shot whose cache write hits a full disk fails with the cache's message; the others go on."""
    from usdface.pipeline.batch.manifest import load_manifest
    from usdface.pipeline.batch.runner import run_batch
    from usdface import cache as cache_mod

    real = shutil.disk_usage
    monkeypatch.setattr(cache_mod.shutil, "disk_usage", lambda p: real(p)._replace(free=10_000))
    m = load_manifest(make_manifest(tmp_path, broken=False, trim=(0, 30)))
    m.shots = m.shots[:2]
    s = run_batch(m, BatchOptions(workers=0))
    assert [r["status"] for r in s["shots"]] == ["failed", "failed"]
    assert "too little free space" in s["shots"][0]["error"]
    assert ContentCache(m.cache).entries() == []
    assert s["_exit"] == 1


def test_a_killed_holder_of_an_entry_blocks_nobody(tmp_path):
    """A worker SIGKILLed while it computes an entry: the next process waiting for that entry gets
    the lock at once (the system releases a dead process's flock). With Dask's lock, the default
    inside a worker until now, it waited for the lease to time out (30 s; 26-28 s measured in
    benchmarks/batch_faults.py scenario b)."""
    import os
    import signal
    import subprocess
    import sys
    import time

    root = tmp_path / "c"
    code = ("import sys, time; from usdface.cache import ContentCache; c = ContentCache(sys.argv[1]); "
            "cm = c.lock('distances', 'k'); cm.__enter__(); print('holding', flush=True); time.sleep(60)")
    p = subprocess.Popen([sys.executable, "-c", code, str(root)], stdout=subprocess.PIPE, text=True)
    try:
        assert p.stdout.readline().strip() == "holding"
        c = ContentCache(root)
        got = []
        waiter = threading.Thread(target=lambda: got.append(c.lock("distances", "k").__enter__()))
        waiter.start()
        waiter.join(0.5)
        assert waiter.is_alive()  # a live holder makes it wait
        os.kill(p.pid, signal.SIGKILL)
        t0 = time.monotonic()
        waiter.join(5)
        assert not waiter.is_alive() and time.monotonic() - t0 < 1.0
    finally:
        p.kill()
        p.wait()


def test_auto_takes_the_file_lock_in_a_dask_worker(tmp_path, monkeypatch):
    """In a Dask worker too: the file lock, not the scheduler's (which a dead worker holds for its
    lease and a restarted scheduler forgets)."""
    import usdface.cache as cache

    monkeypatch.setattr(cache, "_in_dask_worker", lambda: True)
    c = ContentCache(tmp_path / "c")
    with c.lock("distances", "k"):
        assert (tmp_path / "c" / "locks" / "distances-k.lock").is_file()
