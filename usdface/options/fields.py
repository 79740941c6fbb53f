"""The option field and the behaviour every options class shares.

An option is a field of a frozen dataclass made with :func:`option`: its metadata gives the
command-line flag, the help text, the group it is listed under in ``--help`` and the function that
checks and converts a value (:mod:`usdface.options.values`). The command line builds its
arguments from the fields (:mod:`usdface.console.arguments`), a batch manifest's keys are the field
names, and Python code passes the object; values are checked when the object is made, whatever
their source.
"""
from __future__ import annotations

import difflib
import json
from dataclasses import MISSING, dataclass, field, fields, replace
from pathlib import Path
from typing import Any, Callable, Mapping

from ..errors import OptionError
from .values import choice

__all__ = ["option", "Options", "NoOptions", "option_fields", "flag_of", "defaults_of", "GROUP_ORDER"]


def option(default, *, flag: str, help: str, group: str, coerce: Callable | None = None,
           choices: tuple | None = None, negate=None, negate_help: str | None = None, **cli) -> Any:
    """A dataclass field that is a usdface option (see the module docstring).

    ``flag``: the long command-line flag; ``coerce(value, flag)``: checks and converts a value
    (:mod:`usdface.options.values`; ``choices`` alone makes one); ``negate``: a second flag that
    sets the value to None (``"--no-stabilize"``), or ``(flag, value)`` (``("--no-cache", False)``);
    ``negate_help``: that flag's help where "do not <flag's words>" does not read as a sentence.
    Booleans: a field defaulting to False is set by ``flag``, one defaulting to True is cleared by
    ``--no-<name>`` (give that as ``flag``).

    ``cli``: how argparse reads it: ``metavar``, ``nargs``, ``const`` (the value of a flag given
    without an argument, ``nargs="?"``), ``action`` (``append``, or ``store_true`` for a flag whose
    default is None) and ``type`` (for the options whose values argparse itself has always checked:
    ``--frame 1.5``).
    """
    unknown = set(cli) - {"metavar", "nargs", "const", "action", "type"}
    if unknown:
        raise TypeError(f"option {flag}: unknown argparse setting(s) {', '.join(sorted(unknown))}")
    if coerce is None and choices is not None:
        coerce = choice(*choices)
    negate_flag, negate_const = (negate if isinstance(negate, tuple) else (negate, None))
    return field(default=default, metadata={
        "flag": flag, "help": help, "coerce": coerce, "group": group, "choices": choices,
        "metavar": cli.get("metavar"), "nargs": cli.get("nargs"), "negate": negate_flag, "negate_const": negate_const,
        "negate_help": negate_help,
        "const": cli.get("const"), "action": cli.get("action"), "cli_type": cli.get("type")})


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


def defaults_of(cls) -> dict:
    """{name: default} of an options class."""
    out = {}
    for f in fields(cls):
        out[f.name] = f.default if f.default is not MISSING else f.default_factory()  # type: ignore[misc]
    return out


class Options:
    """Behaviour shared by every options class (a mixin: the classes are frozen dataclasses)."""

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

    @classmethod
    def from_other(cls, other: "Options", *, strict: bool = True):
        """This class's options taken from another options object: the fields both have, the
        others at their defaults (a `run`'s :class:`RunOptions` gives each step its own options).
        An object sharing no field with this class is an OptionError naming both classes, unless
        ``strict`` is false (a studio's deliverable step whose options `run` does not have)."""
        if type(other) is cls:
            return other
        mine = {f.name for f in fields(cls)}
        shared = {f.name: getattr(other, f.name) for f in fields(other) if f.name in mine}
        if strict and not shared and mine:
            raise OptionError(f"options: expected {cls.__name__} (or options sharing its fields); got "
                              f"{type(other).__name__}")
        return cls(**shared)

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
                              + (f"; expected one of {', '.join(sorted(known))}" if known else
                                 "; this command takes no options"))
        return cls(**dict(mapping))


@dataclass(frozen=True)
class NoOptions(Options):
    """The options of a command that has none (`info`, `check`, `plugin-path`)."""
