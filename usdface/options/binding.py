"""Options of binding markers to the surface (`bind`, and every command that binds)."""
from __future__ import annotations

from dataclasses import dataclass

from .capture import PlausibilityOptions
from .fields import option
from .values import boolean, path


@dataclass(frozen=True)
class BindOptions(PlausibilityOptions):
    """Binding markers to the surface (`bind`, `run`): from a marker layout, or automatically."""

    layout: str | None = option(None, flag="--layout", coerce=path, group="binding",
                                help="marker layout JSON (usdface-layout/1)")
    auto: bool = option(False, flag="--auto", coerce=boolean, group="binding",
                        help="align the neutral marker cloud to the surface")
    retarget: str = option("displacement", flag="--retarget", choices=("displacement", "similarity"),
                           group="binding",
                           help="displacement: capture motion rotated, not scaled (the paper); similarity: also scaled")
