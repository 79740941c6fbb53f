"""Options of the skeletal deliverable (`skel`, `run --output-kind skel`)."""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from ..errors import OptionError
from .fields import Options, option
from .transfer import TransferOptions
from .values import boolean, number, shown


def max_influences_value(value, flag):
    if value == "all":
        return "all"
    n = number(value, flag, kind=int, what="an integer >= 1 or 'all'")
    if n < 1:
        raise OptionError(f"{flag} {shown(value)}: expected an integer >= 1 (joints per vertex) or 'all'")
    return n


def corrective_shapes_value(value, flag):
    n = number(value, flag, kind=int, what="0 or a whole number from 2 to 16")
    if not (n == 0 or 2 <= n <= 16):
        raise OptionError(f"{flag} {n}: expected 0 or a whole number from 2 to 16 (one shape alone corrects nothing)")
    return n


@dataclass(frozen=True)
class SkelOptions(Options):
    """Skeletal keyframes (`skel`, `run --output-kind skel`)."""

    skin_weights: str = option("dcc", flag="--skin-weights", choices=("dcc", "exact"), group="skeleton",
                               help="dcc: non-negative weights summing to one, at most --max-influences per vertex, "
                                    "fitted to the transfer, with corrective blend shapes (what Blender, Maya and "
                                    "game engines take as they are); exact: the transfer matrix itself (signed "
                                    "weights, UsdSkel only)")
    max_influences: Any = option(8, flag="--max-influences", coerce=max_influences_value, metavar="K|all",
                                 group="skeleton",
                                 help="joints per vertex, root included (game engines often take 4); 'all' keeps "
                                      "every joint")
    skin_fit: str = option("rom", flag="--skin-fit", choices=("rom", "take"), group="skeleton",
                           help="dcc: fit the weights on a synthetic range of motion (the character's weights, the "
                                "same for every take) or on this take's marker motion")
    corrective_shapes: int = option(16, flag="--corrective-shapes", coerce=corrective_shapes_value, metavar="S",
                                    group="skeleton",
                                    help="dcc: time-invariant corrective blend shapes with weights in [0, 1], 0 or "
                                         "2..16")
    weight_fit: str = option("lsq", flag="--weight-fit", choices=("lsq", "renormalize"), group="skeleton",
                             help="exact with K < all: refit the kept weights by least squares over the take, or "
                                  "just rescale them to sum to one")


@dataclass(frozen=True)
class SkelLayerOptions(SkelOptions, TransferOptions):
    """Everything `usdface skel` takes: the transfer it reproduces and the skeleton's options."""

    negative_weights: str | None = option(None, flag="--negative-weights", choices=("clamp", "keep"),
                                          group="skeleton",
                                          help="deprecated: keep = --skin-weights exact, clamp = --skin-weights dcc")
    verify: bool = option(True, flag="--no-verify", coerce=boolean, group="skeleton",
                          help="skip deforming the written layer with UsdSkel to measure its error")
