"""Options of the skeletal deliverable (`skel`, `run --output-kind skel`)."""
from __future__ import annotations

import logging
from dataclasses import dataclass, field, fields
from typing import Any

from ..errors import OptionError
from ..skel.modes import (DEFAULT_FIT_METHOD, DEFAULT_MAX_INFLUENCES, DEFAULT_SHAPES, DEFAULT_SKIN_FIT,
                          DEFAULT_SKIN_WEIGHTS, FIT_METHODS, MAX_SHAPES, NEGATIVE_WEIGHTS_ALIAS, SKIN_FITS,
                          SKIN_WEIGHTS)
from .fields import Options, option
from .transfer import TransferOptions
from .values import boolean, number, shown

log = logging.getLogger("usdface")


def max_influences_value(value, flag):
    if value == "all":
        return "all"
    n = number(value, flag, kind=int, what="an integer >= 1 or 'all'")
    if n < 1:
        raise OptionError(f"{flag} {shown(value)}: expected an integer >= 1 (joints per vertex) or 'all'")
    return n


def corrective_shapes_value(value, flag):
    n = number(value, flag, kind=int, what=f"0 or a whole number from 2 to {MAX_SHAPES}")
    if not (n == 0 or 2 <= n <= MAX_SHAPES):
        raise OptionError(f"{flag} {n}: expected 0 or a whole number from 2 to {MAX_SHAPES} (one shape alone corrects "
                          "nothing)")
    return n


@dataclass(frozen=True)
class SkelOptions(Options):
    """Skeletal keyframes (`skel`, `run --output-kind skel`)."""

    skin_weights: str = option(DEFAULT_SKIN_WEIGHTS, flag="--skin-weights", choices=SKIN_WEIGHTS, group="skeleton",
                               help="dcc: non-negative weights summing to one, at most --max-influences per vertex, "
                                    "fitted to the transfer, with corrective blend shapes (what Blender, Maya and "
                                    "game engines take as they are); exact: the transfer matrix itself (signed "
                                    "weights, UsdSkel only)")
    max_influences: Any = option(DEFAULT_MAX_INFLUENCES, flag="--max-influences", coerce=max_influences_value,
                                 metavar="K|all", group="skeleton",
                                 help="joints per vertex, root included (game engines often take 4); 'all' keeps "
                                      "every joint")
    skin_fit: str = option(DEFAULT_SKIN_FIT, flag="--skin-fit", choices=SKIN_FITS, group="skeleton",
                           help="dcc: fit the weights on a synthetic range of motion (the character's weights, the "
                                "same for every take) or on this take's marker motion")
    corrective_shapes: int = option(DEFAULT_SHAPES, flag="--corrective-shapes", coerce=corrective_shapes_value,
                                    metavar="S", group="skeleton",
                                    help=f"dcc: time-invariant corrective blend shapes with weights in [0, 1], 0 or "
                                         f"2..{MAX_SHAPES}")
    weight_fit: str = option(DEFAULT_FIT_METHOD, flag="--weight-fit", choices=FIT_METHODS, group="skeleton",
                             help="exact with K < all: refit the kept weights by least squares over the take, or "
                                  "just rescale them to sum to one")

    def skin_parameters(self):
        """The compute parameters (:class:`usdface.skel.fitting.SkinParameters`): K is None for 'all',
        and the exact weights get no corrective shapes."""
        from ..skel.fitting import SkinParameters

        mode = str(self.skin_weights)
        return SkinParameters(mode=mode, max_influences=None if self.max_influences == "all" else self.max_influences,
                              skin_fit=self.skin_fit, corrective_shapes=self.corrective_shapes if mode == "dcc" else 0,
                              weight_fit=self.weight_fit)


class _DefaultSkinWeights(str):
    """The default of `skel --skin-weights` ("dcc"), told apart from a "dcc" the user gave: the
    deprecated --negative-weights decides the mode only when --skin-weights was not given."""


def _skin_weights_field():
    declared = next(f for f in fields(SkelOptions) if f.name == "skin_weights")
    return field(default=_DefaultSkinWeights(DEFAULT_SKIN_WEIGHTS), metadata=declared.metadata)


@dataclass(frozen=True)
class SkelLayerOptions(SkelOptions, TransferOptions):
    """Everything `usdface skel` takes: the transfer it reproduces and the skeleton's options."""

    skin_weights: str = _skin_weights_field()
    negative_weights: str | None = option(None, flag="--negative-weights",
                                          choices=tuple(sorted(NEGATIVE_WEIGHTS_ALIAS)), group="skeleton",
                                          help="deprecated: keep = --skin-weights exact, clamp = --skin-weights dcc")
    verify: bool = option(True, flag="--no-verify", coerce=boolean, group="skeleton",
                          help="skip deforming the written layer with UsdSkel to measure its error")

    def validate(self) -> None:
        """The deprecated ``negative_weights`` becomes the ``skin_weights`` it means ("keep" ->
        "exact", "clamp" -> "dcc"), with a warning; given with a ``skin_weights`` of another meaning,
        it is an error."""
        super().validate()
        alias = self.negative_weights
        if alias is None:
            return
        mapped = NEGATIVE_WEIGHTS_ALIAS[alias]
        if not isinstance(self.skin_weights, _DefaultSkinWeights) and self.skin_weights != mapped:
            raise OptionError(f"--negative-weights {alias} (deprecated; means --skin-weights {mapped}) contradicts "
                              f"--skin-weights {self.skin_weights}: give --skin-weights only")
        log.warning("--negative-weights %s is deprecated: use --skin-weights %s", alias, mapped)
        object.__setattr__(self, "skin_weights", mapped)
        object.__setattr__(self, "negative_weights", None)
