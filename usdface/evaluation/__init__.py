"""Evaluation of usdface's transfer against ground truth (pure numpy, no pxr).

- :mod:`usdface.evaluation.quality`: transfer ground-truth expression shapes through their marker
  displacements with each distance method / RBF mode / pinned-border variant and measure the
  vertex errors per face region; the paper's claim (Euclidean artifacts around the mouth and eyes)
  made measurable. Its parts: :mod:`~usdface.evaluation.configs` (what a row transfers with),
  :mod:`~usdface.evaluation.regions` (error regions, pinned vertices), :mod:`~usdface.evaluation.setup`
  (distances and fitted transfers), :mod:`~usdface.evaluation.results` (errors, the report) and
  :mod:`~usdface.evaluation.tables` (summaries, markdown), :mod:`~usdface.evaluation.metrics` (issue
  19's mesh error and jaw-drop mouth error, hold-out splits).
"""
from __future__ import annotations

from .metrics import HeldOutSplit, jaw_drop_mouth_error, mesh_error, read_split
from .quality import (
    AUTHORS_WIDTH_CM,
    MIN_SHAPE_DISPLACEMENT_CM,
    REGION_NAMES,
    REGION_RADIUS_CM,
    ConfigResult,
    EvaluationRegions,
    QualityReport,
    TransferSetup,
    TransferConfig,
    claim_numbers,
    default_configs,
    evaluate,
    evaluation_regions,
    format_report,
    marker_displacements,
    parse_configs,
    select_shapes,
    shape_errors,
    report_summary,
    summary_rows,
)

__all__ = [
    "AUTHORS_WIDTH_CM",
    "MIN_SHAPE_DISPLACEMENT_CM",
    "REGION_NAMES",
    "REGION_RADIUS_CM",
    "ConfigResult",
    "HeldOutSplit",
    "EvaluationRegions",
    "QualityReport",
    "TransferSetup",
    "TransferConfig",
    "claim_numbers",
    "default_configs",
    "evaluate",
    "evaluation_regions",
    "format_report",
    "jaw_drop_mouth_error",
    "mesh_error",
    "marker_displacements",
    "parse_configs",
    "read_split",
    "select_shapes",
    "shape_errors",
    "report_summary",
    "summary_rows",
]
