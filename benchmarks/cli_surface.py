"""Print every command's command-line surface as JSON: for each leaf command (``landmarks train``
is one), each argument's flags, dest, choices, effective default, nargs, const, required and kind.

Run against any checkout to compare two versions of usdface (the redesign promises users an
unchanged command line; ``tests/test_cli_surface.py`` compares the current tree with the snapshot
taken from usdface 0.2.0, ``tests/data/cli_surface_0.2.0.json``)::

    PYTHONPATH=OLD_TREE python benchmarks/cli_surface.py > old.json
    PYTHONPATH=NEW_TREE python benchmarks/cli_surface.py > new.json

The effective default is what the command gets when the argument is left out: argparse's default,
or, where the parser leaves the argument out of the namespace (``argparse.SUPPRESS``, as options
generated from the option dataclasses do), the dataclass field's default.
"""
from __future__ import annotations

import argparse
import dataclasses
import json
import sys
from pathlib import Path


#: usdface 0.2.0 had no registry: the options class of the commands whose fields' defaults differ
#: between classes (`stabilize`: None for import-capture, "auto" for run and solve)
_OLD_COMMAND_OPTIONS = {"import-capture": "CaptureOptions", "run": "RunOptions", "solve": "RunOptions"}


def _option_defaults(command: str) -> dict:
    """{dest: default} for ``command``: its options class first, then every options dataclass
    usdface defines (the effective defaults of arguments whose parser default is SUPPRESS)."""
    import usdface.options as options_module

    found = {}
    classes = []
    import usdface

    if (Path(usdface.__file__).parent / "registry").is_dir():  # the registry knows each command's options class
        from usdface.registry import find

        classes.append(find(command).options)
    else:
        if command in _OLD_COMMAND_OPTIONS:
            classes.append(getattr(options_module, _OLD_COMMAND_OPTIONS[command]))
    classes += [getattr(options_module, n) for n in dir(options_module)]
    for cls in classes:
        if isinstance(cls, type) and dataclasses.is_dataclass(cls):
            for f in dataclasses.fields(cls):
                if f.default is not dataclasses.MISSING:
                    found.setdefault(f.name, f.default)
                elif f.default_factory is not dataclasses.MISSING:  # type: ignore[misc]
                    found.setdefault(f.name, f.default_factory())  # type: ignore[misc]
    return found


def _plain(value):
    if isinstance(value, (list, tuple)):
        return [_plain(v) for v in value]
    if isinstance(value, (str, int, float, bool)) or value is None:
        return value
    return repr(value)


def _kind(action: argparse.Action) -> str:
    return type(action).__name__.lstrip("_").replace("Action", "").lower() or "store"


def surface(parser: argparse.ArgumentParser) -> dict:
    """{command: [argument records]} for every leaf command of ``parser``."""
    out = {}

    def walk(p: argparse.ArgumentParser, path: list[str]) -> None:
        subs = [a for a in p._actions if isinstance(a, argparse._SubParsersAction)]
        if subs and path:
            for name, sp in subs[0].choices.items():
                walk(sp, path + [name])
            return
        if subs:
            for name, sp in subs[0].choices.items():
                walk(sp, [name])
            return
        records = []
        defaults = _option_defaults(" ".join(path))
        for a in p._actions:
            if isinstance(a, argparse._HelpAction):
                continue
            default = a.default
            if default is argparse.SUPPRESS:
                default = defaults.get(a.dest, "<none>")
            records.append({"flags": sorted(a.option_strings), "dest": a.dest,
                            "choices": _plain(list(a.choices)) if a.choices is not None else None,
                            "default": _plain(default), "nargs": _plain(a.nargs), "const": _plain(a.const),
                            "required": bool(a.required), "kind": _kind(a)})
        out[" ".join(path)] = sorted(records, key=lambda r: (r["flags"], r["dest"]))

    walk(parser, [])
    return out


def main() -> int:
    import usdface

    # a tree with the console package (0.3) or without it (0.2): decided by the tree's files, since an
    # editable install elsewhere could otherwise supply a module the tree lacks
    if (Path(usdface.__file__).parent / "console").is_dir():
        from usdface.console.parser import build_parser
    else:
        from usdface.cli import build_parser
    json.dump(surface(build_parser()), sys.stdout, indent=1, sort_keys=True)
    print()
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
