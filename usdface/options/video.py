"""Options of the video capture commands: tracking painted dots (`track`) and lifting 2D tracks
onto a mesh (`lift`)."""
from __future__ import annotations

from dataclasses import dataclass

from ..errors import OptionError
from .capture import PlausibilityOptions
from .fields import Options, option
from .values import integer, path, shown

MESH_UNITS = ("mm", "cm", "dm", "m", "in", "ft")


def real(value, flag):
    """A number as the command line has always taken it (``type=float``): the computation that
    uses it checks its range, with the message `usdface` has always printed."""
    if isinstance(value, bool):
        raise OptionError(f"{flag} {shown(value)}: expected a number")
    try:
        return float(value)
    except (TypeError, ValueError):
        raise OptionError(f"{flag} {shown(value)}: expected a number") from None


def radius_range(value, flag):
    """--radius R1 R2: the dot radius range, checked by the tracker's own rule
    (:func:`usdface.tracking.detect.check_radius_range`, 1 <= R1 <= R2)."""
    from ..tracking.detect import check_radius_range

    return check_radius_range(value)


@dataclass(frozen=True)
class TrackOptions(Options):
    """Tracking coloured dots in a video (`track`, seed 002)."""

    seeds: str | None = option(None, flag="--seeds", coerce=path, metavar="SEEDS.json", group="video capture",
                               help='seed points on the first frame: {"Chin": [x, y], ...} (pixels; integer = pixel '
                                    'centre, y down)')
    auto: int | None = option(None, flag="--auto", coerce=integer, type=int, metavar="N",
                              group="video capture", help="find N dots automatically on the first frame")
    layout: str | None = option(None, flag="--layout", coerce=path, metavar="L.json", group="video capture",
                                help="marker layout to name --auto dots (front view)")
    mesh: str | None = option(None, flag="--mesh", coerce=path, metavar="M", group="video capture",
                              help="mesh for the layout's vertex entries")
    radius: tuple = option((3.0, 10.0), flag="--radius", coerce=radius_range, type=float, nargs=2,
                           metavar=("R1", "R2"), group="video capture", help="dot radius range in pixels")
    rate: float | None = option(None, flag="--rate", coerce=real, type=float, metavar="HZ",
                                group="video capture", help="frames per second (default: the container's)")
    threshold: float = option(4.0, flag="--threshold", coerce=real, type=float, group="video capture",
                              help="Mahalanobis distance threshold")
    min_std: float = option(8.0, flag="--min-std", coerce=real, type=float, metavar="LEVELS",
                            group="video capture",
                            help="colour covariance floor in 8-bit levels (regularises degenerate models)")
    gate: float | None = option(None, flag="--gate", coerce=real, type=float, metavar="PX",
                                group="video capture", help="association gate (default: half the smallest spacing)")
    preview_frame: int | None = option(None, flag="--preview-frame", coerce=integer, type=int, metavar="F",
                                       group="video capture", help="frame for --preview (default: the middle)")


@dataclass(frozen=True)
class LiftOptions(PlausibilityOptions):
    """Lifting 2D image tracks to a 3D capture on a mesh (`lift`)."""

    binding: str | None = option(None, flag="--binding", coerce=path, group="binding",
                                 help="binding layer giving the markers' bound points")
    layout: str | None = option(None, flag="--layout", coerce=path, group="binding",
                                help="marker layout JSON (usdface-layout/1) on the mesh")
    mesh_units: str | None = option(None, flag="--mesh-units", choices=MESH_UNITS, group="mesh",
                                    help="units of a mesh file that does not say (OBJ: default cm)")
    depth: str = option("zero", flag="--depth", choices=("zero", "tangent"), group="video capture",
                        help="depth change: none (default), or slide on the tangent plane at the bound point")
    neutral: int | None = option(None, flag="--neutral", coerce=integer, type=int, metavar="FRAME",
                                 group="video capture", help="neutral frame index (default: the tracks')")
    rate: float | None = option(None, flag="--rate", coerce=real, type=float, metavar="HZ",
                                group="video capture", help="track rate when a CSV does not declare it")
