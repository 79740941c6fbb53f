"""Options, named once: the dataclasses shared by the command line, batch manifests and the Python API.

Every option of the pipeline is one field of one of the frozen dataclasses below. The field's
metadata gives its command-line flag, its help text and the function that checks and converts a
value, so the three ways of giving an option mean the same thing:

- the command line builds its arguments from the fields (:mod:`usdface.cliargs`): ``--pin-border``
  is the field ``pin_border``, and the help text is the field's;
- a batch manifest's keys are the field names (``pin_border = "all"``);
- Python code passes the object: ``RunOptions(method="euclidean", trim=(0, 300))``.

Values are checked and converted when the object is made (``__post_init__``), whatever their
source: a bad value raises :class:`~usdface.errors.OptionError` naming the command-line flag
(``--max-influences 0: expected an integer >= 1``), which a manifest reports with its line.

Groups (each a dataclass, :class:`RunOptions` combines them): :class:`CaptureOptions`,
:class:`BindOptions`, :class:`DistanceOptions`, :class:`TransferOptions`, :class:`SkelOptions`,
:class:`VideoOptions`. ``options.group(TransferOptions)`` takes one group out of a combined object.
"""
from __future__ import annotations

import difflib
import json
from dataclasses import MISSING, dataclass, field, fields, replace
from pathlib import Path
from typing import Any, Callable, Mapping

from .errors import OptionError
from .units import METERS_PER_UNIT

__all__ = [
    "PlausibilityOptions", "CaptureOptions", "BindOptions", "DistanceOptions", "TransferOptions", "SkelOptions",
    "VideoOptions", "SolveOptions", "RunOptions", "PlayblastOptions", "OUTPUT_KINDS", "option_fields", "flag_of",
]

UNITS = tuple(METERS_PER_UNIT)
METHODS = ("euclidean", "geodesic", "hybrid")
BACKENDS = ("graph", "fmm", "heat", "exact")   # geodesic back-ends (usdface.distance.GeodesicSolver)
DEFAULT_BACKEND = "graph"                       # the paper's edge paths (README: why not fmm)
KERNELS = ("gaussian", "multiquadric", "inverse_multiquadric", "thin_plate_spline", "cubic")
#: deliverables `run` can write, in the order they are written
OUTPUT_KINDS = ("points", "skel", "blendshapes")
#: aliases of --output-kind lists
OUTPUT_ALIASES = {"both": ("points", "skel"), "all": OUTPUT_KINDS}


# -- coercion: one function per kind of value, used by every entry point --------------------------

def _show(v) -> str:
    """A value as the user typed it (command-line strings without quotes)."""
    return v if isinstance(v, str) else repr(v)


def _is_blank(v) -> bool:
    return v is None or (isinstance(v, str) and v.strip().lower() in ("", "none"))


def _choice(*choices: str) -> Callable:
    def coerce(value, flag):
        if value not in choices:
            raise OptionError(f"{flag} {_show(value)}: expected one of {', '.join(choices)}")
        return value
    return coerce


def _optional(coerce: Callable) -> Callable:
    def wrapped(value, flag):
        return None if _is_blank(value) else coerce(value, flag)
    return wrapped


def _number(value, flag, *, kind=float, what="a number"):
    if isinstance(value, bool):
        raise OptionError(f"{flag} {_show(value)}: expected {what}")
    try:
        x = kind(value)
    except (TypeError, ValueError):
        raise OptionError(f"{flag} {_show(value)}: expected {what}") from None
    if kind is int and isinstance(value, float) and value != x:
        raise OptionError(f"{flag} {_show(value)}: expected {what}")
    if kind is float and not x == x:  # NaN
        raise OptionError(f"{flag} {_show(value)}: expected {what}")
    return x


def _positive_float(value, flag):
    x = _number(value, flag, what="a number > 0")
    if not x > 0 or x == float("inf"):
        raise OptionError(f"{flag} {_show(value)}: expected a number > 0")
    return x


def _nonnegative_float(value, flag):
    x = _number(value, flag, what="a number >= 0")
    if not x >= 0 or x == float("inf"):
        raise OptionError(f"{flag} {_show(value)}: expected a number >= 0")
    return x


def _unit_interval(value, flag):
    x = _number(value, flag, what="a number in [0, 1]")
    if not 0.0 <= x <= 1.0:
        raise OptionError(f"{flag} {_show(value)}: expected a number in [0, 1]")
    return x


def _positive_int(value, flag):
    n = _number(value, flag, kind=int, what="a whole number > 0")
    if n <= 0:
        raise OptionError(f"{flag} {_show(value)}: expected a whole number > 0")
    return n


def _int(value, flag):
    return _number(value, flag, kind=int, what="a whole number")


def _flag(value, flag):
    if isinstance(value, bool):
        return value
    if isinstance(value, str) and value.lower() in ("true", "false", "yes", "no", "1", "0"):
        return value.lower() in ("true", "yes", "1")
    raise OptionError(f"{flag} {_show(value)}: expected true or false")


def _stabilize(value, flag):
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
    raise OptionError(f"{flag} {_show(value)}: expected 'auto' or a comma-separated list of marker names")


def _pair(kind: Callable, what: str) -> Callable:
    def coerce(value, flag):
        if isinstance(value, str):
            value = value.replace(",", " ").split()
        if not isinstance(value, (list, tuple)) or len(value) != 2:
            raise OptionError(f"{flag} {_show(value)}: expected two values ({what})")
        return tuple(kind(v, flag) for v in value)
    return coerce


def _trim(value, flag):
    start, end = _pair(_int, "START END")(value, flag)
    if start < 0 or end <= start:
        raise OptionError(f"{flag} {start} {end}: expected 0 <= START < END (0-based frame indices; END excluded)")
    return (start, end)


def _radius(value, flag):
    r1, r2 = _pair(_positive_float, "R1 R2 in pixels")(value, flag)
    if r2 < r1:
        raise OptionError(f"{flag} {r1:g} {r2:g}: expected R1 <= R2 (the smallest and largest dot radius)")
    return (r1, r2)


def _neutral(value, flag):
    if value == "auto":
        return "auto"
    n = _number(value, flag, kind=int, what="a frame index (0-based, after --trim) or 'auto'")
    if n < 0:
        raise OptionError(f"{flag} {_show(value)}: expected a frame index >= 0 or 'auto'")
    return n


def _regularization(value, flag):
    if value == "auto":
        return "auto"
    return _nonnegative_float(value, flag)


def _stiffness(value, flag):
    """A width in mesh units, a {marker: width} dict, or the path of a JSON file holding one."""
    if isinstance(value, Mapping):
        widths = {}
        for k, v in value.items():
            widths[str(k)] = _positive_float(v, f"{flag} {k}")
        return widths
    if isinstance(value, (int, float)) and not isinstance(value, bool):
        return _positive_float(value, flag)
    if isinstance(value, (str, Path)):
        try:
            return _positive_float(float(value), flag)
        except (ValueError, OptionError):
            pass
        return str(value)
    raise OptionError(f"{flag} {_show(value)}: expected a width in mesh units or a JSON file {{marker: width}}")


def _auto(value, flag):
    """--auto: bind without a layout (True), or for a video find N dots (an integer)."""
    if value is None or value is False:
        return False
    if value is True or value == "":
        return True
    return _positive_int(value, flag)


def _output_kinds(value, flag):
    if isinstance(value, str):
        items = [v.strip() for v in value.split(",") if v.strip()]
    elif isinstance(value, (list, tuple)):
        items = [str(v).strip() for v in value]
    else:
        raise OptionError(f"{flag} {_show(value)}: expected a comma list of {', '.join(OUTPUT_KINDS)} (or all, both)")
    kinds = []
    for item in items:
        expanded = OUTPUT_ALIASES.get(item, (item,))
        for k in expanded:
            if k not in OUTPUT_KINDS:
                raise OptionError(f"{flag} {item}: expected a comma list of {', '.join(OUTPUT_KINDS)} "
                                  "(or all = every kind, both = points,skel)")
            kinds.append(k)
    if not kinds:
        raise OptionError(f"{flag}: expected at least one of {', '.join(OUTPUT_KINDS)}")
    return tuple(k for k in OUTPUT_KINDS if k in kinds)


def _max_influences(value, flag):
    if value == "all":
        return "all"
    n = _number(value, flag, kind=int, what="an integer >= 1 or 'all'")
    if n < 1:
        raise OptionError(f"{flag} {_show(value)}: expected an integer >= 1 (joints per vertex) or 'all'")
    return n


def _allow(value, flag):
    """Plausibility check codes, as a list or comma-separated text (usdface.capture.plausibility)."""
    from .capture.plausibility import parse_allow

    if value is None:
        return ()
    if isinstance(value, (list, tuple)) and all(isinstance(v, str) for v in value) or isinstance(value, str):
        return tuple(sorted(parse_allow(value)))
    raise OptionError(f"{flag} {_show(value)}: expected plausibility check names")


def _path(value, flag):
    if not isinstance(value, (str, Path)):
        raise OptionError(f"{flag} {_show(value)}: expected a file path")
    return str(value)


# -- the option field ------------------------------------------------------------------------------

def option(default, *, flag: str, help: str, coerce: Callable | None = None, group: str,
           choices: tuple | None = None, metavar=None, nargs=None, negate: str | None = None,
           const=None) -> Any:
    """A dataclass field that is a usdface option (see the module docstring).

    ``flag``: the long command-line flag; ``negate``: a second flag setting the value to None
    (``--no-stabilize``); ``const``: value of the flag given without an argument (``nargs="?"``).
    Booleans: a field defaulting to False is set by ``flag``, one defaulting to True is cleared
    by ``--no-<name>`` (give that as ``flag``).
    """
    if coerce is None and choices is not None:
        coerce = _choice(*choices)
    return field(default=default, metadata={
        "flag": flag, "help": help, "coerce": coerce, "group": group, "choices": choices,
        "metavar": metavar, "nargs": nargs, "negate": negate, "const": const})


#: order of the option groups in `--help`
GROUP_ORDER = ("mesh", "capture reading and conditioning", "plausibility checks", "binding", "video capture",
               "distances", "transfer", "deliverables", "skeleton", "blend-shape solve", "curves", "frames", "look",
               "side by side", "encoding")


def option_fields(cls) -> list:
    """The option fields of an options class (every field has the metadata above), by group."""
    found = [f for f in fields(cls) if "flag" in f.metadata]
    rank = {g: i for i, g in enumerate(GROUP_ORDER)}
    return sorted(found, key=lambda f: rank.get(f.metadata["group"], len(rank)))


def flag_of(cls, name: str) -> str:
    """The command-line flag of option ``name`` of ``cls``."""
    return next(f.metadata["flag"] for f in fields(cls) if f.name == name)


class _Options:
    """Behaviour shared by the option groups (a mixin: the groups are frozen dataclasses)."""

    def __post_init__(self):
        for f in option_fields(type(self)):
            value = getattr(self, f.name)
            coerce = f.metadata["coerce"]
            if coerce is not None and not (value is None and f.default is None):
                object.__setattr__(self, f.name, coerce(value, f.metadata["flag"]))
        self.validate()

    def validate(self) -> None:
        """Checks that involve several options (subclasses add theirs)."""

    def group(self, cls):
        """The options of group ``cls`` taken from this (combined) object."""
        return cls(**{f.name: getattr(self, f.name) for f in fields(cls)})

    def replace(self, **changes):
        """A copy with some options changed (checked like a new object)."""
        return replace(self, **changes)

    def to_dict(self) -> dict:
        """Every option as plain JSON types (tuples become lists)."""
        out = {}
        for f in fields(self):
            v = getattr(self, f.name)
            out[f.name] = list(v) if isinstance(v, tuple) else v
        return out

    def record(self) -> dict:
        """The options as recorded in provenance: JSON types, files by name (no folders, so the
        same job gives the same record wherever it runs)."""
        rec = self.to_dict()
        for name in ("layout", "seeds"):
            if rec.get(name):
                rec[name] = Path(rec[name]).name
        st = rec.get("stiffness")
        if isinstance(st, str):
            rec["stiffness"] = Path(st).name
        return json.loads(json.dumps(rec, sort_keys=True, default=str))

    @classmethod
    def from_mapping(cls, mapping: Mapping, *, what: str = "options"):
        """Build from a dict of ``{option name: value}`` (a manifest's keys); unknown names are an
        error that suggests the closest name."""
        known = {f.name for f in fields(cls)}
        unknown = [k for k in mapping if k not in known]
        if unknown:
            k = unknown[0]
            close = difflib.get_close_matches(k, sorted(known), n=1)
            raise OptionError(f"{what}: unknown option {k!r}" + (f" (did you mean {close[0]!r}?)" if close else "")
                              + f"; expected one of {', '.join(sorted(known))}")
        return cls(**dict(mapping))


# -- the groups ------------------------------------------------------------------------------------

@dataclass(frozen=True)
class PlausibilityOptions(_Options):
    """Which plausibility findings to accept (`import-capture`, `bind`, `lift`, `run`); see
    :mod:`usdface.capture.plausibility` for the checks."""

    allow: tuple = option((), flag="--allow", coerce=_allow, nargs="+", metavar="CHECK", group="plausibility checks",
                          help="accept these findings: an error becomes a warning, a warning is silenced; checks: "
                               "zeros, outliers, far-markers, mixed-units, face-size, speed, stabilize, "
                               "layout-distance, fit-residual, unit-scale (the README's table)")


@dataclass(frozen=True)
class CaptureOptions(PlausibilityOptions):
    """Reading and conditioning a capture (`import-capture`, `run`)."""

    units: str | None = option(None, flag="--units", choices=UNITS, group="capture reading and conditioning",
                               help="units of the capture file when it does not declare them (CSV)")
    rate: float | None = option(None, flag="--rate", coerce=_positive_float, metavar="HZ",
                                group="capture reading and conditioning",
                                help="capture rate when the file does not declare it")
    up_axis: str | None = option(None, flag="--up-axis", choices=("Y", "Z"), group="capture reading and conditioning",
                                 help="the source's up axis (default: Z for C3D, Y otherwise)")
    stabilize: Any = option(None, flag="--stabilize", coerce=_stabilize, metavar="auto|M1,M2,...", nargs="?",
                            const="auto", negate="--no-stabilize", group="capture reading and conditioning",
                            help="remove rigid head motion: 'auto' picks the most rigid markers, or name them")
    fill_gaps: int | None = option(None, flag="--fill-gaps", coerce=_positive_int, metavar="N",
                                   group="capture reading and conditioning", help="fill gaps of at most N frames")
    filter: str | None = option(None, flag="--filter", choices=("butterworth", "savgol"),
                                group="capture reading and conditioning", help="zero-phase noise filter")
    cutoff: float = option(8.0, flag="--cutoff", coerce=_positive_float, metavar="HZ",
                           group="capture reading and conditioning",
                           help="filter cutoff (below half the capture rate)")
    trim: tuple | None = option(None, flag="--trim", coerce=_trim, nargs=2, metavar=("START", "END"),
                                group="capture reading and conditioning",
                                help="keep frames START..END-1 (0-based frame indices of the file)")
    start_frame: int | None = option(None, flag="--start-frame", coerce=_int, metavar="F",
                                     group="capture reading and conditioning",
                                     help="time code of the first frame after trimming (default 0)")
    resample: float | None = option(None, flag="--resample", coerce=_positive_float, metavar="HZ",
                                    group="capture reading and conditioning", help="resample to this rate")
    neutral: Any = option(None, flag="--neutral", coerce=_neutral, metavar="FRAME|auto",
                          group="capture reading and conditioning",
                          help="neutral frame (0-based index after trimming) or 'auto' (default: the first frame)")
    keep_zeros: bool = option(False, flag="--keep-zeros", coerce=_flag, group="plausibility checks",
                              help="C3D: keep samples at exactly (0, 0, 0) as positions (default: they are gaps)")
    drop_outliers: bool = option(False, flag="--drop-outliers", coerce=_flag, group="plausibility checks",
                                 help="make outlier samples gaps instead of stopping (fill them with --fill-gaps N)")


@dataclass(frozen=True)
class BindOptions(PlausibilityOptions):
    """Binding markers to the surface (`bind`, `run`)."""

    retarget: str = option("displacement", flag="--retarget", choices=("displacement", "similarity"),
                           group="binding",
                           help="displacement: capture motion rotated, not scaled (the paper); similarity: also scaled")


@dataclass(frozen=True)
class DistanceOptions(_Options):
    """Distance matrices (`distances`, `run`)."""

    method: str = option("hybrid", flag="--method", choices=METHODS, group="distances",
                         help="Euclidean (Eq. 6), geodesic (Eq. 7) or hybrid (Eq. 8)")
    backend: str = option(DEFAULT_BACKEND, flag="--backend", choices=BACKENDS, group="distances",
                          help="geodesic back-end: shortest edge paths (the paper's, default), fmm (fast marching: accurate), heat method, exact polyhedral (small meshes)")
    region_radius: float = option(1.0, flag="--region-radius", coerce=_nonnegative_float, metavar="CM",
                                  group="distances",
                                  help="hybrid: geodesic regions = vertices within this distance of the mouth/eye "
                                       "loops (cm)")
    sigma: float = option(2.0, flag="--sigma", coerce=_positive_float, metavar="CM", group="distances",
                          help="hybrid: weight width (cm)")
    threshold: float = option(0.6, flag="--threshold", coerce=_unit_interval, group="distances",
                              help="hybrid: geodesic term skipped where w <= this")
    pin_border: str = option("upper", flag="--pin-border", choices=("upper", "all", "none"), group="distances",
                             help="outer border as zero-displacement centres: above the mouth corners (the jaw's "
                                  "border moves with the jaw), all of it, or none")
    components: str = option("error", flag="--components", choices=("error", "euclidean"), group="distances",
                             help="markers on different mesh components: error, or Euclidean distance across them")


@dataclass(frozen=True)
class TransferOptions(_Options):
    """The RBF transfer (`transfer`, `skel`, `run`)."""

    rbf: str = option("interpolate", flag="--rbf", choices=("paper", "interpolate"), group="transfer",
                      help="paper: Eqs. 1-5 as published; interpolate: exact RBF solve")
    kernel: str = option("gaussian", flag="--kernel", choices=KERNELS, group="transfer", help="radial basis function")
    stiffness: Any = option(None, flag="--stiffness", coerce=_stiffness, metavar="WIDTH|JSON", group="transfer",
                            help="kernel width in mesh units for every marker, or a JSON file {marker: width} "
                                 "(default: 1.1 x the median nearest-marker distance, about 2 cm on a face)")
    regularization: Any = option("auto", flag="--regularization", coerce=_regularization, metavar="LAMBDA|auto",
                                 group="transfer",
                                 help="ridge term added to the kernel matrix (interpolate mode). auto: exact "
                                      "interpolation unless it amplifies marker motion more than 25x (geodesic "
                                      "kernels can), then the lambda with the least amplification")
    polynomial: bool = option(False, flag="--polynomial", coerce=_flag, group="transfer",
                              help="add a linear polynomial term (interpolate mode)")

    def validate(self) -> None:
        super().validate()
        if self.rbf == "paper" and (self.polynomial or self.regularization not in ("auto", 0.0)):
            raise OptionError("--polynomial and --regularization apply to --rbf interpolate only "
                              "(paper mode solves nothing)")


def _corrective_shapes(value, flag):
    n = _number(value, flag, kind=int, what="0 or a whole number from 2 to 16")
    if not (n == 0 or 2 <= n <= 16):
        raise OptionError(f"{flag} {n}: expected 0 or a whole number from 2 to 16 (one shape alone corrects nothing)")
    return n


@dataclass(frozen=True)
class SkelOptions(_Options):
    """Skeletal keyframes (`skel`, `run --output-kind skel`)."""

    skin_weights: str = option("dcc", flag="--skin-weights", choices=("dcc", "exact"), group="skeleton",
                               help="dcc: non-negative weights summing to one, at most --max-influences per vertex, "
                                    "fitted to the transfer, with corrective blend shapes (what Blender, Maya and "
                                    "game engines take as they are); exact: the transfer matrix itself (signed "
                                    "weights, UsdSkel only)")
    max_influences: Any = option(8, flag="--max-influences", coerce=_max_influences, metavar="K|all",
                                 group="skeleton",
                                 help="joints per vertex, root included (game engines often take 4); 'all' keeps "
                                      "every joint")
    skin_fit: str = option("rom", flag="--skin-fit", choices=("rom", "take"), group="skeleton",
                           help="dcc: fit the weights on a synthetic range of motion (the character's weights, the "
                                "same for every take) or on this take's marker motion")
    corrective_shapes: int = option(16, flag="--corrective-shapes", coerce=_corrective_shapes, metavar="S",
                                    group="skeleton",
                                    help="dcc: time-invariant corrective blend shapes with weights in [0, 1], 0 or "
                                         "2..16")
    weight_fit: str = option("lsq", flag="--weight-fit", choices=("lsq", "renormalize"), group="skeleton",
                             help="exact with K < all: refit the kept weights by least squares over the take, or "
                                  "just rescale them to sum to one")


def _patterns(value, flag):
    """Comma-separated shape-name globs; 'none' (or empty) for no pattern."""
    if value is None:
        return ()
    if isinstance(value, str):
        value = [] if value.strip().lower() in ("", "none") else value.split(",")
    if not isinstance(value, (list, tuple)):
        raise OptionError(f"{flag} {_show(value)}: expected comma-separated shape names or globs, or 'none'")
    return tuple(str(v).strip() for v in value if str(v).strip())


@dataclass(frozen=True)
class SolveOptions(_Options):
    """The blend-shape solve (`solve`, `run --output-kind blendshapes`)."""

    shapes: str | None = option(None, flag="--shapes", coerce=_path, metavar="DIR|NPZ|RIG.usd",
                                group="blend-shape solve",
                                help="the rig's shapes for a neutral mesh: a folder of <shape>.obj, an .npz (names, "
                                     "deltas[, neutral]) or a USD rig (not needed when the mesh is a USD mesh with "
                                     "UsdSkel blend shapes)")
    smoothing: float = option(6.0, flag="--smoothing", coerce=_nonnegative_float, metavar="HZ",
                              group="blend-shape solve", help="temporal smoothness cut-off in Hz (0: none)")
    sparsity: float = option(0.01, flag="--sparsity", coerce=_nonnegative_float, metavar="BETA",
                             group="blend-shape solve", help="L1 weight picking few shapes per frame, cm^2")
    symmetry: float = option(0.05, flag="--symmetry", coerce=_nonnegative_float, metavar="GAMMA",
                             group="blend-shape solve",
                             help="left/right prior on ...Left/...Right pairs whose deltas mirror each other (0: none)")
    exclude: tuple = option(("eyeLook*", "tongueOut"), flag="--exclude", coerce=_patterns, metavar="PATTERNS",
                            group="blend-shape solve",
                            help="shapes held at 0, comma-separated globs (markers see neither gaze nor tongue; "
                                 "'none' solves every shape)")
    refit: bool = option(True, flag="--no-refit", coerce=_flag, group="blend-shape solve",
                         help="skip the second pass that refits the active shapes without the sparsity shrinkage")
    max_iterations: int = option(300, flag="--max-iterations", coerce=_positive_int, metavar="N",
                                 group="blend-shape solve", help="ADMM iterations at most")
    tolerance: float = option(2e-3, flag="--tolerance", coerce=_positive_float, metavar="CM",
                              group="blend-shape solve", help="ADMM stopping tolerance (cm)")
    fps: float | None = option(None, flag="--fps", coerce=_positive_float, metavar="FPS", group="curves",
                               help="deliver the curves at this rate (24, 25, 30...) instead of the capture's")
    key_tolerance: float | None = option(None, flag="--key-tolerance", coerce=_nonnegative_float, metavar="W",
                                         group="curves",
                                         help="reduce keys: each curve stays within W (weight units) of the solved one")
    livelink_fill_zeros: bool = option(False, flag="--livelink-fill-zeros", coerce=_flag, group="curves",
                                       help="Live Link CSV: zeros for ARKit shapes the rig lacks (default: an error "
                                            "naming them)")

    def solver_kwargs(self) -> dict:
        """The keyword arguments of the solver (usdface.processors.solve.solver_defaults)."""
        return dict(smoothing_hz=self.smoothing or None, sparsity=self.sparsity, symmetry=self.symmetry,
                    exclude=self.exclude, refit=self.refit, max_iterations=self.max_iterations,
                    tolerance=self.tolerance)


@dataclass(frozen=True)
class VideoOptions(_Options):
    """Tracking a video of painted dots inside `run`."""

    seeds: str | None = option(None, flag="--seeds", coerce=_path, metavar="SEEDS.json", group="video capture",
                               help="JSON {marker: [x, y]} of every dot on the first frame (pixels)")
    radius: tuple = option((3.0, 10.0), flag="--radius", coerce=_radius, nargs=2, metavar=("R1", "R2"),
                           group="video capture", help="dot radius range in pixels")


@dataclass(frozen=True)
class RunOptions(CaptureOptions, BindOptions, DistanceOptions, TransferOptions, SkelOptions, SolveOptions,
                 VideoOptions):
    """Everything `usdface run` (and a batch shot, and :func:`usdface.api.run`) takes besides its
    inputs and output folder. Defaults are the main job's."""

    layout: str | None = option(None, flag="--layout", coerce=_path, metavar="LAYOUT.json", group="binding",
                                help="marker layout JSON (usdface-layout/1); required for a video capture")
    auto: Any = option(False, flag="--auto", coerce=_auto, metavar="N", nargs="?", const=True, group="binding",
                       help="bind automatically; for a video capture, --auto N finds N dots on the first frame")
    mesh_units: str | None = option(None, flag="--mesh-units", choices=UNITS, group="mesh",
                                    help="units of the mesh file (OBJ has none: cm)")
    stabilize: Any = option("auto", flag="--stabilize", coerce=_stabilize, metavar="auto|M1,M2,...", nargs="?",
                            const="auto", negate="--no-stabilize", group="capture reading and conditioning",
                            help="remove rigid head motion: 'auto' picks the most rigid markers, or name them; "
                                 "--no-stabilize keeps the head motion in the marker displacements")
    output_kind: tuple = option(("points",), flag="--output-kind", coerce=_output_kinds, metavar="KIND[,KIND]",
                                group="deliverables",
                                help="what to deliver, a comma list: points (time-sampled mesh points, anim.usdc), "
                                     "skel (UsdSkel keyframes, skel.usdc), blendshapes (weight curves on a "
                                     "blend-shape rig, blendshapes.usdc + curves.csv; needs --shapes or a USD mesh "
                                     "with blend shapes); 'all' for every kind ('both' = points,skel)")
    livelink: bool = option(False, flag="--livelink", coerce=_flag, group="deliverables",
                            help="blendshapes: also write curves_livelink.csv in the layout of Unreal's Live Link "
                                 "Face app (ARKit names and order)")
    head_motion: bool = option(True, flag="--no-head-motion", coerce=_flag, group="deliverables",
                               help="drop the head motion removed by stabilisation (by default every deliverable "
                                    "carries it as a time-sampled transform on the face's root prim /Face)")

    def validate(self) -> None:
        super().validate()
        if self.layout is not None and self.auto is True:
            raise OptionError("--layout and --auto: give one of them (a layout places the markers; --auto aligns "
                              "the neutral marker cloud)")


# -- playblasts ------------------------------------------------------------------------------------

def _movie_size(value, flag):
    """``"960x540"`` or (960, 540): an even movie frame size (H.264 yuv420p)."""
    if isinstance(value, (tuple, list)) and len(value) == 2:
        w, h = value
    else:
        try:
            w, h = (int(v) for v in str(value).lower().split("x"))
        except ValueError:
            raise OptionError(f"{flag} {_show(value)}: expected WIDTHxHEIGHT in pixels, e.g. 960x540") from None
    w, h = _number(w, flag, kind=int, what="whole pixels"), _number(h, flag, kind=int, what="whole pixels")
    if not (16 <= w <= 7680 and 16 <= h <= 4320):
        raise OptionError(f"{flag} {w}x{h}: expected 16..7680 x 16..4320 pixels")
    if w % 2 or h % 2:
        raise OptionError(f"{flag} {w}x{h}: H.264 (yuv420p) needs an even width and height")
    return (w, h)


def _frame_range(value, flag):
    first, last = _pair(_int, "FIRST LAST time codes")(value, flag)
    if last < first:
        raise OptionError(f"{flag} {first} {last}: expected FIRST <= LAST (time codes, both played)")
    return (first, last)


def _in_range(lo, hi, kind=int):
    def coerce(value, flag):
        x = _number(value, flag, kind=kind, what=f"a number in {lo}..{hi}")
        if not lo <= x <= hi:
            raise OptionError(f"{flag} {_show(value)}: expected {lo}..{hi}")
        return x
    return coerce


def _workers(value, flag):
    n = _number(value, flag, kind=int, what="0 (this thread) or more workers")
    if n < 0:
        raise OptionError(f"{flag} {n}: expected 0 (this thread) or more")
    return n


#: time integrators of the tissue simulator (usdface.tissue.integrators.Simulator)
INTEGRATORS = ("explicit", "symplectic", "implicit")

#: camera views shared by `preview` and `playblast` (usdface.preview.camera.VIEW_CHOICES)
VIEWS = ("front", "three-quarter", "side", "turntable", "left", "right", "side_right")
#: surface colours shared by `preview` and `playblast`
COLORS = ("regions", "displacement", "error", "hybrid-weight", "none")
X264_PRESETS = ("ultrafast", "superfast", "veryfast", "faster", "fast", "medium", "slow", "slower")


@dataclass(frozen=True)
class PlayblastOptions(_Options):
    """How `usdface playblast` (and a report's movie) renders a shot."""

    frame_range: tuple | None = option(None, flag="--range", coerce=_frame_range, nargs=2, metavar=("FIRST", "LAST"),
                                       group="frames", help="time codes to play, inclusive (default: the whole shot)")
    size: tuple = option((960, 540), flag="--size", coerce=_movie_size, metavar="WxH", group="frames",
                         help="movie frame in pixels, even numbers")
    view: str = option("front", flag="--view", choices=VIEWS, group="look", help="camera (the list preview shares)")
    turntable_period: float = option(6.0, flag="--turntable-period", coerce=_positive_float, metavar="SECONDS",
                                     group="look", help="--view turntable: seconds per swing")
    projection: str = option("orthographic", flag="--projection", choices=("orthographic", "perspective"),
                             group="look", help="camera projection")
    stabilized: bool = option(False, flag="--stabilized", coerce=_flag, group="look",
                              help="without the head motion on the face's root (the face as the transfer moved it)")
    color: str = option("regions", flag="--color", choices=COLORS, group="look",
                        help="surface colour: regions, displacement from rest, error against --reference, hybrid "
                             "weight")
    reference: str | None = option(None, flag="--reference", coerce=_path, metavar="SHOT", group="look",
                                   help="shot or layer with reference points (for --color error)")
    markers: bool = option(False, flag="--markers", coerce=_flag, group="look", help="draw the capture markers")
    bound: bool = option(False, flag="--bound", coerce=_flag, group="look", help="draw the markers' bound points")
    labels: bool = option(False, flag="--labels", coerce=_flag, group="look",
                          help="write marker names (implies the markers' positions)")
    burnin: bool = option(True, flag="--no-burnin", coerce=_flag, group="look",
                          help="no shot/method/frame/timecode text")
    legend: bool = option(True, flag="--no-legend", coerce=_flag, group="look", help="no region legend or colour bar")
    supersample: int = option(1, flag="--supersample", coerce=_in_range(1, 4), metavar="K", group="look",
                              help="anti-aliasing factor 1..4")
    compare: str | None = option(None, flag="--compare", coerce=_path, metavar="SHOT", group="side by side",
                                 help="a second shot side by side on the right (aligned in seconds; a shorter one "
                                      "holds its last frame)")
    video: str | None = option(None, flag="--video", coerce=_path, metavar="PATH", group="side by side",
                               help="the shot's source video side by side on the right (frame k + trim)")
    workers: int | None = option(None, flag="--workers", coerce=_workers, metavar="N", group="encoding",
                                 help="render workers (default: the usable cores)")
    parallel: str = option("threads", flag="--parallel", choices=("threads", "processes"), group="encoding",
                           help="how workers run (threads: the renderer releases the GIL)")
    crf: int = option(18, flag="--crf", coerce=_in_range(0, 51), group="encoding",
                      help="x264 quality, 0 (lossless) .. 51")
    preset: str = option("veryfast", flag="--preset", choices=X264_PRESETS, group="encoding",
                         help="x264 speed preset")

    def validate(self) -> None:
        super().validate()
        if self.compare is not None and self.video is not None:
            raise OptionError("--compare and --video: one panel on the right, give one of them")


def defaults_of(cls) -> dict:
    """{name: default} of an options class."""
    out = {}
    for f in fields(cls):
        out[f.name] = f.default if f.default is not MISSING else f.default_factory()  # type: ignore[misc]
    return out
