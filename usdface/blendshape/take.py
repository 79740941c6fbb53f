"""One take solved on one rig, and its deliverable curves (pure numpy; the processors do the I/O).

:func:`solve_take` goes from a conditioned capture, a binding and a rig to weight curves at the
capture rate (the solver of :mod:`usdface.blendshape.solver`), with the head motion in mesh space
(decision D1: ``H_mesh(f) = C H(n)^-1 H(f) C^-1``). :func:`deliverable_curves` then resamples to
the delivery rate and reduces keys, giving the values every output (USD, CSV, Live Link Face CSV)
writes, so they all hold the same curves.
"""
from __future__ import annotations

import fnmatch
import logging
from dataclasses import dataclass, field

import numpy as np

from ..errors import InputError, OptionError, list_names
from .posefit import refit_pose
from .mirror import find_mirror_pairs
from .parameters import DEFAULT_EXCLUDE, DELIVERY_RATES, TakeParameters  # noqa: F401 (re-exported)
from .rig import BlendShapeRig, marker_basis
from .solver import CurveSolution, CurveSolver

log = logging.getLogger("usdface")

__all__ = ["TakeSolution", "DeliverableCurves", "TakeParameters", "solve_take", "deliverable_curves",
           "resolve_exclude", "DEFAULT_EXCLUDE", "DELIVERY_RATES"]


@dataclass
class TakeSolution:
    """A solved take at the capture rate (mesh units in ``residual``)."""

    solution: CurveSolution
    rate: float
    start_frame: int
    head_motion: np.ndarray | None  # (F, 4, 4) mesh space, relative to the rest pose (pose refit included)
    displacements: np.ndarray       # (F, M, 3) mesh units, NaN where invalid (as solved: pose refit applied)
    basis: np.ndarray               # (M, K, 3) mesh units
    mirror: dict
    warnings: list = field(default_factory=list)
    pose_refit: dict | None = None  # :meth:`usdface.blendshape.posefit.PoseRefit.summary`; None: not run

    @property
    def weights(self) -> np.ndarray:
        return self.solution.weights


@dataclass
class DeliverableCurves:
    """The curves as delivered: at ``rate``, frame indices ``frames`` (0-based)."""

    names: tuple
    rate: float
    values: np.ndarray          # (F', K) every frame, in [0, 1]
    sample_frames: np.ndarray   # frames with a USD time sample (all, or the union of reduced keys)
    sample_values: np.ndarray   # (T, K)
    head_motion: np.ndarray | None  # (F', 4, 4)
    key_counts: dict | None
    tolerance: float | None


def resolve_exclude(patterns, names) -> list[str]:
    """Shape names matching any of ``patterns`` (glob, case-sensitive); 'none' or () -> []."""
    if patterns is None:
        return []
    if isinstance(patterns, str):
        patterns = [p.strip() for p in patterns.split(",") if p.strip()]
    pats = [p for p in patterns if p.lower() != "none"]
    return [n for n in names if any(fnmatch.fnmatchcase(n, p) for p in pats)]


def mesh_head_motion(capture, binding) -> np.ndarray | None:
    """The capture's removed head motion in mesh space relative to the neutral frame (D1), or None
    (:func:`usdface.skel.joints.capture_head_motion`: the skeleton carries the same one)."""
    from ..skel.joints import capture_head_motion

    return capture_head_motion(capture, binding.capture_to_mesh)


def solve_take(rig: BlendShapeRig, capture, binding, params: TakeParameters = TakeParameters()) -> TakeSolution:
    """Solve a conditioned capture on a rig through a binding.

    Parameters
    ----------
    rig : BlendShapeRig
        On the mesh the binding was made for.
    capture : usdface.model.capture.Capture
        Conditioned (stabilised unless the caller chose not to).
    binding : usdface.model.mesh.Binding
    params : TakeParameters
        The solver's settings (:class:`usdface.blendshape.parameters.SolverParameters`; sparsity
        and symmetry are in cm^2 / dimensionless whatever the mesh units: converted here), the
        shapes held at 0 (glob patterns; default :data:`DEFAULT_EXCLUDE`, ``()`` or ``"none"``
        solves every shape), whether the capture's head motion is kept for the outputs (D1), and
        the rounds of pose refit: correcting the rest pose (over the quiet frames of the neutral
        stretch) and, for a stabilised capture, the head stabilisation with the rig's pose
        (:mod:`usdface.blendshape.posefit`; the head correction joins the head motion; 0: off).

    Returns
    -------
    TakeSolution
    """
    from ..capture.retarget import marker_displacements
    from ..units import scale_between

    from ..errors import MarkerError

    warnings: list[str] = []
    extra = [n for n in capture.names if n not in binding.names]
    missing = [n for n in binding.names if n not in capture.names]
    if extra or missing:
        raise MarkerError(f"capture {capture.source} and the binding have different markers: "
                          + "; ".join(p for p in (f"not in the capture: {list_names(missing)}" if missing else "",
                                                  f"not in the binding: {list_names(extra)}" if extra else "") if p)
                          + "; bind this capture (usdface bind) or use the capture the binding was made for")
    disp = marker_displacements(capture, binding.names, binding.displacement_transform())  # mesh units
    basis = marker_basis(rig, binding)
    to_cm = scale_between(rig.units, "cm") if rig.units else 1.0
    mirror = find_mirror_pairs(rig)
    excluded = resolve_exclude(params.exclude, rig.names)
    solver = CurveSolver(basis * to_cm, names=rig.names, marker_names=binding.names,
                         symmetric_pairs=mirror.symmetric_pairs, exclude=excluded, params=params.solver)
    if solver.unmoved_markers:
        msg = (f"marker(s) {list_names(solver.unmoved_markers)} moved by no shape of the rig: their motion cannot be "
               "explained (it stays in the residual; the corrective transfers it)")
        warnings.append(msg)
        log.warning("%s", msg)
    unseen = [n for n in solver.unobservable if n not in excluded]
    if unseen:
        msg = f"shape(s) {list_names(unseen)} move no bound marker: held at weight 0"
        warnings.append(msg)
        log.warning("%s", msg)
    valid = np.isfinite(disp).all(axis=2)
    if not valid.any():
        raise InputError(f"capture {capture.source}: no valid marker sample to solve from")
    bound = binding.surface_points(rig.mesh.points) * to_cm
    sol, solved, refit = refit_pose(solver, disp * to_cm, bound, rate=capture.rate, rounds=params.pose_refit,
                                    tolerance=params.solver.tolerance, solve_options={},
                                    head=capture.head_motion is not None, rest_frames=capture.neutral_frames)
    disp = solved / to_cm
    sol.residual = sol.residual / to_cm  # back to mesh units
    sol.still_residual = sol.still_residual / to_cm
    sol.marker_rms = sol.marker_rms / to_cm
    if not sol.converged:
        msg = (f"the solver stopped after {sol.iterations} iterations before reaching tolerance "
               f"{params.solver.tolerance:g} "
               f"(primal {sol.primal:.2g}, dual {sol.dual:.2g}); raise --max-iterations for tighter curves")
        warnings.append(msg)
        log.warning("%s", msg)
    hm = mesh_head_motion(capture, binding) if params.head_motion else None
    if hm is not None and refit.corrections is not None:
        # the stabilised markers sit at corrections[f] @ (rig pose): the head moved that much more
        corr = refit.corrections.copy()
        corr[:, :3, 3] /= to_cm
        hm = np.einsum("fij,fjk->fik", hm, corr)
    return TakeSolution(sol, float(capture.rate), int(capture.start_frame), hm, disp, basis, mirror.summary(),
                        warnings, refit.summary())


def deliverable_curves(names, weights, *, rate: float, fps: float | None = None, key_tolerance: float | None = None,
                       head_motion=None) -> DeliverableCurves:
    """Resample curves (F, K) at ``rate`` to ``fps`` and reduce keys within ``key_tolerance``.

    Parameters
    ----------
    fps : float, optional
        Delivery rate (24, 25, 30, ...); None keeps ``rate``.
    key_tolerance : float, optional
        Largest weight error of the reduced curves; None keeps a sample at every frame.
    head_motion : ndarray (F, 4, 4), optional
        Resampled with the curves (slerp).
    """
    from .curves import reduce_keys, resample_curves, resample_rigid

    w = np.asarray(weights, dtype=np.float64)
    out_rate = float(rate)
    hm = head_motion
    if fps is not None:
        if not (np.isfinite(fps) and fps > 0):
            raise OptionError(f"--fps {fps}: expected a positive frame rate")
        w = np.clip(resample_curves(w, rate, fps), 0.0, 1.0)
        hm = resample_rigid(head_motion, rate, fps) if head_motion is not None else None
        out_rate = float(fps)
    if key_tolerance is not None:
        keyed = reduce_keys(w, names, key_tolerance)
        frames = keyed.union_keys()
        values = keyed.sample()
        return DeliverableCurves(tuple(names), out_rate, values, frames, values[frames], hm, keyed.key_counts(),
                                 float(key_tolerance))
    frames = np.arange(w.shape[0])
    return DeliverableCurves(tuple(names), out_rate, w, frames, w, hm, None, None)
