"""Capture data and conditioning (stabilisation, gap filling, filtering, resampling...)."""
from ..model.capture import Capture

__all__ = ["Capture"]
