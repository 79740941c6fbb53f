"""What a processor declaration says: its name, summary, inputs, outputs, options class and function.

One :class:`Processor` per command (and per internal step of `run`). Everything a user reaches is
made from these: the `usdface` command's subcommands and arguments (:mod:`usdface.console`), the
functions of :mod:`usdface.api`, the steps a batch manifest may list, `run`'s steps, and the
README's command table.
"""
from __future__ import annotations

import importlib
from dataclasses import dataclass
from typing import Any, Callable

__all__ = ["Input", "Output", "Processor", "CommandGroup"]

#: kinds of input: a USD layer (a path, or in memory an ``Sdf.Layer`` / ``Usd.Stage``), a file, a
#: folder, or several files
INPUT_KINDS = ("usd", "file", "folder", "files")
#: kinds of output: a USD layer (a path, or in memory a layer / a stage's edit target), a file, a folder
OUTPUT_KINDS = ("usd", "file", "folder")


@dataclass(frozen=True)
class Input:
    """One thing a processor reads.

    ``name``: the function's parameter (and the argparse destination, unless ``dest``);
    ``flag``: ``"--mesh"``, or None for a positional argument; ``kind``: one of
    :data:`INPUT_KINDS`; ``default_from``: in the Python API, an optional USD input defaults to
    this other input (``capture`` defaults to the stage holding the mesh: one scene holds both);
    ``positional``: False for an input that chooses another way of working (``solve --apply``),
    which the Python API takes by keyword only.
    """

    name: str
    help: str
    flag: str | None = None
    kind: str = "usd"
    required: bool = True
    default_from: str | None = None
    metavar: str | None = None
    dest: str | None = None
    positional: bool = True

    def __post_init__(self):
        if self.kind not in INPUT_KINDS:
            raise ValueError(f"input {self.name}: kind {self.kind!r} is not one of {', '.join(INPUT_KINDS)}")

    @property
    def argument(self) -> str:
        """The argparse destination."""
        return self.dest or self.name


@dataclass(frozen=True)
class Output:
    """One thing a processor writes.

    ``flags``: ``("-o", "--output")``; ``kind``: one of :data:`OUTPUT_KINDS`; a ``usd`` output
    may be an in-memory layer or stage in the Python API (``into=``). ``nargs``/``const``: a
    flag whose value may be left out (``--corrective`` alone names the file after the output).
    """

    name: str
    help: str
    flags: tuple = ("-o", "--output")
    kind: str = "usd"
    required: bool = True
    metavar: str | None = None
    nargs: str | None = None
    const: Any = None
    dest: str | None = None

    def __post_init__(self):
        if self.kind not in OUTPUT_KINDS:
            raise ValueError(f"output {self.name}: kind {self.kind!r} is not one of {', '.join(OUTPUT_KINDS)}")

    @property
    def argument(self) -> str:
        """The argparse destination."""
        return self.dest or self.name


@dataclass(frozen=True)
class CommandGroup:
    """A command with sub-commands (``usdface landmarks train``): its help and description."""

    name: str
    summary: str
    description: str
    metavar: str = "ACTION"


@dataclass(frozen=True)
class Processor:
    """A processor, declared once.

    Parameters
    ----------
    name : str
        The command (``"import-capture"``; a sub-command is ``"landmarks train"``). Its Python API
        function is :attr:`api_name` (``import_capture``, ``landmarks_train``).
    summary : str
        One line: the command's help in ``usdface --help`` and the README's table.
    description : str
        The paragraph ``usdface NAME --help`` shows.
    function : str or callable
        ``"module:function"``, imported when the processor runs (the command line's start-up
        loads none of them), or the function itself (code registering at run time). It takes the
        inputs (positionally, in order), ``options=`` and the outputs as keywords, and returns a
        :class:`~usdface.registry.Result`.
    options : type
        The options dataclass (:mod:`usdface.options`): every flag the command takes besides its
        inputs and outputs.
    inputs, outputs : tuples of :class:`Input` / :class:`Output`
    exclusive : tuple of (names, required)
        Groups of options of which at most one (exactly one when ``required``) may be given on
        the command line (``bind --layout | --auto``).
    batch_step : bool
        A manifest shot may list it in ``processors``: it runs after `run` on the shot's stage
        (``OUTDIR/shot.usda``, its one input) with its default options, and its exit code counts.
    command : bool
        False for `run`'s internal steps (no subcommand, no API function).
    hidden_options : tuple
        Fields of ``options`` the command line does not offer (set from Python only).
    deliverable : usdface.options.Deliverable, optional
        A studio processor that is a new kind of `run` deliverable declares it here (usdface's own
        are in :data:`usdface.options.DELIVERABLES`).
    """

    name: str
    summary: str
    description: str
    function: Any
    options: type
    inputs: tuple = ()
    outputs: tuple = ()
    exclusive: tuple = ()
    batch_step: bool = False
    command: bool = True
    hidden_options: tuple = ()
    deliverable: Any = None

    @property
    def api_name(self) -> str:
        """The Python API function's name: '-' becomes '_', a sub-command is joined with '_'."""
        return self.name.replace("-", "_").replace(" ", "_")

    @property
    def path(self) -> tuple:
        """The command words (``("landmarks", "train")``)."""
        return tuple(self.name.split(" "))

    def load(self) -> Callable:
        """The processor function."""
        if callable(self.function):
            return self.function
        module, _, attr = self.function.partition(":")
        return getattr(importlib.import_module(module), attr)

    def input(self, name: str) -> Input:
        return next(i for i in self.inputs if i.name == name)

    def output(self, name: str) -> Output:
        return next(o for o in self.outputs if o.name == name)

    def synopsis(self) -> str:
        """``usdface bind --mesh MESH --capture CAPTURE -o OUTPUT [options]``: the README's first column."""
        words = ["usdface", self.name]
        for i in self.inputs:
            meta = i.metavar or i.name.upper()
            word = f"{i.flag} {meta}" if i.flag else meta + (" ..." if i.kind == "files" else "")
            words.append(word if i.required else f"[{word}]")
        for o in self.outputs:
            meta = o.metavar or o.name.upper()
            word = f"{o.flags[0]} {meta}"
            words.append(word if o.required else f"[{word}]")
        return " ".join(words) + " [options]"
