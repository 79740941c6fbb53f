"""Option values: one function per kind of value, ``coerce(value, flag) -> value``.

Every entry point (the command line, a batch manifest, the Python API) hands the raw value to the
option field's coercion function, which checks and converts it or raises
:class:`~usdface.errors.OptionError` naming the command-line flag and what was expected
(``--sigma -1: expected a number > 0``).
"""
from __future__ import annotations

from pathlib import Path
from typing import Callable

from ..errors import OptionError


def shown(v) -> str:
    """A value as the user typed it (command-line strings without quotes)."""
    return v if isinstance(v, str) else repr(v)


def is_blank(v) -> bool:
    return v is None or (isinstance(v, str) and v.strip().lower() in ("", "none"))


def choice(*choices: str) -> Callable:
    def coerce(value, flag):
        if value not in choices:
            raise OptionError(f"{flag} {shown(value)}: expected one of {', '.join(choices)}")
        return value
    return coerce


def optional(coerce: Callable) -> Callable:
    def wrapped(value, flag):
        return None if is_blank(value) else coerce(value, flag)
    return wrapped


def number(value, flag, *, kind=float, what="a number"):
    if isinstance(value, bool):
        raise OptionError(f"{flag} {shown(value)}: expected {what}")
    try:
        x = kind(value)
    except (TypeError, ValueError):
        raise OptionError(f"{flag} {shown(value)}: expected {what}") from None
    if kind is int and isinstance(value, float) and value != x:
        raise OptionError(f"{flag} {shown(value)}: expected {what}")
    if kind is float and not x == x:  # NaN
        raise OptionError(f"{flag} {shown(value)}: expected {what}")
    return x


def positive_float(value, flag):
    x = number(value, flag, what="a number > 0")
    if not x > 0 or x == float("inf"):
        raise OptionError(f"{flag} {shown(value)}: expected a number > 0")
    return x


def nonnegative_float(value, flag):
    x = number(value, flag, what="a number >= 0")
    if not x >= 0 or x == float("inf"):
        raise OptionError(f"{flag} {shown(value)}: expected a number >= 0")
    return x


def unit_interval(value, flag):
    x = number(value, flag, what="a number in [0, 1]")
    if not 0.0 <= x <= 1.0:
        raise OptionError(f"{flag} {shown(value)}: expected a number in [0, 1]")
    return x


def positive_int(value, flag):
    n = number(value, flag, kind=int, what="a whole number > 0")
    if n <= 0:
        raise OptionError(f"{flag} {shown(value)}: expected a whole number > 0")
    return n


def integer(value, flag):
    return number(value, flag, kind=int, what="a whole number")


def boolean(value, flag):
    if isinstance(value, bool):
        return value
    if isinstance(value, str) and value.lower() in ("true", "false", "yes", "no", "1", "0"):
        return value.lower() in ("true", "yes", "1")
    raise OptionError(f"{flag} {shown(value)}: expected true or false")
def pair(kind: Callable, what: str) -> Callable:
    def coerce(value, flag):
        if isinstance(value, str):
            value = value.replace(",", " ").split()
        if not isinstance(value, (list, tuple)) or len(value) != 2:
            raise OptionError(f"{flag} {shown(value)}: expected two values ({what})")
        return tuple(kind(v, flag) for v in value)
    return coerce
def path(value, flag):
    if not isinstance(value, (str, Path)):
        raise OptionError(f"{flag} {shown(value)}: expected a file path")
    return str(value)
