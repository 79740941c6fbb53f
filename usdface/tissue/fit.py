"""Fitting muscle contractions to marker motion (beyond the paper).

Given markers bound to the face surface (a :class:`~usdface.mesh.Binding`: triangle and
barycentric weights per marker) and their captured displacements per frame (in mesh space, from
the capture's rest pose), find per frame the contractions in [0, 1] (and the jaw opening) that best
reproduce them:

1. **linearised response** (:func:`linear_response`): the static response of the bound points to
   each control, from the model's tangent stiffness at rest: ``K dx = f_k`` (``f_k`` the forces of
   muscle k at full contraction; for the jaw, the forces of a small jaw rotation of the bone
   nodes), giving ``J`` (3M, C);
2. **bounded least squares** per frame (:func:`fit_frames`): ``min |J a - d|^2 + lam |S a|^2``,
   ``0 <= a <= 1`` (``scipy.optimize.lsq_linear``; ``S`` scales the regulariser to each column),
   NaN markers (gaps) dropped frame by frame;
3. **refinement by simulation** (:func:`fit_sequence`): simulate the fitted sequence
   quasi-statically, measure per control how much it really moves the markers compared with the
   rest tangent (a secant gain per column: the tissue stiffens as it deforms), take a bounded
   Gauss-Newton step on the simulated marker residual with the rescaled response, simulate again.

Errors are reported as marker distances (mesh units): the linear prediction, each simulated pass,
and the "still face" baseline (the displacement itself) for scale.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ..errors import ComputeError, MarkerError, OptionError, list_names
from . import _kernels as kn
from .expressions import JAW_KEY
from .integrators import DivergenceError, Simulator


@dataclass(frozen=True)
class FitParameters:
    """How :func:`fit_sequence` fits (the options of `usdface fit-muscles` build it:
    :meth:`usdface.options.FitMusclesOptions.parameters`).

    Attributes
    ----------
    regularization : float
        ``lam`` >= 0: Tikhonov weight relative to each column's norm (keeps unobservable muscles
        at 0).
    refine : int
        Refinement passes >= 0 (each: simulate, correct the controls from the marker residual).
    settle_steps : int
        Extra steps per frame with the controls held (see :func:`simulate_controls`).
    """

    regularization: float = 1e-3
    refine: int = 1
    settle_steps: int = 1


def capture_displacements(capture, binding, *, stabilize="auto"):
    """Marker displacements from the rest pose in mesh space, in the binding's marker order.

    Parameters
    ----------
    capture : Capture
        Marker positions (F, M', 3) in capture units.
    binding : Binding
        The markers bound on the mesh (its names pick and order the capture's markers).
    stabilize : {"auto", "none"}
        "auto": remove the head motion first when the capture is not stabilised.

    Returns
    -------
    displacements : ndarray (F, M, 3) float64
        ``T (p_f - rest)`` with ``T`` the binding's displacement transform (mesh units) and
        ``rest`` the capture's rest pose (:attr:`usdface.model.capture.Capture.neutral`).
    capture : Capture
        The capture used (stabilised when it was done here).

    Raises
    ------
    MarkerError
        A bound marker is not in the capture (named).
    """
    if stabilize not in ("auto", "none"):
        raise OptionError(f"stabilize must be 'auto' or 'none'; got {stabilize!r}")
    missing = [n for n in binding.names if n not in capture.names]
    if missing:
        raise MarkerError(f"binding markers not in the capture: {list_names(missing)}; capture has "
                          f"{list_names(capture.names)}")
    if stabilize == "auto" and capture.head_motion is None:
        from ..capture.stabilize import stabilize as stabilize_fn

        capture, _ = stabilize_fn(capture)
    idx = [capture.names.index(n) for n in binding.names]
    # from the capture's rest pose (averaged over its neutral stretch), not its neutral frame alone
    disp = capture.positions[:, idx] - capture.neutral[idx][None]
    return disp @ binding.displacement_transform().T, capture


@dataclass(frozen=True)
class LinearResponse:
    """Marker response to each control.

    Attributes
    ----------
    names : tuple of str
        Controls: the muscles, then ``jawOpen`` when the rig has a jaw.
    J : ndarray (3M, C)
        Displacement of the bound points (x, y, z per marker, marker-major) per unit control.
    """

    names: tuple
    J: np.ndarray

    @property
    def n_controls(self) -> int:
        return len(self.names)


def bound_points(points: np.ndarray, tri_vertices: np.ndarray, bary: np.ndarray) -> np.ndarray:
    """(M, 3) points at barycentric coordinates of mesh triangles."""
    return np.einsum("mk,mkd->md", bary, np.asarray(points)[tri_vertices])


def _solve_static(sim: Simulator, rhs: np.ndarray, x0: np.ndarray | None = None) -> np.ndarray:
    """Solve ``K dx = rhs`` on the free nodes with the stiffness assembled at the current state."""
    imp = sim._implicit
    nf = sim.n_free
    eps = 1e-9 * float(np.abs(imp["K"][imp["diag"]]).max())
    A = imp["K"].copy()
    diag = imp["diag"]
    A[diag, 0, 0] += eps
    A[diag, 1, 1] += eps
    A[diag, 2, 2] += eps
    x0 = np.zeros((nf, 3)) if x0 is None else x0
    if sim.backend == "numba":
        sol, it, res = kn.block_cg(A, imp["indices"], imp["indptr"], diag, imp["G"], sim.prisms,
                                   sim.model.volume_coef, imp["Dv"], np.ascontiguousarray(rhs), x0, 1e-7, 0.0, 20000)
    else:
        from .implicit import _cg_numpy

        sol, it, res = _cg_numpy(A, imp, sim.prisms, sim.model.volume_coef, imp["Dv"], rhs, x0, 1e-7, 0.0)
    if not np.isfinite(res) or res > 1e-4:
        raise ComputeError(f"static response solve did not converge (residual {res:.2g} after {it} iterations)")
    return sol


def linear_response(sim: Simulator, tri_vertices, bary, *, jaw_probe: float = 0.05) -> LinearResponse:
    """Tangent static response of bound points to each muscle (and the jaw) at rest.

    Parameters
    ----------
    sim : Simulator
        Its model, muscles and jaw; its state is reset to rest (and left there).
    tri_vertices, bary : ndarray (M, 3)
        Marker binding on the mesh.
    jaw_probe : float
        Jaw opening used to probe the jaw's (nearly linear, kinematic) response.

    Returns
    -------
    LinearResponse
    """
    sim.reset()
    sim._implicit_setup()
    ms = sim.muscles
    n = sim.n
    nf = sim.n_free
    sim.m_coef = np.zeros_like(sim.m_coef)
    sim._assemble()
    cols = []
    tri_vertices = np.asarray(tri_vertices)
    bary = np.asarray(bary, dtype=np.float64)
    for k in range(ms.n_muscles):
        F = _muscle_only_forces(sim, np.where(ms.muscle == k, ms.base, 0.0))
        dx = _solve_static(sim, F[:nf])
        cols.append(bound_points(dx[:n], tri_vertices, bary).ravel())
    names = list(ms.names)
    if sim.jaw is not None:
        saved = sim.x.copy()
        sim.set_controls(jaw=jaw_probe)
        sim._move_bones(1.0)
        sim.v[:] = 0.0
        F = sim.compute_forces().copy()
        dx = _solve_static(sim, F[:nf])
        cols.append(bound_points(dx[:n], tri_vertices, bary).ravel() / jaw_probe)
        names.append(JAW_KEY)
        sim.x = saved
        sim.reset()
    return LinearResponse(names=tuple(names), J=np.stack(cols, axis=1))


def _muscle_only_forces(sim: Simulator, coef: np.ndarray) -> np.ndarray:
    """Forces of the muscle entries with forces ``coef`` at the current state."""
    ms = sim.muscles
    if sim.backend == "numba":
        F = np.zeros_like(sim.x)
        kn.muscle_kernel(sim.x, ms.nodes, ms.muscle, coef, sim.anchors, ms.metric, sim.m_eps, F)
        return F
    from .forces import muscle_forces

    F, _ = muscle_forces(sim.x, ms.nodes, ms.muscle, coef, sim.anchors, ms.metric, sim.m_eps)
    return F


def fit_frames(response: LinearResponse, displacements, *, regularization: float = 1e-3, lower=None,
               upper=None) -> tuple[np.ndarray, np.ndarray]:
    """Bounded least-squares controls per frame.

    Parameters
    ----------
    response : LinearResponse
    displacements : ndarray (F, M, 3)
        Marker displacements from the neutral pose (mesh units); NaN for missing markers.
    regularization : float
        ``lam``: Tikhonov weight relative to each column's norm (keeps unobservable muscles at 0).
    lower, upper : ndarray (F, C), optional
        Bounds (default 0 and 1).

    Returns
    -------
    controls : ndarray (F, C)
    predicted : ndarray (F, M, 3)
        ``J controls`` (the linear prediction).
    """
    from scipy.optimize import lsq_linear

    d = np.asarray(displacements, dtype=np.float64)
    f_count, m_count = d.shape[0], d.shape[1]
    J = response.J
    c = J.shape[1]
    if J.shape[0] != 3 * m_count:
        raise OptionError(f"response has {J.shape[0] // 3} markers, displacements {m_count}")
    scale = np.linalg.norm(J, axis=0)
    scale = np.where(scale > 0, scale, 1.0)
    reg = math.sqrt(regularization) * np.diag(scale)
    lo = np.zeros((f_count, c)) if lower is None else np.asarray(lower, dtype=np.float64)
    hi = np.ones((f_count, c)) if upper is None else np.asarray(upper, dtype=np.float64)
    out = np.zeros((f_count, c))
    flat = d.reshape(f_count, -1)
    for f in range(f_count):  # one small (3M x C) problem per frame
        ok = np.isfinite(flat[f])
        if not ok.any():
            out[f] = np.clip(0.0, lo[f], hi[f])
            continue
        A = np.vstack([J[ok], reg])
        b = np.concatenate([flat[f, ok], np.zeros(c)])
        lo_f, hi_f = lo[f], np.maximum(hi[f], lo[f] + 1e-12)
        out[f] = lsq_linear(A, b, bounds=(lo_f, hi_f), method="bvls").x
    pred = (out @ J.T).reshape(f_count, m_count, 3)
    return out, pred


def simulate_controls(sim: Simulator, controls: np.ndarray, names, *, rate: float, settle_steps: int = 1,
                      settle_h: float = 0.04, h: float | None = None, progress=None):
    """Simulate a control sequence quasi-statically; yield skin points (N, 3) per frame.

    Each frame: the controls move linearly over ``1 / rate`` s (steps of ``h``, default the frame
    interval for the implicit integrator), then ``settle_steps`` extra steps of ``settle_h`` s with
    the controls held bring the tissue close to equilibrium (the markers of a capture show a face
    in (quasi) equilibrium, and a lagging simulation would bias the fit).
    """
    ms_names = list(sim.muscles.names)
    has_jaw = JAW_KEY in names
    idx = [names.index(n) for n in ms_names]
    if h is None:
        h = 1.0 / rate if sim.integrator == "implicit" else sim.dt
    sim.reset()
    for f in range(controls.shape[0]):
        a = np.clip(controls[f, idx], 0.0, 1.0)
        jaw = float(np.clip(controls[f, names.index(JAW_KEY)], 0.0, 1.0)) if has_jaw else None
        try:
            if f == 0:
                sim.set_controls(a, jaw=jaw)
                if a.any() or (jaw or 0) > 0:
                    sim.run_to_equilibrium(max_time=2.0, h=h if sim.integrator == "implicit" else None)
            else:
                sim.advance(1.0 / rate, contraction=a, jaw=jaw, h=h)
                for _ in range(settle_steps):
                    sim.step(settle_h if sim.integrator == "implicit" else sim.dt)
        except DivergenceError as e:
            raise e.at_frame(f) from None
        if progress is not None:
            progress.update(1)
        yield sim.skin()


def _secant_gains(J, controls, simulated, prior) -> np.ndarray:
    """Per-control gains g minimising ``|J diag(g) a_f - s_f|`` over frames (kept near ``prior`` for
    controls that were hardly used)."""
    from scipy.optimize import lsq_linear

    c = J.shape[1]
    # rows: every frame and coordinate; columns: J[:, k] * a_fk
    A = (controls[:, None, :] * J[None, :, :]).reshape(-1, c)
    b = simulated.reshape(-1)
    ok = np.isfinite(b)
    use = np.sqrt((A[ok] ** 2).sum(axis=0))
    w = 1e-2 * max(float(use.max()), 1e-12)
    A = np.vstack([A[ok], w * np.eye(c)])
    b = np.concatenate([b[ok], w * prior])
    return lsq_linear(A, b, bounds=(0.05, 20.0), method="bvls").x


@dataclass
class FitResult:
    """Result of :func:`fit_sequence`.

    Attributes
    ----------
    names : tuple of str
        Controls (muscles, then jawOpen).
    controls : ndarray (F, C)
        Final contractions (and jaw opening) per frame, in [0, 1].
    skin : ndarray (F, N, 3)
        Simulated skin points of the final pass.
    errors : dict
        Marker error statistics (mesh units): ``still`` (the displacement itself: error of a face
        that does not move), ``linear`` (the linear prediction), ``pass1``, ``pass2``... (simulated).
    per_marker : dict {name: float}
        RMS error per marker of the final pass.
    """

    names: tuple
    controls: np.ndarray
    skin: np.ndarray
    errors: dict = field(default_factory=dict)
    per_marker: dict = field(default_factory=dict)


def marker_error(pred: np.ndarray, target: np.ndarray) -> dict:
    """RMS, mean, median, 95th percentile and max marker distance (ignoring NaN markers)."""
    dist = np.linalg.norm(np.asarray(pred) - np.asarray(target), axis=-1)
    dist = dist[np.isfinite(dist)]
    if dist.size == 0:
        return {"rms": math.nan, "mean": math.nan, "median": math.nan, "p95": math.nan, "max": math.nan}
    return {"rms": float(np.sqrt(np.mean(dist ** 2))), "mean": float(dist.mean()), "median": float(np.median(dist)),
            "p95": float(np.percentile(dist, 95)), "max": float(dist.max())}


def fit_sequence(sim: Simulator, tri_vertices, bary, displacements, *, rate: float,
                 parameters: FitParameters | None = None, marker_names=None, response=None,
                 progress=None) -> FitResult:
    """Fit contractions to a marker sequence and simulate them (linear fit, then refinement).

    Parameters
    ----------
    sim : Simulator
    tri_vertices, bary : ndarray (M, 3)
        Marker binding.
    displacements : ndarray (F, M, 3)
        Marker displacements from neutral in mesh space (mesh units); NaN for gaps.
    rate : float
        Frames per second of the sequence.
    parameters : FitParameters, optional
        Regularisation, refinement passes and settling steps (default :class:`FitParameters`).
    marker_names : sequence of str, optional
        Names of the M markers, for the per-marker errors.
    response : LinearResponse, optional
        Reuse a response computed on this simulator and binding.
    progress : object with ``update(n)``, optional
        Told of every simulated frame.

    Returns
    -------
    FitResult
    """
    params = parameters or FitParameters()
    regularization, refine, settle_steps = params.regularization, params.refine, params.settle_steps
    tri_vertices = np.asarray(tri_vertices)
    bary = np.asarray(bary, dtype=np.float64)
    d = np.asarray(displacements, dtype=np.float64)
    resp = response or linear_response(sim, tri_vertices, bary)
    names = list(resp.names)
    controls, pred = fit_frames(resp, d, regularization=regularization)
    rest_markers = bound_points(sim.model.rest[:sim.n], tri_vertices, bary)
    errors = {"still": marker_error(np.zeros_like(d), d), "linear": marker_error(pred, d)}
    skin = None
    history_a, history_s = [], []
    gains = np.ones(resp.n_controls)
    for p in range(refine + 1):
        skin = np.stack(list(simulate_controls(sim, controls, names, rate=rate, settle_steps=settle_steps,
                                               progress=progress)))
        sim_disp = np.einsum("mk,fmkd->fmd", bary, skin[:, tri_vertices]) - rest_markers
        errors[f"pass{p + 1}"] = marker_error(sim_disp, d)
        if p == refine:
            break
        # secant gains: how much each control actually moves the markers compared with the rest
        # tangent (the tissue stiffens as it deforms), fitted on all simulated passes so far
        history_a.append(controls.copy())
        history_s.append(sim_disp.reshape(len(d), -1))
        gains = _secant_gains(resp.J, np.concatenate(history_a), np.concatenate(history_s), gains)
        scaled = LinearResponse(names=resp.names, J=resp.J * gains)
        # Gauss-Newton step on the simulated residual with the rescaled response, within [0, 1]
        delta, _ = fit_frames(scaled, d - sim_disp, regularization=regularization, lower=-controls,
                              upper=1.0 - controls)
        controls = np.clip(controls + delta, 0.0, 1.0)
    dist = np.linalg.norm(sim_disp - d, axis=-1)
    per_marker = {}
    if marker_names is not None:
        for j, name in enumerate(marker_names):
            col = dist[:, j]
            col = col[np.isfinite(col)]
            per_marker[name] = float(np.sqrt(np.mean(col ** 2))) if col.size else math.nan
    return FitResult(names=tuple(names), controls=controls, skin=skin, errors=errors, per_marker=per_marker)
