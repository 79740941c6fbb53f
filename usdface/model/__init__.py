"""The data every layer shares: a marker capture (:class:`Capture`), a face mesh with its regions
(:class:`FaceMesh`, :class:`Region`) and markers bound to it (:class:`Binding`). Plain dataclasses
of numpy arrays: the io readers make them, the compute packages transform them, usd/ writes them."""
from .capture import Capture
from .mesh import Binding, FaceMesh, Region
from .timing import FrameRange

__all__ = ["Capture", "FaceMesh", "Region", "Binding", "FrameRange"]
