"""The record a shot stage carries (the run id, every file's sha256 and provenance id) and the
checks of a shot folder against it: a complete shot, a mixed one, an interrupted commit.

`usdface run` writes the record (:mod:`usdface.pipeline.shot_commit`); `usdface check` and
`batch --resume` read it.
"""
from __future__ import annotations

import json
import os
from pathlib import Path

from ..fileutil import is_temporary_name, path_digest
from .layers import USD_SUFFIXES, layer_provenance, provenance_id

__all__ = ["RUN_FOLDER_PREFIX", "MARKER_NAME", "SUMMARY_NAME", "is_shot_stage", "leftovers", "interrupted_commit",
           "shot_record", "read_shot_record", "verify_shot"]

#: a run's private work folder in OUTDIR starts with this
RUN_FOLDER_PREFIX = ".usdface-run-"
#: the commit's plan, written in the run folder before anything is renamed
MARKER_NAME = "COMMIT.json"
SUMMARY_NAME = "summary.json"


def is_shot_stage(name: str) -> bool:
    """Whether an OUTDIR file name is a shot stage (``shot.usda``, ``shot_<kind>.usda``)."""
    return name.endswith(".usda") and (name == "shot.usda" or name.startswith("shot_"))


def leftovers(folder) -> list[Path]:
    """Run folders and temporary files in ``folder`` (whoever owns them)."""
    folder = Path(folder)
    try:
        entries = list(os.scandir(folder))
    except OSError:
        return []
    found = []
    for e in entries:
        if e.name.startswith(RUN_FOLDER_PREFIX) and e.is_dir(follow_symlinks=False):
            found.append(Path(e.path))
        elif is_temporary_name(e.name) and e.is_file(follow_symlinks=False):
            found.append(Path(e.path))
    return sorted(found)


def interrupted_commit(folder) -> dict | None:
    """The plan of an interrupted commit in ``folder`` (a run folder holding COMMIT.json), with the
    files it has not yet put in place under ``"pending"``; None when there is none."""
    for path in leftovers(folder):
        marker = path / MARKER_NAME
        if path.is_dir() and marker.exists():
            try:
                plan = json.loads(marker.read_text())
            except (OSError, ValueError):
                continue
            plan["folder"] = path.name
            plan["pending"] = [f for f in plan.get("files", []) if (path / f).exists()]
            return plan
    return None


def shot_record(folder, files, run: str) -> dict:
    """What a shot stage lists: the run id and, per file, sha256 and provenance id (USD layers) or
    nothing (summary.json and shot stages are named; their run id is checked)."""
    folder = Path(folder)
    entries = {}
    for name in files:
        if is_shot_stage(name) or name == SUMMARY_NAME:
            entries[name] = {}
            continue
        path = folder / name
        entry = {"sha256": path_digest(path)}
        if path.suffix.lower() in USD_SUFFIXES:
            entry["id"] = provenance_id(layer_provenance(path))
        entries[name] = entry
    return {"runId": run, "files": entries}


def read_shot_record(path) -> dict | None:
    """The record of a shot stage (None: not a shot written by this usdface, or unreadable)."""
    prov = layer_provenance(path)
    if not prov or "shot" not in prov:
        return None
    try:
        return json.loads(prov["shot"])
    except (TypeError, ValueError):
        return None


def verify_shot(stage_path) -> list[str]:
    """Problems of a committed shot: files missing, or not the ones the shot was committed with.

    [] for a complete shot (or a shot stage without a record: written before records existed).
    """
    stage_path = Path(stage_path)
    record = read_shot_record(stage_path)
    if record is None:
        return []
    folder = stage_path.parent
    run = record.get("runId")
    problems = []
    for name, entry in sorted(record.get("files", {}).items()):
        path = folder / name
        if name == stage_path.name:
            continue
        if not path.exists():
            problems.append(f"{name} is missing")
            continue
        if "sha256" in entry:
            if path_digest(path) != entry["sha256"]:
                what = "its bytes differ"
                if path.suffix.lower() in USD_SUFFIXES:
                    pid = provenance_id(layer_provenance(path))
                    if pid != entry.get("id"):
                        what = f"provenance id {pid}, expected {entry.get('id')}"
                problems.append(f"{name} is not the file committed with this shot ({what})")
        elif name == SUMMARY_NAME:
            try:
                other = json.loads(path.read_text()).get("runId")
            except (OSError, ValueError):
                other = "unreadable"
            if other != run:
                problems.append(f"{name} is from run {other}")
        elif is_shot_stage(name):  # committed with this one; a stage with its own record names its run
            other = read_shot_record(path)
            if other is not None and other.get("runId") != run:
                problems.append(f"{name} is from run {other.get('runId')}")
    return problems
