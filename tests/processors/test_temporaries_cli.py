"""Every writer's temporaries follow the one scheme of usdface.fileutil (issue 20, items 1 and 9):
SIGINT, SIGTERM and SIGHUP leave none (exit 130/143/129, one line, the old output intact); after
SIGKILL the next command writing that output removes them.

The signal is sent by the process to itself at the moment a finished temporary is about to be
renamed over its output (``os.replace`` wrapped before usdface is imported), so the test hits the
writer's temporary every time, whatever the machine's load. Commands writing several files
(track, detect) commit them together: a stop signal waits for the renames, so their outputs are
the old ones or the new ones, never a mix, and no temporary is left either way.
"""
from __future__ import annotations

import os
import signal
import subprocess
import sys
from pathlib import Path

import pytest

from tests.hostile import terminal_signals

from usdface.cli import main
from usdface.fileutil import file_digest

SA = Path(__file__).resolve().parents[2] / "sample_assets"
DATA = Path(__file__).resolve().parents[3] / "shared" / "data"
MESH = SA / "meshes" / "makehuman_hm08_face_cm.obj"
TAKE = SA / "capture" / "JawMoCap.ma"
LAYOUT = SA / "layouts" / "makehuman_hm08_face.layout.json"

# signals itself when a temporary is renamed over the output named argv[2], then runs the command
# (argv[3:]) or, with "--python", the code in argv[3]
_HOOK = r"""
import os, signal, sys, time
from pathlib import Path
sig, name = int(sys.argv[1]), sys.argv[2]
real, fired = os.replace, []
def replace(src, dst, *args, **kwargs):
    if not fired and Path(os.fsdecode(dst)).name == name and Path(os.fsdecode(src)).name.startswith("."):
        fired.append(1)
        os.kill(os.getpid(), sig)
        time.sleep(0.5)  # the handler raises here (unless a commit defers it); SIGKILL never returns
    return real(src, dst, *args, **kwargs)
os.replace = replace
if sys.argv[3] == "--python":
    exec(sys.argv[4])
    sys.exit(0)
from usdface.cli import main
sys.exit(main(sys.argv[3:]))
"""

STOPPED = {signal.SIGTERM: "stopped by SIGTERM; partial work removed", signal.SIGHUP: "stopped by SIGHUP; partial work removed",
           signal.SIGINT: "interrupted; partial work removed"}


def _hooked(sig, name: str, argv, cwd) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-c", _HOOK, str(int(sig)), name, *map(os.fsdecode, argv)], cwd=cwd,
                          capture_output=True, text=True, timeout=600,
                          preexec_fn=terminal_signals)


def _plain(argv, cwd) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "usdface", *map(str, argv)], cwd=cwd, capture_output=True, text=True,
                          timeout=600)


def _hidden(folder: Path) -> list[str]:
    return sorted(p.name for p in folder.iterdir() if p.name.startswith("."))


def _state(folder: Path) -> dict:
    return {p.name: file_digest(p) if p.is_file() else sorted(q.name for q in p.iterdir())
            for p in sorted(folder.iterdir())}


@pytest.fixture(scope="module")
def shot(tmp_path_factory):
    out = tmp_path_factory.mktemp("shot") / "shot"
    assert main(["run", "--mesh", str(MESH), "--capture", str(TAKE), "--layout", str(LAYOUT), "--method", "euclidean",
                 "--trim", "0", "12", "-o", str(out), "-q"]) == 0
    return out


def _commands(shot: Path) -> dict:
    """command name -> (argv writing into the current folder, name of the output the hook waits for)."""
    seeds, video = SA / "video" / "animface_dots.seeds.json", SA / "video" / "animface_dots.mp4"
    return {
        "playblast": (["playblast", shot / "shot.usda", "-o", "m.mp4", "--size", "64x48", "--workers", "1"], "m.mp4"),
        "report media": (["report", shot, "-o", "r.html", "--playblast-size", "64x48"], "r_media"),
        "report page": (["report", shot, "-o", "r.html", "--no-playblast"], "r.html"),
        "track csv": (["track", video, "--seeds", seeds, "-o", "t.usdc", "--csv", "t.csv"], "t.csv"),
        "track preview": (["track", video, "--seeds", seeds, "-o", "t.usdc", "--preview", "t.png"], "t.png"),
        "detect preview": (["detect", DATA / "images" / "astronaut.png", "-o", "f.json", "--preview", "p.png"], "p.png"),
        "detect json": (["detect", DATA / "images" / "astronaut.png", "-o", "f.json"], "f.json"),
        "import-capture": (["import-capture", TAKE, "--trim", "0", "20", "-o", "c.usdc"], "c.usdc"),
    }


CASES = ["playblast", "report media", "report page", "track csv", "track preview", "detect preview", "detect json",
         "import-capture"]


@pytest.mark.parametrize("case", CASES)
def test_stop_signals_leave_no_temporary_and_keep_the_old_output(shot, tmp_path, case):
    if case.startswith("detect") and not DATA.is_dir():
        pytest.skip(f"{DATA} not present")
    argv, name = _commands(shot)[case]
    first = _plain(argv, tmp_path)  # the old output, which every stopped run must leave as it was
    assert first.returncode == 0, first.stderr
    before = _state(tmp_path)
    for sig, text in STOPPED.items():
        p = _hooked(sig, name, argv, tmp_path)
        lines = [ln for ln in p.stderr.splitlines() if ln.strip() and not ln.startswith("usdface: compil")]
        assert p.returncode == 128 + sig, (sig, p.stderr)
        assert lines == [f"usdface {argv[0]}: {text}"], p.stderr
        assert _hidden(tmp_path) == [] and _state(tmp_path) == before, (sig, _hidden(tmp_path))


@pytest.mark.parametrize("case", CASES)
def test_after_sigkill_the_next_writer_of_the_output_removes_the_temporaries(shot, tmp_path, case):
    if case.startswith("detect") and not DATA.is_dir():
        pytest.skip(f"{DATA} not present")
    argv, name = _commands(shot)[case]
    p = _hooked(signal.SIGKILL, name, argv, tmp_path)
    assert p.returncode == -signal.SIGKILL, p.stderr
    assert any(".tmp-" in n for n in _hidden(tmp_path)), _hidden(tmp_path)  # what the killed writer left
    again = _plain(argv, tmp_path)
    assert again.returncode == 0, again.stderr
    assert _hidden(tmp_path) == []
    assert (tmp_path / name).exists()


_API_WRITES = {
    "c3d": "from usdface.io.captures import read_capture, write_capture\n"
           "write_capture('take.c3d', read_capture({take!r}))",
    "C3D": "from usdface.io.captures import read_capture, write_capture\n"
           "write_capture('take.C3D', read_capture({take!r}))",
    "trc": "from usdface.io.captures import read_capture, write_capture\n"
           "write_capture('take.trc', read_capture({take!r}))",
    "csv": "from usdface.io.captures import read_capture, write_capture\n"
           "write_capture('take.csv', read_capture({take!r}))",
    "pfm": "import numpy as np\nfrom usdface.io.images import write_float_map\n"
           "write_float_map('d.pfm', np.ones((8, 8)))",
    "npy": "import numpy as np\nfrom usdface.io.images import write_float_map\n"
           "write_float_map('d.npy', np.ones((8, 8)))",
    "timeline": "from usdface.tissue.expressions import Timeline, write_timeline\n"
                "write_timeline('t.json', Timeline(rate=24, keys={{'a': [[0, 0.0], [10, 1.0]]}}))",
}
_API_OUTPUT = {"c3d": "take.c3d", "C3D": "take.C3D", "trc": "take.trc", "csv": "take.csv", "pfm": "d.pfm",
               "npy": "d.npy", "timeline": "t.json"}


@pytest.mark.parametrize("kind", sorted(_API_WRITES))
def test_library_writers_follow_the_scheme(tmp_path, kind):
    """The writers the API offers (captures, float maps, timelines): after SIGKILL mid-write the next
    write of that output removes the temporary; an interruption removes it at once."""
    code, name = _API_WRITES[kind].format(take=str(TAKE)), _API_OUTPUT[kind]
    killed = subprocess.run([sys.executable, "-c", _HOOK, str(int(signal.SIGKILL)), name, "--python", code],
                            cwd=tmp_path, capture_output=True, text=True, timeout=300)
    assert killed.returncode == -signal.SIGKILL, killed.stderr
    assert any(".tmp-" in n for n in _hidden(tmp_path)), _hidden(tmp_path)
    stopped = subprocess.run([sys.executable, "-c", _HOOK, str(int(signal.SIGINT)), name, "--python", code],
                             cwd=tmp_path, capture_output=True, text=True, timeout=300,
                             preexec_fn=terminal_signals)
    assert stopped.returncode != 0 and "KeyboardInterrupt" in stopped.stderr
    assert _hidden(tmp_path) == []  # its own temporary removed on the way out, the dead one's before
    again = subprocess.run([sys.executable, "-c", code], cwd=tmp_path, capture_output=True, text=True, timeout=300)
    assert again.returncode == 0, again.stderr
    assert _hidden(tmp_path) == [] and sorted(p.name for p in tmp_path.iterdir()) == [name]
