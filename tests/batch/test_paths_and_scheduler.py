"""Batch paths (normalised, confined to --out-root, clashes after normalisation, no shot writing
over its inputs) and a --scheduler that is not a Dask scheduler (fails within 10 s)."""
from __future__ import annotations

import http.server
import os
import socket
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest

from usdface.pipeline.batch.manifest import load_manifest
from usdface.pipeline.batch.cluster import PROBE_TIMEOUT, probe_scheduler
from usdface.errors import EnvironmentFault, InputError

SA = Path(__file__).resolve().parents[2] / "sample_assets"


def _manifest(folder: Path, shots: list[dict], batch: str = "", defaults: str = "") -> Path:
    text = [f"[batch]\n{batch}", f"[defaults]\nmethod = \"euclidean\"\n{defaults}"]
    for s in shots:
        text.append("[[shots]]")
        text += [f'{k} = "{v}"' for k, v in s.items()]
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / "shots.toml"
    path.write_text("\n".join(text) + "\n")
    return path


def _shot(capture="JawMoCap", **extra) -> dict:
    return {"mesh": SA / "meshes" / "makehuman_hm08_face_cm.obj", "capture": SA / "capture" / f"{capture}.ma",
            "layout": SA / "layouts" / "makehuman_hm08_face.layout.json", **extra}


def test_outputs_cache_and_summary_stay_inside_out_root(tmp_path):
    root = tmp_path / "root"
    m = _manifest(tmp_path / "a" / "b", [_shot(output="../../x")], batch='cache = "../c"\nsummary = "/tmp/s.json"')
    with pytest.raises(InputError) as info:
        load_manifest(m, out_root=root)
    text = str(info.value)
    lines = m.read_text().splitlines()
    n = {key: 1 + next(i for i, ln in enumerate(lines) if ln.startswith(key)) for key in ("output", "cache", "summary")}
    escaped = Path(os.path.normpath(root.resolve() / ".." / ".." / "x"))  # relative to --out-root
    assert (f"manifest {m} line {n['output']}: output = '../../x' resolves to {escaped}, outside "
            f"--out-root {root}") in text
    assert f"line {n['cache']}: cache = '../c' resolves to" in text
    assert f"line {n['summary']}: summary = '/tmp/s.json'" in text
    # through a symbolic link inside the root: still outside
    root.mkdir()
    (root / "escape").symlink_to(tmp_path, target_is_directory=True)
    m = _manifest(tmp_path / "a" / "b", [_shot(output="escape/y")])
    with pytest.raises(InputError, match=r"outside --out-root"):
        load_manifest(m, out_root=root)
    # inside: normalised
    m = _manifest(tmp_path / "a" / "b", [_shot(output="x/../same/{capture}")])
    man = load_manifest(m, out_root=root)
    assert man.shots[0].output == str(root.resolve() / "same" / "JawMoCap")
    assert man.cache == str(root.resolve() / ".usdface-cache")
    # without --out-root, relative to the manifest (normalised, not confined)
    man = load_manifest(_manifest(tmp_path / "a" / "b", [_shot(output="../../x")]))
    assert man.shots[0].output == str(tmp_path.resolve() / "x")


def test_clashes_are_found_after_normalisation(tmp_path):
    m = _manifest(tmp_path, [_shot(output="x/../same"), _shot("NoseMoCap", output="same")])
    with pytest.raises(InputError, match=r"NoseMoCap and makehuman_hm08_face_cm/JawMoCap both write .*same"):
        load_manifest(m)
    (tmp_path / "link").symlink_to(tmp_path / "same", target_is_directory=True)
    (tmp_path / "same").mkdir()
    m = _manifest(tmp_path, [_shot(output="link"), _shot("NoseMoCap", output="same")])
    with pytest.raises(InputError, match=r"both write"):
        load_manifest(m)
    m = _manifest(tmp_path, [_shot(output="c/{capture}")], batch='cache = "c"')
    with pytest.raises(InputError, match=r"overlaps the cache folder"):
        load_manifest(m)


def test_a_shot_writing_over_its_inputs_is_refused_before_any_work(tmp_path):
    out = tmp_path / "out"
    out.mkdir()
    (out / "capture.usdc").write_bytes((SA / "capture" / "JawMoCap.usdc").read_bytes())
    m = _manifest(tmp_path, [{"mesh": SA / "meshes" / "makehuman_hm08_face_cm.obj", "capture": out / "capture.usdc",
                              "layout": SA / "layouts" / "makehuman_hm08_face.layout.json", "output": "out"}])
    with pytest.raises(InputError, match=r"would overwrite the input .*out/capture\.usdc \(capture of shot makehuman_hm08_face_cm/capture\)"):
        load_manifest(m)


# -- --scheduler that is not a Dask scheduler -----------------------------------------------------

class _Quiet(http.server.SimpleHTTPRequestHandler):
    def log_message(self, *args):
        pass


def _serve(kind: str):
    """A listener on a free port: 'http' (a web server, like the dashboard), 'silent' (accepts,
    never answers), 'garbage' (answers another protocol and closes)."""
    if kind == "http":
        server = http.server.ThreadingHTTPServer(("127.0.0.1", 0), _Quiet)
        threading.Thread(target=server.serve_forever, daemon=True).start()
        return server.server_address[1], server.shutdown
    sock = socket.socket()
    sock.bind(("127.0.0.1", 0))
    sock.listen(8)
    stop = threading.Event()
    conns = []

    def loop():
        sock.settimeout(0.2)
        while not stop.is_set():
            try:
                c, _ = sock.accept()
            except OSError:
                continue
            conns.append(c)
            if kind == "garbage":
                c.sendall(b"SSH-2.0-OpenSSH_9.6\r\n" * 64)
                c.close()

    threading.Thread(target=loop, daemon=True).start()

    def close():
        stop.set()
        for c in conns:
            c.close()
        sock.close()
    return sock.getsockname()[1], close


@pytest.mark.parametrize("kind,message", [("http", "does not answer as a Dask scheduler within"),
                                          ("silent", "does not answer as a Dask scheduler within"),
                                          ("garbage", "does not answer as a Dask scheduler"),
                                          ("nothing", "nothing listens there")])
def test_probe_fails_fast_on_anything_but_a_scheduler(kind, message):
    if kind == "nothing":
        with socket.socket() as s:
            s.bind(("127.0.0.1", 0))
            port, close = s.getsockname()[1], (lambda: None)
    else:
        port, close = _serve(kind)
    try:
        t0 = time.perf_counter()
        with pytest.raises(EnvironmentFault, match=message):
            probe_scheduler(f"tcp://127.0.0.1:{port}", timeout=1.5)
        assert time.perf_counter() - t0 < 1.5 + 2.0
    finally:
        close()


def test_probe_accepts_a_real_scheduler():
    from distributed import LocalCluster

    with LocalCluster(n_workers=0, processes=False, dashboard_address=None) as cluster:
        assert probe_scheduler(cluster.scheduler_address)["type"] == "Scheduler"


def test_batch_pointed_at_a_web_server_fails_within_10_s(tmp_path):
    port, close = _serve("http")
    try:
        m = _manifest(tmp_path, [_shot(output="o")], defaults="trim = [0, 30]")
        t0 = time.perf_counter()
        p = subprocess.run([sys.executable, "-m", "usdface", "batch", str(m), "--scheduler",
                            f"tcp://127.0.0.1:{port}"], capture_output=True, text=True, timeout=120,
                           env=dict(os.environ))
        seconds = time.perf_counter() - t0
    finally:
        close()
    assert p.returncode == 1 and "Traceback" not in p.stderr
    assert "does not answer as a Dask scheduler within" in p.stderr and "8787 is its dashboard" in p.stderr
    # the probe itself is bounded by PROBE_TIMEOUT; the rest is starting Python and usdface (slower on a loaded
    # machine): measured in the same run, so the bound holds wherever the start-up takes under 10 - 4 s
    t0 = time.perf_counter()
    subprocess.run([sys.executable, "-m", "usdface", "batch", "--help"], capture_output=True, timeout=120)
    startup = time.perf_counter() - t0
    assert seconds - startup < PROBE_TIMEOUT + 4.0, (seconds, startup)  # slack for a loaded machine
    assert not (tmp_path / "o").exists()


# -- the batch never writes over what it reads (issue 20, case 1: data loss) ----------------------

def _digests(*paths):
    import hashlib

    return {str(p): hashlib.sha256(Path(p).read_bytes()).hexdigest() for p in paths}


@pytest.mark.parametrize("target", ["manifest", "layout", "mesh"])
def test_manifest_summary_never_replaces_the_manifest_or_an_input(tmp_path, target, capsys):
    from usdface.cli import main

    layout = tmp_path / "face.layout.json"
    layout.write_bytes((SA / "layouts" / "makehuman_hm08_face.layout.json").read_bytes())
    mesh = tmp_path / "face.obj"
    mesh.write_bytes((SA / "meshes" / "makehuman_hm08_face_cm.obj").read_bytes())
    name = {"manifest": "shots.toml", "layout": "face.layout.json", "mesh": "face.obj"}[target]
    m = _manifest(tmp_path, [_shot(output="out/{capture}", layout=layout, mesh=mesh)],
                  batch=f'summary = "{name}"', defaults="trim = [0, 20]")
    before = _digests(m, layout, mesh)
    code = main(["batch", str(m), "--workers", "0"])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2
    assert len(err) == 1 and f"summary {tmp_path / name}" in err[0] and "would overwrite the input" in err[0]
    assert _digests(m, layout, mesh) == before
    assert not (tmp_path / "out").exists()  # refused before any work


def test_command_line_summary_and_report_never_replace_a_shots_input(tmp_path, capsys):
    from usdface.cli import main

    layout = tmp_path / "face.layout.json"
    layout.write_bytes((SA / "layouts" / "makehuman_hm08_face.layout.json").read_bytes())
    m = _manifest(tmp_path, [_shot(output="out/{capture}", layout=layout)], defaults="trim = [0, 20]")
    before = _digests(m, layout)
    assert main(["batch", str(m), "--workers", "0", "--summary", str(layout)]) == 2
    assert "--summary" in capsys.readouterr().err
    assert main(["batch", str(m), "--workers", "0", "--report", str(layout)]) == 2
    err = capsys.readouterr().err
    assert "--report" in err and "would overwrite the input" in err
    assert _digests(m, layout) == before
    assert not (tmp_path / "out").exists()


def test_a_shot_never_writes_over_another_shots_input(tmp_path):
    # shot 2 reads a layout kept inside the folder shot 1 writes (as a file run would write)
    out1 = tmp_path / "out" / "JawMoCap"
    out1.mkdir(parents=True)
    layout = out1 / "summary.json"
    layout.write_bytes((SA / "layouts" / "makehuman_hm08_face.layout.json").read_bytes())
    m = _manifest(tmp_path, [_shot(output="out/{capture}"), _shot(capture="NoseMoCap", output="out/{capture}",
                                                                  layout=layout)])
    with pytest.raises(InputError, match=r"would overwrite the input .*summary.json \(layout of shot "):
        load_manifest(m)


def test_shots_named_alike_are_told_apart_in_a_clash(tmp_path):
    for name in ("jaw200.csv", "jaw200.trc"):
        (tmp_path / name).write_text("not read: the manifest is checked before any work\n")
    m = _manifest(tmp_path, [_shot(output="out/{capture}") | {"capture": tmp_path / "jaw200.csv"},
                             _shot(output="out/{capture}") | {"capture": tmp_path / "jaw200.trc"}])
    with pytest.raises(InputError, match=r"makehuman_hm08_face_cm/jaw200 \(jaw200.trc\) and "
                                         r"makehuman_hm08_face_cm/jaw200 \(jaw200.csv\) both write"):
        load_manifest(m)
