"""Seed points of a video's dots on its first frame: ``{"Name": [x, y], ...}`` (pixels, OpenCV
convention: integer = pixel centre, y down), as JSON."""
from __future__ import annotations

from pathlib import Path

from ..errors import InputError
from ..inputfiles import read_json

__all__ = ["read_seeds"]


def read_seeds(path, *, option: str = "--seeds") -> dict:
    """Read seed points ``{"Name": [x, y]}`` (or ``{"Name": {"image": [x, y]}}``, or either under
    a ``"markers"`` key) from JSON; ``option`` names the file in messages. The points are checked
    against the frame later (:func:`usdface.tracking.detect.check_seeds`)."""
    p = Path(path)
    data = read_json(p, label=f"{option} {p}")  # a regular file, bounded size and nesting, UTF-8
    if isinstance(data, dict) and "markers" in data and isinstance(data["markers"], dict):
        data = data["markers"]
    if not isinstance(data, dict):
        raise InputError(f"{option} {p}: expected a JSON object {{\"MarkerName\": [x, y], ...}}")
    out = {}
    for k, v in data.items():
        if isinstance(v, dict):
            v = v.get("image", v.get("xy"))
        out[str(k)] = v
    return out
