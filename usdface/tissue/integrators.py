"""Time integration of the tissue model (seed 001 §5.3): the Simulator.

Integrators (``integrator=``):

``"explicit"``
    The paper's scheme, forward (explicit) Euler on a damped system:
    ``x_{n+1} = x_n + h v_n``, ``v_{n+1} = v_n + h M^-1 F(x_n, v_n)``. Forward Euler is stable only
    with damping: for a mode of frequency ``w`` with damping rate ``c = gamma + beta w^2`` (node
    damping ``gamma``, stiffness-proportional spring damping ``beta``) it needs ``h <= c / w^2``
    (under-damped modes) or ``h <= 2 / |lambda|`` (over-damped ones).
``"symplectic"``
    Semi-implicit (symplectic) Euler, same cost: ``v_{n+1} = v_n + h M^-1 F(x_n, v_n)``,
    ``x_{n+1} = x_n + h v_{n+1}``; stable up to ``h ~ 2 / w_max`` even without damping.
``"implicit"``
    Linearised backward Euler (Baraff-Witkin): ``(M + h C + h^2 K) dv = h (F - h K v)``,
    ``v += dv``, ``x += h v``, with ``K`` the positive semi-definite part of the tangent stiffness
    (springs, volume Gauss-Newton term, skull contact, muscles) assembled each step and solved by
    block-Jacobi preconditioned conjugate gradients. Unconditionally stable for the linearised
    system; its fixed points are exactly the equilibria, so runs to equilibrium take large steps.

The Simulator holds the state (positions, velocities of all nodes; bone nodes move with the head
and jaw), the controls (contractions, jaw opening, head transform) and reports energies, prism
volume changes and divergence (NaN, energy or displacement blow-up) as :class:`DivergenceError`
with the time, step and likely cause. The implicit step and its assembly are in
:mod:`usdface.tissue.implicit`.
"""
from __future__ import annotations

import logging
import math
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg  # noqa: F401  (sp.linalg)

from ..errors import OptionError
from . import _kernels as kn
from .divergence import DivergenceError
from .forces import incidence, muscle_forces, prism_volume_gradients, skull_forces, spring_forces, volume_forces
from . import INTEGRATORS  # named once, in the package
from .implicit import ImplicitEuler
from .model import TissueModel
from .muscles import Jaw, MuscleSet, check_contractions

log = logging.getLogger("usdface")

__all__ = ["BACKENDS", "DivergenceError", "EquilibriumReport", "Simulator"]

BACKENDS = ("auto", "numba", "numpy")


@dataclass
class EquilibriumReport:
    """Result of :meth:`Simulator.run_to_equilibrium`."""

    converged: bool
    time: float
    steps: int
    max_speed: float
    max_residual: float

    def to_dict(self) -> dict:
        return dict(self.__dict__)


class Simulator(ImplicitEuler):
    """Simulate a tissue model driven by muscles, jaw and head.

    Parameters
    ----------
    model : TissueModel
    muscles : MuscleSet, optional
        Compiled muscles (:func:`usdface.tissue.muscles.compile_muscles`).
    jaw : Jaw, optional
        Jaw rotation of the bone nodes below the mouth.
    integrator : {"explicit", "symplectic", "implicit"}
    dt : float or "auto"
        Integration step (s). "auto": explicit and symplectic take half the estimated stability
        limit (:meth:`stable_step`); implicit takes 1/240 s.
    backend : {"auto", "numba", "numpy"}
        Force kernels: numba when installed (about 10x faster), else vectorised numpy.
    skull : bool, optional
        Skull non-penetration force (default: on when the model's ``k_skull`` > 0).
    cg_tol : float
        Relative residual of the implicit solve.

    Examples
    --------
    >>> sim = Simulator(model, muscles, jaw=jaw)                           # doctest: +SKIP
    >>> sim.set_controls(contraction=preset_vector, jaw=0.3)               # doctest: +SKIP
    >>> sim.run_to_equilibrium(); skin = sim.skin()                        # doctest: +SKIP
    """

    def __init__(self, model: TissueModel, muscles: MuscleSet | None = None, *, jaw: Jaw | None = None,
                 integrator: str = "implicit", dt="auto", backend: str = "auto", skull: bool | None = None,
                 cg_tol: float = 1e-3):
        if integrator not in INTEGRATORS:
            raise OptionError(f"integrator must be one of {', '.join(INTEGRATORS)}; got {integrator!r}")
        if backend not in BACKENDS:
            raise OptionError(f"backend must be one of {', '.join(BACKENDS)}; got {backend!r}")
        if backend == "numba" and not kn.AVAILABLE:
            raise OptionError("backend 'numba' needs numba (pip install numba)")
        self.model = model
        self.integrator = integrator
        self.backend = ("numba" if kn.AVAILABLE else "numpy") if backend == "auto" else backend
        self.cg_tol = float(cg_tol)
        # absolute floor of the implicit solve: a velocity error of 1e-5 cm/s per node
        self._cg_atol = 1e-5 * model.length_scale * float(np.linalg.norm(model.mass[:2 * model.n_vertices]))
        o = model.options
        n = model.n_vertices
        self.n = n
        self.n_free = 2 * n
        self.x = model.rest.copy()
        self.v = np.zeros_like(self.x)
        self.time = 0.0
        self.steps = 0
        self.inv_mass = np.where(np.isfinite(model.mass), 1.0 / model.mass, 0.0)
        self.mass_free = np.ascontiguousarray(model.mass[:self.n_free])
        # springs
        self.si = np.ascontiguousarray(model.springs[:, 0])
        self.sj = np.ascontiguousarray(model.springs[:, 1])
        self.l0 = model.rest_length
        self.k = model.stiffness
        if o.biphasic_strain is not None and o.biphasic_factor != 1.0:
            self.lc = model.rest_length * (1.0 + o.biphasic_strain)
            self.kb = model.stiffness * (o.biphasic_factor - 1.0)
        else:
            self.lc = np.full_like(model.rest_length, np.inf)
            self.kb = np.zeros_like(model.rest_length)
        self.beta = float(o.spring_damping)
        self.cs = self.beta * model.stiffness
        self.gamma = float(o.node_damping)
        self.prisms = np.ascontiguousarray(model.prisms)
        self.vol = model.rest_volume.copy()
        # skull
        self.k_skull = float(o.k_skull) if (skull is None or skull) else 0.0
        self.skull_margin = o.skull_margin * o.bone_depth * model.length_scale * model.depth
        self.bone_rest = model.rest[model.layer("bone")].copy()
        self.skull_normals = model.direction.copy()
        # muscles
        if muscles is None:
            muscles = MuscleSet(muscles=(), nodes=np.zeros(0, np.int64), muscle=np.zeros(0, np.int64),
                                base=np.zeros(0), weights=np.zeros(0), anchors=np.zeros((0, 3)), metric=np.zeros((0, 3, 3)),
                                on_jaw=np.zeros(0))
        self.muscles = muscles
        self.contraction = np.zeros(muscles.n_muscles)
        self.m_coef = np.zeros(muscles.nodes.size)
        self.anchors = muscles.anchors.copy()
        self.m_eps = float(o.muscle_softening) * model.length_scale
        self.jaw = jaw
        self.jaw_open = 0.0
        self.head = np.eye(4)
        self.energies = np.zeros(4)
        self.F = np.zeros_like(self.x)
        self._D = incidence(model.springs, model.n_nodes) if self.backend == "numpy" else None
        self._implicit = None
        self.last_cg = (0, 0.0)
        self.last_alpha = 1.0
        self._h_stable = None
        self._blowup_disp = 0.5 * float(np.linalg.norm(np.ptp(model.rest, axis=0)))
        self._vzero = np.zeros_like(self.x)
        self._dv = np.zeros((self.n_free, 3))
        self._fel = None
        self._fel_energies = np.zeros(4)
        self._fel_valid = False
        self._place_bones()
        if dt == "auto" or dt is None:
            self.dt = self.default_step()
        else:
            self.dt = float(dt)
            if not (np.isfinite(self.dt) and self.dt > 0):
                raise OptionError(f"dt must be a positive number of seconds; got {dt!r}")

    # -- controls -------------------------------------------------------------------------------

    def set_controls(self, contraction=None, *, jaw: float | None = None, head=None) -> None:
        """Set contractions (M,) in [0, 1], the jaw opening in [0, 1] and the head transform (4, 4)."""
        if contraction is not None:
            self.contraction = check_contractions(contraction, self.muscles.names).copy()
            self.m_coef = self.contraction[self.muscles.muscle] * self.muscles.base
        if jaw is not None:
            j = float(jaw)
            if not (np.isfinite(j) and 0 <= j <= 1):
                raise OptionError(f"jaw opening must be in [0, 1]; got {jaw!r}")
            if j > 0 and self.jaw is None:
                raise OptionError("a jaw opening was given but the rig has no jaw")
            self.jaw_open = j
        if head is not None:
            h = np.asarray(head, dtype=np.float64)
            if h.shape != (4, 4) or not np.isfinite(h).all():
                raise OptionError(f"head transform must be a finite (4, 4) matrix; got shape {h.shape}")
            self.head = h
        self._place_bones()
        self._fel_valid = False

    def _place_bones(self) -> None:
        b0, n0, a0 = self.bone_rest, self.model.direction, self.muscles.anchors
        if self.jaw is not None and self.jaw_open > 0:
            rot = self.jaw.rotation(self.jaw_open)
            p = self.jaw.pivot
            w = self.jaw.weights[:, None]
            b = (1 - w) * b0 + w * ((b0 - p) @ rot.T + p)
            nn = (1 - w) * n0 + w * (n0 @ rot.T)
            wa = self.muscles.on_jaw[:, None]
            a = (1 - wa) * a0 + wa * ((a0 - p) @ rot.T + p)
        else:
            b, nn, a = b0, n0, a0
        if not np.array_equal(self.head, np.eye(4)):
            r, t = self.head[:3, :3], self.head[:3, 3]
            b, nn, a = b @ r.T + t, nn @ r.T, a @ r.T + t
        nn = nn / np.maximum(np.linalg.norm(nn, axis=1, keepdims=True), 1e-300)
        self._bone_target = b
        self._bones_moving = True
        self.skull_normals = np.ascontiguousarray(nn)
        self.anchors = np.ascontiguousarray(a)

    def _move_bones(self, h: float) -> None:
        """Put the bone nodes at their targets, with the velocity that takes them there in ``h``."""
        if not self._bones_moving:
            return
        self._fel_valid = False
        sl = self.model.layer("bone")
        new = self._bone_target
        self.v[sl] = (new - self.x[sl]) / h
        self.x[sl] = new
        # once in place with zero velocity, later steps have nothing to do until the controls move
        self._bones_moving = bool(np.any(self.v[sl]))

    # -- forces and energy ----------------------------------------------------------------------

    def compute_forces(self) -> np.ndarray:
        """Total force on every node (bone rows included but unused); also updates energies."""
        if self.backend == "numba":
            kn.total_forces(self.x, self.v, self.si, self.sj, self.l0, self.k, self.lc, self.kb, self.cs, self.prisms,
                            self.model.rest_volume, self.model.volume_coef, self.muscles.nodes, self.muscles.muscle,
                            self.m_coef, self.anchors, self.muscles.metric, self.m_eps, self.n, self.skull_normals,
                            self.skull_margin, self.k_skull, self.gamma, self.beta, self.mass_free, self.n_free, self.F,
                            self.vol,
                            self.energies)
            return self.F
        o = self.model.options
        F, e_s = spring_forces(self.x, self.v, self.model.springs, self.l0, self.k,
                               biphasic_strain=o.biphasic_strain, biphasic_factor=o.biphasic_factor,
                               damping=o.spring_damping, D=self._D)
        fv, e_v, self.vol = volume_forces(self.x, self.prisms, self.model.rest_volume, self.model.volume_coef,
                                          v=self.v, damping=self.beta)
        F += fv
        fm, e_m = muscle_forces(self.x, self.muscles.nodes, self.muscles.muscle, self.m_coef, self.anchors,
                                self.muscles.metric, self.m_eps)
        F += fm
        e_k = 0.0
        if self.k_skull > 0:
            fs, e_k = skull_forces(self.x[self.model.layer("fascia")], self.x[self.model.layer("bone")],
                                   self.skull_normals, self.skull_margin, self.k_skull,
                                   v_fascia=self.v[self.model.layer("fascia")], v_bone=self.v[self.model.layer("bone")],
                                   damping=self.beta)
            F[self.model.layer("fascia")] += fs
        F[:self.n_free] -= self.gamma * self.mass_free[:, None] * self.v[:self.n_free]
        self.F = F
        self.energies[:] = (e_s, e_v, e_k, e_m)
        return F

    def energy(self) -> dict:
        """Energies of the current state (force units x mesh units): kinetic, spring, volume,
        skull, muscle (the muscles' potential ``sum a F w |x - anchor|``) and total."""
        self.compute_forces()
        kin = 0.5 * float(np.einsum("i,ij,ij->", self.mass_free, self.v[:self.n_free], self.v[:self.n_free]))
        e = {"kinetic": kin, "spring": float(self.energies[0]), "volume": float(self.energies[1]),
             "skull": float(self.energies[2]), "muscle": float(self.energies[3])}
        e["total"] = sum(e.values())
        return e

    def skin(self) -> np.ndarray:
        """(N, 3) current epidermis positions (the animated mesh points)."""
        return self.x[:self.n].copy()

    def volume_change(self) -> np.ndarray:
        """(T,) relative volume change of each three-layer element, ``(V - V0) / V0``."""
        vol, _ = prism_volume_gradients(self.x, self.prisms)
        t = self.model.n_elements
        v0 = self.model.element_rest_volume
        return (vol[:t] + vol[t:] - v0) / np.abs(v0)

    def prism_volume_change(self) -> np.ndarray:
        """(2T,) relative volume change of each prism (dermal then deep)."""
        vol, _ = prism_volume_gradients(self.x, self.prisms)
        v0 = self.model.rest_volume
        return (vol - v0) / np.maximum(np.abs(v0), 1e-300)

    def reset(self) -> None:
        self._fel_valid = False
        self._dv[:] = 0.0
        self.x = self.model.rest.copy()
        self.v[:] = 0.0
        self.time = 0.0
        self.steps = 0
        self.set_controls(np.zeros(self.muscles.n_muscles), jaw=0.0 if self.jaw is not None else None, head=np.eye(4))
        self._move_bones(1.0)
        self.v[:] = 0.0

    # -- stability ------------------------------------------------------------------------------

    def max_frequency(self, iterations: int = 60) -> float:
        """Largest angular frequency (rad/s) of the model linearised at rest (power iteration)."""
        imp = self._implicit_setup()
        x_saved = self.x
        self.x = self.model.rest.copy()
        coef_saved = self.m_coef
        self.m_coef = np.zeros_like(self.m_coef)
        self._assemble()
        self.x, self.m_coef = x_saved, coef_saved
        self._fel_valid = False
        K = imp["K"].copy()
        vc = self.model.volume_coef
        nf = self.n_free
        mat = sp.linalg.LinearOperator((3 * nf, 3 * nf), matvec=lambda y: self._apply(K, vc, y.reshape(nf, 3)).ravel())
        s = 1.0 / np.sqrt(np.repeat(self.mass_free, 3))
        rng = np.random.default_rng(0)
        y = rng.standard_normal(3 * self.n_free)
        lam = 0.0
        for _ in range(iterations):
            z = s * mat.matvec(s * y)
            lam = float(np.linalg.norm(z) / np.linalg.norm(y))
            y = z / np.linalg.norm(z)
        return math.sqrt(max(lam, 0.0) * 1.02)  # power iteration approaches from below

    def stable_step(self) -> float:
        """Estimated largest stable step (s) of the explicit or symplectic integrator.

        From the largest frequency ``w`` and the damping ``c = gamma + beta w^2`` of that mode:
        forward Euler needs ``h <= c / w^2`` when the mode is under-damped and
        ``h <= 2 / (c/2 + sqrt(c^2/4 - w^2))`` when over-damped; symplectic Euler ``h <= 2 / w``
        (less when heavily damped). The implicit integrator has no such limit (inf).
        """
        if self.integrator == "implicit":
            return math.inf
        if self._h_stable is None:
            w = self.max_frequency()
            beta = self.model.options.spring_damping
            c = self.gamma + beta * w * w
            if self.integrator == "explicit":
                if c < 2 * w:
                    h = c / (w * w)
                else:
                    h = 2.0 / (0.5 * c + math.sqrt(0.25 * c * c - w * w))
            else:
                h = 2.0 / w if c < 2 * w else 2.0 / (0.5 * c + math.sqrt(0.25 * c * c - w * w))
                h = min(h, 2.0 / w)
            # lower frequencies can bind for forward Euler under light damping: bound them too
            if self.integrator == "explicit" and beta > 0:
                h = min(h, beta + self.gamma / (w * w) if c < 2 * w else h)
            self._h_stable = h
        return self._h_stable

    def default_step(self) -> float:
        """The step used when ``dt="auto"``."""
        if self.integrator == "implicit":
            return 1.0 / 240.0
        return 0.5 * self.stable_step()

    # -- stepping -------------------------------------------------------------------------------

    def step(self, h: float | None = None) -> None:
        """One integration step of ``h`` seconds (default ``dt``); the controls hold during it."""
        h = self.dt if h is None else float(h)
        self._move_bones(h)
        if self.integrator == "implicit":
            self._implicit_step(h)
        else:
            self._fel_valid = False
            F = self.compute_forces()
            if self.backend == "numba":
                kn.explicit_update(self.x, self.v, F, self.inv_mass, h, self.n_free, self.integrator == "symplectic")
            else:
                a = F[:self.n_free] * self.inv_mass[:self.n_free, None]
                if self.integrator == "symplectic":
                    self.v[:self.n_free] += h * a
                    self.x[:self.n_free] += h * self.v[:self.n_free]
                else:
                    self.x[:self.n_free] += h * self.v[:self.n_free]
                    self.v[:self.n_free] += h * a
        self.time += h
        self.steps += 1
        self._check(h)

    def advance(self, duration: float, *, contraction=None, jaw: float | None = None, head=None,
                h: float | None = None) -> int:
        """Simulate ``duration`` seconds, moving the controls linearly from their current values to
        the given ones over the interval (substeps of at most ``h``/``dt``). Returns the step count."""
        h = self.dt if h is None else float(h)
        n_sub = max(1, int(math.ceil(duration / h - 1e-9)))
        hs = duration / n_sub
        a0, j0, h0 = self.contraction.copy(), self.jaw_open, self.head.copy()
        a1 = a0 if contraction is None else check_contractions(contraction, self.muscles.names)
        j1 = j0 if jaw is None else jaw
        h1 = h0 if head is None else np.asarray(head, dtype=np.float64)
        for k in range(1, n_sub + 1):
            s = k / n_sub
            self.set_controls(a0 + s * (a1 - a0) if contraction is not None else None,
                              jaw=j0 + s * (j1 - j0) if jaw is not None else None,
                              head=_blend_rigid(h0, h1, s) if head is not None else None)
            self.step(hs)
        return n_sub

    def residual(self) -> float:
        """Largest force on a free node divided by its mass (mesh units / s^2), velocities ignored."""
        v = self.v
        self.v = np.zeros_like(v)
        F = self.compute_forces()
        self.v = v
        return float(np.max(np.linalg.norm(F[:self.n_free], axis=1) * self.inv_mass[:self.n_free]))

    def run_to_equilibrium(self, *, tol: float = 0.02, max_time: float = 5.0, min_time: float = 0.0,
                           h: float | None = None, check_every: float = 0.02) -> EquilibriumReport:
        """Step with fixed controls until the tissue is still.

        Still means: over two successive intervals of ``check_every`` seconds, no free node's net
        displacement exceeds ``tol`` cm/s times the interval (0.02 cm/s: 4 micrometres per 20 ms).
        Net displacement, not instantaneous speed, so a sub-micrometre jitter of one node does not
        hold it up.

        Returns
        -------
        EquilibriumReport
            ``max_speed`` is the largest net speed over the last interval (cm/s);
            ``max_residual`` the largest remaining force / mass at the end (cm/s^2).
        """
        h = self.dt if h is None else float(h)
        L = self.model.length_scale
        t0, s0 = self.time, self.steps
        every = max(1, int(round(check_every / h)))
        converged = False
        still = 0
        speed = math.inf
        last = self.x[:self.n_free].copy()
        while self.time - t0 < max_time - 1e-12:
            t_check = self.time
            for _ in range(every):
                self.step(h)
            now = self.x[:self.n_free]
            speed = float(np.max(np.linalg.norm(now - last, axis=1))) / L / (self.time - t_check)
            last = now.copy()
            if self.time - t0 < min_time:
                continue
            still = still + 1 if speed < tol else 0
            if still >= 2:
                converged = True
                break
        return EquilibriumReport(converged=converged, time=self.time - t0, steps=self.steps - s0, max_speed=speed,
                                 max_residual=self.residual() / L)

    # -- divergence -----------------------------------------------------------------------------

    def _check(self, h: float) -> None:
        with np.errstate(all="ignore"):
            self._check_state(h)

    def _check_state(self, h: float) -> None:
        bad = not np.isfinite(self.energies).all()
        if not bad and self.steps % 8 == 0:
            xs = self.x[:self.n_free]
            if not np.isfinite(xs).all():
                bad = True
            else:
                disp = np.linalg.norm(xs - self.model.rest[:self.n_free], axis=1)
                bad = float(disp.max()) > self._blowup_disp
        if bad:
            raise DivergenceError(self._diagnose(h), time=self.time, step=self.steps, cause=self._cause(h))

    def _cause(self, h: float) -> str:
        if self.integrator != "implicit":
            try:
                hs = self.stable_step()
            except Exception:  # noqa: BLE001 - diagnosis must not fail
                hs = math.nan
            if np.isfinite(hs) and h > 0.95 * hs:
                return (f"the step {h:.3g} s exceeds the {self.integrator} Euler stability limit (about {hs:.3g} s "
                        f"for this stiffness and mass): use a smaller dt, more substeps, or integrator 'implicit'")
        active = [n for n, a in zip(self.muscles.names, self.contraction) if a > 0]
        if active:
            return ("muscle forces overwhelm the tissue (elements invert): lower the maxForce or contraction of "
                    f"{', '.join(active[:6])}{'...' if len(active) > 6 else ''}, or stiffen the tissue")
        return "the tissue parameters make the system unstable (check stiffness, damping and masses)"

    def _worst_node(self) -> str:
        xs = self.x[:self.n_free]
        with np.errstate(all="ignore"):
            disp = np.linalg.norm(xs - self.model.rest[:self.n_free], axis=1)
        bad = np.flatnonzero(~np.isfinite(disp))
        k = int(bad[0]) if bad.size else int(np.argmax(disp))
        layer = ("epidermis", "fascia")[k // self.n]
        p = self.model.rest[k]
        return f"worst at mesh vertex {k % self.n} ({layer}, rest position {p[0]:.2f} {p[1]:.2f} {p[2]:.2f})"

    def _diagnose(self, h: float) -> str:
        return (f"simulation diverged at t = {self.time:.4f} s (step {self.steps}, {self.integrator} Euler, "
                f"dt {h:.3g} s): positions became non-finite or ran away, {self._worst_node()}; likely cause: "
                f"{self._cause(h)}")


def _blend_rigid(a: np.ndarray, b: np.ndarray, s: float) -> np.ndarray:
    """Interpolate two rigid 4x4 transforms (translation linear, rotation along the geodesic)."""
    if np.array_equal(a, b):
        return a.copy()
    from scipy.spatial.transform import Rotation, Slerp

    rots = Rotation.from_matrix(np.stack([a[:3, :3], b[:3, :3]]))
    out = np.eye(4)
    out[:3, :3] = Slerp([0.0, 1.0], rots)([s]).as_matrix()[0]
    out[:3, 3] = (1 - s) * a[:3, 3] + s * b[:3, 3]
    return out
