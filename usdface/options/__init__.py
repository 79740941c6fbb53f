"""Options, named once: the frozen dataclasses shared by the command line, batch manifests and the
Python API.

Every option is one field of one of these dataclasses; the field's metadata gives its command-line
flag, its help text and the function that checks and converts a value
(:mod:`usdface.options.fields`), so the three ways of giving an option mean the same thing:

- the command line builds each command's arguments from its options class (the registry names it:
  :mod:`usdface.registry`): ``--pin-border`` is the field ``pin_border``;
- a batch manifest's keys are the field names (``pin_border = "all"``);
- Python code passes the object: ``RunOptions(method="euclidean", trim=(0, 300))``.

Values are checked and converted when the object is made, whatever their source: a bad value
raises :class:`~usdface.errors.OptionError` naming the command-line flag
(``--max-influences 0: expected an integer >= 1``), which a manifest reports with its line.

Each command has one options class (:class:`CaptureOptions` for `import-capture`,
:class:`RunOptions` for `run`, ...); groups shared by several commands are classes too, and a
command's class combines them. ``RunOptions(...).group(TransferOptions)`` takes one group out of a
combined object; ``TransferOptions.from_other(run_options)`` takes the fields two classes share.
"""
from .acquisition import (DetectOptions, LandmarksTrainOptions, RegisterOptions, ShapesTransferOptions,
                          StereoOptions)
from .batch import BatchOptions
from .binding import BindOptions
from .capture import UNITS, CaptureOptions, ImportMeshOptions, PlausibilityOptions
from .distances import DistanceOptions
from .evaluation import EvaluateOptions
from .fields import GROUP_ORDER, NoOptions, Options, defaults_of, flag_of, option, option_fields
from .media import COLORS, VIEWS, X264_PRESETS, PlayblastOptions, PreviewOptions, ReportOptions
from .run import (DELIVERABLES, OUTPUT_ALIASES, Deliverable, RunOptions, VideoOptions, add_deliverable, output_kinds,
                  remove_deliverable)
from .skel import SkelLayerOptions, SkelOptions
from .solve import BlendshapeOptions, SolveOptions
from .tissue import FitMusclesOptions, MusclesOptions, SimulateOptions
from .transfer import TransferOptions
from .video import LiftOptions, TrackOptions

#: kept for code written against usdface 0.2 (``from usdface.options import _Options``)
_Options = Options

__all__ = [
    "Options", "NoOptions", "PlausibilityOptions", "CaptureOptions", "ImportMeshOptions", "BindOptions",
    "DistanceOptions", "TransferOptions", "SkelOptions", "VideoOptions", "SolveOptions", "RunOptions",
    "PlayblastOptions", "PreviewOptions", "ReportOptions", "SkelLayerOptions", "BlendshapeOptions", "TrackOptions",
    "LiftOptions", "StereoOptions", "DetectOptions", "LandmarksTrainOptions", "RegisterOptions",
    "ShapesTransferOptions", "EvaluateOptions", "MusclesOptions", "SimulateOptions", "FitMusclesOptions",
    "BatchOptions", "Deliverable", "DELIVERABLES", "OUTPUT_KINDS", "OUTPUT_ALIASES",
    "add_deliverable", "remove_deliverable", "output_kinds", "option", "option_fields", "flag_of", "defaults_of", "GROUP_ORDER", "UNITS",
    "VIEWS", "COLORS", "X264_PRESETS",
]


def __getattr__(name: str):
    if name == "OUTPUT_KINDS":  # the deliverable kinds as they are now (a processor package may add one)
        return output_kinds()
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
