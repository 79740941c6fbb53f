"""Options of the blend-shape solve (`solve`, `run --output-kind blendshapes`)."""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from ..blendshape.parameters import (DEFAULT_EXCLUDE, DEFAULT_MAX_ITERATIONS, DEFAULT_POSE_REFIT_ROUNDS,
                                     DEFAULT_SMOOTHING_HZ, DEFAULT_SPARSITY, DEFAULT_SYMMETRY, DEFAULT_TOLERANCE)
from ..errors import OptionError
from .binding import BindOptions
from .capture import UNITS, CaptureOptions, stabilize_value
from .fields import Options, option
from .values import boolean, nonnegative_float, number, path, positive_float, positive_int, shown


def patterns_value(value, flag):
    """Comma-separated shape-name globs; 'none' (or empty) for no pattern."""
    if value is None:
        return ()
    if isinstance(value, str):
        value = [] if value.strip().lower() in ("", "none") else value.split(",")
    if not isinstance(value, (list, tuple)):
        raise OptionError(f"{flag} {shown(value)}: expected comma-separated shape names or globs, or 'none'")
    return tuple(str(v).strip() for v in value if str(v).strip())


def rounds_value(value, flag):
    """A number of rounds: a whole number >= 0 (0: off)."""
    n = number(value, flag, kind=int, what="a whole number >= 0")
    if n < 0:
        raise OptionError(f"{flag} {shown(value)}: expected a whole number >= 0")
    return n


@dataclass(frozen=True)
class BlendshapeOptions(Options):
    """The rig's shapes, the solver's settings and the curves delivered (`solve`, `run --output-kind
    blendshapes`)."""

    shapes: str | None = option(None, flag="--shapes", coerce=path, metavar="DIR|NPZ|RIG.usd",
                                group="blend-shape solve",
                                help="the rig's shapes for a neutral mesh: a folder of <shape>.obj, an .npz (names, "
                                     "deltas[, neutral]) or a USD rig (not needed when the mesh is a USD mesh with "
                                     "UsdSkel blend shapes)")
    smoothing: float = option(DEFAULT_SMOOTHING_HZ, flag="--smoothing", coerce=nonnegative_float, metavar="HZ",
                              group="blend-shape solve", help="temporal smoothness cut-off in Hz (0: none)")
    sparsity: float = option(DEFAULT_SPARSITY, flag="--sparsity", coerce=nonnegative_float, metavar="BETA",
                             group="blend-shape solve", help="L1 weight picking few shapes per frame, cm^2")
    symmetry: float = option(DEFAULT_SYMMETRY, flag="--symmetry", coerce=nonnegative_float, metavar="GAMMA",
                             group="blend-shape solve",
                             help="left/right prior on ...Left/...Right pairs whose deltas mirror each other (0: none)")
    exclude: tuple = option(DEFAULT_EXCLUDE, flag="--exclude", coerce=patterns_value, metavar="PATTERNS",
                            group="blend-shape solve",
                            help="shapes held at 0, comma-separated globs (markers see neither gaze nor tongue; "
                                 "'none' solves every shape)")
    refit: bool = option(True, flag="--no-refit", coerce=boolean, group="blend-shape solve",
                         help="skip the second pass that refits the active shapes without the sparsity shrinkage")
    max_iterations: int = option(DEFAULT_MAX_ITERATIONS, flag="--max-iterations", coerce=positive_int, metavar="N",
                                 group="blend-shape solve", help="ADMM iterations at most")
    tolerance: float = option(DEFAULT_TOLERANCE, flag="--tolerance", coerce=positive_float, metavar="CM",
                              group="blend-shape solve", help="ADMM stopping tolerance (cm)")
    pose_refit: int = option(DEFAULT_POSE_REFIT_ROUNDS, flag="--pose-refit", coerce=rounds_value, metavar="N",
                             group="blend-shape solve",
                             help="rounds of correcting the head stabilisation and the rest pose with what the rig "
                                  "explains, solving again after each (0: off; the solve of usdface 0.2)")
    fps: float | None = option(None, flag="--fps", coerce=positive_float, metavar="FPS", group="curves",
                               help="deliver the curves at this rate (24, 25, 30...) instead of the capture's")
    key_tolerance: float | None = option(None, flag="--key-tolerance", coerce=nonnegative_float, metavar="W",
                                         group="curves",
                                         help="reduce keys: each curve stays within W (weight units) of the solved one")
    livelink_fill_zeros: bool = option(False, flag="--livelink-fill-zeros", coerce=boolean, group="curves",
                                       help="Live Link CSV: zeros for ARKit shapes the rig lacks (default: an error "
                                            "naming them)")

    def solver_parameters(self):
        """The solver's settings (:class:`usdface.blendshape.parameters.SolverParameters`); a
        smoothing of 0 is none."""
        from ..blendshape.parameters import SolverParameters

        return SolverParameters(smoothing_hz=self.smoothing or None, sparsity=self.sparsity, symmetry=self.symmetry,
                                refit=self.refit, max_iterations=self.max_iterations, tolerance=self.tolerance)

    def delivery(self):
        """How the curves are delivered (:class:`usdface.blendshape.parameters.DeliveryParameters`)."""
        from ..blendshape.parameters import DeliveryParameters

        return DeliveryParameters(fps=self.fps, key_tolerance=self.key_tolerance,
                                  livelink_fill_zeros=self.livelink_fill_zeros)


@dataclass(frozen=True)
class SolveOptions(CaptureOptions, BindOptions, BlendshapeOptions):
    """Everything `usdface solve` takes besides its inputs and outputs: the capture's conditioning,
    the binding, the rig's shapes and the solve (its options are `run`'s of the same names)."""

    mesh_units: str | None = option(None, flag="--mesh-units", choices=UNITS, group="mesh",
                                    help="units of the mesh file (OBJ has none: cm)")
    stabilize: Any = option("auto", flag="--stabilize", coerce=stabilize_value, metavar="auto|M1,M2,...", nargs="?",
                            const="auto", negate="--no-stabilize", group="capture reading and conditioning",
                            help="remove rigid head motion: 'auto' picks the most rigid markers, or name them; "
                                 "--no-stabilize keeps the head motion in the marker displacements")
    head_motion: bool = option(True, flag="--no-head-motion", coerce=boolean, group="deliverables",
                               help="drop the head motion removed by stabilisation (by default the curves layer "
                                    "carries it as a time-sampled transform on the face's root prim /Face)")

    def take_parameters(self):
        """How a take is solved (:class:`usdface.blendshape.parameters.TakeParameters`): the solver's
        settings, the shapes held at 0, whether the head motion is kept and the pose refit's rounds."""
        from ..blendshape.parameters import TakeParameters

        return TakeParameters(solver=self.solver_parameters(), exclude=self.exclude, head_motion=self.head_motion,
                              pose_refit=self.pose_refit)
