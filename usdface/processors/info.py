"""`usdface info`: what a layer holds."""
from __future__ import annotations

from ..options import NoOptions
from ..registry import Result
from ..usd.info import describe, format_description


def info(file, *, options: NoOptions) -> Result:
    """Summarise a USD file (a path, layer or stage): prims, schemas, markers, frames, rate, units."""
    summary = describe(file)
    return Result(summary=summary, text=format_description(summary))
