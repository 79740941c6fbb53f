"""usdface.tissue.integrators: the paper's explicit Euler, symplectic and implicit Euler, divergence."""
from __future__ import annotations

import math

import numpy as np
import pytest

from usdface.errors import OptionError
from usdface.tissue import _kernels as kn
from usdface.tissue.animation import animate
from usdface.tissue.expressions import expression_timeline, preset_contractions
from usdface.tissue.integrators import DivergenceError, Simulator
from usdface.tissue.model import build_tissue_model
from usdface.tissue.muscles import Muscle, compile_muscles

from .conftest import grid_mesh


@pytest.fixture(scope="module")
def patch():
    mesh = grid_mesh(5)
    model = build_tissue_model(mesh, regions=[])
    m = Muscle(name="m", origin=[3.0, 2.0, -0.8], insertion=[2.0, 2.0, 0.2], zone_angle=60.0, max_force=5.0)
    return model, compile_muscles(model, [m], max_origin_distance=10.0)


def _perturbed(model, muscles, integrator, backend="auto"):
    sim = Simulator(model, muscles, integrator=integrator, backend=backend, dt=1e-4)
    sim.set_controls([0.5])
    rng = np.random.default_rng(0)
    sim.x[:sim.n_free] += rng.normal(scale=0.01, size=(sim.n_free, 3))
    sim.v[:sim.n_free] = rng.normal(scale=0.1, size=(sim.n_free, 3))
    return sim


@pytest.mark.parametrize("backend", [pytest.param("numba", marks=pytest.mark.skipif(not kn.AVAILABLE,
                                                                                    reason="numba not installed")),
                                     "numpy"])
def test_explicit_euler_is_the_papers_scheme(patch, backend):
    """x_{n+1} = x_n + h v_n, v_{n+1} = v_n + h F(x_n, v_n) / m."""
    model, ms = patch
    sim = _perturbed(model, ms, "explicit", backend)
    x0, v0 = sim.x.copy(), sim.v.copy()
    F0 = sim.compute_forces().copy()
    h = 1e-4
    sim.step(h)
    nf = sim.n_free
    assert np.allclose(sim.x[:nf], x0[:nf] + h * v0[:nf], rtol=0, atol=1e-14)
    assert np.allclose(sim.v[:nf], v0[:nf] + h * F0[:nf] / model.mass[:nf, None], rtol=1e-12, atol=1e-12)
    assert np.array_equal(sim.x[nf:], x0[nf:])  # bone nodes are kinematic


def test_symplectic_euler_updates_velocity_first(patch):
    model, ms = patch
    sim = _perturbed(model, ms, "symplectic")
    x0, v0 = sim.x.copy(), sim.v.copy()
    F0 = sim.compute_forces().copy()
    h = 1e-4
    sim.step(h)
    nf = sim.n_free
    v1 = v0[:nf] + h * F0[:nf] / model.mass[:nf, None]
    assert np.allclose(sim.v[:nf], v1, atol=1e-12)
    assert np.allclose(sim.x[:nf], x0[:nf] + h * v1, atol=1e-14)


def test_bad_options(patch):
    model, ms = patch
    with pytest.raises(OptionError, match="integrator"):
        Simulator(model, ms, integrator="rk4")
    with pytest.raises(OptionError, match="dt"):
        Simulator(model, ms, dt=-1.0)
    sim = Simulator(model, ms)
    with pytest.raises(OptionError, match=r"m=1\.2"):
        sim.set_controls([1.2])
    with pytest.raises(OptionError, match="no jaw"):
        sim.set_controls([0.2], jaw=0.5)


def test_explicit_beyond_its_stability_limit_diverges_with_the_cause(face):
    sim = face.simulator(integrator="explicit")
    hs = sim.stable_step()
    assert sim.dt == pytest.approx(0.5 * hs)
    a, jaw = preset_contractions("surprise", face.rig.names, intensity=0.5)
    sim.set_controls(a, jaw=jaw)
    with pytest.raises(DivergenceError) as info:
        sim.advance(0.02, h=4 * hs)
    e = info.value
    assert "stability limit" in e.cause and "explicit" in str(e)
    assert "worst at mesh vertex" in str(e) and e.step > 0 and e.time > 0


def test_divergence_names_the_frame(face):
    sim = face.simulator(integrator="explicit")
    sim = face.simulator(integrator="explicit", dt=5 * sim.stable_step())
    tl = expression_timeline("surprise", face.rig.names, ramp_frames=4, hold_frames=0)
    with pytest.raises(DivergenceError, match=r"^frame \d+: simulation diverged") as info:
        for _ in animate(sim, tl):
            pass
    assert info.value.frame is not None


def test_explicit_default_step_is_stable_at_rest(face):
    sim = face.simulator(integrator="explicit")
    rng = np.random.default_rng(0)
    sim.x[:sim.n_free] += rng.normal(scale=1e-3, size=(sim.n_free, 3))
    e0 = sim.energy()["total"]
    sim.advance(0.03)
    e1 = sim.energy()["total"]
    assert math.isfinite(e1) and e1 < e0  # damped: the perturbation's energy decays


def test_implicit_takes_frame_sized_steps(face, preset_runs):
    """Implicit Euler at a whole 24 fps frame per step (about 480x the explicit step) stays stable
    and lands on the same equilibrium as the default 1/240 s steps."""
    a, jaw = preset_contractions("surprise", face.rig.names)
    sim = face.simulator(integrator="implicit", dt=1 / 24)
    sim.set_controls(a, jaw=jaw)
    rep = sim.run_to_equilibrium(max_time=3.0, tol=0.1)
    assert rep.converged
    small_steps = face.mesh.points + preset_runs["realistic", "surprise"].displacement
    assert np.linalg.norm(sim.skin() - small_steps, axis=1).max() < 0.01  # cm


def test_energy_decreases_with_fixed_controls(face):
    """Damped and conservative: with the controls held, the total energy never rises."""
    sim = face.simulator()
    a, jaw = preset_contractions("joy", face.rig.names)
    sim.set_controls(a, jaw=jaw)
    energies = []
    for _ in range(30):
        sim.step()
        energies.append(sim.energy()["total"])
    e = np.asarray(energies)
    assert (np.diff(e) <= 1e-9 * np.abs(e[:-1]) + 1e-9).all()


def test_reset_returns_to_rest(face):
    sim = face.simulator()
    a, jaw = preset_contractions("fear", face.rig.names)
    sim.set_controls(a, jaw=jaw)
    sim.advance(0.05)
    sim.reset()
    assert np.array_equal(sim.x, face.model.rest) and not sim.v.any() and sim.time == 0.0
