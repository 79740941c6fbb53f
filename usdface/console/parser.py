"""The `usdface` command's parser, made from the registry: one subcommand per processor."""
from __future__ import annotations

import argparse

from .. import __version__
from .arguments import add_common_options, add_inputs_and_outputs, add_options, plain_help

__all__ = ["build_parser"]


def build_parser() -> argparse.ArgumentParser:
    """``usdface`` with a subcommand for every command of the registry (plug-ins' included)."""
    from .. import registry

    parser = argparse.ArgumentParser(
        prog="usdface",
        description="Facial-animation stage processors for OpenUSD: import capture and meshes, bind markers, "
                    "compute distance matrices, transfer marker motion to the face, preview and check layers.")
    parser.add_argument("--version", action="version", version=f"usdface {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)
    nested: dict = {}
    groups = registry.groups()
    for p in registry.commands():
        words = p.path
        if len(words) == 1:
            target = sub
        else:
            if words[0] not in nested:
                g = groups[words[0]]
                gp = sub.add_parser(words[0], help=plain_help(g.summary), description=g.description)
                nested[words[0]] = gp.add_subparsers(dest=f"{words[0]}_command", metavar=g.metavar, required=True)
            target = nested[words[0]]
        leaf = target.add_parser(words[-1], help=plain_help(p.summary), description=p.description)
        add_inputs_and_outputs(leaf, p)
        add_options(leaf, p.options, exclude=p.hidden_options, exclusive=p.exclusive)
        add_common_options(leaf)
        leaf.set_defaults(_processor=p)
    return parser
