"""Layers for the skel and lift tests, made once per session through the real CLI."""
from __future__ import annotations

import numpy as np
import pytest

import usdface.cli as cli_module


def run(*args) -> int:
    """`usdface ARGS...` in-process; returns the exit code."""
    return cli_module.main([str(a) for a in args])


@pytest.fixture(scope="session")
def ucli():
    return run


def mesh_points(path, prim="/Face/Geom"):
    """(F, N, 3) time-sampled points (or (1, N, 3) rest points) of the mesh prim of a layer."""
    from pxr import Usd

    stage = Usd.Stage.Open(str(path))
    attr = stage.GetPrimAtPath(prim).GetAttribute("points")
    times = attr.GetTimeSamples()
    if not times:
        return np.asarray(attr.Get(), dtype=np.float64)[None]
    return np.stack([np.asarray(attr.Get(t), dtype=np.float64) for t in times])


@pytest.fixture(scope="session")
def points_of():
    """mesh_points(path) -> (F, N, 3) points of /Face/Geom."""
    return mesh_points


@pytest.fixture(scope="session")
def jaw(tmp_path_factory, sample_assets):
    """hm08 mesh, stabilised Jaw capture, layout binding, hybrid distances, transfer point cache;
    and a copy of the capture with markers missing in some frames, with its own point cache."""
    from usdface.usd.capture_layer import read_capture_layer, write_capture_layer

    d = tmp_path_factory.mktemp("skel")
    f = {"dir": d, "mesh": d / "mesh.usdc", "capture": d / "capture.usdc", "binding": d / "binding.usda",
         "analysis": d / "analysis.usdc", "anim": d / "anim.usdc", "gaps": d / "gaps.usdc",
         "anim_gaps": d / "anim_gaps.usdc",
         "layout": sample_assets / "layouts" / "makehuman_hm08_face.layout.json"}
    assert run("import-mesh", sample_assets / "meshes" / "makehuman_hm08_face_cm.obj", "-o", f["mesh"], "-q") == 0
    assert run("import-capture", sample_assets / "capture" / "JawMoCap.ma", "-o", f["capture"], "--stabilize",
               "-q") == 0
    assert run("bind", "--mesh", f["mesh"], "--capture", f["capture"], "--layout", f["layout"], "-o", f["binding"],
               "-q") == 0
    assert run("distances", "--mesh", f["mesh"], "--binding", f["binding"], "-o", f["analysis"], "-q") == 0
    assert run("transfer", "--mesh", f["mesh"], "--capture", f["capture"], "--binding", f["binding"],
               "--analysis", f["analysis"], "-o", f["anim"], "-q") == 0
    cap = read_capture_layer(f["capture"])
    pos = cap.positions.copy()
    pos[400:460, cap.index("Mouth_DownL")] = np.nan      # a lower-lip marker lost while the jaw moves
    pos[400:430, cap.index("Chin")] = np.nan
    pos[900:905, cap.index("ForeHead_M")] = np.nan
    write_capture_layer(f["gaps"], cap.replace(positions=pos), prov={"processor": "test"})
    assert run("transfer", "--mesh", f["mesh"], "--capture", f["gaps"], "--binding", f["binding"],
               "--analysis", f["analysis"], "-o", f["anim_gaps"], "-q") == 0
    return f
