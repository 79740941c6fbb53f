"""Issue 20's attempts on commands (cases 1, 2, 5, 6, 9, 10, 15) and more of the same classes, for
benchmarks/fault_attempts.py: outputs that are inputs, closed and full standard outputs, SIGINT /
SIGTERM / SIGHUP / SIGKILL to every writer, 250-byte output names, misleading messages, hostile
manifests, seeds, timelines and widths. How each runs and what "handled" means:
benchmarks/hostile_harness.py.
"""
from __future__ import annotations

import glob
import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

from hostile_harness import (LAYOUT, MESH_OBJ, MESH_USD, MOVIE, MP_LAYOUT, MP_OBJ, PHOTO, REPO, RUN, SA, SEEDS,
                             TAKE_MA, TAKE_USD, Attempt, Ctx, Outcome, _fifo, digests, finish, run_one, signal_group,
                             temporaries, wait_for)


def _manifest(d: Path, shots: list[dict], batch: str = "", defaults: str = 'method = "euclidean"\ntrim = [0, 30]') -> Path:
    text = [f"[batch]\ncache = false\n{batch}", f"[defaults]\n{defaults}"]
    for s in shots:
        text.append("[[shots]]")
        text += [f'{k} = "{v}"' for k, v in s.items()]
    (d / "m.toml").write_text("\n".join(text) + "\n")
    return d / "m.toml"


# -- case 1: outputs that are inputs ------------------------------------------------------------------

def a_summary_is_manifest(c: Ctx, d: Path) -> Outcome:
    m = _manifest(d, [{"mesh": MESH_OBJ, "layout": LAYOUT, "capture": TAKE_MA, "output": "o"}], batch='summary = "m.toml"')
    before = digests([m])
    rc, err, _ = c.run("batch", m, "--workers", 0, "-q", cwd=d)
    return Outcome(rc, err, digests([m]) == before, temporaries(d), not (d / "o").exists())


def a_summary_is_layout(c: Ctx, d: Path) -> Outcome:
    lay = d / "l.json"
    shutil.copy(LAYOUT, lay)
    m = _manifest(d, [{"mesh": MESH_OBJ, "layout": lay, "capture": TAKE_MA, "output": "o"}], batch='summary = "l.json"')
    before = digests([m, lay])
    rc, err, _ = c.run("batch", m, "--workers", 0, "-q", cwd=d)
    return Outcome(rc, err, digests([m, lay]) == before, temporaries(d), not (d / "o").exists())


def a_cache_is_manifest(c: Ctx, d: Path) -> Outcome:
    m = _manifest(d, [{"mesh": MESH_OBJ, "layout": LAYOUT, "capture": TAKE_MA, "output": "o"}])
    m.write_text(m.read_text().replace("cache = false", 'cache = "m.toml"'))
    before = digests([m])
    rc, err, _ = c.run("batch", m, "--workers", 0, "-q", cwd=d)
    return Outcome(rc, err, digests([m]) == before, temporaries(d), not (d / "o").exists())


def a_cli_summary_is_capture(c: Ctx, d: Path) -> Outcome:
    cap = d / "take.ma"
    shutil.copy(TAKE_MA, cap)
    m = _manifest(d, [{"mesh": MESH_OBJ, "layout": LAYOUT, "capture": cap, "output": "o"}])
    before = digests([m, cap])
    rc, err, _ = c.run("batch", m, "--summary", cap, "--workers", 0, "-q", cwd=d)
    return Outcome(rc, err, digests([m, cap]) == before, temporaries(d), not (d / "o").exists())


# -- case 2: layers made for another mesh ----------------------------------------------------------------

def a_binding_of_another_mesh(c: Ctx, d: Path) -> Outcome:
    for args in (["import-mesh", MP_OBJ, "-o", "mp.usdc"], ["import-mesh", MESH_OBJ, "-o", "mh.usdc"],
                 ["bind", "--mesh", "mp.usdc", "--capture", TAKE_USD, "--layout", MP_LAYOUT, "-o", "b.usda"]):
        rc, err, _ = c.run(*args, "-q", cwd=d)
        if rc != 0:
            return Outcome(rc, err, ok=False, note="set-up failed")
    ins = [d / "mh.usdc", d / "b.usda", d / "mp.usdc"]
    before = digests(ins)
    rc, err, _ = c.run("distances", "--mesh", "mh.usdc", "--binding", "b.usda", "-o", "a.usdc", cwd=d)
    return Outcome(rc, err, digests(ins) == before, temporaries(d), not (d / "a.usdc").exists())


# -- case 5: closed and full standard output; Ctrl-C to a batch with workers -----------------------------

def _closed_pipe(c: Ctx, d: Path, *args) -> Outcome:
    read_end, write_end = os.pipe()
    os.close(read_end)  # the reader is gone before the first write (`| head -c 10` after 10 bytes)
    try:
        p = subprocess.Popen([sys.executable, "-m", "usdface", *c.argv(args)], cwd=d, env=c.env, stdout=write_end,
                             stderr=subprocess.PIPE)
    finally:
        os.close(write_end)
    rc, err = finish(p, 120)
    return Outcome(rc, err, left=temporaries(d))


def a_info_closed_pipe(c: Ctx, d: Path) -> Outcome:
    return _closed_pipe(c, d, "info", "--json", c.shot() / "shot.usda")


def a_check_closed_pipe(c: Ctx, d: Path) -> Outcome:
    return _closed_pipe(c, d, "check", "--json", c.shot() / "shot.usda")


def a_info_full_stdout(c: Ctx, d: Path) -> Outcome:
    with open("/dev/full", "wb") as full:
        p = subprocess.Popen([sys.executable, "-m", "usdface", "info", "--json", os.fsencode(str(c.shot() / "shot.usda"))],
                             cwd=d, env=c.env, stdout=full, stderr=subprocess.PIPE)
        rc, err = finish(p, 120)
    return Outcome(rc, err, left=temporaries(d), ok="disk full" in err or "No space" in err)


def _batch_signalled(c: Ctx, d: Path, sig) -> Outcome:
    caps = d / "caps"
    caps.mkdir()
    for name in ("JawMoCap", "NoseMoCap", "EyebrowsMoCap"):
        shutil.copy(SA / "capture" / f"{name}.ma", caps / f"{name}.ma")
    m = _manifest(d, [{"mesh": MESH_OBJ, "layout": LAYOUT, "capture": caps / "*.ma", "output": "out/{capture}"}],
                  defaults='method = "hybrid"')
    ins = [m] + sorted(caps.iterdir())
    before = digests(ins)
    p = c.start("batch", m, "--workers", 2, "-q", cwd=d)
    started = wait_for(lambda: glob.glob(str(d / "out" / "*" / ".usdface-run-*")), p)
    time.sleep(1.0)
    signal_group(p, sig)
    rc, err = finish(p, 240)
    return Outcome(rc, err, digests(ins) == before, temporaries(d), started, "" if started else "ended before the signal")


def a_batch_ctrl_c(c, d):
    return _batch_signalled(c, d, signal.SIGINT)


def a_batch_sigterm(c, d):
    return _batch_signalled(c, d, signal.SIGTERM)


def a_batch_sighup(c, d):
    return _batch_signalled(c, d, signal.SIGHUP)


# -- case 9: SIGHUP, SIGKILL and the next writer -----------------------------------------------------------

def a_run_sighup(c: Ctx, d: Path) -> Outcome:
    out = d / "shot"
    shutil.copytree(c.shot(), out)
    before = digests(sorted(out.iterdir()))
    p = c.start(*RUN, "--trim", 0, 400, "-o", out, cwd=d)
    started = wait_for(lambda: any(x.name.startswith(".usdface-run-") for x in out.iterdir()), p)
    signal_group(p, signal.SIGHUP)
    rc, err = finish(p, 120)
    return Outcome(rc, err, digests(sorted(p for p in out.iterdir() if not p.name.startswith("."))) == before,
                   temporaries(d), started)


def _working(c: Ctx, d: Path, sig, args, ready) -> Outcome:
    p = c.start(*args, cwd=d)
    started = wait_for(lambda: ready(d), p)
    time.sleep(0.3)
    signal_group(p, sig)
    rc, err = finish(p, 180)
    return Outcome(rc, err, left=temporaries(d), ok=started, note="" if started else "ended before the signal")


def _hidden_file(d: Path) -> bool:
    return any(x.name.startswith(".") and x.is_file() for x in d.iterdir())


def a_playblast_sighup(c: Ctx, d: Path) -> Outcome:
    return _working(c, d, signal.SIGHUP, ["playblast", c.shot() / "shot.usda", "-o", "m.mp4", "--size", "320x240"],
                    _hidden_file)


def a_track_sigterm(c: Ctx, d: Path) -> Outcome:
    t0 = time.time()  # track writes nothing before it ends: the signal lands 5 s in (start-up is about 2 s)
    return _working(c, d, signal.SIGTERM, ["track", MOVIE, "--seeds", SEEDS, "-o", "t.usdc", "--csv", "t.csv"],
                    lambda d: time.time() - t0 > 5)


def a_report_ctrl_c(c: Ctx, d: Path) -> Outcome:
    # a large movie: at 320x240 the 30-frame render ended within the 0.3 s before the signal on a
    # quiet machine, and the signal found a finished command exiting (-2, its work complete)
    return _working(c, d, signal.SIGINT, ["report", c.shot(), "-o", "r.html", "--playblast-size", "1280x960"],
                    lambda d: any(x.name.startswith(".r_media") or x.name.startswith(".r.") for x in d.iterdir()))


def _killed_then_next(c: Ctx, d: Path, name: str, args, inputs=()) -> Outcome:
    """SIGKILL at the rename of ``name``'s temporary, then the same command again."""
    before = digests(inputs)
    rc_k, err_k = c.hooked(signal.SIGKILL, name, *args, cwd=d)
    right_after = temporaries(d)
    rc, err, _ = c.run(*args, cwd=d)
    return Outcome(rc, err, digests(inputs) == before, temporaries(d),
                   ok=rc_k == -signal.SIGKILL and bool(right_after) and (d / name).exists(),
                   note=f"killed: {len(right_after)} left, then the next run")


def a_import_capture_sigkill(c, d):
    return _killed_then_next(c, d, "cap.usdc", ["import-capture", TAKE_MA, "--trim", 0, 100, "-o", "cap.usdc", "-q"],
                             [TAKE_MA])


def a_playblast_sigkill(c, d):
    return _killed_then_next(c, d, "m.mp4", ["playblast", c.shot() / "shot.usda", "-o", "m.mp4", "--size", "64x48",
                                             "-q"])


def a_track_sigkill(c, d):
    return _killed_then_next(c, d, "t.csv", ["track", MOVIE, "--seeds", SEEDS, "-o", "t.usdc", "--csv", "t.csv", "-q"],
                             [MOVIE, SEEDS])


def a_report_sigkill(c, d):
    return _killed_then_next(c, d, "r_media", ["report", c.shot(), "-o", "r.html", "--playblast-size", "64x48", "-q"])


def a_detect_sigkill(c, d):
    return _killed_then_next(c, d, "p.png", ["detect", PHOTO, "-o", "f.json", "--preview", "p.png", "-q"], [PHOTO])


def _stopped_at_rename(c: Ctx, d: Path, sig, name, args, first=True) -> Outcome:
    """A stop signal at the rename of ``name``'s temporary, over a complete old output."""
    if first:
        rc, err, _ = c.run(*args, cwd=d)
        if rc != 0:
            return Outcome(rc, err, ok=False, note="the first run failed")
    old = digests(sorted(p for p in d.iterdir() if p.is_file()))
    rc, err = c.hooked(sig, name, *args, cwd=d)
    kept = digests(sorted(p for p in d.iterdir() if p.is_file())) == old
    return Outcome(rc, err, kept, temporaries(d), note="" if kept else "old output changed")


def a_detect_sigterm_rename(c, d):
    return _stopped_at_rename(c, d, signal.SIGTERM, "p.png", ["detect", PHOTO, "-o", "f.json", "--preview", "p.png"])


def a_playblast_sigterm_rename(c, d):
    return _stopped_at_rename(c, d, signal.SIGTERM, "m.mp4", ["playblast", c.shot() / "shot.usda", "-o", "m.mp4",
                                                              "--size", "64x48", "-q"])


def a_report_sighup_rename(c, d):
    return _stopped_at_rename(c, d, signal.SIGHUP, "r_media", ["report", c.shot(), "-o", "r.html",
                                                              "--playblast-size", "64x48", "-q"])


# -- case 10: 250-byte output names ----------------------------------------------------------------------

def _long(stem_bytes: int, suffix: str) -> str:
    return "n" * (stem_bytes - len(suffix)) + suffix


def _long_output(c: Ctx, d: Path, args, name) -> Outcome:
    rc, err, _ = c.run(*args, cwd=d)
    return Outcome(rc, err, left=temporaries(d), ok=(d / name).is_file())


def a_long_import_capture(c, d):
    name = _long(250, ".usdc")
    return _long_output(c, d, ["import-capture", TAKE_MA, "--trim", 0, 50, "-o", name, "-q"], name)


def a_long_track_csv(c, d):
    name = _long(250, ".csv")
    return _long_output(c, d, ["track", MOVIE, "--seeds", SEEDS, "-o", "t.usdc", "--csv", name, "-q"], name)


def a_long_playblast(c, d):
    name = _long(250, ".mp4")
    return _long_output(c, d, ["playblast", c.shot() / "shot.usda", "-o", name, "--size", "64x48", "-q"], name)


def a_long_report(c, d):
    name = _long(240, ".html")  # its media folder <stem>_media is 241 bytes
    return _long_output(c, d, ["report", c.shot(), "-o", name, "--playblast-size", "64x48", "-q"], name)


# -- case 15: misleading messages ------------------------------------------------------------------------

def a_symlink_loop_outdir(c: Ctx, d: Path) -> Outcome:
    (d / "loop").symlink_to(d / "loop")
    rc, err, _ = c.run(*RUN, "-o", d / "loop", cwd=d)
    return Outcome(rc, err, left=temporaries(d), ok="symbolic link" in err and "File exists" not in err)


def a_clash_csv_trc(c: Ctx, d: Path) -> Outcome:
    import numpy as np

    if str(REPO) not in sys.path:
        sys.path.insert(0, str(REPO))
    from usdface.io.captures import read_capture, write_capture  # this tree writes the (valid) inputs

    cap = read_capture(TAKE_MA)
    cap = cap.replace(positions=np.ascontiguousarray(cap.positions[:200]))
    write_capture(d / "jaw200.csv", cap)
    write_capture(d / "jaw200.trc", cap)
    m = _manifest(d, [{"mesh": MESH_OBJ, "layout": LAYOUT, "capture": "jaw200.*", "output": "out/{capture}"}],
                  defaults='method = "euclidean"')
    rc, err, _ = c.run("batch", m, "--workers", 0, "-q", cwd=d)
    return Outcome(rc, err, left=temporaries(d), ok="jaw200.csv" in err and "jaw200.trc" in err)


def a_one_frame_run(c: Ctx, d: Path) -> Outcome:
    rc, err, out = c.run(*RUN, "--trim", 0, 1, "-o", d / "one", cwd=d, stdout=subprocess.PIPE)
    text = out.decode("utf-8", "replace")
    return Outcome(rc, err, left=temporaries(d), ok="nan" not in text.lower() and "nan" not in err.lower(),
                   note=next((ln for ln in err.splitlines() if ln.strip()), "")[:90])


def a_stiffness_negative(c: Ctx, d: Path) -> Outcome:
    rc, err, _ = c.run(*RUN, "--stiffness", "-1", "-o", d / "o", cwd=d)
    return Outcome(rc, err, left=temporaries(d), ok="no such file" not in err and not (d / "o").exists())


# -- the same classes on other readers: structured inputs, images ------------------------------------------

def _hostile_text(d: Path, kind: str, suffix: str) -> Path:
    p = d / f"{kind}{suffix}"
    if kind == "pipe":
        return _fifo(p)
    if kind == "deep":
        p.write_text(("a = " if suffix == ".toml" else "") + "[" * 100000)
    elif kind == "latin":
        p.write_bytes(b'[batch]\nsummary = "r\xe9sum\xe9.json"\n' if suffix == ".toml" else b'{"Chin": [1, 2], "N\xe9": 1}')
    else:
        with open(p, "wb") as f:
            f.truncate(70 * 1024 * 1024)  # sparse
    return p


def _text_input(c: Ctx, d: Path, kind: str, suffix: str, build) -> Outcome:
    p = _hostile_text(d, kind, suffix)
    before = {} if kind == "pipe" else digests([p])
    rc, err, _ = c.run(*build(p), cwd=d, timeout=60)
    return Outcome(rc, err, digests(before) == before, temporaries(d), ok=p.name in err)


def _manifest_attempt(kind):
    return lambda c, d: _text_input(c, d, kind, ".toml", lambda p: ["batch", p, "--workers", 0])


def _seeds_attempt(kind):
    return lambda c, d: _text_input(c, d, kind, ".json", lambda p: ["track", MOVIE, "--seeds", p, "-o", "t.usdc"])


def a_stiffness_deep(c, d):
    return _text_input(c, d, "deep", ".json", lambda p: [*RUN, "--stiffness", p, "-o", "o"])


def a_stiffness_pipe(c, d):
    return _text_input(c, d, "pipe", ".json", lambda p: [*RUN, "--stiffness", p, "-o", "o"])


def a_timeline_deep(c: Ctx, d: Path) -> Outcome:
    rc, err, _ = c.run("muscles", "--mesh", MESH_USD, "--layout", LAYOUT, "-o", "rig.usda", "-q", cwd=d)
    if rc != 0:
        return Outcome(rc, err, ok=False, note="set-up failed")
    return _text_input(c, d, "deep", ".json", lambda p: ["simulate", "--mesh", MESH_USD, "--rig", "rig.usda",
                                                         "--timeline", p, "-o", "sim.usdc"])


def a_report_summary_pipe(c: Ctx, d: Path) -> Outcome:
    out = d / "shot"
    shutil.copytree(c.shot(), out)
    (out / "summary.json").unlink()
    _fifo(out / "summary.json")
    rc, err, _ = c.run("report", out, "-o", "r.html", "--no-playblast", cwd=d, timeout=60)
    return Outcome(rc, err, left=temporaries(d), ok="summary.json" in err and "named pipe" in err)


def a_detect_photo(c: Ctx, d: Path) -> Outcome:
    before = digests([PHOTO])
    rc, err, _ = c.run("detect", PHOTO, "-o", "f.json", cwd=d)
    return Outcome(rc, err, digests([PHOTO]) == before, temporaries(d), ok=(d / "f.json").is_file())


def a_detect_cut_png(c: Ctx, d: Path) -> Outcome:
    cut = d / "cut.png"
    cut.write_bytes(PHOTO.read_bytes()[:20000])
    before = digests([cut])
    rc, err, _ = c.run("detect", cut, "-o", "f.json", cwd=d)
    return Outcome(rc, err, digests([cut]) == before, temporaries(d), ok="cut.png" in err)


def attempts() -> list[Attempt]:
    a = Attempt
    sig_ok = 0
    out = [
        a("outputs are inputs (1)", "batch `[batch] summary` = the manifest itself", a_summary_is_manifest),
        a("outputs are inputs (1)", "batch `[batch] summary` = the layout the shots read", a_summary_is_layout),
        a("outputs are inputs (new)", "batch `[batch] cache` = the manifest file", a_cache_is_manifest),
        a("outputs are inputs (new)", "`batch --summary` = a shot's capture", a_cli_summary_is_capture),
        a("layers of another mesh (2)", "`distances --mesh` MakeHuman `--binding` made on MediaPipe",
          a_binding_of_another_mesh),
        a("tracebacks (5)", "`info --json shot.usda | head -c 10` (reader gone)", a_info_closed_pipe, 141, 0),
        a("tracebacks (new)", "`check --json shot.usda | head -c 10` (reader gone)", a_check_closed_pipe, 141, 0),
        a("tracebacks (new)", "`info --json shot.usda > /dev/full`", a_info_full_stdout, 1, 1),
        a("tracebacks (5)", "Ctrl-C (process group) to `batch --workers 2`", a_batch_ctrl_c, 130, 1),
        a("signals (6)", "SIGTERM to `batch --workers 2`", a_batch_sigterm, 143, 1),
        a("signals (new)", "SIGHUP (process group) to `batch --workers 2`", a_batch_sighup, 129, 1),
        a("signals (9)", "SIGHUP (process group) to `run` over an old shot", a_run_sighup, 129, 1),
        a("signals (9)", "SIGHUP (process group) to `playblast` while it encodes", a_playblast_sighup, 129, 1),
        a("signals (new)", "SIGTERM to `track --csv` while it tracks", a_track_sigterm, 143, 1),
        a("signals (new)", "Ctrl-C (process group) to `report` while it renders", a_report_ctrl_c, 130, 1),
        a("signals (new)", "SIGTERM to `detect --preview` at its rename, over old outputs", a_detect_sigterm_rename,
          143, 1),
        a("signals (new)", "SIGTERM to `playblast` at its rename, over an old movie", a_playblast_sigterm_rename, 143, 1),
        a("signals (new)", "SIGHUP to `report` at its media folder's rename, over an old report",
          a_report_sighup_rename, 129, 1),
        a("SIGKILL, next writer (9)", "SIGKILL `import-capture`, then import again", a_import_capture_sigkill,
          sig_ok, 0),
        a("SIGKILL, next writer (9)", "SIGKILL `playblast`, then playblast again", a_playblast_sigkill, sig_ok, 0),
        a("SIGKILL, next writer (new)", "SIGKILL `track --csv`, then track again", a_track_sigkill, sig_ok, 0),
        a("SIGKILL, next writer (new)", "SIGKILL `report` (media folder), then report again", a_report_sigkill,
          sig_ok, 0),
        a("SIGKILL, next writer (new)", "SIGKILL `detect --preview`, then detect again", a_detect_sigkill, sig_ok, 0),
        a("names (10)", "`import-capture -o` a 250-byte name", a_long_import_capture, 0, 0),
        a("names (new)", "`track --csv` a 250-byte name", a_long_track_csv, 0, 0),
        a("names (new)", "`playblast -o` a 250-byte name", a_long_playblast, 0, 0),
        a("names (new)", "`report -o` a 240-byte name (media folder 241 bytes)", a_long_report, 0, 0),
        a("messages (15)", "a symbolic link loop as OUTDIR", a_symlink_loop_outdir),
        # a manifest error lists its problems under a heading: two lines for one clash
        a("messages (15)", "shots from jaw200.csv and jaw200.trc in one manifest", a_clash_csv_trc, 2, 2),
        a("messages (15)", "a 1-frame `run` (no nan, no warning)", a_one_frame_run, 0, 0),
        a("messages (15)", "`run --stiffness -1`", a_stiffness_negative),
    ]
    for kind, what in (("pipe", "a named pipe"), ("deep", "100000 nested '['"), ("latin", "not UTF-8"),
                       ("huge", "70 MB")):
        out.append(a("structured inputs (new)", f"batch manifest: {what}", _manifest_attempt(kind)))
    for kind, what in (("deep", "100000 nested '['"), ("latin", "not UTF-8"), ("pipe", "a named pipe")):
        out.append(a("structured inputs (new)", f"`track --seeds`: {what}", _seeds_attempt(kind)))
    out += [
        a("structured inputs (new)", "`run --stiffness`: 100000 nested '['", a_stiffness_deep),
        a("structured inputs (new)", "`run --stiffness`: a named pipe", a_stiffness_pipe),
        a("structured inputs (new)", "`simulate --timeline`: 100000 nested '['", a_timeline_deep),
        a("structured inputs (new)", "`report` of a folder whose summary.json is a named pipe", a_report_summary_pipe),
        a("chatter (13)", "`detect` of the shared astronaut photo (libpng iCCP warning)", a_detect_photo, 0, 0),
        a("chatter (new)", "`detect` of a cut PNG", a_detect_cut_png),
    ]
    return out


def table(code: Path, scratch: Path, only: str | None = None) -> list[dict]:
    """Print the commands' table; returns its rows (klass, what, ok, ...)."""
    c = Ctx(code, scratch)
    print("| class (issue 20 item) | attempt | exit | stderr lines | traceback | inputs unchanged | left behind | "
          "first line | handled |")
    print("|---|---|---|---|---|---|---|---|---|")
    rows = []
    for i, attempt in enumerate(attempts()):
        if only and only not in attempt.what:
            continue
        r = run_one(c, attempt, i)
        rows.append(dict(r, klass=attempt.klass, what=attempt.what))
        rc = "killed (timeout)" if r["rc"] is None else str(r["rc"])
        first = (r["first"] + (f" ({r['note']})" if r["note"] else "")).replace("|", "/").replace("`", "'")
        left = ", ".join(r["left"][:4]) + (f", ... ({len(r['left'])})" if len(r["left"]) > 4 else "")
        print(f"| {attempt.klass} | {attempt.what} | {rc} | {r['lines']} | {'**yes**' if r['traceback'] else 'no'} | "
              f"{'yes' if r['same'] else '**CHANGED**'} | {left or 'nothing'} | `{first}` | "
              f"{'yes' if r['ok'] else '**no**'} |", flush=True)
    return rows
