"""Options of reading captures and meshes: plausibility checks, capture conditioning
(`import-capture`, and every command that conditions a take), mesh import (`import-mesh`)."""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from ..errors import OptionError
from ..findings import CHECKS
from ..units import METERS_PER_UNIT
from .fields import Options, option
from .values import boolean, integer, pair, positive_float, positive_int, shown

UNITS = tuple(METERS_PER_UNIT)


def stabilize_value(value, flag):
    """None/False: no stabilisation; True/'auto': automatic; 'A,B,C' or a list: these markers."""
    if value is None or value is False:
        return None
    if value is True or value == "auto":
        return "auto"
    if isinstance(value, str):
        value = [v.strip() for v in value.split(",")]
    if isinstance(value, (list, tuple)):
        names = tuple(str(v).strip() for v in value if str(v).strip())
        if len(names) < 3:
            raise OptionError(f"{flag} {','.join(names) or value!r}: expected 'auto' or at least 3 marker names "
                              "(a rigid head needs three markers)")
        return names
    raise OptionError(f"{flag} {shown(value)}: expected 'auto' or a comma-separated list of marker names")


def trim_value(value, flag):
    start, end = pair(integer, "START END")(value, flag)
    if start < 0 or end <= start:
        raise OptionError(f"{flag} {start} {end}: expected 0 <= START < END (0-based frame indices; END excluded)")
    return (start, end)


def neutral_value(value, flag):
    """--neutral: "auto", a frame index F or a range START:END (a pair), as
    :func:`usdface.capture.neutral.parse_neutral` reads it."""
    from ..capture.neutral import parse_neutral

    return parse_neutral(value)


def allow_value(value, flag):
    """Plausibility check codes, as a list or comma-separated text (usdface.capture.plausibility)."""
    from ..capture.plausibility import parse_allow

    if value is None:
        return ()
    if isinstance(value, (list, tuple)) and all(isinstance(v, str) for v in value) or isinstance(value, str):
        return tuple(sorted(parse_allow(value)))
    raise OptionError(f"{flag} {shown(value)}: expected plausibility check names")


@dataclass(frozen=True)
class PlausibilityOptions(Options):
    """Which plausibility findings to accept (`import-capture`, `bind`, `lift`, `run`); see
    :mod:`usdface.capture.plausibility` for the checks."""

    allow: tuple = option((), flag="--allow", coerce=allow_value, nargs="+", metavar="CHECK",
                          group="plausibility checks",
                          help="accept these findings: an error becomes a warning, a warning is silenced; checks: "
                               f"{', '.join(CHECKS)} (the README's table)")


@dataclass(frozen=True)
class CaptureOptions(PlausibilityOptions):
    """Reading and conditioning a capture (`import-capture`, `run`)."""

    units: str | None = option(None, flag="--units", choices=UNITS, group="capture reading and conditioning",
                               help="units of the capture file when it does not declare them (CSV)")
    rate: float | None = option(None, flag="--rate", coerce=positive_float, metavar="HZ",
                                group="capture reading and conditioning",
                                help="capture rate when the file does not declare it")
    up_axis: str | None = option(None, flag="--up-axis", choices=("Y", "Z"), group="capture reading and conditioning",
                                 help="the source's up axis (default: Z for C3D, Y otherwise)")
    stabilize: Any = option(None, flag="--stabilize", coerce=stabilize_value, metavar="auto|M1,M2,...", nargs="?",
                            const="auto", negate="--no-stabilize", group="capture reading and conditioning",
                            help="remove rigid head motion: 'auto' picks the most rigid markers, or name them "
                                 "(default: none, the capture keeps its head motion; run and solve stabilise with "
                                 "auto by default: give --stabilize for the same stabilisation)")
    fill_gaps: int | None = option(None, flag="--fill-gaps", coerce=positive_int, metavar="N",
                                   group="capture reading and conditioning", help="fill gaps of at most N frames")
    filter: str | None = option(None, flag="--filter", choices=("butterworth", "savgol"),
                                group="capture reading and conditioning", help="zero-phase noise filter")
    cutoff: float = option(8.0, flag="--cutoff", coerce=positive_float, metavar="HZ",
                           group="capture reading and conditioning",
                           help="filter cutoff (below half the capture rate)")
    trim: tuple | None = option(None, flag="--trim", coerce=trim_value, nargs=2, metavar=("START", "END"),
                                group="capture reading and conditioning",
                                help="keep frames START..END-1 (0-based frame indices of the file)")
    start_frame: int | None = option(None, flag="--start-frame", coerce=integer, metavar="F",
                                     group="capture reading and conditioning",
                                     help="time code of the first frame after trimming (default 0)")
    resample: float | None = option(None, flag="--resample", coerce=positive_float, metavar="HZ",
                                    group="capture reading and conditioning", help="resample to this rate")
    neutral: Any = option(None, flag="--neutral", coerce=neutral_value, metavar="F|START:END|auto",
                          group="capture reading and conditioning",
                          help="where the rest pose every displacement is measured from comes from: the still "
                               "stretch around frame F, around the frame 'auto' chooses, or exactly frames "
                               "START..END-1 (0-based indices after --trim; default: the still stretch around the "
                               "first frame)")
    keep_zeros: bool = option(False, flag="--keep-zeros", coerce=boolean, group="plausibility checks",
                              help="C3D: keep samples at exactly (0, 0, 0) as positions (default: they are gaps)")
    drop_outliers: bool = option(False, flag="--drop-outliers", coerce=boolean, group="plausibility checks",
                                 help="make outlier samples gaps instead of stopping (fill them with --fill-gaps N)")

    def conditioning(self):
        """The conditioning steps these options ask for (:class:`usdface.capture.conditioning.Conditioning`)."""
        from ..capture.conditioning import Conditioning

        return Conditioning(trim=self.trim, fill_gaps=self.fill_gaps, filter=self.filter, cutoff=self.cutoff,
                            resample=self.resample, neutral=self.neutral, stabilize=self.stabilize,
                            start_frame=self.start_frame, allow=self.allow, drop_outliers=self.drop_outliers)


@dataclass(frozen=True)
class ImportMeshOptions(Options):
    """Importing a face mesh (`import-mesh`)."""

    units: str | None = option(None, flag="--units", choices=("mm", "cm", "dm", "m", "in", "ft"), group="mesh",
                               help="units of the mesh file (OBJ has none: default cm)")
    up_axis: str = option("Y", flag="--up-axis", choices=("Y", "Z"), group="mesh",
                          help="the source's up axis (Z is rotated to Y)")
