"""usdface.shot_commit: the OUTDIR lock, tidying dead processes' temporaries, the whole-shot commit,
and SIGKILL at every step of it (the short version of benchmarks/crash_consistency.py: one kill
per step; `check` never accepts a mixed shot and the next run's tidy always completes it)."""
from __future__ import annotations

import json
import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from usdface.errors import Interrupted, LockedError
from usdface.fileutil import HOST_TAG, file_digest
from usdface.pipeline.shot_commit import KILL_ENV, LOCK_NAME, OutdirLock, ShotSession, commit_order, commit_steps, tidy
from usdface.usd.shot_record import MARKER_NAME, interrupted_commit, leftovers
from usdface.usd.validation import check_layer

SA = Path(__file__).resolve().parents[1] / "sample_assets"
RUN = ["--mesh", SA / "meshes" / "makehuman_hm08_face_cm.obj", "--capture", SA / "capture" / "JawMoCap.ma",
       "--layout", SA / "layouts" / "makehuman_hm08_face.layout.json", "--method", "euclidean", "-q"]


def _dead_pid() -> int:
    p = subprocess.Popen([sys.executable, "-c", "pass"])
    p.wait()
    return p.pid


# -- the lock -------------------------------------------------------------------------------------

def test_lock_refuses_a_second_writer_and_names_the_first(tmp_path):
    first = OutdirLock(tmp_path)
    first.acquire()
    with pytest.raises(LockedError, match=rf"being written by another usdface run \(pid {os.getpid()} on "):
        OutdirLock(tmp_path).acquire()
    first.release()
    assert not (tmp_path / LOCK_NAME).exists()
    # a lock file left by a killed process holds no lock: the next writer takes it
    (tmp_path / LOCK_NAME).write_text(json.dumps({"pid": _dead_pid(), "host": "x", "hostTag": HOST_TAG}))
    again = OutdirLock(tmp_path)
    again.acquire()
    again.release()


def test_lock_in_another_process(tmp_path):
    code = ("import sys, time; from usdface.pipeline.shot_commit import OutdirLock; l = OutdirLock(sys.argv[1]); "
            "l.acquire(); print('locked', flush=True); time.sleep(60)")
    p = subprocess.Popen([sys.executable, "-c", code, str(tmp_path)], stdout=subprocess.PIPE, text=True)
    try:
        assert p.stdout.readline().strip() == "locked"
        with pytest.raises(LockedError, match=rf"pid {p.pid}"):
            OutdirLock(tmp_path).acquire()
    finally:
        p.send_signal(signal.SIGKILL)
        p.wait()
    lock = OutdirLock(tmp_path)  # SIGKILL released it
    lock.acquire()
    lock.release()


# -- tidying --------------------------------------------------------------------------------------

def test_tidy_removes_only_temporaries_of_dead_or_old_owners(tmp_path):
    dead, me = _dead_pid(), os.getpid()
    day = 24 * 3600
    names = {
        f".anim.tmp-{dead}@{HOST_TAG}-0a0b.usdc": (True, 0),        # dead owner on this host
        f".anim.tmp-{me}@{HOST_TAG}-0a0c.usdc": (False, 0),         # alive (this process)
        f".anim.tmp-{dead}@farm_node_7-0a0d.usdc": (False, 0),      # another host, recent: cannot tell
        f".anim.tmp-{dead}@farm_node_7-0a0e.usdc ": (False, 0),     # not a temporary name (trailing space)
        f".mesh.tmp-{dead}@farm_node_7-0a0f.usdc": (True, 2 * day),  # another host, older than a day
        f".mesh.tmp-{dead}-0a10.usdc": (True, 2 * day),              # written before host tags, old
        f".mesh.tmp-{dead}-0a11.usdc": (False, 0),                   # ... recent
        "anim.usdc": (False, 0),
    }
    for name, (_, age) in names.items():
        p = tmp_path / name
        p.write_bytes(b"x" * 100)
        if age:
            os.utime(p, (time.time() - age, time.time() - age))
    work = tmp_path / f".usdface-run-{dead}@{HOST_TAG}-1234"
    work.mkdir()
    (work / "anim.usdc").write_bytes(b"y" * 1000)
    report = tidy(tmp_path)
    expected_removed = {n for n, (gone, _) in names.items() if gone} | {work.name}
    assert set(report["removed"]) == expected_removed
    assert report["bytes"] == 100 * 3 + 1000
    assert {p.name for p in tmp_path.iterdir()} == set(names) - expected_removed


# -- the commit -----------------------------------------------------------------------------------

def _session_with(folder: Path, files: dict, run="r1", inputs=None) -> ShotSession:
    s = ShotSession(folder, run, inputs=inputs)
    work = s.open()
    for name, data in files.items():
        (work / name).write_bytes(data)
    return s


def test_commit_order_and_stale_files(tmp_path):
    assert commit_order(["shot.usda", "mesh.usdc", "summary.json", "anim.usdc", "shot_skel.usda"]) == \
        ["mesh.usdc", "anim.usdc", "summary.json", "shot.usda", "shot_skel.usda"]
    # the previous run wrote a skeleton as well; this one does not: its skel files go, inputs never
    (tmp_path / "summary.json").write_text(json.dumps({"files": ["mesh.usdc", "skel.usdc", "shot_skel.usda",
                                                                 "notes.usdc"]}))
    for n in ("mesh.usdc", "skel.usdc", "shot_skel.usda", "notes.usdc"):
        (tmp_path / n).write_bytes(b"old")
    s = _session_with(tmp_path, {"mesh.usdc": b"new", "summary.json": b"{}", "shot.usda": b"#usda 1.0\n"},
                      inputs={"--layout": tmp_path / "notes.usdc"})
    s.commit(["mesh.usdc", "summary.json", "shot.usda"])
    s.close()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["mesh.usdc", "notes.usdc", "shot.usda", "summary.json"]
    assert (tmp_path / "mesh.usdc").read_bytes() == b"new"


def test_sigterm_during_a_commit_waits_for_its_end(tmp_path, monkeypatch):
    import usdface.pipeline.shot_commit as sc

    def on_step(name):
        if name == "rename:mesh.usdc":
            os.kill(os.getpid(), signal.SIGTERM)

    def interrupt(signum, frame):
        raise Interrupted(signum)

    monkeypatch.setattr(sc, "_step", on_step)
    previous = signal.signal(signal.SIGTERM, interrupt)
    try:
        s = _session_with(tmp_path, {"mesh.usdc": b"m", "anim.usdc": b"a", "summary.json": b"{}",
                                     "shot.usda": b"#usda 1.0\n"})
        with pytest.raises(Interrupted) as info:
            s.commit(["mesh.usdc", "anim.usdc", "summary.json", "shot.usda"])
        s.close()
    finally:
        signal.signal(signal.SIGTERM, previous)
    assert info.value.exit_code == 143
    assert sorted(p.name for p in tmp_path.iterdir()) == ["anim.usdc", "mesh.usdc", "shot.usda", "summary.json"]


# -- SIGKILL at each step of a real shot's commit -------------------------------------------------

@pytest.fixture(scope="module")
def two_shots(tmp_path_factory):
    """Two real shots of different jobs (30 and 40 frames): the old OUTDIR and the new run's files."""
    from usdface.cli import main

    root = tmp_path_factory.mktemp("shots")
    for name, trim in (("old", "30"), ("new", "40")):
        assert main(["run", *map(str, RUN), "--trim", "0", trim, "-o", str(root / name)]) == 0
    files = json.loads((root / "new" / "summary.json").read_text())["files"]
    run_id = json.loads((root / "new" / "summary.json").read_text())["runId"]
    digests = {k: {f: file_digest(root / k / f) for f in files if f != "summary.json"} for k in ("old", "new")}
    return root, files, run_id, digests


_KILLED_COMMIT = """
import shutil, sys
from pathlib import Path
from usdface.pipeline.shot_commit import ShotSession
out, new, run_id, files = Path(sys.argv[1]), Path(sys.argv[2]), sys.argv[3], sys.argv[4].split(",")
s = ShotSession(out, run_id)
work = s.open()
for f in files:
    shutil.copy2(new / f, work / f)
s.commit(files)
s.close()
"""


def _state(out: Path, files, digests) -> str:
    """'old' / 'new' when OUTDIR holds that complete shot, else 'mixed'."""
    now = {f: file_digest(out / f) if (out / f).is_file() else None for f in digests["old"]}
    for k in ("old", "new"):
        if now == digests[k]:
            return k
    return "mixed"


# the short version: one kill per step, each step of the commit
@pytest.mark.parametrize("step", commit_steps(["mesh.usdc", "capture.usdc", "binding.usda", "analysis.usdc",
                                               "anim.usdc", "shot.usda", "summary.json"]))
def test_sigkill_at_each_commit_step(two_shots, tmp_path, step):
    root, files, run_id, digests = two_shots
    out = tmp_path / "out"
    shutil.copytree(root / "old", out)
    p = subprocess.run([sys.executable, "-c", _KILLED_COMMIT, str(out), str(root / "new"), run_id, ",".join(files)],
                       env=dict(os.environ, **{KILL_ENV: step}), capture_output=True, text=True)
    assert p.returncode == -signal.SIGKILL, p.stderr
    state = _state(out, files, digests)
    errors = [f for f in check_layer(out / "shot.usda") if f.severity == "error"]
    if not errors:  # check accepts only a complete shot, old or new, never a mix
        assert state in ("old", "new") and (out / "shot.usda").is_file()
    if (out / "shot.usda").is_file():  # a shot stage present never composes a mix
        assert state in ("old", "new"), step
    pending = interrupted_commit(out)
    assert (pending is not None) == (step not in ("written", "cleanup")), step
    report = tidy(out)  # what the next run does first
    assert leftovers(out) == []
    assert _state(out, files, digests) == ("old" if step == "written" else "new")
    assert not [f for f in check_layer(out / "shot.usda") if f.severity == "error"]
    assert (step != "written") == bool(report["completed"] or step == "cleanup")
    assert not (out / MARKER_NAME).exists()


def test_folder_and_nested_deliverables_are_committed_and_checked(tmp_path):
    """Other deliverables (a playblast's frames in a folder, a file in a subfolder) commit like layers."""
    from pxr import Sdf

    from usdface.usd.shot_record import shot_record, verify_shot

    out = tmp_path / "out"
    out.mkdir()
    (out / "playblast").mkdir()
    (out / "playblast" / "old.0001.png").write_bytes(b"old frame")
    s = ShotSession(out, "r2")
    work = s.open()
    (work / "playblast").mkdir()
    for i in range(3):
        (work / "playblast" / f"f.{i:04d}.png").write_bytes(bytes([i]) * 10)
    (work / "reports").mkdir()
    (work / "reports" / "curves.csv").write_text("frame,x\n0,1\n")
    files = ["playblast", "reports/curves.csv", "summary.json", "shot.usda"]
    (work / "summary.json").write_text(json.dumps({"runId": "r2", "files": files}))
    record = shot_record(work, files, "r2")
    layer = Sdf.Layer.CreateNew(str(work / "shot.usda"))
    layer.customLayerData = {"usdface": {"shot": json.dumps(record)}}
    layer.Save()
    s.commit(files)
    s.close()
    assert sorted(p.name for p in (out / "playblast").iterdir()) == ["f.0000.png", "f.0001.png", "f.0002.png"]
    assert (out / "reports" / "curves.csv").read_text().startswith("frame")
    assert leftovers(out) == [] and verify_shot(out / "shot.usda") == []
    (out / "playblast" / "f.0001.png").write_bytes(b"another run's frame")
    assert verify_shot(out / "shot.usda") == ["playblast is not the file committed with this shot (its bytes differ)"]


def test_tidy_under_the_lock_removes_this_hosts_run_folders_whatever_their_pid(tmp_path):
    """A run keeps OUTDIR's lock while its work folder lives: whoever holds the lock finds only dead
    runs' folders, even when their pid still runs (a Dask worker outlives its shots). Another host's
    recent run folder cannot be asked and stays."""
    sleeper = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(60)"])
    try:
        live = tmp_path / f".usdface-run-{sleeper.pid}@{HOST_TAG}-ab12cd34"
        other_host = tmp_path / f".usdface-run-{sleeper.pid}@farm_node_7-ab12cd35"
        for work in (live, other_host):
            work.mkdir()
            (work / "anim.usdc").write_bytes(b"partial")
        report = tidy(tmp_path)
    finally:
        sleeper.kill()
        sleeper.wait()
    assert report["removed"] == [live.name] and report["kept"] == [other_host.name]
    assert not live.exists() and other_host.exists()


def test_tidy_unlocked_folder_removes_a_lock_nobody_holds(tmp_path):
    from usdface.pipeline.shot_commit import tidy_unlocked_folder

    # a SIGKILLed run's lock file, and nothing else: removed
    (tmp_path / LOCK_NAME).write_text(json.dumps({"pid": _dead_pid(), "host": "x", "hostTag": HOST_TAG}))
    assert tidy_unlocked_folder(tmp_path) is not None
    assert not (tmp_path / LOCK_NAME).exists()
    # a lock a live process holds: left to it, with its work folder
    code = ("import sys, time; from usdface.pipeline.shot_commit import ShotSession; "
            "s = ShotSession(sys.argv[1], 'r'); s.open(); print(s.work.name, flush=True); time.sleep(60)")
    p = subprocess.Popen([sys.executable, "-c", code, str(tmp_path)], stdout=subprocess.PIPE, text=True)
    try:
        work = p.stdout.readline().strip()
        assert tidy_unlocked_folder(tmp_path) is None
        assert sorted(x.name for x in tmp_path.iterdir()) == sorted([LOCK_NAME, work])
    finally:
        p.kill()
        p.wait()
    # once it is dead (SIGKILL: no clean-up), the lock and its work folder go
    assert tidy_unlocked_folder(tmp_path)["removed"] == [work]
    assert list(tmp_path.iterdir()) == []
