"""usdface.tissue.forces and the numba kernels: against slow obvious loops, and forces = -grad(energy)."""
from __future__ import annotations

import numpy as np
import pytest

from usdface.tissue import _kernels as kn
from usdface.tissue.forces import (incidence, muscle_forces, prism_volume_gradients, skull_forces, smooth_ramp,
                                   spring_forces, volume_forces)
from usdface.tissue.model import build_tissue_model

from .conftest import grid_mesh


def slow_spring_forces(x, v, springs, l0, k, strain_c, factor, damping):
    """The obvious per-spring loop (reference only)."""
    F = np.zeros_like(x)
    e = 0.0
    for (i, j), L0, K in zip(springs, l0, k):
        d = x[j] - x[i]
        length = np.linalg.norm(d)
        u = d / length
        f = K * (length - L0)
        e += 0.5 * K * (length - L0) ** 2
        over = length - L0 * (1 + strain_c)
        if over > 0:
            fb, eb, _ = smooth_ramp(np.array([over]), K * (factor - 1), 0.5 * strain_c * L0)
            f += fb[0]
            e += eb[0]
        f += damping * K * np.dot(v[j] - v[i], u)
        F[i] += f * u
        F[j] -= f * u
    return F, e


@pytest.fixture(scope="module")
def small():
    rng = np.random.default_rng(7)
    model = build_tissue_model(grid_mesh(5), regions=[])
    x = model.rest + rng.normal(scale=0.08, size=model.rest.shape)
    v = rng.normal(size=model.rest.shape)
    return model, x, v


def test_springs_match_the_slow_loop(small):
    model, x, v = small
    o = model.options
    F, e = spring_forces(x, v, model.springs, model.rest_length, model.stiffness, biphasic_strain=o.biphasic_strain,
                         biphasic_factor=o.biphasic_factor, damping=0.01)
    F2, e2 = slow_spring_forces(x, v, model.springs, model.rest_length, model.stiffness, o.biphasic_strain,
                                o.biphasic_factor, 0.01)
    assert np.allclose(F, F2, rtol=1e-10, atol=1e-10)
    assert e == pytest.approx(e2, rel=1e-12)


def test_volume_gradient_and_forces(small):
    model, x, _ = small
    vol, g = prism_volume_gradients(x, model.prisms)
    eps = 1e-6
    p, r, c = 3, 4, 1
    xp = x.copy()
    xp[model.prisms[p, r], c] += eps
    assert (prism_volume_gradients(xp, model.prisms)[0][p] - vol[p]) / eps == pytest.approx(g[p, r, c], rel=1e-4)
    F, e, _ = volume_forces(x, model.prisms, model.rest_volume, model.volume_coef)
    # a slow loop over prisms
    F2 = np.zeros_like(x)
    for q in range(len(model.prisms)):
        for rr in range(6):
            F2[model.prisms[q, rr]] -= model.volume_coef[q] * (vol[q] - model.rest_volume[q]) * g[q, rr]
    assert np.allclose(F, F2)


def _energy_gradient_check(energy_fn, force_fn, x, nodes, eps=1e-6):
    F = force_fn(x)
    for n in nodes:
        for c in range(3):
            xp, xm = x.copy(), x.copy()
            xp[n, c] += eps
            xm[n, c] -= eps
            num = -(energy_fn(xp) - energy_fn(xm)) / (2 * eps)
            assert F[n, c] == pytest.approx(num, rel=1e-4, abs=1e-6)


def test_forces_are_minus_energy_gradients(small):
    model, x, _ = small
    o = model.options
    v0 = np.zeros_like(x)
    nodes = [0, 7, model.n_vertices + 3, model.n_vertices + 12]
    sp = lambda y: spring_forces(y, v0, model.springs, model.rest_length, model.stiffness,  # noqa: E731
                                 biphasic_strain=o.biphasic_strain, biphasic_factor=o.biphasic_factor)
    _energy_gradient_check(lambda y: sp(y)[1], lambda y: sp(y)[0], x, nodes)
    vf = lambda y: volume_forces(y, model.prisms, model.rest_volume, model.volume_coef)  # noqa: E731
    _energy_gradient_check(lambda y: vf(y)[1], lambda y: vf(y)[0], x, nodes)
    n = model.n_vertices
    nodes_m = np.arange(n, 2 * n)
    coef = np.linspace(1.0, 3.0, n)
    anchors = np.array([[0.5, 1.0, -1.0]])
    metric = np.diag([1.0, 0.3, 0.0])[None]
    mf = lambda y: muscle_forces(y, nodes_m, np.zeros(n, int), coef, anchors, metric, eps=0.3)  # noqa: E731
    _energy_gradient_check(lambda y: mf(y)[1], lambda y: mf(y)[0], x, nodes)
    normals = model.direction
    margin = np.full(n, 0.4)

    def skull(y):
        f, e = skull_forces(y[n:2 * n], y[2 * n:], normals, margin, 50.0)
        F = np.zeros_like(y)
        F[n:2 * n] = f
        return F, e
    _energy_gradient_check(lambda y: skull(y)[1], lambda y: skull(y)[0], x, [n + 1, n + 5, n + 9])


def test_smooth_ramp_is_c1():
    k, d = 10.0, 0.2
    p = np.array([d - 1e-9, d + 1e-9, -1.0, 0.0])
    f, e, s = smooth_ramp(p, k, d)
    assert f[0] == pytest.approx(f[1], abs=1e-6) and s[0] == pytest.approx(s[1], abs=1e-6)
    assert f[2] == f[3] == e[2] == s[2] == 0.0


def test_incidence_scatter():
    D = incidence(np.array([[0, 2], [1, 2]]), 3)
    assert np.allclose(D.toarray(), [[-1, 0, 1], [0, -1, 1]])


@pytest.mark.skipif(not kn.AVAILABLE, reason="numba not installed")
def test_numba_kernels_match_numpy(face):
    rng = np.random.default_rng(3)
    a = np.clip(rng.uniform(-0.5, 1.0, face.muscles.n_muscles), 0, 1)
    sims = {}
    for backend in ("numba", "numpy"):
        sim = face.simulator(backend=backend, integrator="implicit")
        sim.set_controls(a, jaw=0.3)
        sim._move_bones(1.0)
        sim.x[:sim.n_free] += np.random.default_rng(1).normal(scale=0.05, size=(sim.n_free, 3))
        sim.v[:sim.n_free] = np.random.default_rng(2).normal(size=(sim.n_free, 3))
        F = sim.compute_forces().copy()
        sims[backend] = (sim, F, sim.energies.copy())
    (s1, F1, e1), (s2, F2, e2) = sims["numba"], sims["numpy"]
    assert np.allclose(F1[:s1.n_free], F2[:s2.n_free], rtol=1e-9, atol=1e-8)
    assert np.allclose(e1, e2, rtol=1e-9)
    # implicit assembly: same blocks and same matrix-free volume operator
    for s in (s1, s2):
        s._implicit_setup()
        s._assemble()
    assert np.allclose(s1._implicit["K"], s2._implicit["K"], rtol=1e-9, atol=1e-8)
    y = np.random.default_rng(4).normal(size=(s1.n_free, 3))
    assert np.allclose(s1._apply(s1._implicit["K"], s1.model.volume_coef, y),
                       s2._apply(s2._implicit["K"], s2.model.volume_coef, y), rtol=1e-9, atol=1e-8)
    # one implicit step agrees too
    s1.step(1 / 120)
    s2.step(1 / 120)
    assert np.allclose(s1.x, s2.x, atol=1e-5)  # the two CG solvers stop at the same tolerance, not the same iterate


def test_tangent_stiffness_matches_finite_differences(face):
    """Where every spring is stretched (no dropped compressive terms) K is the exact Jacobian."""
    sim = face.simulator(integrator="implicit", skull=False)
    sim.x[:sim.n_free] = sim.model.rest[:sim.n_free] * 1.0
    sim.x[:sim.n] += 0.02 * sim.model.direction  # skin pushed out: its springs stretch
    sim._implicit_setup()
    sim._assemble()
    K = sim._implicit["K"]
    rng = np.random.default_rng(0)
    dx = np.zeros((sim.n_free, 3))
    dx[:sim.n] = rng.normal(scale=1e-6, size=(sim.n, 3))
    F0 = sim.compute_forces()[:sim.n_free].copy()
    sim.x[:sim.n_free] += dx
    F1 = sim.compute_forces()[:sim.n_free].copy()
    Kdx = sim._apply(K, sim.model.volume_coef, dx)
    rel = np.linalg.norm(-(F1 - F0) - Kdx) / np.linalg.norm(Kdx)
    assert rel < 0.05  # the volume term is Gauss-Newton (exact at rest volumes only)
