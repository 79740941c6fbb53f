"""Options of `usdface run` (and a batch shot): every step's options, and the deliverables.

A deliverable is one form of the performance that `run` writes (``--output-kind``): its layer, its
shot stage and the registered processor that writes it. They are declared here, once, as
:data:`DELIVERABLES`; a studio's processor package adds its own (:func:`add_deliverable`, called by
the registry for a processor declared with a deliverable).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from ..errors import OptionError
from ..distance.methods import BACKENDS, default_backend
from .distances import DistanceOptions
from .fields import Options, option
from .skel import SkelOptions
from .solve import SolveOptions
from .transfer import TransferOptions
from .values import boolean, pair, path, positive_float, positive_int, shown


@dataclass(frozen=True)
class Deliverable:
    """One form of the performance `run` delivers.

    ``kind``: the ``--output-kind`` name; ``layer``: the file it writes in OUTDIR (the step's
    ``output``); ``shot``: its shot stage (the first kind's is always ``shot.usda``); ``step``: the
    registered processor that writes it; ``files``: {the step's output name: file} of the other
    files it writes; ``optional_files``: {the step's output name: (run option, file)} written when
    that option of :class:`RunOptions` is true (``livelink`` -> ``curves_livelink.csv``).

    `run` calls the step with the inputs it names among ``mesh``, ``capture``, ``binding``,
    ``analysis`` (the layers `run` wrote) and ``rig`` (the blend-shape rig: the imported mesh with
    ``--shapes``, else the mesh file itself), its options taken from :class:`RunOptions`.
    """

    kind: str
    layer: str
    shot: str
    step: str
    files: dict = field(default_factory=dict)
    optional_files: dict = field(default_factory=dict)

    def all_files(self, options=None) -> tuple:
        """The files the deliverable writes into OUTDIR with ``options`` (its layer first)."""
        extra = [name for output, (flag, name) in self.optional_files.items()
                 if options is not None and getattr(options, flag, False)]
        return (self.layer, *self.files.values(), *extra)


#: the deliverables `run` can write, in the order they are written
DELIVERABLES: dict[str, Deliverable] = {d.kind: d for d in (
    Deliverable("points", "anim.usdc", "shot.usda", step="transfer"),
    Deliverable("skel", "skel.usdc", "shot_skel.usda", step="skel"),
    Deliverable("blendshapes", "blendshapes.usdc", "shot_blendshapes.usda", step="blendshapes",
                files={"csv": "curves.csv"}, optional_files={"livelink": ("livelink", "curves_livelink.csv")}),
)}
#: aliases of --output-kind lists
OUTPUT_ALIASES = {"both": ("points", "skel")}


def output_kinds() -> tuple:
    """The deliverable kinds, in the order they are written."""
    return tuple(DELIVERABLES)


def add_deliverable(deliverable: Deliverable) -> None:
    """Let `run` deliver ``deliverable`` (a studio processor's); its kind must be new."""
    known = DELIVERABLES.get(deliverable.kind)
    if known is not None and known != deliverable:
        raise OptionError(f"deliverable {deliverable.kind!r} is declared twice ({known.step} and {deliverable.step})")
    DELIVERABLES[deliverable.kind] = deliverable


def remove_deliverable(kind: str) -> None:
    """Forget a studio processor's deliverable (its processor was unregistered)."""
    DELIVERABLES.pop(kind, None)


def __getattr__(name: str):
    if name == "OUTPUT_KINDS":  # the kinds as they are now (a processor package may add one)
        return output_kinds()
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def radius_value(value, flag):
    r1, r2 = pair(positive_float, "R1 R2 in pixels")(value, flag)
    if r2 < r1:
        raise OptionError(f"{flag} {r1:g} {r2:g}: expected R1 <= R2 (the smallest and largest dot radius)")
    return (r1, r2)


def auto_value(value, flag):
    """--auto: bind without a layout (True), or for a video find N dots (an integer)."""
    if value is None or value is False:
        return False
    if value is True or value == "":
        return True
    return positive_int(value, flag)


def output_kinds_value(value, flag):
    kinds_known = output_kinds()
    if isinstance(value, str):
        items = [v.strip() for v in value.split(",") if v.strip()]
    elif isinstance(value, (list, tuple)):
        items = [str(v).strip() for v in value]
    else:
        raise OptionError(f"{flag} {shown(value)}: expected a comma list of {', '.join(kinds_known)} (or all, both)")
    kinds = []
    for item in items:
        expanded = kinds_known if item == "all" else OUTPUT_ALIASES.get(item, (item,))
        for k in expanded:
            if k not in kinds_known:
                raise OptionError(f"{flag} {item}: expected a comma list of {', '.join(kinds_known)} "
                                  "(or all = every kind, both = points,skel)")
            kinds.append(k)
    if not kinds:
        raise OptionError(f"{flag}: expected at least one of {', '.join(kinds_known)}")
    return tuple(k for k in kinds_known if k in kinds)


@dataclass(frozen=True)
class VideoOptions(Options):
    """Tracking a video of painted dots inside `run`."""

    seeds: str | None = option(None, flag="--seeds", coerce=path, metavar="SEEDS.json", group="video capture",
                               help="JSON {marker: [x, y]} of every dot on the first frame (pixels)")
    radius: tuple = option((3.0, 10.0), flag="--radius", coerce=radius_value, nargs=2, metavar=("R1", "R2"),
                           group="video capture", help="dot radius range in pixels")


@dataclass(frozen=True)
class RunOptions(SolveOptions, DistanceOptions, TransferOptions, SkelOptions, VideoOptions):
    """Everything `usdface run` (and a batch shot, and :func:`usdface.api.run`) takes besides its
    inputs and output folder. Defaults are the main job's (the capture's, mesh units and
    stabilisation among them, are `solve`'s: :class:`SolveOptions`)."""

    layout: str | None = option(None, flag="--layout", coerce=path, metavar="LAYOUT.json", group="binding",
                                help="marker layout JSON (usdface-layout/1); required for a video capture")
    auto: Any = option(False, flag="--auto", coerce=auto_value, metavar="N", nargs="?", const=True, group="binding",
                       help="bind automatically; for a video capture, --auto N finds N dots on the first frame")
    output_kind: tuple = option(("points",), flag="--output-kind", coerce=output_kinds_value, metavar="KIND[,KIND]",
                                group="deliverables",
                                help="what to deliver, a comma list: points (time-sampled mesh points, anim.usdc), "
                                     "skel (UsdSkel keyframes, skel.usdc), blendshapes (weight curves on a "
                                     "blend-shape rig, blendshapes.usdc + curves.csv; needs --shapes or a USD mesh "
                                     "with blend shapes); 'all' for every kind ('both' = points,skel)")
    livelink: bool = option(False, flag="--livelink", coerce=boolean, group="deliverables",
                            help="blendshapes: also write curves_livelink.csv in the layout of Unreal's Live Link "
                                 "Face app (ARKit names and order)")
    head_motion: bool = option(True, flag="--no-head-motion", coerce=boolean, group="deliverables",
                               help="drop the head motion removed by stabilisation (by default every deliverable "
                                    "carries it as a time-sampled transform on the face's root prim /Face)")
    backend: str | None = option(None, flag="--backend", choices=BACKENDS, group="distances",
                                 help="geodesic back-end: fmm (fast marching: accurate; the default), graph (shortest "
                                      "edge paths, the paper's: 8-15% long; the default with --rbf paper), heat "
                                      "method, exact polyhedral (small meshes)")

    def validate(self) -> None:
        if self.backend is None:  # the RBF mode's: the paper's edge paths for Eqs. 1-5, fast marching otherwise
            object.__setattr__(self, "backend", default_backend(self.rbf))
        super().validate()
        if self.layout is not None and self.auto is True:
            raise OptionError("--layout and --auto: give one of them (a layout places the markers; --auto aligns "
                              "the neutral marker cloud)")
