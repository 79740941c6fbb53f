"""The registry: every processor declared once (:class:`Processor`), usdface's own and those of
installed packages.

usdface's processors are declared in :mod:`usdface.registry.catalog`. A package adds its own
through the entry-point group ``usdface.processors`` (as OpenTimelineIO adapters do): each entry
point names a :class:`Processor`, a list of them, or a function returning either::

    # a studio package's pyproject.toml
    [project.entry-points."usdface.processors"]
    export-fbx = "studio_face.usdface_plugin:EXPORT_FBX"

and the processor appears in the `usdface` command, in :mod:`usdface.api` and among the steps a
batch manifest may list. Code may also :func:`register` one at run time.

Pipelines (`run`, `solve`, `report`, `batch`) call processors through :func:`call`, never directly.
"""
from __future__ import annotations

import logging
import time
from contextlib import contextmanager

from ..errors import OptionError, UsdFaceError
from .declarations import CommandGroup, Input, Output, Processor
from .result import Result

__all__ = ["Processor", "Input", "Output", "CommandGroup", "Result", "processors", "commands", "find", "register",
           "unregister", "groups", "batch_steps", "call", "timed_calls", "command_table", "api_table",
           "ENTRY_POINT_GROUP"]

log = logging.getLogger("usdface")

#: the entry-point group other packages declare their processors in
ENTRY_POINT_GROUP = "usdface.processors"

_processors: dict[str, Processor] = {}
_groups: dict[str, CommandGroup] = {}
_loaded = False
_timers: list[dict] = []


def _load() -> None:
    global _loaded
    if _loaded:
        return
    _loaded = True
    from .catalog import GROUPS, PROCESSORS

    for g in GROUPS:
        _groups[g.name] = g
    for p in PROCESSORS:
        _add(p)
    _load_entry_points()


def _load_entry_points() -> None:
    from importlib.metadata import entry_points

    for ep in entry_points(group=ENTRY_POINT_GROUP):
        try:
            found = ep.load()
            if callable(found) and not isinstance(found, Processor):
                found = found()
            for p in (found if isinstance(found, (list, tuple)) else [found]):
                if not isinstance(p, Processor):
                    raise TypeError(f"expected a usdface.registry.Processor, got {type(p).__name__}")
                _add(p, source=f"entry point {ep.name} ({ep.value})")
        except Exception as exc:  # noqa: BLE001 - a broken plug-in must not stop usdface itself
            log.warning("processor plug-in %s (%s) not loaded: %s: %s", ep.name, ep.value, type(exc).__name__, exc)


def _add(p: Processor, *, source: str = "usdface", replace: bool = False) -> None:
    if not replace and p.name in _processors:
        raise UsdFaceError(f"processor {p.name!r} from {source} is declared twice")
    words = p.path
    if len(words) > 2:
        raise UsdFaceError(f"processor {p.name!r} from {source}: a command has at most one sub-command")
    if len(words) == 2 and words[0] not in _groups:
        _groups[words[0]] = CommandGroup(words[0], f"{words[0]} commands", f"{words[0]} commands.")
    if p.deliverable is not None:
        from ..options import add_deliverable

        add_deliverable(p.deliverable)
    _processors[p.name] = p


def register(processor: Processor, *, replace: bool = False) -> Processor:
    """Add ``processor`` in this process (a studio's code, a test); ``replace`` an existing one."""
    _load()
    _add(processor, source="register()", replace=replace)
    return processor


def unregister(name: str) -> None:
    """Remove a processor added with :func:`register`."""
    _load()
    p = _processors.pop(name, None)
    if p is not None and p.deliverable is not None:
        from ..options import remove_deliverable

        remove_deliverable(p.deliverable.kind)


def processors() -> list[Processor]:
    """Every processor, `run`'s internal steps included, in declaration order."""
    _load()
    return list(_processors.values())


def commands() -> list[Processor]:
    """The processors that are commands (and API functions), in declaration order."""
    return [p for p in processors() if p.command]


def groups() -> dict[str, CommandGroup]:
    """{word: CommandGroup} of the commands with sub-commands."""
    _load()
    return dict(_groups)


def find(name: str) -> Processor:
    """The processor named ``name`` (a command, ``"landmarks train"``, or its API name)."""
    _load()
    p = _processors.get(name) or next((q for q in _processors.values() if q.api_name == name), None)
    if p is None:
        raise OptionError(f"no processor named {name!r}; processors: {', '.join(_processors)}")
    return p


def batch_steps() -> tuple:
    """The processors a batch manifest shot may list (`run` always runs)."""
    return tuple(p.name for p in processors() if p.batch_step)


def call(name: str, *inputs, options=None, **outputs) -> Result:
    """Run processor ``name`` with its inputs, options object and outputs: what pipelines do."""
    p = find(name)
    fn = p.load()
    started = time.perf_counter()
    try:
        return fn(*inputs, options=p.options() if options is None else p.options.from_other(options), **outputs)
    finally:
        for timer in _timers:
            timer[name] = round(timer.get(name, 0.0) + time.perf_counter() - started, 3)


@contextmanager
def timed_calls():
    """``{processor: wall seconds}`` of every :func:`call` made inside the block (calls of one
    processor add up); a batch reports each shot's steps with it."""
    timer: dict = {}
    _timers.append(timer)
    try:
        yield timer
    finally:
        _timers.remove(timer)


def command_table() -> str:
    """The README's command table (markdown): every command's synopsis and summary, from the
    declarations; ``tests/test_registry.py`` keeps the README's copy equal to it."""
    def cell(text: str) -> str:
        return text.replace("|", "\\|")

    rows = ["| command | what it does |", "|---|---|"]
    rows += [f"| `{cell(p.synopsis())}` | {cell(p.summary)} |" for p in commands()]
    return "\n".join(rows) + "\n"


def api_table() -> str:
    """The README's table of :mod:`usdface.api` functions (markdown): each command's function, its
    inputs (positional, then keyword-only), its options class and its outputs; kept equal to the
    README's copy by a test."""
    rows = ["| function | inputs | options | outputs |", "|---|---|---|---|"]
    for p in commands():
        ins = [i.name if i.positional else f"{i.name}=" for i in p.inputs]
        outs = [f"{o.name}=" for o in p.outputs] + (["into="] if any(o.kind == "usd" for o in p.outputs) else [])
        rows.append(f"| `{p.api_name}` | {', '.join(f'`{n}`' for n in ins) or '-'} | `{p.options.__name__}` | "
                    f"{', '.join(f'`{n}`' for n in outs) or '-'} |")
    return "\n".join(rows) + "\n"
