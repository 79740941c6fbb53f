"""Help text generated from the declarations says what the code does (a new user's pass over
``--help``): lists come from the lists the code checks against, negated flags read as sentences."""
from __future__ import annotations

import argparse

from usdface.console import build_parser
from usdface.findings import CHECKS


def _commands(parser: argparse.ArgumentParser) -> dict:
    """{command path: its parser}, sub-commands (``shapes transfer``) included."""
    out = {}
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for name, sub in action.choices.items():
                out[name] = sub
                out.update({f"{name} {k}": v for k, v in _commands(sub).items()})
    return out


def _helps(flag: str) -> dict:
    """{command: the help of its ``flag``} over every command that has it."""
    return {name: next(a.help for a in sub._actions if flag in a.option_strings)
            for name, sub in _commands(build_parser()).items()
            if any(flag in a.option_strings for a in sub._actions)}


def test_allow_help_lists_every_check_it_accepts():
    helps = _helps("--allow")
    assert {"import-capture", "bind", "lift", "run"} <= set(helps)
    for command, text in helps.items():
        listed = text.split("checks: ")[1].split(" (")[0].split(", ")
        assert listed == list(CHECKS), command


def test_negated_flags_read_as_sentences():
    helps = {**_helps("--no-polynomial"), "--no-stabilize": _helps("--no-stabilize")["run"],
             "--no-cache": _helps("--no-cache")["batch"]}
    assert {helps[c] for c in ("run", "skel", "transfer")} == {
        "do not add the polynomial term, not even to the kernels that need it (thin_plate_spline is then refused)"}
    assert helps["--no-stabilize"] == "do not stabilize" and helps["--no-cache"] == "do not cache"


def test_a_default_is_shown_once_and_as_it_is_typed():
    assert _helps("--size")["playblast"] == "movie frame in pixels, even numbers (default: 960x540)"
    for name, sub in _commands(build_parser()).items():
        for action in sub._actions:
            assert (action.help or "").count("(default: ") <= 1, (name, action.option_strings)
