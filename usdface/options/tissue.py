"""Options of the muscle-driven tissue model (seed 001 §5): placing a rig (`muscles`), simulating
(`simulate`) and fitting contractions to a capture (`fit-muscles`).

The ranges of the simulation's numbers (``dt``, ``rate``, ``ramp``, ``hold``, ``intensity``) and of
the tissue settings are checked by the tissue package itself (:class:`usdface.tissue.Simulator`,
:func:`usdface.tissue.expression_timeline`, :class:`usdface.tissue.TissueOptions`), with the
messages usdface has always given; the options check their types, and the checks no compute
function makes.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Mapping

from ..errors import OptionError, list_names
from ..tissue import INTEGRATORS
from ..tissue.presets import PRESET_NAMES
from .fields import Options, option
from .values import nonnegative_float, number, path, shown


def pairs_value(value, flag):
    """Repeated ``NAME=VALUE`` flags (``--force zygomaticMajor=30000``), or in Python a mapping
    ``{name: number}`` or ``(name, number)`` pairs: a tuple of ``(name, float)`` pairs in the order
    given (a name given twice keeps its last value)."""
    if value is None:
        return None
    if isinstance(value, Mapping):
        value = list(value.items())
    items = [value] if isinstance(value, str) else list(value)
    out = {}
    for item in items:
        if isinstance(item, (tuple, list)) and len(item) == 2 and isinstance(item[0], str):
            key, text = item[0].strip(), item[1]
        elif isinstance(item, str) and "=" in item:
            key, text = item.split("=", 1)
            key = key.strip()
        else:
            raise OptionError(f"{flag}: expected NAME=VALUE; got {item!r}")
        try:
            out[key] = float(text)
        except (TypeError, ValueError):
            raise OptionError(f"{flag}: {key} needs a number; got {text!r}") from None
    return tuple(out.items())


def real_value(value, flag):
    """Any real number (NaN and infinities included: the function that uses it says which it takes)."""
    if isinstance(value, bool) or not isinstance(value, (int, float, str)):
        raise OptionError(f"{flag} {shown(value)}: expected a number")
    try:
        return float(value)
    except ValueError:
        raise OptionError(f"{flag} {shown(value)}: expected a number") from None


def whole_value(value, flag):
    """A whole number (its range is checked where it is used)."""
    return number(value, flag, kind=int, what="a whole number")


def nonnegative_whole_value(value, flag):
    n = number(value, flag, kind=int, what="a whole number >= 0")
    if n < 0:
        raise OptionError(f"{flag} {shown(value)}: expected a whole number >= 0")
    return n


def step_value(value, flag):
    n = number(value, flag, kind=int, what="a whole number >= 1")
    if n < 1:
        raise OptionError(f"{flag} must be >= 1; got {n}")
    return n


def frames_range_value(value, flag):
    """``FIRST END`` capture frame indices (checked against the capture when it is read)."""
    if isinstance(value, str):
        value = value.replace(",", " ").split()
    if not isinstance(value, (list, tuple)) or len(value) != 2:
        raise OptionError(f"{flag} {shown(value)}: expected two values (FIRST END)")
    return tuple(whole_value(v, flag) for v in value)


def _check_tissue(pairs, flag) -> None:
    """The tissue model's own check of its settings (names and ranges)."""
    if pairs:
        from ..tissue.model import TissueOptions

        TissueOptions().replace(**dict(pairs))


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

    def validate(self) -> None:
        super().validate()
        if self.layout is not None and self.binding is not None:
            raise OptionError("muscles: give at most one of --layout and --binding")
        _check_tissue(self.tissue, "--tissue")
        if self.force:
            from ..tissue.rig import DEFAULT_FORCES

            bad = sorted(set(self.max_forces()) - set(DEFAULT_FORCES))
            if bad:
                raise OptionError(f"--force: unknown muscle(s) {list_names(bad)}; known: "
                                  f"{list_names(sorted(DEFAULT_FORCES))}")

    def max_forces(self) -> dict:
        """``{base muscle name: maximum force}`` given with ``--force``."""
        return dict(self.force or ())

    def tissue_settings(self) -> dict:
        """``{tissue option: value}`` given with ``--tissue``."""
        return dict(self.tissue or ())


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
    dt: float | None = option(None, flag="--dt", coerce=real_value, type=float, group="simulation",
                              help="integration step in seconds (default: implicit 1/240; explicit and symplectic "
                                   "half their estimated stability limit)")
    rate: float = option(24.0, flag="--rate", coerce=real_value, type=float, group="simulation",
                         help="frames per second of an expression")
    ramp: int = option(12, flag="--ramp", coerce=whole_value, type=int, group="simulation",
                       help="frames of the 0 -> 1 ramp of an expression")
    hold: int = option(12, flag="--hold", coerce=whole_value, type=int, group="simulation",
                       help="frames the expression is held after the ramp")
    intensity: float = option(1.0, flag="--intensity", coerce=real_value, type=float, group="simulation",
                              help="scale of the preset's contractions, 0..1")
    tissue: tuple | None = option(None, flag="--tissue", coerce=pairs_value, action="append", metavar="KEY=VALUE",
                                  group="simulation", help="override a tissue option")

    def validate(self) -> None:
        super().validate()
        _check_tissue(self.tissue, "--tissue")

    def tissue_settings(self) -> dict:
        """``{tissue option: value}`` overrides given with ``--tissue``."""
        return dict(self.tissue or ())


@dataclass(frozen=True)
class FitMusclesOptions(Options):
    """Fitting muscle contractions to captured markers (`fit-muscles`)."""

    step: int = option(1, flag="--step", coerce=step_value, type=int, group="fit",
                       help="fit every N-th capture frame")
    frames: tuple | None = option(None, flag="--frames", coerce=frames_range_value, type=int, nargs=2,
                                  metavar=("FIRST", "END"), group="fit", help="capture frames FIRST..END-1 only")
    refine: int = option(2, flag="--refine", coerce=nonnegative_whole_value, type=int, group="fit",
                         help="refinement passes by simulation")
    regularization: float = option(1e-3, flag="--regularization", coerce=nonnegative_float, type=float,
                                   group="fit", help="Tikhonov weight of the fit")
    stabilize: str = option("auto", flag="--stabilize", choices=("auto", "none"), group="fit",
                            help="remove head motion first when the capture layer is not stabilised")

    def parameters(self):
        """The fit's parameters (:class:`usdface.tissue.fit.FitParameters`)."""
        from ..tissue.fit import FitParameters

        return FitParameters(regularization=self.regularization, refine=self.refine)
