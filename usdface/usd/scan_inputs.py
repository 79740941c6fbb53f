"""What `register` reads from a scan layer besides its mesh: the camera a `stereo` scan records."""
from __future__ import annotations

import json

from .layers import get_provenance, open_stage

__all__ = ["scan_camera"]


def scan_camera(scan) -> dict | None:
    """The ``scanCamera`` a ``stereo`` scan layer records in its provenance
    (:func:`usdface.scan.calibration.scan_camera_dict`), or None for other meshes. ``scan``: a
    path, or an in-memory ``Sdf.Layer`` / ``Usd.Stage``."""
    prov = get_provenance(open_stage(scan, what="scan"))
    raw = prov.get("scanCamera")
    return json.loads(raw) if raw else None
