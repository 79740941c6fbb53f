"""Issue 20's attempts (hostile readers and attempts on commands) run against two usdface trees, and
the table comparing them per case of the issue, for benchmarks/fault_attempts.py ``--before``.

An attempt is matched across trees by its description; "handled" is each section's own verdict
(expected exit code and stderr lines, no traceback, inputs unchanged, nothing left behind, the
attempt's own condition).
"""
from __future__ import annotations

import re
import shutil
from pathlib import Path

CASE = re.compile(r"\((\d+|new)\)")


def issue20_rows(code: Path, scratch: Path, sections, only=None) -> list[dict]:
    """Run the given sections ("readers", "commands") against ``code``; print their tables; return the rows."""
    rows = []
    shutil.rmtree(scratch, ignore_errors=True)
    scratch.mkdir(parents=True)
    print(f"\n## usdface from {code}\n")
    if "readers" in sections:
        from hostile_readers import table

        part = table(code, scratch, only)
        print(f"\n{sum(r['ok'] for r in part)}/{len(part)} hostile readers' attempts handled\n")
        rows += [dict(r, section="readers") for r in part]
    if "commands" in sections:
        from hostile_commands import table

        part = table(code, scratch, only)
        print(f"\n{sum(r['ok'] for r in part)}/{len(part)} attempts on commands handled\n")
        rows += [dict(r, section="commands") for r in part]
    return rows


def case_of(klass: str) -> str:
    m = CASE.search(klass)
    return m.group(1) if m else "new"


def print_before_after(before: list[dict], after: list[dict], before_name: str, after_name: str) -> None:
    """Per attempt, then per case of issue 20: handled before and after, with counts."""
    was = {r["what"]: r for r in before}
    print(f"\n## Before ({before_name}) and after ({after_name})\n")
    print("| case | class | attempt | before | after |")
    print("|---|---|---|---|---|")
    for r in after:
        b = was.get(r["what"])
        print(f"| {case_of(r['klass'])} | {r['klass']} | {r['what'].replace('|', '/')} | "
              f"{'-' if b is None else ('handled' if b['ok'] else '**not handled**')} | "
              f"{'handled' if r['ok'] else '**not handled**'} |")
    cases: dict[str, list] = {}
    for r in after:
        cases.setdefault(case_of(r["klass"]), []).append(r)
    order = sorted((k for k in cases if k != "new"), key=int) + (["new"] if "new" in cases else [])
    print("\n| issue 20 case | attempts | handled before | handled after | not handled after |")
    print("|---|---|---|---|---|")
    for k in order:
        rs = cases[k]
        hb = sum(bool(was.get(r["what"], {}).get("ok")) for r in rs)
        ha = sum(bool(r["ok"]) for r in rs)
        rest = "; ".join(r["what"].replace("|", "/") for r in rs if not r["ok"]) or "-"
        label = "new (same classes, not in the issue)" if k == "new" else k
        print(f"| {label} | {len(rs)} | {hb} | {ha} | {rest} |")
    hb = sum(bool(was.get(r["what"], {}).get("ok")) for r in after)
    ha = sum(bool(r["ok"]) for r in after)
    print(f"| **all** | {len(after)} | {hb} | {ha} | |")
