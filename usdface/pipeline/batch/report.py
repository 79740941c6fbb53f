"""A batch's HTML report: written after the shots (``batch --report``) or rebuilt later from the
batch summary alone (``batch --report-only``: no shot is run or checked)."""
from __future__ import annotations

import json
from pathlib import Path

from ...errors import FormatError, InputError
from ...registry import Result

__all__ = ["write_batch_report", "read_batch_summary", "report_only"]


def write_batch_report(summary, output) -> Result:
    """The report pipeline's batch report of ``summary`` (a batch summary dict) into ``output``
    (None: beside the summary file, ``.html``). The one place the batch calls it."""
    from ..report import batch_report

    return batch_report(summary, output)


def read_batch_summary(path) -> dict:
    """A batch summary written by ``usdface batch``, checked: InputError naming the file when it is
    missing, not JSON or not a batch summary."""
    path = Path(path)
    if not path.is_file():
        raise InputError(f"batch summary {path}: no such file (run the batch first; --report-only rebuilds the report "
                         "of a finished batch)")
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except (UnicodeDecodeError, ValueError) as exc:
        raise FormatError(f"batch summary {path}: not JSON ({exc})") from None
    except OSError as exc:
        from ...fileutil import describe_exception

        raise InputError(f"batch summary {path}: cannot be read ({describe_exception(exc)})") from None
    if not isinstance(data, dict) or not isinstance(data.get("shots"), list) or not all(
            isinstance(s, dict) for s in data["shots"]):
        raise FormatError(f"batch summary {path}: not a usdface batch summary (expected a JSON object with a "
                          "\"shots\" list)")
    return data


def report_only(manifest, summary_file, report, *, out_root=None) -> Result:
    """``batch --report-only``: the report of the batch whose summary is ``summary_file`` (default:
    the manifest's), into ``report`` (default, or ``True``: beside the summary, ``.html``).

    The manifest is read for the summary's place (its inputs need not exist any more) and so
    that the report replaces none of its shots' inputs.
    """
    from ...report.output import check_report_output
    from .manifest import check_batch_outputs, load_manifest

    m = load_manifest(manifest, out_root=out_root, check_files=False)
    summary_file = Path(summary_file or m.summary)
    report_file = summary_file.with_suffix(".html") if report in (None, True) else Path(report)
    check_batch_outputs(m.path, m.shots, {"--report": report_file})
    check_report_output(report_file)
    data = read_batch_summary(summary_file)
    rep = write_batch_report(data, report_file)
    result = {"summaryFile": str(summary_file), "report": rep.summary["output"], "shots": rep.summary.get("shots"),
              "sections": rep.summary.get("sections"), "_text": list(rep.text)}
    return Result.from_summary(result, files={"report": rep.summary["output"]})
