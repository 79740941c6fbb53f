"""Benchmark: UsdSkel skinning error of the skeleton deliverable against the point cache.

Run:  python benchmarks/skin_weights.py [--work DIR] [--json out.json] [--takes Jaw Eyebrows Nose]

The MakeHuman face (sample_assets/meshes/makehuman_hm08_face_cm.obj, its sample layout) with the
three real AnimFace takes (Jaw, Eyebrows, Nose; stabilised, hybrid distances, interpolating
Gaussian transfer: the defaults of `usdface run`). For every rig and every take it is applied to, a
skeleton layer is written as `usdface skel` writes it (head motion on /Face), deformed by UsdSkel
(BlendShapeQuery + SkinningQuery.ComputeSkinnedPoints, world space) and compared with the take's
point cache (`usdface transfer`'s anim.usdc moved by the head motion H_mesh(f)): max and rms vertex
error over every frame, in cm.

Rigs (weights, joint mapping and corrective shapes are fitted once, then applied to every take):
- dcc/rom: the default, DCC-safe weights fitted on the synthetic range of motion (the character's);
- dcc/<take>: DCC-safe weights fitted on one take's marker motion;
- exact/<take>: the signed transfer-matrix weights, pruned to K and refitted on one take (K = all:
  no pruning, the same for every take).
dcc rigs carry 16 corrective blend shapes, except the dcc/rom rows with 0 shapes (what the
translation-only joints reach alone).
K = 4, 8 and all (every joint). "fit" marks the take a rig was fitted on (others are unseen takes).

Gap frames: each take again with 5% of its marker samples dropped in runs of 10-60 frames (fixed
seed, never on the neutral frame), its own point cache re-solved by the transfer; the rig is
applied to the effective displacements; the error on frames with a missing marker is reported
apart from the other frames of that gapped take.

Placement: the default rig's face centred at the origin, at y = 170 cm and at y = 10 m, skinned
by UsdSkel and moved back, with the writer's float32 weights (rows re-summed to one) and with
plain float32 rounding, against the face at the origin.
"""
from __future__ import annotations

import argparse
import dataclasses
import json
import platform
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
ASSETS = REPO / "sample_assets"
GAP_FRACTION = 0.05
GAP_SEED = 20260
KS = (4, 8, None)


def _cli(*args) -> None:
    from usdface.cli import main

    code = main([str(a) for a in args] + ["-q"])
    if code != 0:
        raise SystemExit(f"usdface {' '.join(map(str, args))} failed ({code})")


def drop_samples(positions: np.ndarray, neutral: int, *, fraction: float, seed: int) -> np.ndarray:
    """Copy of (F, M, 3) positions with runs of 10-60 frames of single markers set to NaN."""
    rng = np.random.default_rng(seed)
    pos = positions.copy()
    f, m, _ = pos.shape
    target = int(round(fraction * f * m))
    gone = np.zeros((f, m), dtype=bool)
    while gone.sum() < target:
        j = int(rng.integers(m))
        length = int(rng.integers(10, 61))
        a = int(rng.integers(0, f - length))
        if a <= neutral < a + length:
            continue
        gone[a:a + length, j] = True
        if gone.all(axis=1).any():  # never a frame without any marker
            gone[a:a + length, j] = False
    pos[gone] = np.nan
    return pos


def prepare(work: Path, take: str) -> dict:
    """Layers of one take (and its gapped copy) through the CLI; returns paths."""
    from usdface.usd.capture_layer import read_capture_layer, write_capture_layer

    d = work / take
    d.mkdir(parents=True, exist_ok=True)
    f = {k: d / v for k, v in dict(mesh="mesh.usdc", capture="capture.usdc", binding="binding.usda",
                                    analysis="analysis.usdc", anim="anim.usdc", gaps="gaps.usdc",
                                    anim_gaps="anim_gaps.usdc").items()}
    if not f["anim_gaps"].exists():
        _cli("import-mesh", ASSETS / "meshes" / "makehuman_hm08_face_cm.obj", "-o", f["mesh"])
        _cli("import-capture", ASSETS / "capture" / f"{take}MoCap.ma", "-o", f["capture"], "--stabilize")
        _cli("bind", "--mesh", f["mesh"], "--capture", f["capture"], "--layout",
             ASSETS / "layouts" / "makehuman_hm08_face.layout.json", "-o", f["binding"])
        _cli("distances", "--mesh", f["mesh"], "--binding", f["binding"], "-o", f["analysis"])
        _cli("transfer", "--mesh", f["mesh"], "--capture", f["capture"], "--binding", f["binding"],
             "--analysis", f["analysis"], "-o", f["anim"])
        cap = read_capture_layer(f["capture"])
        pos = drop_samples(cap.positions, cap.neutral_frame, fraction=GAP_FRACTION, seed=GAP_SEED)
        write_capture_layer(f["gaps"], cap.replace(positions=pos), prov={"processor": "benchmark"})
        _cli("transfer", "--mesh", f["mesh"], "--capture", f["gaps"], "--binding", f["binding"],
             "--analysis", f["analysis"], "-o", f["anim_gaps"])
    return f


def cache_points(path) -> np.ndarray:
    from pxr import Usd

    stage = Usd.Stage.Open(str(path))
    attr = stage.GetPrimAtPath("/Face/Geom").GetAttribute("points")
    return np.stack([np.asarray(attr.Get(t), dtype=np.float64) for t in attr.GetTimeSamples()])


def world(points, hm):
    return points if hm is None else np.matmul(points, hm[:, :3, :3].transpose(0, 2, 1)) + hm[:, None, :3, 3]


class Rig:
    """A fitted rig, applicable to any take of the character."""

    def __init__(self, mode, source, k, fit=None, weights=None):
        self.mode, self.source, self.k, self.fit, self.weights = mode, source, k, fit, weights
        self.shapes = fit.n_shapes if fit is not None else 0

    def write(self, path, inputs, mesh_path):
        from usdface.skel import SkinFit, build_rig
        from usdface.usd.skel_layer import write_skel_layer

        d = inputs.effective
        if self.mode == "dcc":
            tr, weights = self.fit.joint_translations(d), self.fit.weights
            shapes, sw = self.fit.shapes, self.fit.shape_weights(d)
        else:
            tr, weights, shapes, sw = d, self.weights, None, None
        rig = build_rig(inputs.binding.names, inputs.bound_points, tr)
        write_skel_layer(path, rig, SkinFit(weights, tr, shapes, sw), mesh_path=mesh_path, rate=inputs.capture.rate,
                         start=inputs.capture.start_frame, prov={"processor": "benchmark"},
                         head_motion=inputs.head_motion)


def usdskel_error(rig, inputs, mesh_path, cache, tmp: Path, frames=None):
    from usdface.usd.skel_layer import skinned_points

    path = tmp / "rig.usdc"
    rig.write(path, inputs, mesh_path)
    _, pts = skinned_points(path, space="world")
    err = np.linalg.norm(pts - world(cache, inputs.head_motion), axis=2)
    return err


def stats(err) -> tuple[float, float]:
    return float(err.max()), float(np.sqrt((err ** 2).mean()))


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--work", type=Path, help="folder for the layers (default: a temporary one)")
    ap.add_argument("--json", type=Path)
    ap.add_argument("--takes", nargs="+", default=["Jaw", "Eyebrows", "Nose"])
    args = ap.parse_args(argv)
    from usdface import __version__
    from usdface.skel import fit_dcc, full_weights, prune_weights, skel_inputs
    from usdface.skel.weights import motion_gram
    from usdface.usd.inputs import load_transfer_inputs

    def load_skel_inputs(*paths):
        return skel_inputs(*load_transfer_inputs(*paths))

    tmpdir = tempfile.TemporaryDirectory()
    work = args.work or Path(tmpdir.name)
    tmp = Path(tempfile.mkdtemp(dir=work))
    t0 = time.perf_counter()
    files = {t: prepare(work, t) for t in args.takes}
    prep = time.perf_counter() - t0
    inputs = {t: load_skel_inputs(f["mesh"], f["capture"], f["binding"], f["analysis"]) for t, f in files.items()}
    gapped = {t: load_skel_inputs(f["mesh"], f["gaps"], f["binding"], f["analysis"]) for t, f in files.items()}
    caches = {t: cache_points(f["anim"]) for t, f in files.items()}
    gap_caches = {t: cache_points(f["anim_gaps"]) for t, f in files.items()}
    b = inputs[args.takes[0]].transfer_matrix
    for t in args.takes[1:]:
        assert np.array_equal(inputs[t].transfer_matrix, b), "one character: the same transfer matrix for every take"

    rigs, fit_seconds = [], {}
    for k in KS:
        t1 = time.perf_counter()
        rigs.append(Rig("dcc", "rom", k, fit=fit_dcc(inputs[args.takes[0]], k, skin_fit="rom")))
        fit_seconds[f"dcc/rom K={k or 'all'}"] = time.perf_counter() - t1
    for k in KS:  # what translation-only joints reach without the corrective shapes
        rigs.append(Rig("dcc", "rom", k, fit=fit_dcc(inputs[args.takes[0]], k, skin_fit="rom", n_shapes=0)))
    for src in args.takes:
        for k in KS:
            t1 = time.perf_counter()
            rigs.append(Rig("dcc", src, k, fit=fit_dcc(inputs[src], k, skin_fit="take")))
            fit_seconds[f"dcc/{src} K={k or 'all'}"] = time.perf_counter() - t1
    full = full_weights(b)
    rigs.append(Rig("exact", "any", None, weights=prune_weights(full, None)))
    for src in args.takes:
        gram = motion_gram(inputs[src].effective)
        for k in (4, 8):
            rigs.append(Rig("exact", src, k, weights=prune_weights(full, k, gram=gram)))

    rows = []
    for rig in rigs:
        row = {"mode": rig.mode, "fit": rig.source, "K": rig.k or "all", "shapes": rig.shapes, "takes": {}}
        for t in args.takes:
            err = usdskel_error(rig, inputs[t], files[t]["mesh"], caches[t], tmp)
            gerr = usdskel_error(rig, gapped[t], files[t]["mesh"], gap_caches[t], tmp)
            gaps = gapped[t].gap_frames
            other = np.setdiff1d(np.arange(gerr.shape[0]), gaps)
            row["takes"][t] = {"max": stats(err)[0], "rms": stats(err)[1],
                               "gapMax": stats(gerr[gaps])[0], "gapRms": stats(gerr[gaps])[1],
                               "gapTakeOtherMax": stats(gerr[other])[0], "gapFrames": int(gaps.size),
                               "frames": int(err.shape[0])}
        rows.append(row)
        print(".", end="", flush=True, file=sys.stderr)
    print(file=sys.stderr)

    # placement: the default rig far from the origin
    placement = placement_check(inputs[args.takes[0]], rigs[1].fit, files[args.takes[0]]["mesh"], tmp)

    print(f"# UsdSkel skinning error vs the point cache (cm), MakeHuman hm08 face, usdface {__version__}, "
          f"{platform.python_version()}, numpy {np.__version__}")
    print()
    t = args.takes
    first = rows[0]["takes"]
    frames = ", ".join(f"{x} {first[x]['frames']}" for x in t)
    gap_frames = ", ".join(f"{x} {first[x]['gapFrames']} gap frames" for x in t)
    print(f"Frames: {frames}; gapped copies: {gap_frames} ({GAP_FRACTION:.0%} of samples dropped in runs, "
          f"seed {GAP_SEED}).")
    motion = {x: float(np.linalg.norm(caches[x] - caches[x][inputs[x].capture.neutral_frame], axis=2).max()) for x in t}
    print("Largest vertex motion in the point cache (stabilised): "
          + ", ".join(f"{x} {v:.2f} cm" for x, v in motion.items()) + ".")
    print()
    head = " | ".join(f"{x} max / rms | {x} gap frames max" for x in t)
    print(f"| weights | fitted on | K | shapes | {head} |")
    print("|---|---|---|---|" + "---|---|" * len(t))
    for r in rows:
        cells = []
        for x in t:
            v = r["takes"][x]
            mark = " (fit)" if r["fit"] == x else ""
            cells.append(f"{v['max']:.3f} / {v['rms']:.4f}{mark} | {v['gapMax']:.3f}")
        print(f"| {r['mode']} | {r['fit']} | {r['K']} | {r['shapes']} | " + " | ".join(cells) + " |")
    print()
    print("Fit times (s, 2020 vertices, 41 markers): "
          + ", ".join(f"{name} {sec:.2f}" for name, sec in fit_seconds.items()))
    print()
    print("Placement (default rig, K = 8; max distance from the face at the origin over "
          f"{placement['frames']} frames, cm):")
    for name, v in placement["rows"].items():
        print(f"  {name}: " + ", ".join(f"{h}: {e:.2e}" for h, e in v.items()))
    print(f"\nprepare {prep:.1f} s, total {time.perf_counter() - t0:.1f} s")
    if args.json:
        args.json.write_text(json.dumps({"rows": rows, "fitSeconds": fit_seconds, "placement": placement},
                                        indent=2, default=float))
    return 0


def placement_check(inputs, fit, mesh_path, tmp: Path) -> dict:
    """The default rig's face at the origin, y = 170 cm and y = 10 m, with the writer's float32 weights
    and with plain float32 rounding of the weights (what the rows-sum-to-one correction is for)."""
    import usdface.usd.skel_layer as skel_layer
    from usdface.skel import SkinFit, build_rig
    from usdface.usd.mesh_layer import read_mesh_layer, write_mesh_layer
    from usdface.usd.skel_layer import skinned_points, write_skel_layer

    mesh, regions = read_mesh_layer(mesh_path)
    centre = 0.5 * (mesh.points.min(axis=0) + mesh.points.max(axis=0))
    chin = inputs.binding.names.index("Chin")
    frames = sorted({inputs.capture.neutral_frame, int(np.argmax(np.linalg.norm(inputs.effective[:, chin], axis=1))),
                     *range(0, inputs.capture.n_frames, 53)})
    d = inputs.effective[frames]

    def skin(height, *, plain):
        shift = np.array([0.0, height, 0.0]) - centre
        mp, sp = tmp / f"m{height:g}.usdc", tmp / f"s{height:g}.usdc"
        write_mesh_layer(mp, dataclasses.replace(mesh, points=mesh.points + shift), regions, prov={"p": "b"})
        rig = build_rig(inputs.binding.names, inputs.bound_points + shift, fit.joint_translations(d))
        saved = skel_layer.float32_weights
        if plain:
            skel_layer.float32_weights = lambda w: np.ascontiguousarray(w, dtype=np.float32)
        try:
            skin = SkinFit(fit.weights, fit.joint_translations(d), fit.shapes, fit.shape_weights(d))
            write_skel_layer(sp, rig, skin, mesh_path=mp, rate=60.0, start=0.0, prov={"p": "b"})
        finally:
            skel_layer.float32_weights = saved
        return skinned_points(sp)[1] - shift

    out = {}
    for plain in (False, True):
        ref = skin(0.0, plain=plain)
        name = "plain float32 weights" if plain else "float32 weights, rows re-summed to one (written)"
        out[name] = {f"y = {h:g} cm": float(np.linalg.norm(skin(h, plain=plain) - ref, axis=2).max())
                     for h in (170.0, 1000.0)}
    return {"frames": len(frames), "rows": out}


if __name__ == "__main__":
    sys.exit(main())
