"""Linear units: names users type, and USD's metersPerUnit."""
from __future__ import annotations

from .errors import OptionError

#: metres per unit for the unit names usdface accepts
METERS_PER_UNIT = {"mm": 0.001, "cm": 0.01, "dm": 0.1, "m": 1.0, "in": 0.0254, "ft": 0.3048}


def meters_per_unit(unit: str, *, option: str = "--units") -> float:
    """Return metres per unit for a unit name such as ``"cm"``."""
    try:
        return METERS_PER_UNIT[unit]
    except KeyError:
        raise OptionError(
            f"{option}: unknown unit {unit!r}; expected one of {', '.join(METERS_PER_UNIT)}"
        ) from None


def unit_name(meters: float) -> str | None:
    """Return the unit name for a metersPerUnit value, or None if it is not a named unit."""
    for name, value in METERS_PER_UNIT.items():
        if abs(value - meters) <= 1e-9 * max(value, 1.0):
            return name
    return None


def scale_between(from_unit: str, to_unit: str) -> float:
    """Factor that converts lengths in ``from_unit`` to ``to_unit``."""
    return meters_per_unit(from_unit) / meters_per_unit(to_unit)
