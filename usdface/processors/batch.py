"""`usdface batch MANIFEST`: many shots in parallel with dask.distributed (see usdface.batch)."""
from __future__ import annotations

import argparse

__all__ = ["batch", "register_cli"]


def batch(manifest, *, workers=None, scheduler=None, resume=False, force=False, cache=None, out_root=None,
          summary=None, quiet=False, report=None) -> dict:
    """Load and check the manifest (every missing file at once, before any work), run its shots.

    ``report``: also write the HTML batch report (:func:`usdface.processors.report.batch_report`)
    to this file, or beside the batch summary (``.html``) when ``True``.
    Returns the batch summary (``_text``: the shot table; ``_exit``: 1 if any shot failed).
    """
    from ..batch.manifest import load_manifest
    from ..batch.runner import run_batch
    from ..errors import OptionError

    if workers is not None and workers < 0:
        raise OptionError(f"--workers {workers}: expected 0 (serial, no Dask) or more")
    if workers is not None and scheduler:
        raise OptionError("--workers sizes the local cluster; with --scheduler the farm's workers run the shots")
    m = load_manifest(manifest, out_root=out_root)
    from pathlib import Path

    from ..batch.manifest import check_batch_outputs

    summary_file = summary or m.summary
    report_file = None if report in (None, False) else Path(summary_file).with_suffix(".html") if report is True \
        else report
    # --summary and --report never replace the manifest or what a shot reads (before any work)
    check_batch_outputs(m.path, m.shots, {"--summary": summary, "--report": report_file})
    if report not in (None, False, True):
        from .report import _check_output

        _check_output(report)  # an unwritable report fails before the shots run
    result = run_batch(m, workers=workers, scheduler=scheduler, resume=resume, force=force, cache=cache,
                       summary_path=summary, quiet=quiet)
    if report not in (None, False):
        from .report import batch_report

        rep = batch_report(result, None if report is True else report)
        result["report"] = rep["output"]
        result["_text"] = list(result.get("_text", [])) + rep["_text"]
    return result


def register_cli(subparsers) -> None:
    from ..cliargs import add_common_options

    p = subparsers.add_parser(
        "batch", help="run a shot manifest (TOML) in parallel with Dask: local cores or a farm",
        description="Run every shot of a TOML manifest (mesh x capture pairs, globs allowed) through the same "
                    "processors as `usdface run`, in parallel with dask.distributed: on an in-process "
                    "LocalCluster by default, or on a running Dask scheduler. Expensive intermediates (imported "
                    "captures, distance matrices) go to a content-addressed cache shared by shots and runs. "
                    "Writes a JSON summary and prints a table; exits 1 if any shot failed.",
        formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("manifest", help="shot manifest (.toml)")
    p.add_argument("--workers", type=int, metavar="N",
                   help="local worker processes (default: the manifest's, else one per core); 0: one shot after "
                        "the other in this process, without Dask")
    p.add_argument("--scheduler", metavar="tcp://HOST:PORT", help="run on this Dask scheduler's workers (a farm)")
    p.add_argument("--resume", action="store_true",
                   help="skip shots whose outputs exist with matching provenance (inputs, options, version)")
    p.add_argument("--force", action="store_true", help="redo every shot, even current ones")
    c = p.add_mutually_exclusive_group()
    c.add_argument("--cache", metavar="DIR", help="cache folder (default: the manifest's, else .usdface-cache)")
    c.add_argument("--no-cache", dest="cache", action="store_const", const=False, help="no cache")
    p.add_argument("--out-root", metavar="DIR",
                   help="resolve relative outputs, cache and summary against DIR instead of the manifest's folder")
    p.add_argument("--summary", metavar="FILE.json",
                   help="batch summary to write (default: the manifest's, else usdface-batch-summary.json)")
    p.add_argument("--report", nargs="?", const=True, metavar="FILE.html",
                   help="also write an HTML report of the batch (table, thumbnails, each shot's plots; needs the "
                        "'media' extra); default: beside the batch summary, .html")
    add_common_options(p)
    p.set_defaults(func=_cmd_batch)


def _cmd_batch(args) -> dict:
    return batch(args.manifest, workers=args.workers, scheduler=args.scheduler, resume=args.resume,
                 force=args.force, cache=args.cache, out_root=args.out_root, summary=args.summary,
                 quiet=args.quiet, report=args.report)
