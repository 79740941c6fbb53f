"""One panel of a playblast: a shot's face rendered frame after frame with a fixed style and framing.

:class:`ShotPanel` is built once per shot (camera, colours, scalar range, burn-in text) and then
renders any frame from that frame's points; it holds only numpy arrays and plain values, so it can
be handed to worker processes. No USD here: the processor reads the points.
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from ..errors import OptionError
from ..preview import Camera, PointSet, RegionColors, RenderStyle, ScalarColors, fit_camera, render_mesh, view_yaw
from ..preview.burnin import burn_in, placeholder, timecode
from ..preview.colormap import COLORS  # one list of surface colours: preview, playblast, the options

__all__ = ["COLORS", "PanelStyle", "ShotPanel", "framing_sample"]

#: colour modes (as ``usdface preview --color``)


@dataclass(frozen=True)
class PanelStyle:
    """How a panel looks.

    Attributes
    ----------
    color : str
        One of :data:`COLORS`.
    markers, bound, labels : bool
        Draw the capture markers (dots), the bound surface points (diamonds), marker names.
    legend : bool
        Region legend / colour bar.
    burnin : bool
        Shot name, method, frame and timecode at the top.
    supersample : int
        Anti-aliasing factor (1 = off).
    view : str or float
        A view of :data:`usdface.preview.VIEW_CHOICES` or a yaw in degrees.
    projection : str
    turntable_period : float
        Seconds per swing cycle of the ``turntable`` view.
    """

    color: str = "regions"
    markers: bool = False
    bound: bool = False
    labels: bool = False
    legend: bool = True
    burnin: bool = True
    supersample: int = 1
    view: str | float = "front"
    projection: str = "orthographic"
    turntable_period: float = 6.0

    def __post_init__(self):
        if self.color not in COLORS:
            raise OptionError(f"--color {self.color}: expected one of {', '.join(COLORS)}")
        if not 1 <= int(self.supersample) <= 4:
            raise OptionError(f"--supersample {self.supersample}: expected 1..4")
        if not self.turntable_period > 0:
            raise OptionError(f"--turntable-period {self.turntable_period}: expected seconds > 0")
        view_yaw(self.view)  # a bad view fails here


def framing_sample(frames: np.ndarray, *, max_frames: int = 24) -> np.ndarray:
    """The frames to frame the camera on: up to ``max_frames`` of them, evenly spread, plus the
    two that reach farthest from the mean position ((F, N, 3) -> (K, N, 3))."""
    f = np.asarray(frames)
    if f.shape[0] <= max_frames:
        return f
    pick = set(np.linspace(0, f.shape[0] - 1, max_frames - 2).round().astype(int).tolist())
    spread = np.abs(f - f.mean(axis=0, keepdims=True)).max(axis=(1, 2))
    pick.update(np.argsort(spread)[-2:].tolist())
    return f[sorted(pick)]


@dataclass
class ShotPanel:
    """Render one shot's frames into ``size`` panels.

    Parameters
    ----------
    name, method : str
        Burn-in: the shot's name and its transfer method (``hybrid interpolate``...).
    rate : float
        The shot's rate (timecodes, turntable).
    triangles : ndarray (T, 3)
    rest_points : ndarray (N, 3)
    size : (int, int)
    style : PanelStyle
    frame_points : ndarray (K, N, 3)
        Frames to fit the camera on (see :func:`framing_sample`); markers may be included.
    regions : list of Region, optional
    hybrid_weight : ndarray (N,), optional
    marker_names : list of str
    scalar_range : (lo, hi), optional
        Colour range shared by every frame (displacement / error).
    units : str
    """

    name: str
    method: str
    rate: float
    triangles: np.ndarray
    rest_points: np.ndarray
    size: tuple
    style: PanelStyle
    frame_points: np.ndarray
    regions: list = field(default_factory=list)
    hybrid_weight: np.ndarray | None = None
    marker_names: list = field(default_factory=list)
    scalar_range: tuple | None = None
    units: str = "units"
    first_time: int = 0

    def __post_init__(self):
        st = self.style
        if st.color == "hybrid-weight" and self.hybrid_weight is None:
            raise OptionError(f"--color hybrid-weight: shot {self.name} has no primvars:usdface:hybridWeight "
                              "(hybrid distances were not computed)")
        self.size = tuple(int(v) for v in self.size)
        lines = 2 if st.burnin else 0
        colorbar = st.legend and st.color in ("displacement", "error", "hybrid-weight")
        self._fit_kwargs = dict(size=self.size, projection=st.projection, colorbar=colorbar, title_lines=lines)
        self._render_style = RenderStyle(legend=st.legend, supersample=st.supersample)
        sample = np.asarray(self.frame_points, dtype=np.float64).reshape(-1, 3)
        self._sample = sample[np.isfinite(sample).all(axis=1)]
        self._turntable = st.view == "turntable"
        if self._turntable:
            # one scale for the whole swing, so the face does not breathe in and out
            yaws = np.linspace(-1.0, 1.0, 9) * view_yaw("turntable", 0.25)
            self._scale = min(fit_camera(self._sample, view=float(y), **self._fit_kwargs).scale for y in yaws)
            self._camera = None
        else:
            self._camera = fit_camera(self._sample, view=st.view, **self._fit_kwargs)

    # --------------------------------------------------------------------------------------------
    def camera_at(self, time: float) -> Camera:
        """The camera of the frame at ``time`` (fixed, or the turntable's at that moment)."""
        if not self._turntable:
            return self._camera
        phase = (float(time) - self.first_time) / (self.rate * self.style.turntable_period)
        cam = fit_camera(self._sample_small, view=view_yaw("turntable", phase), **self._fit_kwargs)
        return replace(cam, scale=self._scale)

    @property
    def _sample_small(self) -> np.ndarray:
        # the turntable refits every frame: a bounded subset of the framing points is enough
        s = self._sample
        return s if s.shape[0] <= 20000 else s[:: int(np.ceil(s.shape[0] / 20000))]

    def scalars(self, points: np.ndarray, reference: np.ndarray | None = None) -> np.ndarray | None:
        """Per-vertex values of the colour mode at a frame (None for regions / none); ``points``
        head-stabilised (the displacement of the transfer, not of the head)."""
        c = self.style.color
        if c == "displacement":
            return np.linalg.norm(points - self.rest_points, axis=1)
        if c == "error":
            if reference is None:
                raise OptionError("--color error needs --reference SHOT (the points to compare against)")
            return np.linalg.norm(points - reference, axis=1)
        if c == "hybrid-weight":
            return self.hybrid_weight
        return None

    def render(self, time: float, points: np.ndarray, *, markers: np.ndarray | None = None,
               bound: np.ndarray | None = None, reference: np.ndarray | None = None,
               stabilized: np.ndarray | None = None, note: str = "") -> np.ndarray:
        """The panel at ``time`` (BGR uint8, ``size``), with ``note`` added to the burn-in;
        ``stabilized``: the points without head motion, for the colours (default: ``points``)."""
        st = self.style
        c = st.color
        colors = None
        if c == "regions":
            colors = RegionColors(self.regions) if self.regions else None
        elif c in ("displacement", "error", "hybrid-weight"):
            label = {"displacement": f"displacement ({self.units})", "error": f"error ({self.units})",
                     "hybrid-weight": "hybrid weight w"}[c]
            rng = (0.0, 1.0) if c == "hybrid-weight" else self.scalar_range
            colors = ScalarColors(self.scalars(points if stabilized is None else stabilized, reference), range=rng,
                                  label=label)
        shown_markers = None
        if st.markers and markers is not None:
            shown_markers = PointSet(markers, labels=self.marker_names if st.labels and self.marker_names else None)
        shown_bound = PointSet(bound, name="bound points") if st.bound and bound is not None else None
        img = render_mesh(points, self.triangles, camera=self.camera_at(time), style=self._render_style, colors=colors,
                          markers=shown_markers, extra=shown_bound)
        if st.burnin:
            f = int(round(time))
            burn_in(img, [self.name, self.method], [f"frame {f}", f"{timecode(f, self.rate)}  {self.rate:g} fps"
                                                    + (f"  {note}" if note else "")])
        return img

    def missing(self, text: str) -> np.ndarray:
        """A placeholder panel (nothing to show at this frame)."""
        img = placeholder(self.size, text)
        if self.style.burnin:
            burn_in(img, [self.name, self.method], [])
        return img
