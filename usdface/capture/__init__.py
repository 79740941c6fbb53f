"""Capture data and conditioning (stabilisation, gap filling, filtering, resampling...)."""
from .model import Capture

__all__ = ["Capture"]
