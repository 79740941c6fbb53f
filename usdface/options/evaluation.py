"""Options of `usdface evaluate`: transfer quality against ground-truth expression shapes.

The ranges of the region and hybrid numbers are checked by the evaluation itself
(:mod:`usdface.evaluation.quality`, :mod:`usdface.distance`), with the messages usdface has always
given; the options check their types.
"""
from __future__ import annotations

from dataclasses import dataclass

from ..errors import OptionError
from .fields import Options, option
from .tissue import real_value
from .values import boolean, path, shown
from .video import MESH_UNITS


def names_value(value, flag):
    """One or more words (``--methods euclidean hybrid``; commas split too: ``euclidean,hybrid``);
    None when no word is left (the command's default)."""
    if value is None:
        return None
    items = [value] if isinstance(value, (str, int, float)) else list(value)
    if not all(isinstance(v, (str, int, float)) and not isinstance(v, bool) for v in items):
        raise OptionError(f"{flag} {shown(value)}: expected names")
    words = tuple(w.strip() for v in items for w in str(v).split(",") if w.strip())
    return words or None


@dataclass(frozen=True)
class EvaluateOptions(Options):
    """Which transfers `evaluate` measures against the ground-truth shapes, and how."""

    layout: str | None = option(None, flag="--layout", coerce=path, group="markers",
                                help="marker layout JSON (usdface-layout/1)")
    binding: str | None = option(None, flag="--binding", coerce=path, group="markers",
                                 help="binding layer (from `usdface bind`)")
    units: str | None = option(None, flag="--units", choices=MESH_UNITS, group="mesh",
                               help="units of a mesh file (default cm)")
    methods: tuple | None = option(None, flag="--methods", coerce=names_value, nargs="+", metavar="M",
                                   group="transfers", help="euclidean geodesic hybrid (default: all)")
    modes: tuple | None = option(None, flag="--modes", coerce=names_value, nargs="+", metavar="MODE",
                                 group="transfers", help="paper interpolate (default: both)")
    pins: tuple | None = option(None, flag="--pins", coerce=names_value, nargs="+", metavar="PIN", group="transfers",
                                help="pinned border variants for interpolate mode: border (whole outer border), "
                                     "none, upper (border above the mouth corners, the pipeline default); default: "
                                     "all three")
    widths: tuple | None = option(None, flag="--widths", coerce=names_value, nargs="+", metavar="W",
                                  group="transfers",
                                  help="kernel widths: 'default' (the pipeline's rule: per marker, 0.7 x its mean "
                                       "distance to its 3 nearest markers in the row's metric; 1.1 x the Euclidean "
                                       "median marker spacing in paper mode), '1.1h' (that paper rule in every mode, "
                                       "usdface 0.2's default) and/or cm values; default: 'default' and 2 cm")
    backend: str | None = option(None, flag="--backend", choices=("graph", "fmm", "heat", "exact"), group="transfers",
                                 help="geodesic back-end (default: the pipeline's, fmm; graph for paper-mode rows)")
    heat: bool = option(False, flag="--heat", coerce=boolean, group="transfers",
                        help="add a geodesic/heat interpolate row")
    thin_plate: bool = option(False, flag="--thin-plate", coerce=boolean, group="transfers",
                              help="add thin-plate spline + polynomial rows")
    only: tuple | None = option(None, flag="--only", coerce=names_value, nargs="+", metavar="NAME", group="shapes",
                                help="evaluate only these shapes (names or glob patterns)")
    skip: tuple | None = option(None, flag="--skip", coerce=names_value, nargs="+", metavar="NAME", group="shapes",
                                help="skip these shapes (names or glob patterns)")
    min_displacement: float = option(0.1, flag="--min-displacement", coerce=real_value, type=float,
                                     metavar="CM", group="shapes",
                                     help="skip shapes whose largest displacement is below this (cm)")
    region_radius: float = option(1.5, flag="--region-radius", coerce=real_value, type=float, metavar="CM",
                                  group="regions",
                                  help="mouth / eye error regions: vertices within this of the hole loops (cm)")
    hybrid_radius: float = option(1.0, flag="--hybrid-radius", coerce=real_value, type=float,
                                  metavar="CM", group="regions", help="hybrid region radius (cm)")
    sigma: float = option(2.0, flag="--sigma", coerce=real_value, type=float, metavar="CM", group="regions",
                          help="hybrid weight width (cm)")
    threshold: float = option(0.6, flag="--threshold", coerce=real_value, type=float, group="regions",
                              help="hybrid: geodesic term skipped where w <= this")
    no_per_shape: bool = option(False, flag="--no-per-shape", coerce=boolean, group="report",
                                help="leave the per-shape table out")
