"""The face evaluator (usdface/usd/evaluate.py) walking a whole take, as a playblast would.

A synthetic skinned face (N points, 42 joints, 8 influences per point, 1590 frames at 60 Hz, a
time-sampled head transform on the SkelRoot as usdface delivers it) and the same take as a point
cache. Measures, in one run on this machine, wall and CPU seconds for:
  (a) FaceEvaluator.iter_points over every frame, world space (skinned and point cache);
  (b) the baseline: the bare UsdSkel loop (SkeletonQuery.ComputeSkinningTransforms +
      SkinningQuery.ComputeSkinnedPoints + np.asarray per frame, no placement in world space);
and prints (a)/(b). Run by hand:  python benchmarks/bench_evaluate.py [--points 2000 20000]
"""
from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

FRAMES = 1590
JOINTS = 42
K = 8


def build(folder: Path, n: int) -> tuple[Path, Path]:
    """A skinned layer and a point-cache layer of one synthetic take."""
    from pxr import Gf, Usd, UsdGeom, UsdSkel, Vt

    rng = np.random.default_rng(0)
    rest = rng.normal(scale=8, size=(n, 3)).astype(np.float32) + np.float32([0, 70, 10])
    head = [Gf.Matrix4d().SetTranslate(Gf.Vec3d(*rng.normal(scale=0.3, size=3))) for _ in range(FRAMES)]
    paths = []
    for kind in ("skel", "points"):
        path = folder / f"{kind}.usdc"
        stage = Usd.Stage.CreateNew(str(path))
        stage.SetStartTimeCode(0)
        stage.SetEndTimeCode(FRAMES - 1)
        stage.SetTimeCodesPerSecond(60)
        root = (UsdSkel.Root if kind == "skel" else UsdGeom.Xform).Define(stage, "/Face")
        stage.SetDefaultPrim(root.GetPrim())
        op = root.AddTransformOp()
        for f in range(FRAMES):
            op.Set(head[f], f)
        mesh = UsdGeom.Mesh.Define(stage, "/Face/Geom")
        mesh.CreatePointsAttr(Vt.Vec3fArray.FromNumpy(rest))
        if kind == "skel":
            skel = UsdSkel.Skeleton.Define(stage, "/Face/Skeleton")
            names = ["Head"] + [f"Head/J{i}" for i in range(JOINTS - 1)]
            skel.CreateJointsAttr(names)
            pos = rng.normal(scale=5, size=(JOINTS, 3)) + [0, 70, 10]
            bind = [Gf.Matrix4d().SetTranslate(Gf.Vec3d(*p)) for p in pos]
            skel.CreateBindTransformsAttr(Vt.Matrix4dArray(bind))
            rest_local = [bind[0]] + [Gf.Matrix4d().SetTranslate(Gf.Vec3d(*(p - pos[0]))) for p in pos[1:]]
            skel.CreateRestTransformsAttr(Vt.Matrix4dArray(rest_local))
            anim = UsdSkel.Animation.Define(stage, "/Face/Skeleton/Anim")
            anim.CreateJointsAttr(names)
            UsdSkel.BindingAPI.Apply(skel.GetPrim()).CreateAnimationSourceRel().SetTargets([anim.GetPath()])
            binding = UsdSkel.BindingAPI.Apply(mesh.GetPrim())
            binding.CreateSkeletonRel().SetTargets([skel.GetPath()])
            idx = np.argsort(rng.random((n, JOINTS)), axis=1)[:, :K].astype(np.int32)
            w = rng.random((n, K)).astype(np.float32)
            w /= w.sum(axis=1, keepdims=True)
            binding.CreateJointIndicesPrimvar(False, K).Set(Vt.IntArray.FromNumpy(idx.ravel()))
            binding.CreateJointWeightsPrimvar(False, K).Set(Vt.FloatArray.FromNumpy(w.ravel()))
            offsets = np.r_[[pos[0]], pos[1:] - pos[0]].astype(np.float32)
            t_attr, r_attr, s_attr = anim.CreateTranslationsAttr(), anim.CreateRotationsAttr(), anim.CreateScalesAttr()
            for f in range(FRAMES):
                t_attr.Set(Vt.Vec3fArray.FromNumpy(offsets + rng.normal(scale=0.3, size=(JOINTS, 3)).astype(np.float32)), f)
                r_attr.Set(Vt.QuatfArray([Gf.Quatf(1)] * JOINTS), f)
                s_attr.Set(Vt.Vec3hArray([Gf.Vec3h(1, 1, 1)] * JOINTS), f)
        else:
            attr = mesh.GetPointsAttr()
            for f in range(FRAMES):
                attr.Set(Vt.Vec3fArray.FromNumpy(rest + rng.normal(scale=0.3, size=(n, 3)).astype(np.float32)), f)
        stage.GetRootLayer().Save()
        paths.append(path)
    return paths[0], paths[1]


def timed(fn) -> tuple[float, float]:
    wall, cpu = time.perf_counter(), time.process_time()
    fn()
    return time.perf_counter() - wall, time.process_time() - cpu


def bare_usdskel(path: Path) -> None:
    from pxr import Usd, UsdSkel

    stage = Usd.Stage.Open(str(path))
    root = UsdSkel.Root(stage.GetPrimAtPath("/Face"))
    cache = UsdSkel.Cache()
    cache.Populate(root, Usd.TraverseInstanceProxies())
    skin = cache.GetSkinningQuery(stage.GetPrimAtPath("/Face/Geom"))
    skel = cache.GetSkelQuery(UsdSkel.Skeleton(stage.GetPrimAtPath("/Face/Skeleton")))
    rest = stage.GetPrimAtPath("/Face/Geom").GetAttribute("points").Get()
    from pxr import Vt

    for f in range(FRAMES):
        tc = Usd.TimeCode(f)
        pts = Vt.Vec3fArray(rest)
        skin.ComputeSkinnedPoints(skel.ComputeSkinningTransforms(tc), pts, tc)
        np.asarray(pts)


def walk(path: Path) -> None:
    from usdface.usd.face_evaluator import FaceEvaluator

    ev = FaceEvaluator.open(path)
    for _times, _points in ev.iter_points():
        pass


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--points", type=int, nargs="+", default=[2000, 20000])
    args = ap.parse_args()
    import usdface  # noqa: F401  (registers the schemas before any stage opens)

    for n in args.points:
        with tempfile.TemporaryDirectory() as tmp:
            skel, cache = build(Path(tmp), n)
            base = timed(lambda: bare_usdskel(skel))
            ev_skel = timed(lambda: walk(skel))
            ev_cache = timed(lambda: walk(cache))
        print(f"{n} points x {FRAMES} frames: evaluator skinned {ev_skel[0]:.2f} s wall / {ev_skel[1]:.2f} s cpu, "
              f"point cache {ev_cache[0]:.2f} / {ev_cache[1]:.2f} s; bare UsdSkel loop {base[0]:.2f} / {base[1]:.2f} s; "
              f"evaluator / bare (cpu) {ev_skel[1] / base[1]:.2f}")


if __name__ == "__main__":
    main()
