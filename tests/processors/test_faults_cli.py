"""Fault injection through the command line (issue 12): outputs that are inputs, full disks,
read-only folders, permissions, memory, SIGTERM, SIGKILL mid-commit, a second run into a locked
folder. Each is one line on stderr (no traceback), exit 2 (bad input or usage) or 1 (a failure
while working), 143 on SIGTERM, and OUTDIR keeps its complete old shot with no temporaries.

CI runs as root, where chmod-read-only folders do not fail: the file-system faults are injected
at the atomic writers (USDFACE_TEST_FAULT), and, where a private mount namespace can be made
(``unshare``), also produced for real on a 5 MB tmpfs and a read-only bind mount."""
from __future__ import annotations

import json
import os
import shutil
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import pytest

from tests.hostile import terminal_signals

from usdface.cli import main
from usdface.errors import ResourceError
from usdface.fileutil import FAULT_ENV, file_digest
from usdface.pipeline.shot_commit import KILL_ENV, LOCK_NAME, OutdirLock
from usdface.usd.shot_record import leftovers

SA = Path(__file__).resolve().parents[2] / "sample_assets"
MESH = SA / "meshes" / "makehuman_hm08_face_cm.obj"
TAKE = SA / "capture" / "JawMoCap.ma"
LAYOUT = SA / "layouts" / "makehuman_hm08_face.layout.json"
RUN = ["run", "--mesh", str(MESH), "--capture", str(TAKE), "--layout", str(LAYOUT), "--method", "euclidean", "-q"]


def _digests(folder: Path) -> dict:
    return {p.name: file_digest(p) for p in sorted(folder.iterdir()) if p.is_file()}


@pytest.fixture(scope="module")
def old_shot(tmp_path_factory):
    """A complete shot (30 frames) to copy into OUTDIR before each fault."""
    out = tmp_path_factory.mktemp("old") / "shot"
    assert main(RUN + ["--trim", "0", "30", "-o", str(out)]) == 0
    return out


def _one_line_error(err: str, command: str) -> str:
    lines = [ln for ln in err.splitlines() if ln.startswith(f"usdface {command}:")]
    assert "Traceback" not in err and len(lines) == 1, err
    return lines[0]


# -- outputs that are inputs ----------------------------------------------------------------------

def test_outputs_that_are_inputs_are_refused_before_any_work(tmp_path, capsys):
    cap = tmp_path / "cap.usdc"
    shutil.copy(SA / "capture" / "JawMoCap.usdc", cap)
    assert main(["import-mesh", str(MESH), "-o", str(tmp_path / "m.usdc"), "-q"]) == 0
    assert main(["bind", "--mesh", str(tmp_path / "m.usdc"), "--capture", str(cap), "--layout", str(LAYOUT),
                 "-o", str(tmp_path / "b.usda"), "-q"]) == 0
    os.link(cap, tmp_path / "hard.usdc")
    (tmp_path / "sym.usdc").symlink_to(cap)
    before = _digests(tmp_path)
    cases = [
        (["import-capture", str(cap), "--trim", "0", "10", "-o", str(cap)], "cap.usdc"),
        (["import-capture", str(cap), "--trim", "0", "10", "-o", str(tmp_path / "hard.usdc")], "hard link"),
        (["import-capture", str(tmp_path / "sym.usdc"), "--trim", "0", "10", "-o", str(cap)], "sym.usdc"),
        (["import-mesh", str(tmp_path / "m.usdc"), "-o", str(tmp_path / "m.usdc")], "m.usdc"),
        (["bind", "--mesh", str(tmp_path / "b.usda"), "--capture", str(cap), "--layout", str(LAYOUT), "-o",
          str(tmp_path / "b.usda")], "b.usda"),
        (["bind", "--mesh", str(tmp_path / "b.usda"), "--capture", str(cap), "--layout", str(LAYOUT), "-o",
          str(tmp_path / "m.usdc")], "composed by --mesh"),
        (["preview", str(tmp_path / "b.usda"), "-o", str(tmp_path / "b.usda")], "b.usda"),
    ]
    for argv, named in cases:
        assert main(argv) == 2, argv
        line = _one_line_error(capsys.readouterr().err, argv[0])
        assert "would overwrite the input" in line and named in line, line
    # the Python API refuses too (the same helper at each processor's entry)
    from usdface import api
    from usdface.errors import OptionError

    with pytest.raises(OptionError, match="would overwrite the input"):
        api.import_capture(cap, {"trim": (0, 10)}, output=cap)
    assert _digests(tmp_path) == before


def test_run_never_writes_over_its_inputs_in_outdir(tmp_path, capsys):
    out = tmp_path / "out"
    out.mkdir()
    assert main(["import-mesh", str(MESH), "-o", str(out / "mesh.usdc"), "-q"]) == 0
    shutil.copy(SA / "capture" / "JawMoCap.usdc", out / "capture.usdc")
    before = _digests(out)
    for mesh, capture in ((out / "mesh.usdc", TAKE), (MESH, out / "capture.usdc")):
        argv = ["run", "--mesh", str(mesh), "--capture", str(capture), "--layout", str(LAYOUT), "-o", str(out)]
        assert main(argv) == 2
        line = _one_line_error(capsys.readouterr().err, "run")
        assert f"would overwrite the input {mesh if mesh != MESH else capture}" in line, line
    assert _digests(out) == before and leftovers(out) == [] and not (out / LOCK_NAME).exists()


# -- injected faults: EACCES, EROFS, ENOSPC at the atomic writers and in the commit ---------------

@pytest.mark.parametrize("fault,cause", [
    ("ENOSPC:save:anim.usdc", "transfer step failed: cannot write {out}/anim.usdc: disk full"),
    ("EROFS:create:mesh.usdc", "import-mesh step failed: cannot write {out}/mesh.usdc: read-only file system"),
    ("EACCES:replace:binding.usda", "bind step failed: cannot write {out}/binding.usda: permission denied"),
    ("ENOSPC:save:summary.json", "shot step failed: cannot write {out}/summary.json: disk full"),
])
def test_injected_fault_in_run_keeps_the_old_shot(old_shot, tmp_path, monkeypatch, capsys, fault, cause):
    out = tmp_path / "shot"
    shutil.copytree(old_shot, out)
    before = _digests(out)
    monkeypatch.setenv(FAULT_ENV, fault)
    assert main(RUN + ["--trim", "0", "40", "-o", str(out)]) == 1
    line = _one_line_error(capsys.readouterr().err, "run")
    assert cause.format(out=out) in line, line
    assert _digests(out) == before and leftovers(out) == [] and not (out / LOCK_NAME).exists()
    assert main(["check", str(out / "shot.usda"), "-q"]) == 0


def test_failed_rename_mid_commit_is_completed_by_the_next_run(old_shot, tmp_path, monkeypatch, capsys):
    out = tmp_path / "shot"
    shutil.copytree(old_shot, out)
    monkeypatch.setenv(FAULT_ENV, "EIO:commit:anim.usdc")
    assert main(RUN + ["--trim", "0", "40", "-o", str(out)]) == 1
    assert "cannot write" in _one_line_error(capsys.readouterr().err, "run")
    assert main(["check", str(out / "shot.usda")]) == 1  # the commit was interrupted: no shot accepted
    assert "stopped while committing" in capsys.readouterr().out
    monkeypatch.delenv(FAULT_ENV)
    assert main(RUN + ["--trim", "0", "40", "-o", str(out)]) == 0  # completes it, then runs
    assert main(["check", str(out / "shot.usda"), "-q"]) == 0 and leftovers(out) == []


def test_mixed_shot_is_rejected_by_check(old_shot, tmp_path, capsys):
    out, other = tmp_path / "shot", tmp_path / "other"
    shutil.copytree(old_shot, out)
    assert main(RUN + ["--trim", "0", "40", "-o", str(other)]) == 0
    assert main(["check", str(out / "shot.usda"), "-q"]) == 0
    # what a kill between the old run's renames left: analysis.usdc from the new run, anim.usdc from the old
    shutil.copy(other / "analysis.usdc", out / "analysis.usdc")
    assert main(["check", str(out / "shot.usda")]) == 1
    assert "mixed or incomplete shot" in capsys.readouterr().out
    (out / "anim.usdc").unlink()
    assert main(["check", str(out / "shot.usda")]) == 1
    assert "anim.usdc is missing" in capsys.readouterr().out


def test_resample_refused_with_a_size_estimate(tmp_path, capsys):
    out = tmp_path / "r"
    # 1 MHz is an implausible rate (usdface.io.limits): refused before the size is even estimated
    assert main(RUN + ["--resample", "1000000", "-o", str(out)]) == 2
    line = _one_line_error(capsys.readouterr().err, "run")
    assert "--resample 1e+06 Hz from 60 Hz (1590 frames -> 26483334): 1e+06 Hz is outside the plausible" in line, line
    assert not out.exists()
    # accepted, it is refused with the memory it would need
    from usdface.capture.timing import resample
    from usdface.io.captures import read_capture

    with pytest.raises(ResourceError,
                       match=r"26,483,334 frames x 41 markers, which needs about .* of memory but") as err:
        resample(read_capture(TAKE), rate=1e6, allow={"resample"})
    # the advice quotes the README's rates (it said "capture rates are 24-1000 Hz")
    assert str(err.value).endswith("; choose a rate near the capture's 60 Hz (optical capture runs at 60-2000 Hz, "
                                   "high-speed systems to about 10 kHz, video at 24-240 fps)")


def test_second_run_into_a_locked_folder_is_refused(old_shot, tmp_path, capsys):
    out = tmp_path / "shot"
    shutil.copytree(old_shot, out)
    lock = OutdirLock(out)
    lock.acquire()
    try:
        assert main(RUN + ["--trim", "0", "40", "-o", str(out)]) == 1
    finally:
        lock.release()
    line = _one_line_error(capsys.readouterr().err, "run")
    assert f"is being written by another usdface run (pid {os.getpid()}" in line


# -- signals --------------------------------------------------------------------------------------

def _start(argv, **env) -> subprocess.Popen:
    return subprocess.Popen([sys.executable, "-m", "usdface", *argv], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, env=dict(os.environ, **env),
                            preexec_fn=terminal_signals)


@pytest.mark.parametrize("sig,code,said", [(signal.SIGTERM, 143, "stopped by SIGTERM; partial work removed"),
                                           (signal.SIGHUP, 129, "stopped by SIGHUP; partial work removed"),
                                           (signal.SIGINT, 130, "interrupted; partial work removed")])
def test_sigterm_is_handled_like_ctrl_c(old_shot, tmp_path, sig, code, said):
    out = tmp_path / "shot"
    shutil.copytree(old_shot, out)
    before = _digests(out)
    # 400 frames: the run must still be writing when the signal lands, also on a loaded machine
    # (with 40 frames it sometimes finished between two polls and exited 0)
    p = _start(RUN + ["--trim", "0", "400", "-o", str(out)])
    deadline = time.time() + 60
    while not any(x.name.startswith(".usdface-run-") for x in out.iterdir()) and time.time() < deadline:
        time.sleep(0.05)
    assert p.poll() is None, "the run ended before it could be signalled"
    p.send_signal(sig)
    _, err = p.communicate(timeout=60)
    assert p.returncode == code, err
    assert said in _one_line_error(err, "run")
    assert _digests(out) == before and leftovers(out) == [] and not (out / LOCK_NAME).exists()


def test_a_run_started_with_nohup_keeps_going_through_a_hang_up(tmp_path):
    """`nohup usdface run ...`: the hang-up the user asked to ignore stays ignored (usdface used to
    install its own SIGHUP handler over nohup's, so closing the terminal stopped the run)."""
    out = tmp_path / "shot"
    p = subprocess.Popen([sys.executable, "-m", "usdface", *RUN, "--trim", "0", "400", "-o", str(out)],
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                         preexec_fn=lambda: signal.signal(signal.SIGHUP, signal.SIG_IGN))
    deadline = time.time() + 60
    while not (out.is_dir() and any(x.name.startswith(".usdface-run-") for x in out.iterdir())) \
            and time.time() < deadline:
        time.sleep(0.05)
    assert p.poll() is None, "the run ended before it could be signalled"
    p.send_signal(signal.SIGHUP)
    _, err = p.communicate(timeout=120)
    assert p.returncode == 0 and err == "", err
    assert (out / "shot.usda").is_file() and leftovers(out) == []


def test_a_closed_pipe_ends_the_output_quietly(tmp_path):
    """`usdface info --json FILE | head -c 10`: the reader stops reading; usdface exits as the
    shell's tools do (141, SIGPIPE's code) without a traceback. The reader is gone before the first
    write (a reader closing after it would race a short output that fits the pipe's buffer)."""
    read_end, write_end = os.pipe()
    os.close(read_end)
    try:
        p = subprocess.Popen([sys.executable, "-m", "usdface", "info", "--json", str(SA / "capture" / "JawMoCap.usdc")],
                             stdout=write_end, stderr=subprocess.PIPE)
    finally:
        os.close(write_end)
    err = p.communicate(timeout=60)[1].decode()
    assert p.returncode == 141
    assert err == ""



@pytest.mark.skipif(not os.path.exists("/dev/full"), reason="needs /dev/full")
def test_a_full_standard_output_is_one_line(tmp_path):
    """`usdface info --json FILE > /dev/full` (a full disk under a redirected output): one line
    naming the standard output and the cause, exit 1; was a 14-line OSError traceback."""
    with open("/dev/full", "wb") as full:
        p = subprocess.run([sys.executable, "-m", "usdface", "info", "--json", str(SA / "capture" / "JawMoCap.usdc")],
                           stdout=full, stderr=subprocess.PIPE, timeout=60, cwd=tmp_path)
    assert p.returncode == 1
    assert p.stderr.decode() == "usdface info: error: cannot write the standard output: disk full\n"


def test_a_bug_keeps_its_traceback_under_a_line_asking_to_report_it(tmp_path):
    """An unexpected exception (a bug, not bad input or the environment) is not turned into a
    tidy line: its traceback stays, after one line saying it is a bug and asking for a report
    (issue 20: "a bug ... still shows its traceback with a line asking to report it")."""
    hook = textwrap.dedent("""
        import sys
        import usdface.console as console
        def broken(processor, args):
            raise ZeroDivisionError("a bug")
        console.run_command = broken
        sys.exit(console.main(sys.argv[1:]))
    """)
    p = subprocess.run([sys.executable, "-c", hook, "info", str(SA / "capture" / "JawMoCap.usdc")],
                       capture_output=True, text=True, timeout=60, cwd=tmp_path)
    assert p.returncode == 1
    first, rest = p.stderr.split("\n", 1)
    from usdface import __version__

    assert first == (f"usdface info: internal error (a bug in usdface {__version__}, not in your input): "
                     "ZeroDivisionError: a bug; please report it with the traceback below and the command line")
    assert rest.startswith("Traceback (most recent call last):") and rest.rstrip().endswith("ZeroDivisionError: a bug")

@pytest.mark.parametrize("sig,code,said", [(signal.SIGINT, 130, "interrupted; partial work removed"),
                                           (signal.SIGTERM, 143, "stopped by SIGTERM; partial work removed")])
def test_a_signal_inside_an_extension_import_is_still_an_interruption(tmp_path, sig, code, said):
    """A signal that lands while Python imports a C extension comes back as that module's
    ImportError (numpy's import_array prints the KeyboardInterrupt and raises "numpy._core.multiarray
    failed to import": seen once as an 'internal error' in a Ctrl-C test). The command still says
    it was interrupted, with the signal's exit code, not that usdface has a bug."""
    hook = textwrap.dedent(f"""
        import os, sys
        import usdface.console as console
        def lazy_import_hit_by_a_signal(processor, args):
            try:
                os.kill(os.getpid(), {int(sig)})
            except BaseException:
                pass  # what the extension's C init does with it
            raise ImportError("numpy._core.multiarray failed to import")
        console.run_command = lazy_import_hit_by_a_signal
        sys.exit(console.main(sys.argv[1:]))
    """)
    p = subprocess.run([sys.executable, "-c", hook, "info", str(SA / "capture" / "JawMoCap.usdc")],
                       capture_output=True, text=True, timeout=60, cwd=tmp_path, preexec_fn=terminal_signals)
    assert (p.returncode, p.stderr) == (code, f"usdface info: {said}\n")


def test_sigkill_mid_commit_then_the_next_run_repairs(old_shot, tmp_path, capsys):
    out = tmp_path / "shot"
    shutil.copytree(old_shot, out)
    p = _start(RUN + ["--trim", "0", "40", "-o", str(out)], **{KILL_ENV: "rename:anim.usdc"})
    p.communicate(timeout=120)
    assert p.returncode == -signal.SIGKILL
    assert main(["check", str(out / "shot.usda")]) == 1
    capsys.readouterr()
    assert main(RUN + ["--trim", "0", "30", "-o", str(out)]) == 0
    assert main(["check", str(out / "shot.usda"), "-q"]) == 0
    assert _digests(out).keys() == _digests(old_shot).keys() and leftovers(out) == []
    assert not (out / LOCK_NAME).exists()


# -- real file systems: a 5 MB tmpfs and a read-only bind mount, in a private mount namespace -------

def _namespace_prefix(tmp_path) -> list[str]:
    """An ``unshare`` command line that may mount (as root, or with a user namespace), or skip."""
    if shutil.which("unshare") is None:
        pytest.skip("unshare is not installed: the real-mount part is skipped (faults are injected above)")
    probe = tmp_path / "probe"
    probe.mkdir()
    for prefix in (["unshare", "-m", "--propagation", "private"],
                   ["unshare", "-r", "-m", "--propagation", "private"]):
        r = subprocess.run(prefix + ["sh", "-c", f"mount -t tmpfs -o size=1m tmpfs {probe}"], capture_output=True)
        if r.returncode == 0:
            return prefix
    pytest.skip(f"mounting is refused here ({r.stderr.decode().strip()}): the real-mount part is skipped "
                "(faults are injected above)")


_MOUNTED = """
import json, os, sys
from pathlib import Path
from usdface.cli import main
from usdface.fileutil import file_digest
from usdface.usd.shot_record import leftovers
import contextlib, io
root, run = Path(sys.argv[1]), json.loads(sys.argv[2])
def call(argv):
    err = io.StringIO()
    with contextlib.redirect_stderr(err):
        rc = main(argv)
    return rc, err.getvalue()
def digests(d):
    return {p.name: file_digest(p) for p in sorted(d.iterdir()) if p.is_file()}
res = {}
ro = root / "ro" / "shot"
before = digests(ro)
res["ro_run"] = call(run + ["--trim", "0", "40", "-o", str(ro)])
res["ro_intact"] = digests(ro) == before and leftovers(ro) == []
res["ro_import"] = call(["import-capture", run[4], "-o", str(root / "ro" / "c.usdc")])
small = root / "small" / "shot"
res["small_first"] = call(run + ["--trim", "0", "30", "-o", str(small)])
before = digests(small)
res["full_run"] = call(run + ["-o", str(small)])
res["full_intact"] = digests(small) == before and leftovers(small) == []
res["check"] = call(["check", str(small / "shot.usda"), "-q"])
manifest = root / "m.toml"
manifest.write_text(f'''[batch]
cache = false
summary = "{root / 'small' / 'batch.json'}"
[defaults]
method = "euclidean"
output = "{root / 'small' / 'b'}"
[[shots]]
mesh = "{run[2]}"
capture = "{run[4]}"
layout = "{run[6]}"
''')
res["batch"] = call(["batch", str(manifest), "--workers", "0", "-q"])
res["batch_error"] = json.loads((root / "small" / "batch.json").read_text())["shots"][0]["error"]
res["small_left"] = sorted(p.name for p in (root / "small").iterdir())
print(json.dumps(res))
"""


def test_real_full_disk_and_read_only_mount(old_shot, tmp_path):
    prefix = _namespace_prefix(tmp_path)
    for d in ("ro", "small"):
        (tmp_path / d).mkdir()
    shutil.copytree(old_shot, tmp_path / "ro" / "shot")
    script = tmp_path / "mounted.py"
    script.write_text(_MOUNTED)
    run = RUN[:9] + ["-q"]
    shell = textwrap.dedent(f"""
        set -e
        mount --bind {tmp_path / 'ro'} {tmp_path / 'ro'}
        mount -o remount,bind,ro {tmp_path / 'ro'}
        mount -t tmpfs -o size=5m tmpfs {tmp_path / 'small'}
        exec {sys.executable} {script} {tmp_path} '{json.dumps(run)}'
    """)
    p = subprocess.run(prefix + ["sh", "-c", shell], capture_output=True, text=True, timeout=600)
    assert p.returncode == 0, p.stderr[-3000:]
    res = json.loads(p.stdout.strip().splitlines()[-1])
    rc, err = res["ro_run"]
    assert rc == 1 and "read-only file system" in _one_line_error(err, "run") and res["ro_intact"], err
    rc, err = res["ro_import"]
    assert rc == 1 and "read-only file system" in _one_line_error(err, "import-capture"), err
    assert res["small_first"][0] == 0, res["small_first"]
    rc, err = res["full_run"]  # anim.usdc of the whole take is 39 MB: the 5 MB disk fills up
    line = _one_line_error(err, "run")
    assert rc == 1 and "cannot write" in line and "anim.usdc: disk full" in line, err
    assert res["full_intact"] and res["check"][0] == 0
    assert res["batch"][0] == 1
    assert "disk full" in res["batch_error"] and "\n" not in res["batch_error"], res["batch_error"]
    assert res["small_left"] == ["batch.json", "shot"]


def test_a_symbolic_link_loop_as_outdir_is_named(tmp_path, capsys):
    loop = tmp_path / "loop"
    loop.symlink_to(loop)
    assert main(RUN + ["-o", str(loop)]) == 2
    line = _one_line_error(capsys.readouterr().err, "run")
    assert f"-o {loop}: a symbolic link that loops or points nowhere" in line
