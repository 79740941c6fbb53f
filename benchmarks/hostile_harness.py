"""The machinery of benchmarks/hostile_commands.py: run a usdface command line from a source tree
in a fresh folder, signal it as its senders do, and record what it left.

Each attempt runs the real command line (``python -m usdface``, PYTHONPATH = the tree under test)
in a fresh folder and records: exit code, stderr lines, traceback, the sha256 of every input before
and after, the temporaries left (hidden entries a command made: ``.NAME.tmp-...``, ``.usdface-run-*``,
``.usdface-lock``, mkstemp names), and whether that is handled (the expected exit code and number of
stderr lines, no traceback, inputs unchanged, nothing left, plus the attempt's own condition).
A first run's compile notices (``usdface: compiling ... (first run only)``, ``usdface: compiled N
kernels ...``, which issue 20 asks for) are not counted as stderr lines: each tree under test starts
with an empty kernel cache.

Signals are sent as their senders do: SIGINT and SIGHUP to the command's whole process group (a
terminal's Ctrl-C, a closed terminal), SIGTERM to its pid (a farm scheduler). A signal lands either
while the command works (its run folder or temporary exists) or, for quick writers, at the moment
its finished temporary is renamed over the output (``os.replace`` wrapped before usdface starts).
"""
from __future__ import annotations

import hashlib
import os
import re
import shutil
import signal
import subprocess
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable


REPO = Path(__file__).resolve().parents[1]
SA = REPO / "sample_assets"
DATA = REPO.parent / "shared" / "data"
MESH_OBJ, MESH_USD = SA / "meshes" / "makehuman_hm08_face_cm.obj", SA / "meshes" / "makehuman_hm08_face_cm.usdc"
MP_OBJ = SA / "meshes" / "mediapipe_canonical_face_model_holes.obj"
TAKE_MA, TAKE_USD = SA / "capture" / "JawMoCap.ma", SA / "capture" / "JawMoCap.usdc"
LAYOUT, MP_LAYOUT = SA / "layouts" / "makehuman_hm08_face.layout.json", SA / "layouts" / "mediapipe_face_holes.layout.json"
SEEDS, MOVIE = SA / "video" / "animface_dots.seeds.json", SA / "video" / "animface_dots.mp4"
PHOTO = DATA / "images" / "astronaut.png"
RUN = ["run", "--mesh", MESH_OBJ, "--capture", TAKE_MA, "--layout", LAYOUT, "--method", "euclidean"]
MEMORY_LIMIT = 6 * 1024**3
#: a first run's compile notices (not counted as stderr lines)
COMPILE_NOTICE = re.compile(r"^usdface: (compiling .* \(first run only\)|compiled \d+ kernels? )")

# signals itself when a temporary is renamed over the output named argv[2], then runs argv[3:]
HOOK = r"""
import os, signal, sys, time
from pathlib import Path
sig, name = int(sys.argv[1]), sys.argv[2]
real, fired = os.replace, []
def replace(src, dst, *args, **kwargs):
    if not fired and Path(os.fsdecode(dst)).name == name and Path(os.fsdecode(src)).name.startswith("."):
        fired.append(1)
        os.kill(os.getpid(), sig)
        time.sleep(0.5)
    return real(src, dst, *args, **kwargs)
os.replace = replace
from usdface.cli import main
sys.exit(main(sys.argv[3:]))
"""


@dataclass
class Outcome:
    rc: int | None
    err: str
    same: bool = True
    left: list = field(default_factory=list)
    ok: bool = True          # the attempt's own condition
    note: str = ""


@dataclass
class Attempt:
    klass: str
    what: str
    fn: Callable
    code: object = 2         # an exit code, or a tuple of acceptable ones
    lines: int = 1


class Ctx:
    """The tree under test, a scratch folder, and the command line."""

    def __init__(self, code: Path, scratch: Path):
        self.code, self.scratch = code, scratch
        self.env = dict(os.environ, PYTHONPATH=str(code), OMP_NUM_THREADS="1", NUMBA_CACHE_DIR=str(scratch / "numba"))
        self._shot = None

    def argv(self, args) -> list:
        return [a if isinstance(a, bytes) else os.fsencode(str(a)) for a in args]

    def run(self, *args, cwd, timeout=300, stdout=subprocess.DEVNULL):
        try:
            p = subprocess.run([sys.executable, "-m", "usdface", *self.argv(args)], cwd=cwd, env=self.env,
                               stdout=stdout, stderr=subprocess.PIPE, timeout=timeout, preexec_fn=_limit)
            return p.returncode, p.stderr.decode("utf-8", "backslashreplace"), p.stdout
        except subprocess.TimeoutExpired as exc:
            return None, (exc.stderr or b"").decode("utf-8", "backslashreplace"), b""

    def start(self, *args, cwd, prefix=None) -> subprocess.Popen:
        """The command in a new session (its own process group, as a terminal's job), SIGINT and
        SIGHUP default (a harness started in the background or under nohup passes them ignored, and
        usdface keeps an inherited ignore)."""
        def setup():
            _limit()
            signal.signal(signal.SIGINT, signal.SIG_DFL)
            signal.signal(signal.SIGHUP, signal.SIG_DFL)
        argv = (prefix or [sys.executable, "-m", "usdface"]) + self.argv(args)
        return subprocess.Popen(argv, cwd=cwd, env=self.env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                                start_new_session=True, preexec_fn=setup)

    def hooked(self, sig, name, *args, cwd, timeout=300):
        p = self.start(*args, cwd=cwd, prefix=[sys.executable, "-c", HOOK, str(int(sig)), name])
        return finish(p, timeout)

    def folder(self, name: str) -> Path:
        d = self.scratch / name
        shutil.rmtree(d, ignore_errors=True)
        d.mkdir(parents=True)
        return d

    def shot(self) -> Path:
        """A 30-frame shot of the main job, made once (playblast and report attempts copy it)."""
        if self._shot is None:
            out = self.scratch / "shot30"
            shutil.rmtree(out, ignore_errors=True)
            rc, err, _ = self.run(*RUN, "--trim", 0, 30, "-o", out, "-q", cwd=self.scratch)
            if rc != 0:
                raise RuntimeError(f"the shot these attempts need failed: {err.strip()[-300:]}")
            self._shot = out
        return self._shot


def _limit():
    import resource

    resource.setrlimit(resource.RLIMIT_AS, (MEMORY_LIMIT, MEMORY_LIMIT))


def finish(p: subprocess.Popen, timeout: float):
    try:
        _, err = p.communicate(timeout=timeout)
    except subprocess.TimeoutExpired:
        os.killpg(p.pid, signal.SIGKILL)
        _, err = p.communicate()
        return None, err.decode("utf-8", "backslashreplace")
    return p.returncode, err.decode("utf-8", "backslashreplace")


def wait_for(pattern_fn, p: subprocess.Popen, timeout: float = 180) -> bool:
    t0 = time.time()
    while time.time() - t0 < timeout:
        if pattern_fn():
            return True
        if p.poll() is not None:
            return False
        time.sleep(0.05)
    return False


def signal_group(p: subprocess.Popen, sig) -> None:
    """As a terminal does (Ctrl-C, hang-up): the whole process group; SIGTERM/SIGKILL: the pid."""
    try:
        if sig in (signal.SIGINT, signal.SIGHUP):
            os.killpg(p.pid, sig)
        else:
            p.send_signal(sig)
    except ProcessLookupError:
        pass


def sha(path) -> str:
    p = Path(os.fsdecode(path))
    return hashlib.sha256(p.read_bytes()).hexdigest() if p.is_file() else "-"


def digests(paths) -> dict:
    return {os.fsdecode(p): sha(p) for p in paths}


def temporaries(*folders) -> list[str]:
    """Hidden entries a command leaves (two levels deep; the batch cache itself is not one, its
    unfinished entries are)."""
    found = []
    for folder in folders:
        for root, dirs, files in os.walk(folder):
            depth = Path(root).relative_to(folder).parts
            if len(depth) > 2:
                continue
            for name in dirs + files:
                rel = str(Path(root, name).relative_to(folder))
                if name == ".usdface-cache" or name == "numba":
                    continue
                if name.startswith(".") or ".tmp-" in name or name.startswith(".trash-"):
                    found.append(rel)
            dirs[:] = [d for d in dirs if not d.startswith(".usdface-run-")]
    return sorted(found)


def _fifo(path: Path) -> Path:
    os.mkfifo(path)
    return path


def run_one(c: Ctx, attempt: Attempt, index: int) -> dict:
    d = c.folder(f"c{index:02d}")
    t0 = time.perf_counter()
    try:
        o = attempt.fn(c, d)
    except Exception as exc:  # noqa: BLE001 - the attempt itself broke: report it
        o = Outcome(None, "", ok=False, note=f"attempt failed: {type(exc).__name__}: {str(exc)[:100]}")
    seconds = time.perf_counter() - t0
    lines = [ln for ln in o.err.splitlines() if ln.strip() and not COMPILE_NOTICE.match(ln)]
    tb = "Traceback" in o.err
    codes = attempt.code if isinstance(attempt.code, tuple) else (attempt.code,)
    ok = o.rc in codes and len(lines) == attempt.lines and not tb and o.same and not o.left and o.ok
    first = next((ln for ln in lines if "error" in ln.lower() or "stopped" in ln or "interrupted" in ln
                  or "warning" in ln.lower()), lines[-1] if lines else "")
    return {"rc": o.rc, "lines": len(lines), "traceback": tb, "same": o.same, "left": o.left, "ok": ok,
            "first": first if len(first) < 150 else first[:147] + "...", "note": o.note, "seconds": seconds}
