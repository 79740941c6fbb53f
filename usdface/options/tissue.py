"""Options of the muscle-driven tissue model (seed 001 §5): placing a rig (`muscles`), simulating
(`simulate`) and fitting contractions to a capture (`fit-muscles`)."""
from __future__ import annotations

from dataclasses import dataclass

from ..tissue import INTEGRATORS
from ..tissue.expressions import PRESET_NAMES
from .fields import Options, option
from .values import nonnegative_float, pair, path, positive_float, positive_int, shown
from ..errors import OptionError


def pairs_value(value, flag):
    """Repeated ``KEY=VALUE`` flags (``--force zygomaticMajor=30000``), kept as given."""
    if value is None:
        return None
    items = [value] if isinstance(value, str) else list(value)
    for item in items:
        if not isinstance(item, str) or "=" not in item:
            raise OptionError(f"{flag} {shown(item)}: expected KEY=VALUE")
    return tuple(items)


def frames_range_value(value, flag):
    first, end = pair(positive_int_or_zero, "FIRST END")(value, flag)
    if end <= first:
        raise OptionError(f"{flag} {first} {end}: expected FIRST < END (capture frames FIRST..END-1)")
    return (first, end)


def positive_int_or_zero(value, flag):
    from .values import number

    n = number(value, flag, kind=int, what="a frame index >= 0")
    if n < 0:
        raise OptionError(f"{flag} {shown(value)}: expected a frame index >= 0")
    return n


@dataclass(frozen=True)
class MusclesOptions(Options):
    """Placing the default muscle rig on a face (`muscles`)."""

    layout: str | None = option(None, flag="--layout", coerce=path, group="placement",
                                help="marker layout JSON: place brows, nose tip, chin, forehead from its markers")
    binding: str | None = option(None, flag="--binding", coerce=path, group="placement",
                                 help="binding layer: the same, from the bound markers")
    from_rig: str | None = option(None, flag="--from-rig", coerce=path, metavar="RIG", group="placement",
                                  help="warp this rig (built on another face) onto the mesh")
    force: tuple | None = option(None, flag="--force", coerce=pairs_value, action="append", metavar="MUSCLE=F",
                                 group="placement",
                                 help="maximum force of a muscle (base name, both sides), e.g. zygomaticMajor=30000")
    tissue: tuple | None = option(None, flag="--tissue", coerce=pairs_value, action="append", metavar="KEY=VALUE",
                                  group="placement",
                                  help="tissue option recorded with the rig (e.g. fascia_depth=0.4, k_deep=25)")


@dataclass(frozen=True)
class SimulateOptions(Options):
    """Simulating the tissue model driven by its muscles (`simulate`)."""

    expression: str | None = option(None, flag="--expression", choices=PRESET_NAMES, group="simulation",
                                    help="expression preset")
    timeline: str | None = option(None, flag="--timeline", coerce=path, group="simulation",
                                  help="contraction timeline JSON")
    integrator: str = option("implicit", flag="--integrator", choices=INTEGRATORS, group="simulation",
                             help="implicit (stable, default), explicit (the paper's forward Euler) or symplectic "
                                  "Euler")
    dt: float | None = option(None, flag="--dt", coerce=positive_float, type=float, group="simulation",
                              help="integration step in seconds (default: implicit 1/240; explicit and symplectic "
                                   "half their estimated stability limit)")
    rate: float = option(24.0, flag="--rate", coerce=positive_float, type=float, group="simulation",
                         help="frames per second of an expression")
    ramp: int = option(12, flag="--ramp", coerce=positive_int, type=int, group="simulation",
                       help="frames of the 0 -> 1 ramp of an expression")
    hold: int = option(12, flag="--hold", coerce=positive_int_or_zero, type=int, group="simulation",
                       help="frames the expression is held after the ramp")
    intensity: float = option(1.0, flag="--intensity", coerce=nonnegative_float, type=float, group="simulation",
                              help="scale of the preset's contractions, 0..1")
    tissue: tuple | None = option(None, flag="--tissue", coerce=pairs_value, action="append", metavar="KEY=VALUE",
                                  group="simulation", help="override a tissue option")


@dataclass(frozen=True)
class FitMusclesOptions(Options):
    """Fitting muscle contractions to captured markers (`fit-muscles`)."""

    step: int = option(1, flag="--step", coerce=positive_int, type=int, group="fit",
                       help="fit every N-th capture frame")
    frames: tuple | None = option(None, flag="--frames", coerce=frames_range_value, type=int, nargs=2,
                                  metavar=("FIRST", "END"), group="fit", help="capture frames FIRST..END-1 only")
    refine: int = option(2, flag="--refine", coerce=positive_int_or_zero, type=int, group="fit",
                         help="refinement passes by simulation")
    regularization: float = option(1e-3, flag="--regularization", coerce=nonnegative_float, type=float,
                                   group="fit", help="Tikhonov weight of the fit")
    stabilize: str = option("auto", flag="--stabilize", choices=("auto", "none"), group="fit",
                            help="remove head motion first when the capture layer is not stabilised")
