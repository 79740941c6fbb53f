"""Command-line arguments built from the option dataclasses (:mod:`usdface.options`).

Subcommands add their options with :func:`add_options` and turn the parsed arguments back into the
options object with :func:`options_from_args`. Arguments left out by the user are absent from the
parsed namespace (``argparse.SUPPRESS``), so the dataclass is the only place defaults live.
"""
from __future__ import annotations

import argparse
from dataclasses import fields

from .errors import OptionError
from .options import option_fields


def add_common_options(p: argparse.ArgumentParser) -> None:
    """--json, -v, -q: every subcommand has them."""
    p.add_argument("--json", action="store_true", help="print a machine-readable JSON summary on stdout")
    p.add_argument("-v", "--verbose", action="count", default=0, help="more log output (-vv for debug)")
    p.add_argument("-q", "--quiet", action="store_true", help="only errors")


def _default_text(value) -> str:
    if value is None or value is False:
        return ""
    if isinstance(value, tuple):
        value = " ".join(str(v) for v in value) if all(not isinstance(v, str) for v in value) else ",".join(value)
    return f" (default: {value})"


def add_options(parser: argparse.ArgumentParser, cls, *, only=None, exclude=(), groups: dict | None = None) -> dict:
    """Add the options of dataclass ``cls`` to ``parser``, one argument group per option group.

    ``only`` / ``exclude``: option names to keep / leave out. ``groups``: argument groups already
    made ({title: group}), shared between calls. Returns the groups.
    """
    groups = {} if groups is None else groups
    for f in option_fields(cls):
        if (only is not None and f.name not in only) or f.name in exclude:
            continue
        md = f.metadata
        title = md["group"]
        if title not in groups:
            groups[title] = parser.add_argument_group(title)
        g = groups[title]
        if isinstance(f.default, bool):
            g.add_argument(md["flag"], dest=f.name, action="store_false" if f.default else "store_true",
                           default=argparse.SUPPRESS, help=md["help"])
            continue
        kwargs = dict(dest=f.name, default=argparse.SUPPRESS, help=md["help"] + _default_text(f.default))
        for key in ("choices", "metavar", "nargs", "const"):
            if md[key] is not None:
                kwargs[key] = md[key]
        g.add_argument(md["flag"], **kwargs)
        if md["negate"]:
            g.add_argument(md["negate"], dest=f.name, action="store_const", const=None, default=argparse.SUPPRESS,
                           help=f"do not {md['flag'][2:].replace('-', ' ')}")
    return groups


def options_from_args(cls, args: argparse.Namespace, **overrides):
    """The ``cls`` options object from parsed arguments (absent arguments take the defaults)."""
    given = {f.name: getattr(args, f.name) for f in fields(cls) if hasattr(args, f.name)}
    given.update(overrides)
    return cls(**given)


def type_checked(coerce, flag: str):
    """An argparse ``type=`` from an option coercion function (bad values: argparse's usage error)."""
    def convert(value):
        try:
            return coerce(value, flag)
        except OptionError as exc:
            raise argparse.ArgumentTypeError(str(exc).split(": ", 1)[-1]) from None
    return convert


def positive_int(value):
    """argparse type: a whole number > 0."""
    from .options import _positive_int

    return type_checked(_positive_int, "")(value)


def positive_float(value):
    """argparse type: a number > 0."""
    from .options import _positive_float

    return type_checked(_positive_float, "")(value)
