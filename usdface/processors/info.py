"""`usdface info`: what a layer holds."""
from __future__ import annotations

from ..usd.info import describe, format_description


def info(path) -> dict:
    summary = describe(path)
    summary["_text"] = format_description(summary)
    return summary
