"""What the preview and playblast commands offer (``--view``, ``--color``), without numpy: building
the command line reads these."""
from __future__ import annotations

__all__ = ["VIEW_CHOICES", "COLORS"]

#: the views the commands offer (``preview --view``, ``playblast --view``), in help order
VIEW_CHOICES = ("front", "three-quarter", "side", "turntable", "left", "right", "side_right")
#: surface colours the commands offer (``preview --color``, ``playblast --color``)
COLORS = ("regions", "displacement", "error", "hybrid-weight", "none")
