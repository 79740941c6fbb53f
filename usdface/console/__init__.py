"""The ``usdface`` command: parse, call :mod:`usdface.api`, print.

Thin by design: the parser comes from the registry (:mod:`usdface.console.parser`); each
subcommand builds its options object, refuses an output that is one of its inputs, calls the
:mod:`usdface.api` function of the same name and prints the :class:`~usdface.registry.Result`.
Every error reaches the user as one line on stderr (no traceback) and an exit code: 2 bad input or
usage (a UsdFaceError; also argparse's own usage errors), 1 a failure while working (environment
faults included: disk full, read-only folder, permission, out of memory, a USD error, an output
folder locked by another run; a failed `check`; a batch with a failed shot), 130 interrupted by
Ctrl-C (SIGINT), 143 stopped by SIGTERM (how farm schedulers stop jobs), 129 by SIGHUP (a closed
terminal or ssh session), all after removing the partial work. A bug (any other exception) keeps
its traceback, under one line saying it is a bug and asking for a report.
"""
from __future__ import annotations

import argparse
import json
import logging
import os
import signal
import sys
import threading
import warnings

from ..errors import Interrupted, UsdFaceError, stop_signals
from .arguments import options_from_args
from .parser import build_parser

__all__ = ["main", "build_parser", "run_command"]

log = logging.getLogger("usdface")


def _option_labels(parser: argparse.ArgumentParser) -> dict:
    """{dest: how the user wrote it ("-o", "--mesh", "input")} for the chosen subcommand."""
    labels = {}
    todo = [parser]
    while todo:
        p = todo.pop()
        for action in p._actions:
            if isinstance(action, argparse._SubParsersAction):
                todo.extend(action.choices.values())
            elif action.dest not in labels:
                labels[action.dest] = action.option_strings[0] if action.option_strings else action.dest
    return labels


def refuse_outputs_over_inputs(args, processor, parser: argparse.ArgumentParser | None = None) -> None:
    """Every command: refuse (exit 2) when a file it would write is one of the files it reads."""
    from ..fileutil import refuse_overwriting_inputs

    labels = _option_labels(parser) if parser is not None else {}
    output_dests = {o.argument for o in processor.outputs}
    outputs, inputs = {}, {}
    for dest, value in vars(args).items():
        if dest in ("command", "_processor") or dest.endswith("_command"):
            continue
        label = labels.get(dest, dest)
        for v in (value if isinstance(value, list) else [value]):
            if not isinstance(v, (str, os.PathLike)) or not str(v):
                continue
            if dest in output_dests:
                outputs[label] = v
            elif os.path.exists(v):
                inputs.setdefault(label, []).append(os.fspath(v))
    if outputs and inputs:
        from ..usd.layers import composed_files

        for label, paths in list(inputs.items()):
            for p in paths:
                deps = composed_files(p)
                if deps:
                    inputs[f"composed by {label} {p}"] = deps
        refuse_overwriting_inputs(outputs, inputs)


def run_command(processor, args):
    """The command's work: its options object from ``args``, then the API function of the same
    name (looked up when it runs, so a test can replace it) with the inputs and outputs given."""
    from .. import api

    options = options_from_args(processor.options, args)
    inputs = {i.name: getattr(args, i.argument) for i in processor.inputs}
    outputs = {o.name: getattr(args, o.argument) for o in processor.outputs if getattr(args, o.argument) is not None}
    return getattr(api, processor.api_name)(**inputs, options=options, **outputs)


class _terminate_as_interrupt:
    """SIGTERM and SIGHUP raise :class:`~usdface.errors.Interrupted` (like Ctrl-C), so partial work
    is removed; one the process inherited ignored (nohup) stays ignored."""

    #: the stop signal received while the command ran (None: none): a signal landing inside a C
    #: extension's import (numpy's import_array) comes back as that module's ImportError, which
    #: must still read as the interruption it was, not as a bug
    received = None

    def __enter__(self):
        self.previous = {}
        _terminate_as_interrupt.received = None
        if threading.current_thread() is threading.main_thread():
            for s in stop_signals():
                # a signal the command was started with ignored (`nohup usdface ...`: SIGHUP; a
                # background job: SIGINT) stays ignored, as the user asked
                if signal.getsignal(s) is not signal.SIG_IGN:
                    self.previous[s] = signal.signal(s, self._raise)
        return self

    @staticmethod
    def _raise(signum, frame):
        _terminate_as_interrupt.received = signum
        if signum == signal.SIGINT:
            raise KeyboardInterrupt  # Ctrl-C, as Python raises it
        raise Interrupted(signum)

    def __exit__(self, *exc):
        for s, handler in self.previous.items():
            signal.signal(s, handler)
        return False


def _print_result(result, as_json: bool, quiet: bool) -> None:
    if as_json:
        print(json.dumps(result.summary, indent=2, default=str))
        return
    if quiet:
        return
    for line in result.text:
        print(line)


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    level = logging.ERROR if args.quiet else (logging.WARNING, logging.INFO, logging.DEBUG)[min(args.verbose, 2)]
    logging.basicConfig(level=level, format="usdface: %(levelname)s: %(message)s", stream=sys.stderr)
    # a library's or usdface's own warnings.warn reaches the user as one usdface line, not Python's
    # "file:line: Category: text" with its source line
    warnings.showwarning = lambda message, category, *rest, **kw: log.warning("%s", message)
    processor = args._processor
    name = f"usdface {processor.path[0]}"  # as 0.2 named a sub-command's errors (usdface landmarks: error: ...)
    kernels = sys.modules.get("usdface.numba_cache")
    if kernels is not None:  # main called twice in one process (tests, scripts) reports each run's own
        kernels.reset_compile_report()
    code = _run(args, processor, name, parser)
    # the kernels a first run compiled, and how long they took (only where numba was loaded); a
    # failed command keeps its one error line alone
    kernels = sys.modules.get("usdface.numba_cache")
    report = kernels.compile_report() if kernels is not None and code == 0 else None
    if report and not args.quiet:
        print(report, file=sys.stderr, flush=True)
    return code


def _without_command(message: str, processor) -> str:
    """``message`` without a leading command name: a processor's error names its command for Python
    callers ("run: give exactly one of ..."), the command line already did (``usdface run: error:``)."""
    for prefix in (processor.name, processor.path[0]):
        if message.startswith(prefix + ": "):
            return message[len(prefix) + 2:]
    return message


def _run(args, processor, name: str, parser) -> int:
    """The command, its errors as one line and an exit code, its Result printed."""
    try:
        with _terminate_as_interrupt():
            refuse_outputs_over_inputs(args, processor, parser)
            result = run_command(processor, args)
    except UsdFaceError as exc:
        print(f"{name}: error: {_without_command(str(exc), processor)}", file=sys.stderr)
        return exc.exit_code
    except Interrupted as exc:
        print(f"{name}: stopped by {exc}; partial work removed", file=sys.stderr)
        return exc.exit_code
    except KeyboardInterrupt:
        print(f"{name}: interrupted; partial work removed", file=sys.stderr)
        return 130
    except Exception as exc:  # noqa: BLE001 - file system, memory and USD errors: one line, exit 1
        from ..fileutil import describe_exception, is_environment_fault

        stopped_by = _terminate_as_interrupt.received
        if stopped_by is not None:  # the signal, surfacing as another exception (see `received`)
            if stopped_by == signal.SIGINT:
                print(f"{name}: interrupted; partial work removed", file=sys.stderr)
                return 130
            stop = Interrupted(stopped_by)
            print(f"{name}: stopped by {stop}; partial work removed", file=sys.stderr)
            return stop.exit_code
        if not is_environment_fault(exc):
            # a bug: the traceback is what a report needs, under one line saying so
            from .. import __version__

            print(f"{name}: internal error (a bug in usdface {__version__}, not in your input): "
                  f"{type(exc).__name__}: {exc}; please report it with the traceback below and the command line",
                  file=sys.stderr, flush=True)
            raise

        print(f"{name}: error: {describe_exception(exc)}", file=sys.stderr)
        return 1
    try:
        _print_result(result, args.json, args.quiet)
        sys.stdout.flush()
    except BrokenPipeError:
        # the reader stopped reading (`usdface info --json FILE | head -c 10`): end quietly, as the
        # shell's tools do on SIGPIPE (Python would print a traceback when it flushes at exit)
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 141
    except OSError as exc:
        # the output cannot take the result (`> /dev/full`, a full disk, a quota): one line; what is
        # still buffered goes nowhere, so Python's flush at exit cannot print a traceback
        from ..fileutil import os_error_cause

        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        print(f"{name}: error: cannot write the standard output: {os_error_cause(exc)}", file=sys.stderr)
        return 1
    return int(result.exit_code)
