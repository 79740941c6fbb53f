"""A face without a rig: the generic MakeHuman rig transferred through `register`, solve vs RBF.

The stylized MakeHuman face is treated as unrigged: ``usdface shapes transfer`` registers the
generic MakeHuman face onto it from the 20 landmarks (its shared topology is never used) and
carries the 52 shapes over. Reference: the same shapes copied vertex for vertex through the
shared topology (what the stylized face's artist-made expressions would be if it had been rigged
like the generic). Reported, per region as in ``usdface evaluate`` (% of each shape's mean
displacement, averaged over the 51 shapes moving more than 1 mm; face / mouth / eyes / rest and
lips and lids):

1. the transferred rig against the copied one (both transfer methods);
2. each copied expression captured at the stylized face's 41 bound markers and rebuilt four ways:
   the pipeline's RBF transfer (hybrid distances, interpolate, border pinned above the mouth
   corners: the default of ``usdface run``); the blend-shape solve on the transferred rig; the same
   solve with the expression's own shape left out of the rig (an expression the rig does not have,
   which is what real faces show); and that left-out solve plus the RBF transfer of its marker
   residual (``solve --corrective``). The solve on the copied rig is the upper bound a perfect
   transfer would give.

    python benchmarks/blendshape_unrigged.py [--method displacement|deformation]
"""
from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
REGIONS = ("face", "mouth", "eyes", "rest", "upperLip", "lowerLip", "leftUpperLid", "leftLowerLid")


def _pct(errors, truth_mean):
    """(F, R) mean errors -> (R,) mean over shapes of % of the shape's mean displacement."""
    return np.nanmean(100.0 * errors / truth_mean[:, None], axis=0)


def _row(label, values):
    return f"| {label} | " + " | ".join(f"{v:.1f}%" for v in values) + " |"


def main(argv=None) -> int:
    from usdface.blendshape.rig import BlendShapeRig, marker_basis
    from usdface.blendshape.solver import CurveSolver
    from usdface.blendshape.rig_transfer import copy_through_topology
    from usdface.evaluation.quality import REGION_NAMES, TransferConfig, TransferSetup, select_shapes, shape_errors
    from usdface.io.meshes import read_mesh
    from usdface.mesh.layout import read_layout
    from usdface.mesh.topology import find_hole_regions
    from usdface.mesh.layout_binding import binding_from_layout
    from usdface import api
    from usdface.options import ShapesTransferOptions
    from usdface.usd.blendshape_layer import read_blendshape_rig

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--method", choices=["displacement", "deformation", "both"], default="both")
    args = ap.parse_args(argv)
    a = ROOT / "sample_assets"
    generic_mesh = read_mesh(a / "meshes/makehuman_hm08_face_cm.obj")
    z = np.load(a / "meshes/makehuman_hm08_face_units_cm.npz")
    generic = BlendShapeRig(tuple(str(n) for n in z["names"]), z["deltas"], generic_mesh)
    target = read_mesh(a / "meshes/makehuman_hm08_face_stylized_cm.obj")
    regions = find_hole_regions(target)
    copied = copy_through_topology(generic, target)
    names, truth, _ = select_shapes(copied.names, copied.deltas)
    binding = binding_from_layout(target, read_layout(a / "layouts/makehuman_hm08_face_stylized.layout.json"))
    setup = TransferSetup(target, regions, binding)
    masks = [setup.regions[r] for r in REGION_NAMES]
    cols = [REGION_NAMES.index(r) for r in REGIONS]
    truth_mean = np.linalg.norm(truth, axis=2).mean(axis=1)
    markers = np.einsum("mj,fmjd->fmd", binding.barycentrics, truth[:, binding.triangle_vertices])
    header = "| | " + " | ".join(REGIONS) + " |\n|---|" + "---|" * len(REGIONS)
    header2 = "| | " + " | ".join(REGIONS) + " | jawOpen mouth (cm) |\n|---|" + "---|" * (len(REGIONS) + 1)
    j = names.index("jawOpen")
    mouth_col = REGION_NAMES.index("mouth")

    methods = ["displacement", "deformation"] if args.method == "both" else [args.method]
    rigs = {}
    print(f"stylized face, {len(names)} expression shapes moving > 1 mm, 41 markers (its own layout)\n")
    print("## 1. Transferred rig vs the rig copied through the shared topology\n")
    print(header)
    with tempfile.TemporaryDirectory() as tmp:
        for m in methods:
            t0 = time.perf_counter()
            api.shapes_transfer(str(a / "meshes/makehuman_hm08_face_stylized_cm.obj"),
                                str(a / "landmarks/makehuman_hm08_face_stylized.landmarks.layout.json"),
                                ShapesTransferOptions(
                                    generic=str(a / "meshes/makehuman_hm08_face_cm.obj"),
                                    generic_shapes=str(a / "meshes/makehuman_hm08_face_units_cm.npz"),
                                    generic_landmarks=str(a / "landmarks/makehuman_hm08_face.landmarks.layout.json"),
                                    method=m),
                                output=Path(tmp) / f"{m}.usdc")
            usd = read_blendshape_rig(Path(tmp) / f"{m}.usdc")
            rig = BlendShapeRig(tuple(usd.names), usd.deltas, target)
            rigs[m] = rig
            mean_e, _ = shape_errors(rig.deltas[[rig.index(n) for n in names]], truth, masks)
            print(_row(f"`shapes transfer --method {m}` ({time.perf_counter() - t0:.1f} s)",
                       _pct(mean_e, truth_mean)[cols]))
    print("\n## 2. Expressions rebuilt from the 41 markers (error vs the copied expression)\n")
    print(header2)

    def report(label, pred):
        err = shape_errors(pred, truth, masks)[0]
        print(_row(label, _pct(err, truth_mean)[cols])[:-2] + f" | {err[j, mouth_col]:.3f} |")

    rbf = setup.predict(TransferConfig("hybrid", pin="upper"), markers)
    rbf_solver = setup.transfer(TransferConfig("hybrid", pin="upper"))
    report("RBF transfer (hybrid, interpolate: `usdface run`)", rbf)

    def solve_with(rig, leave_out: bool, corrective: bool):
        basis = marker_basis(rig, binding)
        out = np.empty_like(truth)
        for f, n in enumerate(names):
            keep = [k for k, m in enumerate(rig.names) if not (leave_out and m == n)]
            solver = CurveSolver(basis[:, keep], names=[rig.names[k] for k in keep])
            w = solver.solve(markers[f:f + 1], rate=60.0).weights[0]
            posed = np.einsum("k,knd->nd", w, rig.deltas[keep])
            if corrective:
                fit = np.einsum("k,mkd->md", w, basis[:, keep])
                posed = posed + rbf_solver.apply((markers[f] - fit)[None], dtype=np.float64)[0]
            out[f] = posed
        return out

    cases = [("copied rig (the upper bound)", copied, False, False)]
    for m in methods:
        cases += [(f"solve, {m}-transferred rig", rigs[m], False, False),
                  (f"solve + corrective, {m}-transferred rig", rigs[m], False, True),
                  (f"solve, {m}-transferred rig, expression left out", rigs[m], True, False),
                  (f"solve + corrective, {m}-transferred rig, expression left out", rigs[m], True, True)]
    for label, rig, loo, corr in cases:
        report(label, solve_with(rig, loo, corr))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
