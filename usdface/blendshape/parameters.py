"""The blend-shape solve's settings and their defaults, named once: the options offer these
(:class:`usdface.options.SolveOptions` builds the parameter objects), the solver
(:mod:`usdface.blendshape.solver`) and the take (:mod:`usdface.blendshape.take`) read them. Light
(no numpy, no numba kernels): the command line reads the defaults at start-up."""
from __future__ import annotations

from dataclasses import dataclass, field

__all__ = ["SolverParameters", "TakeParameters", "DeliveryParameters", "DEFAULT_SMOOTHING_HZ", "DEFAULT_SPARSITY",
           "DEFAULT_SYMMETRY", "DEFAULT_TOLERANCE", "DEFAULT_MAX_ITERATIONS", "DEFAULT_SUPPORT_THRESHOLD",
           "DEFAULT_SUPPORT_DILATION_S", "DEFAULT_RHO", "DEFAULT_RELAXATION", "DEFAULT_EXCLUDE", "DELIVERY_RATES",
           "RIG_TRANSFER_METHODS", "DEFAULT_RIG_TRANSFER", "DEFAULT_POSE_REFIT_ROUNDS"]

#: temporal smoothness cut-off (Hz): a shape fitted alone is low-passed here
DEFAULT_SMOOTHING_HZ = 6.0
#: L1 weight beta (cm^2 per unit weight)
DEFAULT_SPARSITY = 0.01
#: left/right prior weight gamma (dimensionless: a fraction of each pair's own data curvature)
DEFAULT_SYMMETRY = 0.05
#: ADMM stopping tolerance on the RMS primal and dual residuals (cm of marker motion per shape)
DEFAULT_TOLERANCE = 2e-3
DEFAULT_MAX_ITERATIONS = 300
#: refit: entries above this weight after the sparse pass form the support
DEFAULT_SUPPORT_THRESHOLD = 0.05
#: refit: the support is widened by this many seconds on either side
DEFAULT_SUPPORT_DILATION_S = 0.08
#: initial ADMM penalty (scaled units; adapted during the solve)
DEFAULT_RHO = 0.1
#: ADMM over-relaxation, in [1, 2)
DEFAULT_RELAXATION = 1.8
#: shapes held at 0 by default: skin markers see neither gaze nor the tongue
DEFAULT_EXCLUDE = ("eyeLook*", "tongueOut")
#: pose refit: at most this many rounds (correct the head and the rest pose with the rig's pose, solve
#: again) after the first solve (:mod:`usdface.blendshape.posefit`; chosen on the tuning rig of
#: ``benchmarks/make_heldout_rig.py --tuning``)
DEFAULT_POSE_REFIT_ROUNDS = 4
#: the delivery rates ``--fps`` offers (any positive rate is accepted by the functions)
DELIVERY_RATES = (24.0, 25.0, 30.0)
#: how `shapes transfer` carries each shape onto the registered generic (:mod:`usdface.blendshape.rig_transfer`)
RIG_TRANSFER_METHODS = ("displacement", "deformation")
DEFAULT_RIG_TRANSFER = "displacement"


@dataclass(frozen=True)
class SolverParameters:
    """The whole-take solve's settings (:class:`usdface.blendshape.solver.CurveSolver`; the
    module docstring there gives the objective they weigh).

    smoothing_hz : float or None
        Temporal cut-off f_c (Hz); None or 0: no smoothing (frames independent).
    sparsity : float
        beta >= 0 (cm^2).
    symmetry : float
        gamma >= 0 (dimensionless, relative to each pair's data curvature).
    refit : bool
        Second pass without the sparsity term over the support of the first.
    max_iterations : int
        ADMM iterations at most (each pass).
    tolerance : float
        Stop when the RMS primal and dual residuals fall below it (scaled units, cm).
    support_threshold : float
        Weight above which an entry of the first pass is in the refit's support.
    support_dilation_s : float
        Seconds the support is widened by on either side.
    rho : float
        Initial ADMM penalty (> 0).
    relaxation : float
        ADMM over-relaxation in [1, 2).
    """

    smoothing_hz: float | None = DEFAULT_SMOOTHING_HZ
    sparsity: float = DEFAULT_SPARSITY
    symmetry: float = DEFAULT_SYMMETRY
    refit: bool = True
    max_iterations: int = DEFAULT_MAX_ITERATIONS
    tolerance: float = DEFAULT_TOLERANCE
    support_threshold: float = DEFAULT_SUPPORT_THRESHOLD
    support_dilation_s: float = DEFAULT_SUPPORT_DILATION_S
    rho: float = DEFAULT_RHO
    relaxation: float = DEFAULT_RELAXATION


@dataclass(frozen=True)
class TakeParameters:
    """How one take is solved on a rig (:func:`usdface.blendshape.take.solve_take`).

    solver : SolverParameters
    exclude : tuple of str
        Glob patterns of shapes held at 0 (default :data:`DEFAULT_EXCLUDE`); ``()`` solves every shape.
    head_motion : bool
        Keep the capture's head motion for the outputs (decision D1); False drops it.
    pose_refit : int
        Rounds of pose refit after the first solve (:mod:`usdface.blendshape.posefit`); 0: off.
    """

    solver: SolverParameters = field(default_factory=SolverParameters)
    exclude: tuple = DEFAULT_EXCLUDE
    head_motion: bool = True
    pose_refit: int = DEFAULT_POSE_REFIT_ROUNDS

    def __post_init__(self) -> None:
        rounds = self.pose_refit
        if isinstance(rounds, bool) or not isinstance(rounds, int) or rounds < 0:
            from ..errors import OptionError

            raise OptionError(f"--pose-refit {rounds!r}: expected a whole number >= 0")

    def record(self) -> dict:
        """The solver's settings as provenance records them (JSON types): usdface 0.2's keys and
        ``pose_refit`` (0.2 had no refit: a layer without the key was solved with 0 rounds)."""
        s = self.solver
        return {"smoothing_hz": s.smoothing_hz, "sparsity": s.sparsity, "symmetry": s.symmetry,
                "exclude": list(self.exclude), "refit": s.refit, "max_iterations": s.max_iterations,
                "tolerance": s.tolerance, "pose_refit": self.pose_refit}


@dataclass(frozen=True)
class DeliveryParameters:
    """How solved curves are delivered (:func:`usdface.blendshape.take.deliverable_curves` and the
    Live Link Face CSV of :mod:`usdface.blendshape.csvio`).

    fps : float, optional
        Delivery rate (24, 25, 30, ...); None keeps the capture's.
    key_tolerance : float, optional
        Largest weight error of reduced curves; None keeps a sample at every frame.
    livelink_fill_zeros : bool
        Live Link CSV: zeros for ARKit shapes the rig lacks (otherwise an error naming them).
    """

    fps: float | None = None
    key_tolerance: float | None = None
    livelink_fill_zeros: bool = False
