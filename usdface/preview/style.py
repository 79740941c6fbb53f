"""What :func:`~usdface.preview.render_mesh` is told: how the picture looks (:class:`RenderStyle`),
what colours the surface (:class:`RegionColors`, :class:`ScalarColors`, :class:`VertexColors`) and
which points it marks (:class:`PointSet`). Frozen: one style serves every frame of a movie.

Colours given here are RGB 0..255, as people write them.
"""
from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from ..errors import OptionError
from ._common import _rgb

__all__ = ["SHADINGS", "PointSet", "RegionColors", "RenderStyle", "ScalarColors", "VertexColors", "MARKER_COLOR",
           "EXTRA_COLOR"]

#: shading modes of :func:`~usdface.preview.render_mesh`
SHADINGS = ("smooth", "flat", "unlit")
#: default colours (RGB) of the markers (dots) and of the second point set (diamonds)
MARKER_COLOR = (255, 200, 40)
EXTRA_COLOR = (40, 230, 255)


@dataclass(frozen=True)
class RenderStyle:
    """How a picture looks, whatever it shows.

    Attributes
    ----------
    view : str or float
        The camera fitted when none is given: a view name (``front``, ``three-quarter``,
        ``side``...) or a yaw in degrees.
    size : (int, int)
        Width and height in pixels of the fitted camera (a given camera's size wins).
    projection : str
        ``orthographic`` or ``perspective``.
    pitch : float
        Degrees, positive from above.
    shading : str
        ``"smooth"`` (Lambert per pixel with interpolated vertex normals), ``"flat"`` (one normal
        per triangle) or ``"unlit"`` (the vertex colours exactly, e.g. to read a scalar map).
    background : (r, g, b), optional
        Solid background; default a dark vertical gradient.
    supersample : int
        Render at this multiple of the size and average down (anti-aliasing), 1..8; 1 = off.
    legend : bool
        Draw the region and marker legends and the colour bar.
    wire_color, wire_alpha :
        Wireframe colour (r, g, b) and opacity.
    occlusion_tolerance : float, optional
        World units a marker may lie behind the surface and still count as visible; default 1%
        of the mesh's bounding-box diagonal.
    marker_radius : float, optional
        Dot radius in pixels; default scales with the image (4 px at 512, at least 3.5) and
        shrinks to 0.35 of the median spacing of the points on screen (at least 1.5 px), so
        glyphs never swamp a small picture.
    links : bool
        Draw a thin line from each marker to the extra point of the same index (needs as many of
        both).
    """

    view: str | float = "front"
    size: tuple = (512, 512)
    projection: str = "orthographic"
    pitch: float = 0.0
    shading: str = "smooth"
    background: tuple | None = None
    supersample: int = 2
    legend: bool = True
    wire_color: tuple = (18, 18, 22)
    wire_alpha: float = 0.5
    occlusion_tolerance: float | None = None
    marker_radius: float | None = None
    links: bool = False

    def __post_init__(self):
        if self.shading not in SHADINGS:
            raise OptionError(f"preview: shading must be one of {', '.join(SHADINGS)}; got {self.shading!r}")
        ss = int(self.supersample)
        if ss < 1 or ss > 8:
            raise OptionError(f"preview: supersample must be 1..8; got {self.supersample}")
        object.__setattr__(self, "supersample", ss)
        object.__setattr__(self, "wire_color", _rgb(self.wire_color, "wire_color"))


@dataclass(frozen=True)
class RegionColors:
    """Regions painted in their fixed palette colours (mouth red-ish, eyes blue-ish, outer border
    grey, others distinct; :func:`usdface.preview.colormap.region_palette`), with a legend.

    ``regions``: a dict ``{name: vertex indices or Region}`` or a list of
    :class:`usdface.mesh.Region`; later regions paint over earlier ones, other vertices are clay.
    Loop regions (outer border, mouth, eyes: one vertex wide) also tint a band of vertices around
    them so they show at any size. ``palette``: ``{name: (r, g, b)}`` overrides.
    """

    regions: object
    palette: Mapping | None = None


@dataclass(frozen=True)
class ScalarColors:
    """A value per vertex shown through a colour map, with a colour bar.

    ``values``: (N,) (NaN shows grey; (F, N) for a sequence of frames); ``range``: the values at
    the ends of the map (default: min/max; symmetric for ``coolwarm``); ``label``: the colour
    bar's title (quantity and unit, e.g. ``"displacement (cm)"``); ``colormap``: ``viridis``,
    ``magma`` or ``coolwarm`` (diverging).
    """

    values: np.ndarray
    range: tuple | None = None
    label: str = ""
    colormap: str = "viridis"


@dataclass(frozen=True)
class VertexColors:
    """RGB per vertex (N, 3): floats in [0, 1] or uint8."""

    rgb: np.ndarray


@dataclass(frozen=True)
class PointSet:
    """Points drawn over the surface: filled when visible, hollow and dimmer when the surface
    hides them; NaN rows (gaps) are skipped.

    ``points``: (M, 3) (or (F, M, 3) for a sequence of frames); ``labels``: M names placed so
    that none overlaps another, a glyph or a legend; ``color``: (r, g, b), default
    :data:`MARKER_COLOR` for markers and :data:`EXTRA_COLOR` for the second set; ``name``: its
    legend text (default ``"markers"`` / ``"points"``).
    """

    points: np.ndarray
    labels: tuple | list | None = None
    color: tuple | None = None
    name: str | None = None

    @classmethod
    def of(cls, value) -> "PointSet | None":
        """``value`` as a PointSet: None, a PointSet, or bare points."""
        if value is None or isinstance(value, PointSet):
            return value
        return cls(points=value)
