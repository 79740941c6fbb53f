"""`usdface batch MANIFEST`: many shots in parallel with dask.distributed, resumable, with a
content-addressed cache (:mod:`usdface.cache`).

- :mod:`.manifest` reads and checks a TOML manifest (every problem before any work);
- :mod:`.runner` runs the shots serially or on Dask, skips current ones (``--resume``) and writes
  the batch summary; :mod:`.shot` runs one shot (`run`, then the batch steps it lists, through the
  registry) as a worker does; :mod:`.dask_run` hands the shots out and collects them, again after a
  worker stopped them or the scheduler came back; :mod:`.cluster` connects to Dask and stops a
  batch without leaving partial work (Ctrl-C, SIGTERM, SIGHUP);
- :mod:`.report` writes the batch's HTML report, after the shots or from a finished batch's
  summary (``--report-only``).

>>> from usdface import api
>>> api.batch("shots.toml", {"workers": 2, "resume": True})        # doctest: +SKIP
"""
from __future__ import annotations

from pathlib import Path

from ...options import BatchOptions
from ...registry import Result

__all__ = ["batch"]


def batch(manifest, *, options: BatchOptions, summary=None, report=None) -> Result:
    """Load and check the manifest (every missing file at once, before any work), run its shots.

    ``summary``: the batch summary to write (default: the manifest's, else
    usdface-batch-summary.json); ``report``: also write the HTML batch report to this file, or
    beside the batch summary (``.html``) when ``True``. The Result's ``exit_code`` is 1 if any
    shot failed; its ``text`` is the shot table.

    With ``options.report_only``, no shot runs: the report is rebuilt from the summary of the
    finished batch (``summary``, default the manifest's) by :func:`.report.report_only`.
    """
    from .manifest import check_batch_outputs, load_manifest
    from .report import report_only, write_batch_report
    from .runner import run_batch

    if options.report_only:  # the report of the finished batch, from its summary: no shot runs
        return report_only(manifest, summary, report, out_root=options.out_root)
    m = load_manifest(manifest, out_root=options.out_root)
    summary_file = summary or m.summary
    report_file = None if report in (None, False) else Path(summary_file).with_suffix(".html") if report is True \
        else report
    # --summary and --report never replace the manifest or what a shot reads (before any work)
    check_batch_outputs(m.path, m.shots, {"--summary": summary, "--report": report_file})
    if report not in (None, False, True):
        from ..report import check_report_output

        check_report_output(report)  # an unwritable report fails before the shots run
    result = run_batch(m, options, summary_path=summary)
    files = {"summary": result["summaryFile"]}
    if report not in (None, False):
        rep = write_batch_report(result, None if report is True else report)
        result["report"] = rep.files["output"]
        files["report"] = rep.files["output"]
        result["_text"] = list(result.get("_text", [])) + rep.text
    return Result.from_summary(result, files=files)
