"""Benchmark: the layered mass-spring tissue engine (usdface.tissue), seed 001 §5.

Run by hand (not in CI):  python benchmarks/bench_tissue.py [--quick] [--skip-accuracy]

Measures, in one run on this machine:

1. One full explicit step (springs with biphasic stiffening and damping, node damping, volume
   preservation per prism, skull contact, muscle forces, forward-Euler integration) of a model
   with about 8160 springs (the paper: 0.016 s per step for 8160 springs), for the numba kernels
   and the vectorised numpy kernels (sparse incidence gather/scatter), against the baseline: a
   straightforward per-spring (and per-prism, per-muscle-entry) Python loop over the same model.
   Models are built from a bulging quad grid (21 x 21 vertices -> 8322 springs) with one linear
   muscle, and from the sample face (39380 springs, the default rig).
2. Throughput on a model of >= 100k springs (72 x 72 grid -> 101958 springs): spring
   evaluations per second of the full step.
3. The implicit step (assembly + CG solve) on the sample face.
4. Integrator accuracy: the paper's explicit Euler at its default step h_e (half its estimated
   stability limit), near that limit (1.8 h_e) and beyond it (2.5 h_e), against the implicit
   integrator at 1x, 10x, 50x and 100x h_e, on the "surprise" preset ramped over 6 frames at 24 fps
   and held 6: the largest vertex deviation over all frames from a reference (explicit Euler at
   h_e / 2). With an accuracy target of 0.5 mm, the explicit scheme cannot go past its stability
   limit (about 2 h_e) while the implicit one meets it up to about 50 h_e.

Absolute times depend on the machine and its load (printed); ratios are measured in the same run.
"""
from __future__ import annotations

import argparse
import logging
import math
import os
import platform
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from usdface.io.meshes import read_mesh  # noqa: E402
from usdface.model.mesh import FaceMesh  # noqa: E402
from usdface.mesh.topology import find_hole_regions  # noqa: E402
from usdface.tissue import _kernels as kn  # noqa: E402
from usdface.tissue.animation import animate  # noqa: E402
from usdface.tissue.expressions import expression_timeline  # noqa: E402
from usdface.tissue.integrators import Simulator  # noqa: E402
from usdface.tissue.model import build_tissue_model  # noqa: E402
from usdface.tissue.muscles import Muscle, compile_muscles  # noqa: E402
from usdface.tissue.rig import default_rig  # noqa: E402

REPO = Path(__file__).resolve().parents[1]


def grid_mesh(n: int, spacing: float = 0.45) -> FaceMesh:
    """An n x n quad grid (cm) bulging toward +z like a face patch."""
    x, y = np.meshgrid(np.arange(n, dtype=float), np.arange(n, dtype=float))
    x, y = x * spacing, y * spacing
    c = (n - 1) * spacing / 2
    z = 2.0 * (1.0 - ((x - c) ** 2 + (y - c) ** 2) / (2 * c * c))
    pts = np.stack([x.ravel(), y.ravel(), z.ravel()], axis=1)
    i, j = np.meshgrid(np.arange(n - 1), np.arange(n - 1))
    v0 = (j * n + i).ravel()
    quads = np.stack([v0, v0 + 1, v0 + n + 1, v0 + n], axis=1)
    return FaceMesh(points=pts, face_vertex_counts=np.full(len(quads), 4), face_vertex_indices=quads.ravel(),
                    units="cm", name=f"grid{n}")


def grid_sim(n: int, backend: str) -> Simulator:
    mesh = grid_mesh(n)
    model = build_tissue_model(mesh, regions=[])
    c = mesh.points.mean(axis=0)
    span = np.ptp(mesh.points[:, 0])
    muscle = Muscle(name="m", origin=c + np.array([0.35 * span, 0.3 * span, -1.0]), insertion=c + [0, 0, 1.5],
                    zone_angle=30.0, max_force=2000.0)
    ms = compile_muscles(model, [muscle], max_origin_distance=10 * span)
    sim = Simulator(model, ms, integrator="explicit", backend=backend)
    sim.set_controls([0.7])
    rng = np.random.default_rng(0)
    sim.x[:sim.n_free] += rng.normal(scale=0.01, size=(sim.n_free, 3))
    sim.v[:sim.n_free] = rng.normal(scale=0.1, size=(sim.n_free, 3))
    return sim


# -------------------------------------------------------------------------------- the baseline
def slow_step(sim: Simulator, h: float) -> None:
    """One explicit step with per-spring / per-prism / per-entry Python loops (the baseline)."""
    x = sim.x.tolist()
    v = sim.v.tolist()
    n_nodes = len(x)
    F = [[0.0, 0.0, 0.0] for _ in range(n_nodes)]
    si, sj = sim.si.tolist(), sim.sj.tolist()
    l0, k, lc, kb, cs = sim.l0.tolist(), sim.k.tolist(), sim.lc.tolist(), sim.kb.tolist(), sim.cs.tolist()
    for s in range(len(si)):  # springs
        i, j = si[s], sj[s]
        xi, xj = x[i], x[j]
        dx, dy, dz = xj[0] - xi[0], xj[1] - xi[1], xj[2] - xi[2]
        length = math.sqrt(dx * dx + dy * dy + dz * dz)
        ux, uy, uz = dx / length, dy / length, dz / length
        f = k[s] * (length - l0[s])
        over = length - lc[s]
        if over > 0:
            d = 0.5 * (lc[s] - l0[s])
            f += kb[s] * (0.5 * over * over / d if over <= d else over - 0.5 * d)
        vi, vj = v[i], v[j]
        f += cs[s] * ((vj[0] - vi[0]) * ux + (vj[1] - vi[1]) * uy + (vj[2] - vi[2]) * uz)
        Fi, Fj = F[i], F[j]
        Fi[0] += f * ux
        Fi[1] += f * uy
        Fi[2] += f * uz
        Fj[0] -= f * ux
        Fj[1] -= f * uy
        Fj[2] -= f * uz
    V0, vc = sim.model.rest_volume.tolist(), sim.model.volume_coef.tolist()
    beta = sim.beta
    for p, pr in enumerate(sim.prisms.tolist()):  # prisms: 3 tetrahedra each
        g = [[0.0, 0.0, 0.0] for _ in range(6)]
        vol = 0.0
        for a_, b_, c_, d_ in ((0, 1, 2, 3), (1, 2, 3, 4), (2, 3, 4, 5)):
            A, B, C, D = x[pr[a_]], x[pr[b_]], x[pr[c_]], x[pr[d_]]
            ba = [B[t] - A[t] for t in range(3)]
            ca = [C[t] - A[t] for t in range(3)]
            da = [D[t] - A[t] for t in range(3)]
            gd = [(ba[1] * ca[2] - ba[2] * ca[1]) / 6, (ba[2] * ca[0] - ba[0] * ca[2]) / 6, (ba[0] * ca[1] - ba[1] * ca[0]) / 6]
            gb = [(ca[1] * da[2] - ca[2] * da[1]) / 6, (ca[2] * da[0] - ca[0] * da[2]) / 6, (ca[0] * da[1] - ca[1] * da[0]) / 6]
            gc = [(da[1] * ba[2] - da[2] * ba[1]) / 6, (da[2] * ba[0] - da[0] * ba[2]) / 6, (da[0] * ba[1] - da[1] * ba[0]) / 6]
            vol -= gd[0] * da[0] + gd[1] * da[1] + gd[2] * da[2]
            for t in range(3):
                g[b_][t] -= gb[t]
                g[c_][t] -= gc[t]
                g[d_][t] -= gd[t]
                g[a_][t] += gb[t] + gc[t] + gd[t]
        rate = sum(g[r][t] * v[pr[r]][t] for r in range(6) for t in range(3))
        s_ = -vc[p] * (vol - V0[p] + beta * rate)
        for r in range(6):
            Fr = F[pr[r]]
            for t in range(3):
                Fr[t] += s_ * g[r][t]
    ms = sim.muscles
    for q, (node, m) in enumerate(zip(ms.nodes.tolist(), ms.muscle.tolist())):  # muscle entries
        c = sim.m_coef[q]
        a = sim.anchors[m]
        P = ms.metric[m]
        d = [a[t] - x[node][t] for t in range(3)]
        pd = [P[t][0] * d[0] + P[t][1] * d[1] + P[t][2] * d[2] for t in range(3)]
        s_ = math.sqrt(d[0] * pd[0] + d[1] * pd[1] + d[2] * pd[2] + sim.m_eps ** 2)
        for t in range(3):
            F[node][t] += c * pd[t] / s_
    n = sim.n
    for i in range(n):  # skull contact
        f_, b_ = x[n + i], x[2 * n + i]
        nn = sim.skull_normals[i]
        s_ = sum((f_[t] - b_[t]) * nn[t] for t in range(3))
        pen = sim.skull_margin[i] - s_
        if pen > 0:
            d = 0.5 * sim.skull_margin[i]
            fs = sim.k_skull * (0.5 * pen * pen / d if pen <= d else pen - 0.5 * d)
            for t in range(3):
                F[n + i][t] += fs * nn[t]
    gamma, mass = sim.gamma, sim.mass_free.tolist()
    for i in range(sim.n_free):  # node damping and forward Euler
        for t in range(3):
            F[i][t] -= gamma * mass[i] * v[i][t]
            x[i][t] += h * v[i][t]
            v[i][t] += h * F[i][t] / mass[i]
    sim.x[:] = np.asarray(x)
    sim.v[:] = np.asarray(v)


def timeit(fn, *, min_time=0.5, max_reps=2000) -> float:
    fn()  # warm-up (JIT)
    reps, t0 = 0, time.perf_counter()
    while reps < max_reps and (time.perf_counter() - t0 < min_time or reps < 3):
        fn()
        reps += 1
    return (time.perf_counter() - t0) / reps


def bench_steps(label: str, make, *, slow: bool) -> dict:
    out = {}
    for backend in (["numba"] if kn.AVAILABLE else []) + ["numpy"]:
        sim = make(backend)
        h = sim.dt * 1e-3  # tiny: the state stays put while timing
        out[backend] = timeit(lambda: sim.step(h))
    springs = make("numpy").model.n_springs
    if slow:
        sim = make("numpy")
        h = sim.dt * 1e-3
        t0 = time.perf_counter()
        slow_step(sim, h)
        out["python loop"] = time.perf_counter() - t0
    print(f"\n{label}: {springs} springs")
    base = out.get("python loop")
    for k, t in out.items():
        ratio = f"  ({base / t:7.1f}x the loop)" if base and k != "python loop" else ""
        print(f"  {k:12s} {t * 1e3:9.3f} ms/step  {springs / t / 1e6:8.2f} M springs/s{ratio}")
    return {"springs": springs, **out}


def bench_face_implicit(face) -> None:
    mesh, regions, rig, model, jaw, ms = face
    sim = Simulator(model, ms, jaw=jaw, integrator="implicit")
    from usdface.tissue.expressions import preset_contractions

    a, j = preset_contractions("joy", rig.names)
    sim.set_controls(0.5 * a, jaw=j)
    sim.advance(0.05)
    iters = []

    def one():
        sim.step()
        iters.append(sim.last_cg[0])
    t = timeit(one, min_time=1.0, max_reps=200)
    print(f"\nimplicit step on the sample face ({model.n_springs} springs, dt {sim.dt:.4g} s): {t * 1e3:.1f} ms/step, "
          f"CG iterations median {int(np.median(iters))}")


def bench_accuracy(face, *, preset="surprise") -> None:
    mesh, regions, rig, model, jaw, ms = face
    tl = expression_timeline(preset, rig.names, ramp_frames=6, hold_frames=6)

    def run(integrator, h):
        sim = Simulator(model, ms, jaw=jaw, integrator=integrator, dt=h)
        t0 = time.perf_counter()
        frames = np.stack([s for _, s in animate(sim, tl)])
        return frames, time.perf_counter() - t0, sim.steps

    he = Simulator(model, ms, jaw=jaw, integrator="explicit").dt
    print(f"\nintegrator accuracy, preset {preset!r} ramped over 6 frames at 24 fps and held 6 (sample face); "
          f"explicit default step h_e = {he:.3g} s (half the estimated stability limit)")
    ref, t_ref, _ = run("explicit", he / 2)
    print(f"  reference: explicit Euler at h_e/2 ({t_ref:.1f} s)")
    rows = [("explicit", he), ("explicit", 1.8 * he), ("explicit", 2.5 * he), ("symplectic", he), ("implicit", he),
            ("implicit", 10 * he), ("implicit", 50 * he), ("implicit", 100 * he), ("implicit", 1 / 240),
            ("implicit", 1 / 60)]
    for integ, h in rows:
        try:
            out, t, steps = run(integ, h)
        except Exception as e:  # noqa: BLE001 - a diverging integrator is a result
            print(f"  {integ:10s} h {h:9.3g} s ({h / he:6.1f} h_e): diverged ({str(e)[:80]}...)")
            continue
        err = np.linalg.norm(out - ref, axis=2).max(axis=1)
        print(f"  {integ:10s} h {h:9.3g} s ({h / he:6.1f} h_e): {steps:6d} steps {t:6.1f} s; max vertex deviation "
              f"over frames {err.max() * 10:.3f} mm, at the last frame {err[-1] * 10:.3f} mm")


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="skip the 100k-spring baseline loop")
    ap.add_argument("--skip-accuracy", action="store_true")
    args = ap.parse_args(argv)
    logging.disable(logging.WARNING)
    print(f"python {platform.python_version()}, numpy {np.__version__}, numba {'yes' if kn.AVAILABLE else 'no'}, "
          f"{os.cpu_count()} cpus, load {os.getloadavg()[0]:.2f}")
    bench_steps("paper-size model (21 x 21 grid)", lambda b: grid_sim(21, b), slow=True)
    mesh = read_mesh(REPO / "sample_assets" / "meshes" / "makehuman_hm08_face_cm.obj")
    regions = find_hole_regions(mesh)
    rig = default_rig(mesh, regions)
    model = build_tissue_model(mesh, regions=regions)
    jaw = rig.jaw_for(model.mesh, regions)
    ms = compile_muscles(model, rig.muscles, jaw=jaw)
    face = (mesh, regions, rig, model, jaw, ms)

    def face_sim(backend):
        sim = Simulator(model, ms, jaw=jaw, integrator="explicit", backend=backend)
        from usdface.tissue.expressions import preset_contractions

        a, j = preset_contractions("joy", rig.names)
        sim.set_controls(0.5 * a, jaw=j)
        return sim
    bench_steps("sample face, default rig", face_sim, slow=True)
    bench_steps(">= 100k springs (72 x 72 grid)", lambda b: grid_sim(72, b), slow=not args.quick)
    bench_face_implicit(face)
    if not args.skip_accuracy:
        bench_accuracy(face)


if __name__ == "__main__":
    main()
