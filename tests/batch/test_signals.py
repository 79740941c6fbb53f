"""Real signals to a running `usdface batch` (issue 20, cases 5, 6 and 9), started as a terminal
starts it: in its own session, so a Ctrl-C or a hang-up reaches its whole process group (the local
cluster's workers included). Each: the documented exit code, one line on stderr, no partial work
left in any shot folder (work folders, locks, temporaries), inputs unchanged, no process left."""
from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from tests.hostile import terminal_signals

from usdface.fileutil import file_digest, is_temporary_name

SA = Path(__file__).resolve().parents[2] / "sample_assets"
REPO = SA.parent
INPUTS = [SA / "meshes" / "makehuman_hm08_face_cm.obj", SA / "meshes" / "mediapipe_canonical_face_model_holes.obj",
          SA / "layouts" / "makehuman_hm08_face.layout.json", SA / "layouts" / "mediapipe_face_holes.layout.json",
          SA / "capture" / "JawMoCap.ma", SA / "capture" / "NoseMoCap.ma"]


def _manifest(folder: Path) -> Path:
    """Four shots of a few seconds each (no cache: each computes its distances)."""
    text = ["[batch]", 'summary = "out/summary.json"', "[defaults]", "trim = [0, 400]",
            'output = "out/{mesh}/{capture}"']
    for mesh, layout in (("makehuman_hm08_face_cm", "makehuman_hm08_face"),
                         ("mediapipe_canonical_face_model_holes", "mediapipe_face_holes")):
        text += ["[[shots]]", f'mesh = "{SA}/meshes/{mesh}.obj"', f'layout = "{SA}/layouts/{layout}.layout.json"',
                 f'capture = "{SA}/capture/[JN]*MoCap.ma"']
    path = folder / "shots.toml"
    path.write_text("\n".join(text) + "\n")
    return path


def _leftovers(root: Path) -> list[str]:
    found = []
    for dirpath, dirnames, filenames in os.walk(root):
        for name in dirnames + filenames:
            if name.startswith((".usdface-run-", ".usdface-lock", ".tmp-", ".trash-")) or is_temporary_name(name):
                found.append(os.path.relpath(os.path.join(dirpath, name), root))
    return sorted(found)


def _run_folders(root: Path) -> list[Path]:
    return sorted(root.glob("out/*/*/.usdface-run-*"))


def _start(manifest: Path, *args) -> subprocess.Popen:
    env = dict(os.environ, PYTHONPATH=str(REPO) + os.pathsep + os.environ.get("PYTHONPATH", ""))
    return subprocess.Popen([sys.executable, "-m", "usdface", "batch", str(manifest), "--no-cache", "-q", *args],
                            cwd=manifest.parent, env=env, start_new_session=True, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True,
                            preexec_fn=terminal_signals)


def _wait_until_shots_run(p: subprocess.Popen, root: Path, timeout: float = 120.0) -> list[Path]:
    """Until a shot is writing (a work folder with files in it)."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        running = [w for w in _run_folders(root) if any(w.iterdir())]
        if running:
            return running
        assert p.poll() is None, p.communicate()
        time.sleep(0.05)
    p.kill()
    pytest.fail("no shot started writing within %d s" % timeout)


def _group_gone(pgid: int, timeout: float = 30.0) -> bool:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        try:
            os.killpg(pgid, 0)
        except ProcessLookupError:
            return True
        time.sleep(0.1)
    return False


@pytest.mark.parametrize("workers,signum,to_group,exit_code,line", [
    ("2", signal.SIGINT, True, 130, "usdface batch: interrupted; partial work removed"),
    ("2", signal.SIGTERM, False, 143, "usdface batch: stopped by SIGTERM; partial work removed"),
    ("2", signal.SIGHUP, True, 129, "usdface batch: stopped by SIGHUP; partial work removed"),
    ("0", signal.SIGTERM, True, 143, "usdface batch: stopped by SIGTERM; partial work removed"),
], ids=["ctrl-c-to-the-group", "sigterm-to-the-batch", "hang-up-to-the-group", "sigterm-serial"])
def test_a_stopped_batch_says_one_line_and_leaves_no_partial_work(tmp_path, workers, signum, to_group, exit_code,
                                                                   line):
    manifest = _manifest(tmp_path)
    digests = {p: file_digest(p) for p in [*INPUTS, manifest]}
    p = _start(manifest, "--workers", workers)
    try:
        _wait_until_shots_run(p, tmp_path)
        if to_group:
            os.killpg(p.pid, signum)  # a terminal's Ctrl-C or hang-up: every process of the group
        else:
            os.kill(p.pid, signum)  # a farm scheduler stopping the job
        _, err = p.communicate(timeout=120)
    finally:
        if p.poll() is None:
            os.killpg(p.pid, signal.SIGKILL)
            p.wait()
    assert p.returncode == exit_code, err
    assert err.splitlines() == [line]
    assert _group_gone(p.pid), "worker processes outlived the batch"
    assert _leftovers(tmp_path) == []
    assert {q: file_digest(q) for q in digests} == digests


def test_a_worker_stopped_by_sigterm_cleans_its_shot_and_the_batch_completes(tmp_path):
    """SIGTERM to one worker of the local cluster (the system stopping it): its running shot removes
    its own work folder before the worker ends; the batch hands the shot out again and completes."""
    manifest = _manifest(tmp_path)
    p = _start(manifest, "--workers", "2")
    try:
        work = _wait_until_shots_run(p, tmp_path)[0]
        worker = int(work.name.split("-")[2].split("@")[0])  # .usdface-run-<pid>@<host>-<token>
        os.kill(worker, signal.SIGTERM)
        deadline = time.monotonic() + 60
        while Path(f"/proc/{worker}").exists() and _proc_state(worker) != "Z" and time.monotonic() < deadline:
            time.sleep(0.02)
        assert not work.exists(), "the stopped worker left its shot's work folder"
        out, err = p.communicate(timeout=300)
    finally:
        if p.poll() is None:
            os.killpg(p.pid, signal.SIGKILL)
            p.wait()
    assert p.returncode == 0, err
    assert err == ""
    assert _leftovers(tmp_path) == []
    import json

    summary = json.loads((tmp_path / "out" / "summary.json").read_text())
    assert summary["counts"] == {"ok": 4, "skipped": 0, "failed": 0, "unsupported": 0}


def _proc_state(pid: int) -> str:
    try:
        return Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except (OSError, IndexError):
        return "gone"
