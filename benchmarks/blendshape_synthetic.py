"""Exact truth for the blend-shape solver: synthetic takes on the real MakeHuman ARKit rig.

Smooth random weight curves over the shapes 41 markers can observe (every shape but tongueOut and
the eyeLook* shapes), at most 6 active per frame, fixed seed; markers = the 41 bound points of the
sample layout moved by the shapes, Gaussian noise of 0.5 mm per coordinate, 5% of the (frame,
marker) samples missing. Solved with the solver's defaults (``usdface solve``'s), then again with
one shape removed from the rig (the take still made with the full rig).

Reported: weight RMS over all shapes and frames, a per-shape table (RMS, bias, largest error), and
the mesh error = sum over moving frames and vertices of |posed - true| / sum of |true
displacement| (a moving frame: any true weight > 0), and the same with issue 19's moving frames
(mean true displacement above 0.5 mm; ``benchmarks/solve_metrics.py``). The noise here is on the
displacements (the neutral is exact) and the solver is called directly: the rest pose and the
pose refit of :func:`usdface.blendshape.take.solve_take` do not enter
(``benchmarks/blendshape_heldout.py --tuning`` has them).

    python benchmarks/blendshape_synthetic.py [--frames 3600] [--remove mouthSmileLeft] [--seed 0]
"""
from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]


def load():
    from usdface.blendshape.rig import load_npz_rig, marker_basis
    from usdface.io.meshes import read_mesh
    from usdface.mesh.layout import read_layout
    from usdface.mesh.layout_binding import binding_from_layout

    mesh = read_mesh(ROOT / "sample_assets/meshes/makehuman_hm08_face_cm.obj")
    rig = load_npz_rig(ROOT / "sample_assets/meshes/makehuman_hm08_face_units_cm.npz", mesh)
    binding = binding_from_layout(mesh, read_layout(ROOT / "sample_assets/layouts/makehuman_hm08_face.layout.json"))
    return rig, binding, marker_basis(rig, binding)


def mesh_error(rig_deltas, truth_w, est_deltas, est_w) -> float:
    """sum |posed - true| / sum |true displacement| over moving frames (vertex norms)."""
    moving = (truth_w > 0).any(axis=1)
    t = np.einsum("fk,knd->fnd", truth_w[moving], rig_deltas)
    e = np.einsum("fk,knd->fnd", est_w[moving], est_deltas)
    return float(np.linalg.norm(e - t, axis=2).sum() / np.linalg.norm(t, axis=2).sum())


def issue19_mesh_error(rig_deltas, truth_w, est_deltas, est_w) -> float:
    """The mesh error as issue 19 defines it (frames whose mean true displacement exceeds 0.5 mm)."""
    import sys

    sys.path.insert(0, str(Path(__file__).resolve().parent))
    from solve_metrics import mesh_error as mesh_error_19

    return mesh_error_19(rig_deltas, truth_w, est_deltas, est_w)


def run(frames: int, seed: int, remove: str | None, options: dict, *, table: bool = True) -> dict:
    from usdface.blendshape.mirror import find_mirror_pairs
    from usdface.blendshape.solver import CurveSolver, SolverParameters
    from usdface.blendshape.synthetic import observable_shapes, random_weight_curves, synthetic_take
    from usdface.blendshape.take import DEFAULT_EXCLUDE, resolve_exclude

    rig, binding, basis = load()
    truth = random_weight_curves(frames, rig.n_shapes, shapes=observable_shapes(rig.names), max_active=6, seed=seed)
    take = synthetic_take(basis, truth, noise=0.05, missing=0.05, seed=seed + 1)
    out = {"frames": frames, "activeMax": int((truth > 0).sum(axis=1).max()),
           "activeMean": float((truth > 0).sum(axis=1).mean())}
    for label, keep in (("full rig", list(rig.names)), (f"without {remove}", [n for n in rig.names if n != remove])):
        if label != "full rig" and remove is None:
            continue
        sub = rig.subset(keep)
        idx = [rig.index(n) for n in keep]
        solver = CurveSolver(basis[:, idx], names=keep, marker_names=binding.names,
                             symmetric_pairs=find_mirror_pairs(sub).symmetric_pairs,
                             exclude=resolve_exclude(options.get("exclude", DEFAULT_EXCLUDE), keep),
                             params=SolverParameters(**{k: v for k, v in options.items() if k != "exclude"}))
        t0 = time.perf_counter()
        sol = solver.solve(take.displacements, rate=take.rate)
        seconds = time.perf_counter() - t0
        est = sol.weights
        err = est - truth[:, idx]
        rms = float(np.sqrt((err ** 2).mean()))
        merr = mesh_error(rig.deltas, truth, sub.deltas, est)
        merr19 = issue19_mesh_error(rig.deltas, truth, sub.deltas, est)
        out[label] = {"weightRMS": rms, "meshError": merr, "meshError19": merr19, "seconds": seconds,
                      "iterations": sol.iterations}
        print(f"\n## {label}: {frames} frames, {len(keep)} shapes, {take.valid.size - take.valid.sum()} missing samples "
              f"({100 * (1 - take.valid.mean()):.1f}%), active per frame max {out['activeMax']} mean "
              f"{out['activeMean']:.2f}")
        print(f"weight RMS over all shapes and frames: {rms:.4f}   mesh error (moving frames): {100 * merr:.2f}%   "
              f"(issue 19's definition: {100 * merr19:.2f}%)   solve {seconds:.3f} s, {sol.iterations} iterations")
        if table:
            print("\n| shape | weight RMS | bias | max abs error | true mean | active frames |")
            print("|---|---|---|---|---|---|")
            for j, n in enumerate(keep):
                tw = truth[:, idx[j]]
                print(f"| {n} | {np.sqrt((err[:, j] ** 2).mean()):.4f} | {err[:, j].mean():+.4f} | "
                      f"{np.abs(err[:, j]).max():.3f} | {tw.mean():.3f} | {int((tw > 0).sum())} |")
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--frames", type=int, default=3600, help="take length (default 3600 = 1 min at 60 Hz)")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--remove", default="mouthSmileLeft", help="the shape removed from the rig for the second solve")
    ap.add_argument("--smoothing", type=float, help="override the solver's smoothing (Hz)")
    ap.add_argument("--sparsity", type=float)
    ap.add_argument("--symmetry", type=float)
    ap.add_argument("--no-refit", action="store_true")
    ap.add_argument("--no-table", action="store_true")
    args = ap.parse_args(argv)
    options = {}
    if args.smoothing is not None:
        options["smoothing_hz"] = args.smoothing or None
    if args.sparsity is not None:
        options["sparsity"] = args.sparsity
    if args.symmetry is not None:
        options["symmetry"] = args.symmetry
    if args.no_refit:
        options["refit"] = False
    run(args.frames, args.seed, args.remove, options, table=not args.no_table)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
