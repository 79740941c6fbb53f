"""usdface.fileutil: outputs are never inputs, owners of temporaries, atomic writes under injected
faults (EACCES, EROFS, ENOSPC at every point), one line for every failure."""
from __future__ import annotations

import errno
import os
import subprocess
import sys
import time
from pathlib import Path

import pytest

from usdface.errors import OptionError, WriteError
from usdface.fileutil import (FAULT_ENV, HOST_TAG, atomic_write, describe_exception, failure_cause, owner_is_dead,
                              process_alive, refuse_overwriting_inputs, same_file_problems, temporary_owner,
                              temporary_path)


def _dead_pid() -> int:
    p = subprocess.Popen([sys.executable, "-c", "pass"])
    p.wait()
    return p.pid


# -- outputs are never inputs ---------------------------------------------------------------------

def test_same_path_dotdot_symlink_and_hard_link_are_one_file(tmp_path):
    src = tmp_path / "cap.usdc"
    src.write_bytes(b"take")
    (tmp_path / "x").mkdir()
    inputs = {"input": src}
    assert same_file_problems({"-o": src}, inputs)                      # the same name
    assert same_file_problems({"-o": tmp_path / "x" / ".." / "cap.usdc"}, inputs)  # x/../cap.usdc
    (tmp_path / "link.usdc").symlink_to(src)
    msg = same_file_problems({"-o": tmp_path / "link.usdc"}, inputs)    # a symbolic link to the input
    assert msg and "cap.usdc" in msg[0] and "link.usdc" in msg[0]
    os.link(src, tmp_path / "hard.usdc")
    msg = same_file_problems({"-o": tmp_path / "hard.usdc"}, inputs)    # a hard link: same inode
    assert msg and "hard link" in msg[0]
    (tmp_path / "dirlink").symlink_to(tmp_path, target_is_directory=True)
    assert same_file_problems({"-o": tmp_path / "dirlink" / "cap.usdc"}, inputs)  # through a linked folder
    assert same_file_problems({"-o": tmp_path / "new.usdc"}, inputs) == []        # a new file is fine
    assert same_file_problems({"-o": tmp_path / "x" / "cap.usdc"}, inputs) == []  # same name, other folder
    with pytest.raises(OptionError, match=r"-o .*cap\.usdc would overwrite the input .*cap\.usdc \(input\)"):
        refuse_overwriting_inputs({"-o": src}, inputs)


def test_composed_files_of_a_usd_input_are_inputs_too(tmp_path):
    from pxr import Sdf

    from usdface.usd.layers import check_output_path, composed_files

    Sdf.Layer.CreateNew(str(tmp_path / "mesh.usda")).Save()
    top = Sdf.Layer.CreateNew(str(tmp_path / "binding.usda"))
    top.subLayerPaths.append("./mesh.usda")
    top.Save()
    assert composed_files(tmp_path / "binding.usda") == [str((tmp_path / "mesh.usda").resolve())]
    with pytest.raises(OptionError, match=r"would overwrite the input .*mesh\.usda \(composed by --mesh"):
        check_output_path(tmp_path / "mesh.usda", inputs={"--mesh": tmp_path / "binding.usda"})


# -- temporaries name their owner -----------------------------------------------------------------

def test_temporary_names_carry_pid_and_host():
    t = temporary_path("/x/anim.usdc")
    assert t.suffix == ".usdc" and t.name.startswith(".anim.tmp-")
    assert temporary_owner(t.name) == (os.getpid(), HOST_TAG)
    assert temporary_owner(".anim.tmp-123-ab12cd34.usdc") == (123, None)          # before host tags
    assert temporary_owner(".usdface-run-77@farm_1-0a1b2c3d") == (77, "farm_1")
    assert temporary_owner(".usdface-run-x8q2m1") is None                          # no owner in the name


def test_owner_is_dead_only_when_known():
    now = time.time()
    dead = _dead_pid()
    assert not process_alive(dead)
    assert owner_is_dead(f".a.tmp-{dead}@{HOST_TAG}-00.usdc", now) is True
    assert owner_is_dead(f".a.tmp-{os.getpid()}@{HOST_TAG}-00.usdc", now) is False
    assert owner_is_dead(f".a.tmp-{dead}@another_host-00.usdc", now) is None        # cannot ask another host
    assert owner_is_dead(f".a.tmp-{dead}-00.usdc", now) is None                     # no host in the name
    # a live pid that started after the temporary was written is a reused pid: the owner is dead
    assert owner_is_dead(f".a.tmp-1@{HOST_TAG}-00.usdc", 0.0) is True                # pid 1 started after 1970
    assert owner_is_dead(f".a.tmp-1@{HOST_TAG}-00.usdc", now) is False


# -- atomic writes under injected faults ----------------------------------------------------------

@pytest.mark.parametrize("code,cause", [("EACCES", "permission denied"), ("EROFS", "read-only file system"),
                                        ("ENOSPC", "disk full")])
@pytest.mark.parametrize("point", ["create", "save", "replace"])
def test_atomic_write_fault_leaves_old_file_and_no_temporary(tmp_path, monkeypatch, code, cause, point):
    out = tmp_path / "summary.json"
    out.write_text("old\n")
    monkeypatch.setenv(FAULT_ENV, f"{code}:{point}:summary.json")
    with pytest.raises(WriteError) as info:
        with atomic_write(out) as f:
            f.write("new\n")
    assert str(info.value).startswith(f"cannot write {out}: {cause}")
    assert out.read_text() == "old\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["summary.json"]
    monkeypatch.setenv(FAULT_ENV, f"{code}:{point}:other.json")  # the hook matches names
    with atomic_write(out) as f:
        f.write("new\n")
    assert out.read_text() == "new\n"


def test_failure_cause_and_one_line_descriptions(tmp_path):
    assert failure_cause(tmp_path / "a", OSError(errno.ENOSPC, "No space left on device")).startswith("disk full (")
    assert failure_cause(tmp_path / "a", OSError(errno.EROFS, "x")) == "read-only file system"
    assert failure_cause(tmp_path / "a", OSError(errno.EACCES, "x")) == "permission denied"
    text = describe_exception(PermissionError(errno.EACCES, "Permission denied", "/data/take.c3d"))
    assert text == "/data/take.c3d: permission denied"
    assert describe_exception(MemoryError("Unable to allocate 92.8 GiB for an array")).startswith(
        "out of memory: Unable to allocate 92.8 GiB")
    from pxr import Sdf

    with pytest.raises(Exception) as info:  # a real Tf.ErrorException: long C++ text, no errno
        Sdf.Layer.CreateNew("/proc/a.usda")
    line = describe_exception(info.value)
    assert line.startswith("USD error: ") and "\n" not in line and "pxrInternal" not in line


# -- temporaries: one naming scheme, short enough, tidied by the next writer of the output ----------

def _dead_pid() -> int:
    import subprocess
    import sys

    p = subprocess.Popen([sys.executable, "-c", "pass"])
    p.wait()
    return p.pid


def test_an_output_name_of_250_bytes_is_written(tmp_path, capsys):
    """A legal 250-byte output name: the temporary beside it must fit in 255 bytes too (issue 20,
    case 10: 'File name too long' about the temporary's name)."""
    from usdface.console import main

    sa = Path(__file__).resolve().parents[1] / "sample_assets"
    name = "m" * 245 + ".usdc"
    assert len(name.encode()) == 250
    assert main(["import-mesh", str(sa / "meshes" / "makehuman_hm08_face_cm.obj"), "-o", str(tmp_path / name),
                 "-q"]) == 0, capsys.readouterr().err
    assert (tmp_path / name).is_file() and [p.name for p in tmp_path.iterdir()] == [name]
    wide = "é" * 122 + ".json"  # 249 bytes of two-byte characters
    with atomic_write(tmp_path / wide) as f:
        f.write("{}\n")
    assert (tmp_path / wide).read_text() == "{}\n"


def test_the_next_writer_of_an_output_removes_what_a_killed_one_left(tmp_path):
    """After a SIGKILL the temporary stays (nothing runs); the next command writing that output
    removes it. A live writer's temporary and other outputs' temporaries stay."""
    from usdface.fileutil import HOST_TAG, temporary_path

    dead = _dead_pid()
    left = tmp_path / f".cap.tmp-{dead}@{HOST_TAG}-0badcafe.usdc"
    live = tmp_path / f".cap.tmp-{os.getpid()}@{HOST_TAG}-00c0ffee.usdc"
    other = tmp_path / f".other.tmp-{dead}@{HOST_TAG}-0badcafe.usdc"
    for p in (left, live, other):
        p.write_text("partial")
    with atomic_write(tmp_path / "cap.usdc") as f:
        f.write("whole")
    assert not left.exists() and live.exists() and other.exists()
    assert (tmp_path / "cap.usdc").read_text() == "whole"
    assert temporary_path(tmp_path / "other.usdc").name.startswith(".other.tmp-") and not other.exists()


def test_dead_writers_leftovers_of_every_kind_are_removed(tmp_path):
    """What a killed writer can leave of ``anim.usdc``: its temporary, the temporary USD saves that
    one through (``<stem>.XXXXXX``), a writer-chosen suffix (ezc3d's ``.c3d`` for ``take.C3D``) and a
    temporary folder (a report's media); all removed by the next writer, live ones kept."""
    from usdface.fileutil import HOST_TAG, atomic_path, remove_dead_temporaries, temporaries_of

    dead = _dead_pid()
    stem = f".anim.tmp-{dead}@{HOST_TAG}-0badcafe"
    files = [f"{stem}.usdc", f"{stem}.9pgJv5", f".take.tmp-{dead}@{HOST_TAG}-0badcafe.c3d"]
    for name in files:
        (tmp_path / name).write_text("partial")
    folder = tmp_path / f".r_media.tmp-{dead}@{HOST_TAG}-0badcafe"
    (folder / "sub").mkdir(parents=True)
    (folder / "sub" / "shot.mp4").write_bytes(b"x")
    live = tmp_path / f".anim.tmp-{os.getpid()}@{HOST_TAG}-00c0ffee.9pgJv5"
    live.write_text("being written")
    (tmp_path / "link").symlink_to(tmp_path)
    (tmp_path / f".anim.tmp-{dead}@{HOST_TAG}-0badcafe.usda").symlink_to(tmp_path / "link")  # never followed
    assert {p.name for p in temporaries_of(tmp_path / "anim.usdc")} == {files[0], files[1], live.name}
    assert {p.name for p in remove_dead_temporaries(tmp_path / "anim.usdc")} == {files[0], files[1]}
    assert live.exists()
    with atomic_path(tmp_path / "take.C3D", suffix=".c3d") as tmp:
        assert tmp.name.endswith(".c3d") and tmp.name.startswith(".take.tmp-")
        tmp.write_text("c3d")
    assert (tmp_path / "take.C3D").read_text() == "c3d" and not (tmp_path / files[2]).exists()
    assert remove_dead_temporaries(tmp_path / "r_media") == [folder] and not folder.exists()
    assert (tmp_path / "link").is_symlink()


def test_atomic_path_keeps_the_old_file_on_a_failure_or_an_interruption(tmp_path):
    from usdface.fileutil import atomic_path

    out = tmp_path / "d.npy"
    out.write_text("old")
    for exc in (ValueError("encoder"), KeyboardInterrupt()):
        with pytest.raises(type(exc)):
            with atomic_path(out) as tmp:
                tmp.write_text("half")
                raise exc
        assert out.read_text() == "old" and sorted(p.name for p in tmp_path.iterdir()) == ["d.npy"]
    with pytest.raises(WriteError, match=r"cannot write .*d\.npy: no such file or folder"):
        with atomic_path(out):
            pass  # the writer wrote nothing
    with atomic_path(out) as tmp:
        tmp.write_text("new")
    assert out.read_text() == "new" and oct(out.stat().st_mode & 0o777) != "0o600"


def test_staged_outputs_commit_is_not_stopped_half_way(tmp_path):
    """SIGTERM arriving during StagedOutputs.commit waits for the renames, then stops the process."""
    import signal
    import subprocess
    import sys

    code = (
        "import os, signal, sys\n"
        "from usdface.errors import Interrupted\n"
        "from usdface.fileutil import StagedOutputs\n"
        "def stop(signum, frame): raise Interrupted(signum)\n"
        "signal.signal(signal.SIGTERM, stop)\n"
        "real = os.replace\n"
        "def replace(a, b):\n"
        "    real(a, b)\n"
        "    os.kill(os.getpid(), signal.SIGTERM)   # after the first of the two renames\n"
        "os.replace = replace\n"
        "try:\n"
        "    with StagedOutputs() as s:\n"
        "        s.path('a.txt').write_text('new'); s.path('b.txt').write_text('new'); s.commit()\n"
        "except Interrupted as e:\n"
        "    sys.exit(e.exit_code)\n")
    for name in ("a.txt", "b.txt"):
        (tmp_path / name).write_text("old")
    p = subprocess.run([sys.executable, "-c", code], cwd=tmp_path, capture_output=True, text=True, timeout=60)
    assert p.returncode == 128 + signal.SIGTERM, p.stderr
    assert [(q.name, q.read_text()) for q in sorted(tmp_path.iterdir())] == [("a.txt", "new"), ("b.txt", "new")]
