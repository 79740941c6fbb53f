"""Cost of the layer identities (issue 20, item 2) on a film-resolution face.

    python benchmarks/bench_identity.py [--n 17] [--repeats 7] [--out /tmp/usdface-identity]

The MakeHuman face refined 1-to-n^2 (n = 17: about 560k vertices) is written as a mesh layer; then,
interleaved and repeated, with medians:

- ``mesh identity``: :func:`usdface.usd.identity.mesh_record` of the FaceMesh a processor has read
  (what `distances`, `transfer`, `skel`, ... add per mesh input and per layer written);
- ``read mesh layer``: :func:`usdface.usd.mesh_layer.read_mesh_layer` of the same file, the work every
  such processor does anyway before it (the baseline of the ratio);
- ``composed mesh identity``: :func:`usdface.usd.identity.prim_mesh_record` on the opened stage (what
  `check` and `info` compute);
- the take identity of the whole Jaw take (1590 frames x 41 markers) against reading its capture
  layer;
- on the shot `usdface run` writes for the whole Jaw take (MakeHuman face, Euclidean): the shot
  writer's agreement check (:func:`usdface.usd.identity.agreeing_identity`: the layers' metadata and
  the files they compose) against writing the shot stage with it, and what `playblast` and `report`
  add (:func:`usdface.usd.identity.mixed_layers`: check's identity findings, which hash the composed
  mesh and read the capture layer) against opening the shot for playback
  (:meth:`usdface.usd.playback.ShotReader.open`).

Prints the medians, the bytes hashed and the ratios against the baselines measured in the same run.
"""
from __future__ import annotations

import argparse
import os
import statistics
import sys
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))
SAMPLES = REPO / "sample_assets"


def _timed(fn) -> float:
    t0 = time.perf_counter()
    fn()
    return time.perf_counter() - t0


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--n", type=int, default=17)
    ap.add_argument("--repeats", type=int, default=7)
    ap.add_argument("--out", default="/tmp/usdface-identity")
    args = ap.parse_args()
    import numpy as np
    from pxr import Usd

    import usdface
    from usdface import api
    from usdface.distance.graph import refine_triangles
    from usdface.io.meshes import read_mesh
    from usdface.model.mesh import FaceMesh
    from usdface.usd.capture_layer import read_capture_layer
    from usdface.usd.identity import capture_record, mesh_record, prim_mesh_record
    from usdface.usd.layers import provenance
    from usdface.usd.mesh_layer import find_mesh, read_mesh_layer, write_mesh_layer

    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    base = read_mesh(SAMPLES / "meshes" / "makehuman_hm08_face_cm.obj")
    p, t = refine_triangles(base.points, base.triangles(), args.n)
    mesh = FaceMesh(points=p, face_vertex_counts=np.full(len(t), 3), face_vertex_indices=t.ravel(), units="cm")
    path = out / f"face_n{args.n}.usdc"
    write_mesh_layer(path, mesh, [], prov=provenance("bench", options={}, inputs={}))
    read, _ = read_mesh_layer(path)
    hashed = read.n_points * 12 + read.n_faces * 4 + read.face_vertex_indices.size * 4
    capture = out / "jaw.usdc"
    if not capture.is_file():
        api.import_capture(str(SAMPLES / "capture" / "JawMoCap.ma"), output=capture)
    take = read_capture_layer(capture)
    print(f"usdface from {Path(usdface.__file__).parent}; {os.cpu_count()} CPUs, load average "
          f"{os.getloadavg()[0]:.1f}")
    print(f"mesh: {read.n_points} vertices, {read.n_faces} triangles; identity hashes {hashed / 1e6:.1f} MB")

    stage = Usd.Stage.Open(str(path))
    prim = find_mesh(stage)
    assert mesh_record(read) == prim_mesh_record(prim)[0]
    cases = {"mesh identity": lambda: mesh_record(read), "read mesh layer": lambda: read_mesh_layer(path),
             "composed mesh identity": lambda: prim_mesh_record(prim),
             "take identity": lambda: capture_record(take), "read capture layer": lambda: read_capture_layer(capture)}
    times = {name: [] for name in cases}
    for _ in range(args.repeats):  # interleaved: load changes hit every case alike
        for name, fn in cases.items():
            times[name].append(_timed(fn))
    med = {name: statistics.median(v) for name, v in times.items()}
    for name, v in med.items():
        print(f"  {name:24s} median {1e3 * v:8.1f} ms  (min {1e3 * min(times[name]):.1f}, max "
              f"{1e3 * max(times[name]):.1f})")
    print(f"mesh identity: {hashed / med['mesh identity'] / 1e6:.0f} MB/s; "
          f"{med['mesh identity'] / med['read mesh layer']:.2f}x the read of the mesh layer; composed "
          f"{med['composed mesh identity'] / med['read mesh layer']:.2f}x")
    print(f"take identity ({take.n_frames} frames x {take.n_markers} markers): "
          f"{med['take identity'] / med['read capture layer']:.3f}x the read of the capture layer")
    _shot_costs(out, args.repeats)
    return 0


def _shot_costs(out: Path, repeats: int) -> None:
    """The shot writer's agreement check and the readers' identity findings on a run's shot."""
    from usdface.cli import main as usdface
    from usdface.usd.analysis_layer import write_shot_stage
    from usdface.usd.identity import agreeing_identity, mixed_layers
    from usdface.usd.playback import ShotReader

    shot_dir = out / "jaw_shot"
    if not (shot_dir / "shot.usda").is_file():
        assert usdface(["run", "--mesh", str(SAMPLES / "meshes" / "makehuman_hm08_face_cm.obj"), "--capture",
                        str(SAMPLES / "capture" / "JawMoCap.ma"), "--layout",
                        str(SAMPLES / "layouts" / "makehuman_hm08_face.layout.json"), "--method", "euclidean",
                        "-o", str(shot_dir), "-q"]) == 0
    layers = [shot_dir / n for n in ("anim.usdc", "analysis.usdc", "binding.usda")]
    shot = shot_dir / "shot.usda"
    scratch = out / "shot_again.usda"
    cases = {"agreeing identity": lambda: agreeing_identity(layers, what="shot"),
             "write shot stage": lambda: write_shot_stage(scratch, layers=layers, rate=60, start=0, end=1589,
                                                          units="cm", record={"runId": "bench", "files": {}}),
             "mixed layers": lambda: mixed_layers(shot), "open shot": lambda: ShotReader.open(shot)}
    times = {name: [] for name in cases}
    for _ in range(repeats):
        for name, fn in cases.items():
            times[name].append(_timed(fn))
    med = {name: statistics.median(v) for name, v in times.items()}
    print(f"run shot of the whole Jaw take ({shot_dir}):")
    for name, v in med.items():
        print(f"  {name:24s} median {1e3 * v:8.1f} ms  (min {1e3 * min(times[name]):.1f}, max "
              f"{1e3 * max(times[name]):.1f})")
    writer = med["agreeing identity"] / med["write shot stage"]
    readers = med["mixed layers"] / med["open shot"]
    print(f"shot writer: the agreement check is {writer:.2f}x of writing the stage (which includes it); "
          f"playblast/report: identity findings {readers:.2f}x the opening of the shot for playback")


if __name__ == "__main__":
    sys.exit(main())
