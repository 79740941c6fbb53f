"""Command-line arguments made from a processor's declaration and its options dataclass.

Options left out by the user are absent from the parsed namespace (``argparse.SUPPRESS``), so the
dataclass is the only place defaults live; :func:`options_from_args` turns the namespace back into
the options object, which checks every value.
"""
from __future__ import annotations

import argparse
from dataclasses import fields

from ..options import option_fields

__all__ = ["add_common_options", "add_options", "add_inputs_and_outputs", "options_from_args"]


def add_common_options(p: argparse.ArgumentParser) -> None:
    """--json, -v, -q: every command has them."""
    p.add_argument("--json", action="store_true", help="print a machine-readable JSON summary on stdout")
    p.add_argument("-v", "--verbose", action="count", default=0, help="more log output (-vv for debug)")
    p.add_argument("-q", "--quiet", action="store_true", help="only errors")


def plain_help(text):
    """Declared help is plain text: a '%' in it ("8-15% long") is not an argparse format."""
    return None if text is None else text.replace("%", "%%")


def _default_text(value) -> str:
    if value is None or value is False or value == ():
        return ""
    if isinstance(value, tuple):
        value = " ".join(str(v) for v in value) if all(not isinstance(v, str) for v in value) else ",".join(value)
    return f" (default: {value})"


def _add_field(target, f) -> None:
    """One option field as one argument (two with its ``--no-...`` flag) of ``target``."""
    md = f.metadata
    action = md.get("action")
    if action is None and isinstance(f.default, bool):
        target.add_argument(md["flag"], dest=f.name, action="store_false" if f.default else "store_true",
                            default=argparse.SUPPRESS, help=plain_help(md["help"]))
        return
    if action == "store_true":
        target.add_argument(md["flag"], dest=f.name, action="store_true", default=argparse.SUPPRESS, help=plain_help(md["help"]))
        return
    shown = "" if "(default: " in md["help"] else _default_text(f.default)  # a help may state it as typed
    kwargs = dict(dest=f.name, default=argparse.SUPPRESS, help=plain_help(md["help"] + shown))
    if action is not None:
        kwargs["action"] = action
    for key in ("choices", "metavar", "nargs", "const"):
        if md.get(key) is not None:
            kwargs[key] = md[key]
    if md.get("cli_type") is not None:
        kwargs["type"] = md["cli_type"]
    target.add_argument(md["flag"], **kwargs)
    if md.get("negate"):
        words = md.get("negate_help") or f"do not {md['flag'][2:].replace('-', ' ')}"
        target.add_argument(md["negate"], dest=f.name, action="store_const", const=md.get("negate_const"),
                            default=argparse.SUPPRESS, help=plain_help(words))


def add_options(parser: argparse.ArgumentParser, cls, *, exclude=(), exclusive=()) -> None:
    """Add the options of dataclass ``cls`` to ``parser``, one argument group per option group.

    ``exclude``: option names left out; ``exclusive``: ``((names, required), ...)`` groups of
    options of which at most (exactly, when required) one may be given.
    """
    groups: dict = {}
    together = {}
    for names, required in exclusive:
        group = parser.add_mutually_exclusive_group(required=required)
        together.update({name: group for name in names})
    for f in option_fields(cls):
        if f.name in exclude:
            continue
        if f.name in together:
            _add_field(together[f.name], f)
            continue
        title = f.metadata["group"]
        if title not in groups:
            groups[title] = parser.add_argument_group(title)
        _add_field(groups[title], f)


def add_inputs_and_outputs(parser: argparse.ArgumentParser, processor) -> None:
    """The processor's inputs (positional arguments or flags) and outputs (``-o`` and others)."""
    for i in processor.inputs:
        nargs = "+" if i.kind == "files" else None
        if i.flag is None:
            parser.add_argument(i.argument, help=plain_help(i.help), nargs=nargs)
        else:
            parser.add_argument(i.flag, dest=i.argument, required=i.required, help=plain_help(i.help), metavar=i.metavar,
                                nargs=nargs)
    for o in processor.outputs:
        kwargs = dict(dest=o.argument, required=o.required, help=plain_help(o.help), metavar=o.metavar)
        if o.nargs is not None:
            kwargs.update(nargs=o.nargs, const=o.const)
        parser.add_argument(*o.flags, **kwargs)


def options_from_args(cls, args: argparse.Namespace, **overrides):
    """The ``cls`` options object from parsed arguments (absent arguments take the defaults)."""
    given = {f.name: getattr(args, f.name) for f in fields(cls) if hasattr(args, f.name)}
    given.update(overrides)
    return cls(**given)
