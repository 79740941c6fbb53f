"""Hostile attempts replayed against a usdface source tree, one markdown table per section:

- ``readers``: issue 20's hostile files to every reader (benchmarks/hostile_readers.py);
- ``commands``: issue 20's attempts on commands (outputs that are inputs, layers of another mesh,
  closed and full standard output, SIGINT/SIGTERM/SIGHUP/SIGKILL to every writer and to batch,
  250-byte names, misleading messages, hostile manifests/seeds/timelines; benchmarks/hostile_commands.py);
- ``issue12``: the attempts of issue 12 (items 1-4, 8): outputs that overwrite inputs, partial or
  mixed results, batch paths, faults that used to print tracebacks.

Every row: exit code, stderr lines, traceback, inputs' sha256 unchanged, temporaries left, handled.

    python benchmarks/fault_attempts.py                         # this tree, every section
    python benchmarks/fault_attempts.py --tree /tmp/base        # another checkout (the baseline:
                                                                #   git worktree add /tmp/base 9e2e68a)
    python benchmarks/fault_attempts.py --section commands      # one section

Each attempt runs the real command line (``python -m usdface``, PYTHONPATH = the tree) in a
scratch folder and prints one table row: exit code, whether a traceback reached the user, what
happened to the data, and whether that is handled (one clear line, the right exit code, inputs
and the previous shot intact, no temporaries left after the next run). Full disks and read-only
folders are real (a 5 MB tmpfs and a read-only bind mount in a private mount namespace, made
with ``unshare``; skipped where mounting is refused); permission faults run as user nobody
(``setpriv``). Needs root for those two parts.
"""
from __future__ import annotations

import argparse
import hashlib
import http.server
import json
import os
import shutil
import signal
import socket
import subprocess
import sys
import threading
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
SA = REPO / "sample_assets"
MESH, TAKE = SA / "meshes" / "makehuman_hm08_face_cm.obj", SA / "capture" / "JawMoCap.ma"
LAYOUT = SA / "layouts" / "makehuman_hm08_face.layout.json"
RUN = ["run", "--mesh", str(MESH), "--capture", str(TAKE), "--layout", str(LAYOUT), "--method", "euclidean"]


class Ctx:
    def __init__(self, code: Path, scratch: Path):
        self.code, self.scratch = code, scratch
        self.env = dict(os.environ, PYTHONPATH=str(code), OMP_NUM_THREADS="1", NUMBA_CACHE_DIR=str(scratch / "numba"))

    def cmd(self, *args) -> list[str]:
        return [sys.executable, "-m", "usdface", *map(str, args)]

    def usdface(self, *args, timeout=600, env=None, cwd=None):
        t0 = time.perf_counter()
        try:
            p = subprocess.run(self.cmd(*args), capture_output=True, text=True, timeout=timeout,
                               env=env or self.env, cwd=cwd or self.scratch)
            rc, out, err = p.returncode, p.stdout, p.stderr
        except subprocess.TimeoutExpired as exc:
            rc, out, err = None, exc.stdout or "", (exc.stderr or b"").decode() if isinstance(exc.stderr, bytes) else \
                (exc.stderr or "")
        return rc, out, err, time.perf_counter() - t0

    def folder(self, name) -> Path:
        d = self.scratch / name
        shutil.rmtree(d, ignore_errors=True)
        d.mkdir(parents=True)
        return d

    def shot(self, out: Path, frames=30):
        rc, _, err, _ = self.usdface(*RUN, "--trim", "0", frames, "-o", out, "-q")
        assert rc == 0, err
        return out


def sha(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest() if path.is_file() else "-"


def digests(folder: Path) -> dict:
    return {p.name: sha(p) for p in sorted(folder.iterdir()) if p.is_file() and not p.name.startswith(".")}


def temporaries(folder: Path) -> list[str]:
    if not folder.is_dir():
        return []
    return sorted(p.name for p in folder.iterdir() if p.name.startswith(".usdface-") or ".tmp-" in p.name)


def summary(rc, err, seconds=None) -> str:
    tb = "Traceback" in err
    lines = [ln for ln in err.splitlines() if ln.strip()]
    first = next((ln for ln in lines if "error" in ln.lower() or "stopped" in ln or "interrupted" in ln), lines[-1]
                 if lines else "")
    first = first if len(first) < 150 else first[:147] + "..."
    t = f", {seconds:.1f} s" if seconds is not None else ""
    return f"exit {rc}{t}; {'TRACEBACK, ' if tb else ''}{len(lines)} stderr line(s): `{first}`" if rc != 0 else \
        f"exit 0{t}"


def no_traceback(err) -> bool:
    return "Traceback" not in err


# -- the attempts ---------------------------------------------------------------------------------

def a_import_capture_same(c: Ctx):
    d = c.folder("a1")
    shutil.copy(SA / "capture" / "JawMoCap.usdc", d / "cap.usdc")
    before = sha(d / "cap.usdc")
    rc, _, err, _ = c.usdface("import-capture", d / "cap.usdc", "--trim", 0, 10, "-o", d / "cap.usdc")
    intact = sha(d / "cap.usdc") == before
    return f"{summary(rc, err)}; input {'intact' if intact else 'OVERWRITTEN'}", rc == 2 and intact and no_traceback(err)


def a_import_mesh_same(c: Ctx):
    d = c.folder("a2")
    c.usdface("import-mesh", MESH, "-o", d / "m.usdc", "-q")
    before = sha(d / "m.usdc")
    rc, _, err, _ = c.usdface("import-mesh", d / "m.usdc", "-o", d / "m.usdc")
    intact = sha(d / "m.usdc") == before
    return f"{summary(rc, err)}; input {'intact' if intact else 'OVERWRITTEN'}", rc == 2 and intact and no_traceback(err)


def a_bind_same(c: Ctx):
    d = c.folder("a3")
    c.usdface("import-mesh", MESH, "-o", d / "m.usda", "-q")
    before = sha(d / "m.usda")
    rc, _, err, _ = c.usdface("bind", "--mesh", d / "m.usda", "--capture", SA / "capture" / "JawMoCap.usdc",
                              "--layout", LAYOUT, "-o", d / "m.usda")
    text = (d / "m.usda").read_text(errors="replace")[:4000]
    self_ref = "@./m.usda@" in text
    intact = sha(d / "m.usda") == before
    return (f"{summary(rc, err)}; input {'intact' if intact else 'OVERWRITTEN'}"
            + ("; the file sublayers itself" if self_ref else "")), rc == 2 and intact and no_traceback(err)


def _run_inputs_in_outdir(c: Ctx, which: str):
    out = c.folder(f"a4{which}")
    c.usdface("import-mesh", MESH, "-o", out / "mesh.usdc", "-q")
    shutil.copy(SA / "capture" / "JawMoCap.usdc", out / "capture.usdc")
    mesh = out / "mesh.usdc" if which == "mesh" else MESH
    cap = out / "capture.usdc" if which == "capture" else TAKE
    before = sha(out / f"{which}.usdc")
    rc, _, err, _ = c.usdface("run", "--mesh", mesh, "--capture", cap, "--layout", LAYOUT, "--trim", 0, 30,
                              "--method", "euclidean", "-o", out)
    intact = sha(out / f"{which}.usdc") == before
    return f"{summary(rc, err)}; input {which}.usdc {'intact' if intact else 'OVERWRITTEN'}", \
        rc == 2 and intact and no_traceback(err)


def a_run_mesh_in_outdir(c):
    return _run_inputs_in_outdir(c, "mesh")


def a_run_capture_in_outdir(c):
    return _run_inputs_in_outdir(c, "capture")


def a_hard_link(c: Ctx):
    d = c.folder("a5")
    shutil.copy(SA / "capture" / "JawMoCap.usdc", d / "cap.usdc")
    os.link(d / "cap.usdc", d / "hard.usdc")
    before = sha(d / "cap.usdc")
    rc, _, err, _ = c.usdface("import-capture", d / "cap.usdc", "--trim", 0, 10, "-o", d / "hard.usdc")
    # os.replace onto a hard link replaces the name only: the input's bytes survive either way
    return f"{summary(rc, err)}; input {'intact' if sha(d / 'cap.usdc') == before else 'OVERWRITTEN'}", \
        rc == 2 and no_traceback(err)


def a_symlink(c: Ctx):
    d = c.folder("a6")
    shutil.copy(SA / "capture" / "JawMoCap.usdc", d / "cap.usdc")
    (d / "link.usdc").symlink_to(d / "cap.usdc")
    before = sha(d / "cap.usdc")
    rc, _, err, _ = c.usdface("import-capture", d / "link.usdc", "--trim", 0, 10, "-o", d / "cap.usdc")
    intact = sha(d / "cap.usdc") == before
    return f"{summary(rc, err)}; input {'intact' if intact else 'OVERWRITTEN'}", rc == 2 and intact and no_traceback(err)


def a_composed(c: Ctx):
    d = c.folder("a7")
    c.usdface("import-mesh", MESH, "-o", d / "m.usdc", "-q")
    c.usdface("bind", "--mesh", d / "m.usdc", "--capture", SA / "capture" / "JawMoCap.usdc", "--layout", LAYOUT,
              "-o", d / "b.usda", "-q")
    before = sha(d / "m.usdc")
    rc, _, err, _ = c.usdface("bind", "--mesh", d / "b.usda", "--capture", SA / "capture" / "JawMoCap.usdc",
                              "--layout", LAYOUT, "-o", d / "m.usdc")
    intact = sha(d / "m.usdc") == before
    return f"{summary(rc, err)}; m.usdc (composed by the input) {'intact' if intact else 'OVERWRITTEN'}", \
        rc == 2 and intact and no_traceback(err)


_KILL_BETWEEN_RENAMES = """
import os, signal, sys
from pathlib import Path
out = Path(sys.argv[1]).resolve()
real, n = os.replace, [0]
def replace(src, dst, *a, **k):
    real(src, dst, *a, **k)
    if Path(dst).resolve().parent == out:
        n[0] += 1
        if n[0] == 4:   # three files of the new run in place, the rest still the old run's
            os.kill(os.getpid(), signal.SIGKILL)
os.replace = replace
from usdface.cli import main
sys.exit(main(sys.argv[2:]))
"""


def a_kill_between_renames(c: Ctx):
    out = c.shot(c.folder("b1") / "shot", 30)
    p = subprocess.run([sys.executable, "-c", _KILL_BETWEEN_RENAMES, str(out), *RUN, "--trim", "0", "40", "-o",
                        str(out), "-q"], env=c.env, capture_output=True, text=True, cwd=c.scratch)
    rc_check, out_check, _, _ = c.usdface("check", out / "shot.usda")
    shot = (out / "shot.usda").is_file()
    res = f"killed (exit {p.returncode}); shot.usda {'present' if shot else 'absent'}; `check` exit {rc_check}"
    rc_next, _, err, _ = c.usdface(*RUN, "--trim", 0, 30, "-o", out, "-q")
    rc_check2, _, _, _ = c.usdface("check", out / "shot.usda", "-q")
    left = temporaries(out)
    res += f"; next run exit {rc_next}, then `check` exit {rc_check2}, temporaries left: {len(left)}"
    return res, rc_check != 0 and rc_check2 == 0 and not left


def _kill_during_work(c: Ctx, sig, name):
    out = c.shot(c.folder(name) / "shot", 30)
    before = digests(out)
    p = subprocess.Popen(c.cmd(*RUN, "--trim", 0, 40, "-o", out, "-q"), env=c.env, cwd=c.scratch,
                         stderr=subprocess.PIPE, text=True)
    deadline = time.time() + 120
    while not any(x.name.startswith(".usdface-run-") for x in out.iterdir()) and time.time() < deadline:
        time.sleep(0.05)
    time.sleep(0.3)
    p.send_signal(sig)
    _, err = p.communicate(timeout=120)
    left = temporaries(out)
    sizes = sum((out / n).stat().st_size if (out / n).is_file() else
                sum(f.stat().st_size for f in (out / n).rglob("*") if f.is_file()) for n in left)
    intact = digests(out) == before
    res = f"exit {p.returncode}; {'TRACEBACK; ' if 'Traceback' in err else ''}old shot {'intact' if intact else 'CHANGED'}; " \
          f"{len(left)} temporar{'y' if len(left) == 1 else 'ies'} right after ({sizes / 1e6:.1f} MB)"
    rc, _, _, _ = c.usdface(*RUN, "--trim", 0, 30, "-o", out, "-q")
    left2 = temporaries(out)
    res += f"; after the next run: {len(left2)}"
    want = 143 if sig == signal.SIGTERM else -signal.SIGKILL
    return res, p.returncode == want and intact and not left2 and "Traceback" not in err


def a_sigkill_work(c):
    return _kill_during_work(c, signal.SIGKILL, "b2")


def a_sigterm_work(c):
    return _kill_during_work(c, signal.SIGTERM, "b3")


def a_concurrent(c: Ctx):
    out = c.shot(c.folder("b4") / "shot", 30)
    # the first run is long (the whole take, hybrid distances), so the second starts while it works
    first = subprocess.Popen(c.cmd(*[a if a != "euclidean" else "hybrid" for a in RUN], "-o", out, "-q"),
                             env=c.env, cwd=c.scratch, stderr=subprocess.PIPE, text=True)
    deadline = time.time() + 120
    while not any(x.name.startswith(".usdface-run-") for x in out.iterdir()) and time.time() < deadline:
        time.sleep(0.05)
    rc2, _, err2, _ = c.usdface(*RUN, "--trim", 0, 50, "-o", out, "-q")
    _, err1 = first.communicate(timeout=300)
    rc_check, _, _, _ = c.usdface("check", out / "shot.usda", "-q")
    frames = json.loads((out / "summary.json").read_text()).get("frames")
    res = f"second run: {summary(rc2, err2)}; first run exit {first.returncode}; shot has {frames} frames, " \
          f"`check` exit {rc_check}"
    return res, rc2 == 1 and "another usdface run" in err2 and first.returncode == 0 and rc_check == 0 and \
        frames == 1590


def _manifest(d: Path, shots: list[dict], batch="") -> Path:
    text = [f"[batch]\ncache = false\n{batch}", "[defaults]\nmethod = \"euclidean\"\ntrim = [0, 30]"]
    for s in shots:
        text += ["[[shots]]", f'mesh = "{MESH}"', f'layout = "{LAYOUT}"'] + [f'{k} = "{v}"' for k, v in s.items()]
    (d / "m.toml").write_text("\n".join(text) + "\n")
    return d / "m.toml"


def a_batch_outside_root(c: Ctx):
    d = c.folder("c1")
    (d / "a" / "b").mkdir(parents=True)
    m = _manifest(d / "a" / "b", [{"capture": TAKE, "output": "../../escaped"}])
    rc, _, err, _ = c.usdface("batch", m, "--out-root", d / "a" / "b" / "root", "--workers", 0, "-q")
    escaped = (d / "a" / "escaped").exists()
    return f"{summary(rc, err)}; {'WROTE OUTSIDE --out-root' if escaped else 'nothing outside --out-root'}", \
        rc == 2 and not escaped and "line" in err


def a_batch_cache_outside_root(c: Ctx):
    d = c.folder("c3")
    (d / "a").mkdir()
    m = _manifest(d / "a", [{"capture": TAKE, "output": "o"}])
    m.write_text(m.read_text().replace("cache = false", 'cache = "../cache"'))  # relative to --out-root
    rc, _, err, _ = c.usdface("batch", m, "--out-root", d / "a" / "root", "--workers", 0, "-q")
    escaped = (d / "a" / "cache").exists()  # ../cache from --out-root a/root
    return f"{summary(rc, err)}; {'CACHE OUTSIDE --out-root' if escaped else 'nothing outside --out-root'}", \
        rc == 2 and not escaped


def a_batch_same_folder(c: Ctx):
    d = c.folder("c2")
    m = _manifest(d, [{"capture": TAKE, "output": "x/../same"},
                      {"capture": SA / "capture" / "NoseMoCap.ma", "output": "same"}])
    rc, _, err, _ = c.usdface("batch", m, "--workers", 0, "-q")
    wrote = (d / "same" / "shot.usda").exists()
    return f"{summary(rc, err)}; {'one shot REPLACED the other' if wrote else 'nothing written'}", \
        rc == 2 and not wrote and "both write" in err


def a_resample(c: Ctx):
    d = c.folder("d3")
    rc, _, err, s = c.usdface(*RUN, "--resample", 1000000, "-o", d / "r", timeout=900)
    # refused as an implausible rate (exit 2, issue 20) or, before that check, by its memory estimate (exit 1)
    return summary(rc, err, s), ((rc == 2 and "--allow resample" in err) or (rc == 1 and "GB" in err)) and \
        no_traceback(err) and len([ln for ln in err.splitlines() if ln.strip()]) == 1


def _unshare() -> list[str] | None:
    if shutil.which("unshare") is None:
        return None
    probe = Path("/tmp") / f"usdface-mount-probe-{os.getpid()}"
    probe.mkdir(exist_ok=True)
    try:
        for prefix in (["unshare", "-m", "--propagation", "private"], ["unshare", "-r", "-m", "--propagation", "private"]):
            if subprocess.run(prefix + ["sh", "-c", f"mount -t tmpfs -o size=1m tmpfs {probe}"],
                              capture_output=True).returncode == 0:
                return prefix
    finally:
        probe.rmdir()
    return None


def _mounted(c: Ctx, name: str, mounts: str, commands: list[list], inspect: str) -> list[dict] | None:
    prefix = _unshare()
    if prefix is None:
        return None
    d = c.scratch / name
    res = d / "results"
    res.mkdir(parents=True, exist_ok=True)
    lines = ["set +e", mounts]
    for i, argv in enumerate(commands):
        cmd = " ".join(f"'{a}'" for a in c.cmd(*argv))
        lines.append(f"date +%s.%N >{res}/{i}.t0; {cmd} >{res}/{i}.out 2>{res}/{i}.err; echo $? >{res}/{i}.rc; "
                     f"date +%s.%N >{res}/{i}.t1")
    lines.append(inspect)
    subprocess.run(prefix + ["sh", "-c", "\n".join(lines)], env=c.env, cwd=c.scratch, timeout=1800)
    out = []
    for i in range(len(commands)):
        out.append({"rc": int((res / f"{i}.rc").read_text()), "err": (res / f"{i}.err").read_text(),
                    "t": float((res / f"{i}.t1").read_text()) - float((res / f"{i}.t0").read_text())})
    return out


def a_run_read_only(c: Ctx):
    d = c.folder("d1")
    shot = c.shot(d / "ro" / "shot", 30)
    before = digests(shot)
    r = _mounted(c, "d1", f"mount --bind {d / 'ro'} {d / 'ro'} && mount -o remount,bind,ro {d / 'ro'}",
                 [RUN + ["--trim", "0", "40", "-o", str(shot)], RUN + ["--trim", "0", "40", "-o", str(d / "ro" / "new")]],
                 "true")
    if r is None:
        return "skipped: mounting refused here", None
    intact = digests(shot) == before and not temporaries(shot)
    res = f"into a read-only shot folder: {summary(r[0]['rc'], r[0]['err'])}; new folder: {summary(r[1]['rc'], r[1]['err'])}"
    return res + f"; old shot {'intact' if intact else 'CHANGED'}", \
        all(x["rc"] == 1 and no_traceback(x["err"]) and "read-only" in x["err"] for x in r) and intact


def a_run_full_disk(c: Ctx):
    d = c.folder("d2")
    (d / "small").mkdir()
    r = _mounted(c, "d2", f"mount -t tmpfs -o size=5m tmpfs {d / 'small'}",
                 [RUN + ["-o", str(d / "small" / "x")]],
                 f"ls -A {d / 'small'} > {d / 'left.txt'}")
    if r is None:
        return "skipped: mounting refused here", None
    left = (d / "left.txt").read_text().split()
    return f"{summary(r[0]['rc'], r[0]['err'])}; left on the disk: {left or 'nothing'}", \
        r[0]["rc"] == 1 and no_traceback(r[0]["err"]) and "disk full" in r[0]["err"] and not left


def a_batch_full_disk(c: Ctx):
    d = c.folder("d4")
    (d / "small").mkdir()
    m = _manifest(d, [{"capture": TAKE, "output": d / "small" / "x"}], batch=f'summary = "{d / "summary.json"}"')
    m.write_text(m.read_text().replace("trim = [0, 30]", ""))
    r = _mounted(c, "d4", f"mount -t tmpfs -o size=5m tmpfs {d / 'small'}", [["batch", m, "--workers", "0", "-q"]],
                 "true")
    if r is None:
        return "skipped: mounting refused here", None
    err = json.loads((d / "summary.json").read_text())["shots"][0]["error"] if (d / "summary.json").exists() else "?"
    short = err.splitlines()[0][:140] if err else ""
    return f"exit {r[0]['rc']}; the shot's error: `{short}`", r[0]["rc"] == 1 and "disk full" in err and "\n" not in err


def a_permission(c: Ctx):
    if shutil.which("setpriv") is None or os.geteuid() != 0:
        return "skipped: needs root and setpriv", None
    d = c.folder("d5")
    (d / "locked").mkdir(mode=0o755)
    env = dict(c.env, HOME=str(d), NUMBA_CACHE_DIR=str(d / "numba"))
    os.makedirs(d / "numba", exist_ok=True)
    os.chmod(d / "numba", 0o777)
    os.chmod(d, 0o777)
    cmd = ["setpriv", "--reuid=65534", "--regid=65534", "--clear-groups", *c.cmd(*RUN, "--trim", 0, 30, "-o",
                                                                                   d / "locked" / "x")]
    p = subprocess.run(cmd, capture_output=True, text=True, env=env, cwd=d, timeout=600)
    return summary(p.returncode, p.stderr), p.returncode == 1 and no_traceback(p.stderr) and "permission" in p.stderr


def _scheduler_attempt(c: Ctx, kind: str):
    if kind == "http":
        class Quiet(http.server.SimpleHTTPRequestHandler):
            def log_message(self, *a):
                pass
        server = http.server.ThreadingHTTPServer(("127.0.0.1", 0), Quiet)
        threading.Thread(target=server.serve_forever, daemon=True).start()
        port, stop = server.server_address[1], server.shutdown
    else:
        sock = socket.socket()
        sock.bind(("127.0.0.1", 0))
        sock.listen(8)
        conns, flag = [], threading.Event()

        def loop():
            sock.settimeout(0.2)
            while not flag.is_set():
                try:
                    conns.append(sock.accept()[0])
                except OSError:
                    pass
        threading.Thread(target=loop, daemon=True).start()
        port = sock.getsockname()[1]

        def stop():
            flag.set()
            [x.close() for x in conns]
            sock.close()
    d = c.folder(f"e{kind}")
    m = _manifest(d, [{"capture": TAKE, "output": "o"}])
    try:
        rc, _, err, s = c.usdface("batch", m, "--scheduler", f"tcp://127.0.0.1:{port}", timeout=60)
    finally:
        stop()
    if rc is None:
        return "no output, still waiting after 60 s (stopped)", False
    return summary(rc, err, s), rc == 1 and s < 10 and no_traceback(err)


def a_scheduler_http(c):
    return _scheduler_attempt(c, "http")


def a_scheduler_silent(c):
    return _scheduler_attempt(c, "silent")


ATTEMPTS = [
    ("outputs overwrite inputs", "`import-capture cap.usdc --trim 0 10 -o cap.usdc`", a_import_capture_same),
    ("outputs overwrite inputs", "`import-mesh m.usdc -o m.usdc`", a_import_mesh_same),
    ("outputs overwrite inputs", "`bind --mesh m.usda ... -o m.usda`", a_bind_same),
    ("outputs overwrite inputs", "`run --mesh OUTDIR/mesh.usdc ... -o OUTDIR`", a_run_mesh_in_outdir),
    ("outputs overwrite inputs", "`run --capture OUTDIR/capture.usdc ... -o OUTDIR`", a_run_capture_in_outdir),
    ("outputs overwrite inputs (new)", "`-o` a hard link to the input", a_hard_link),
    ("outputs overwrite inputs (new)", "input through a symbolic link, `-o` its target", a_symlink),
    ("outputs overwrite inputs (new)", "`bind --mesh b.usda -o m.usdc` (b.usda composes m.usdc)", a_composed),
    ("partial or mixed results", "SIGKILL between `run`'s final renames", a_kill_between_renames),
    ("partial or mixed results", "SIGKILL during `run`'s work", a_sigkill_work),
    ("partial or mixed results", "SIGTERM during `run`'s work", a_sigterm_work),
    ("partial or mixed results (new)", "a second `run` into an OUTDIR being written", a_concurrent),
    ("batch paths", "manifest `output = \"../../x\"` with `--out-root`", a_batch_outside_root),
    ("batch paths", "`x/../same` and `same`", a_batch_same_folder),
    ("batch paths (new)", "manifest `cache = \"../cache\"` with `--out-root`", a_batch_cache_outside_root),
    ("tracebacks", "`run` into a read-only folder (read-only bind mount)", a_run_read_only),
    ("tracebacks", "`run` on a full disk (5 MB tmpfs)", a_run_full_disk),
    ("tracebacks", "`run --resample 1000000`", a_resample),
    ("tracebacks", "batch on a full disk (5 MB tmpfs)", a_batch_full_disk),
    ("tracebacks", "`batch --scheduler` an HTTP server (like the dashboard's 8787)", a_scheduler_http),
    ("tracebacks (new)", "`batch --scheduler` a listener that never answers", a_scheduler_silent),
    ("tracebacks (new)", "`run` as user nobody into a root-owned folder (EACCES)", a_permission),
]


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--tree", "--code", dest="code", default=str(REPO),
                    help="usdface source tree to test (default: this one); the inputs come from this tree's sample_assets")
    ap.add_argument("--scratch", default="/tmp/usdface-fault-attempts")
    ap.add_argument("--only", help="run the attempts whose description (issue 12: function name) contains this")
    ap.add_argument("--section", choices=("all", "issue12", "readers", "commands"), default="all",
                    help="issue 20's hostile readers, its attempts on commands, issue 12's attempts, or all (default)")
    ap.add_argument("--before", help="a second tree (e.g. the 0.2 release) to run issue 20's sections against too; "
                                     "prints both tables and the before/after table per case of issue 20")
    args = ap.parse_args()
    scratch = Path(args.scratch)
    shutil.rmtree(scratch, ignore_errors=True)
    scratch.mkdir(parents=True)
    c = Ctx(Path(args.code).resolve(), scratch)
    counts = {}
    sections = [s for s in ("readers", "commands") if args.section in ("all", s)]
    if sections:
        from before_after import issue20_rows, print_before_after

        rows = issue20_rows(c.code, scratch / "after", sections, args.only)
        if args.before:
            before = Path(args.before).resolve()
            print_before_after(issue20_rows(before, scratch / "before", sections, args.only), rows, str(before),
                               str(c.code))
        for s in sections:
            part = [r for r in rows if r["section"] == s]
            counts[s] = (sum(r["ok"] for r in part), len(part))
    if args.section not in ("all", "issue12"):
        return 0
    print(f"\n## Issue 12's attempts, usdface from {c.code}\n")
    print("| class | attempt | outcome | handled |")
    print("|---|---|---|---|")
    handled = total = 0
    for klass, what, fn in ATTEMPTS:
        if args.only and args.only not in fn.__name__:
            continue
        try:
            outcome, ok = fn(c)
        except Exception as exc:  # noqa: BLE001 - the attempt itself broke: report it
            outcome, ok = f"attempt failed: {type(exc).__name__}: {str(exc)[:120]}", False
        total += ok is not None
        handled += bool(ok)
        verdict = "skipped" if ok is None else ("yes" if ok else "**no**")
        print(f"| {klass} | {what} | {outcome.replace('|', '/')} | {verdict} |", flush=True)
    counts["issue12"] = (handled, total)
    print(f"\n{handled}/{total} handled")
    if len(counts) > 1:
        print("\n" + ", ".join(f"{k}: {h}/{t}" for k, (h, t) in counts.items())
              + f"; all: {sum(h for h, _ in counts.values())}/{sum(t for _, t in counts.values())} handled")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
