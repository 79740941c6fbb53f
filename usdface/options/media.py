"""Options of the review media: stills (`preview`), movies (`playblast`), QC reports (`report`)."""
from __future__ import annotations

from dataclasses import dataclass

from ..errors import OptionError
from ..media.formats import X264_PRESETS
from ..preview.choices import COLORS, VIEW_CHOICES as VIEWS
from .fields import Options, option
from .values import boolean, integer, number, pair, path, positive_float, positive_int, shown


def movie_size_value(value, flag):
    """``"960x540"`` or (960, 540): an even movie frame size (H.264 yuv420p)."""
    if isinstance(value, (tuple, list)) and len(value) == 2:
        w, h = value
    else:
        try:
            w, h = (int(v) for v in str(value).lower().split("x"))
        except ValueError:
            raise OptionError(f"{flag} {shown(value)}: expected WIDTHxHEIGHT in pixels, e.g. 960x540") from None
    w, h = number(w, flag, kind=int, what="whole pixels"), number(h, flag, kind=int, what="whole pixels")
    if not (16 <= w <= 7680 and 16 <= h <= 4320):
        raise OptionError(f"{flag} {w}x{h}: expected 16..7680 x 16..4320 pixels")
    if w % 2 or h % 2:
        raise OptionError(f"{flag} {w}x{h}: H.264 (yuv420p) needs an even width and height")
    return (w, h)


def frame_range_value(value, flag):
    first, last = pair(integer, "FIRST LAST time codes")(value, flag)
    if last < first:
        raise OptionError(f"{flag} {first} {last}: expected FIRST <= LAST (time codes, both played)")
    return (first, last)


def in_range(lo, hi, kind=int):
    def coerce(value, flag):
        x = number(value, flag, kind=kind, what=f"a number in {lo}..{hi}")
        if not lo <= x <= hi:
            raise OptionError(f"{flag} {shown(value)}: expected {lo}..{hi}")
        return x
    return coerce


def workers_value(value, flag):
    n = number(value, flag, kind=int, what="0 (this thread) or more workers")
    if n < 0:
        raise OptionError(f"{flag} {n}: expected 0 (this thread) or more")
    return n


@dataclass(frozen=True)
class PlayblastOptions(Options):
    """How `usdface playblast` (and a report's movie) renders a shot."""

    frame_range: tuple | None = option(None, flag="--range", coerce=frame_range_value, nargs=2, metavar=("FIRST", "LAST"),
                                       group="frames", help="time codes to play, inclusive (default: the whole shot)")
    size: tuple = option((960, 540), flag="--size", coerce=movie_size_value, metavar="WxH", group="frames",
                         help="movie frame in pixels, even numbers (default: 960x540)")
    view: str = option("front", flag="--view", choices=VIEWS, group="look", help="camera (the list preview shares)")
    turntable_period: float = option(6.0, flag="--turntable-period", coerce=positive_float, metavar="SECONDS",
                                     group="look", help="--view turntable: seconds per swing")
    projection: str = option("orthographic", flag="--projection", choices=("orthographic", "perspective"),
                             group="look", help="camera projection")
    stabilized: bool = option(False, flag="--stabilized", coerce=boolean, group="look",
                              help="without the head motion on the face's root (the face as the transfer moved it)")
    color: str = option("regions", flag="--color", choices=COLORS, group="look",
                        help="surface colour: regions, displacement from rest, error against --reference, hybrid "
                             "weight")
    reference: str | None = option(None, flag="--reference", coerce=path, metavar="SHOT", group="look",
                                   help="shot or layer with reference points (for --color error)")
    markers: bool = option(False, flag="--markers", coerce=boolean, group="look", help="draw the capture markers")
    bound: bool = option(False, flag="--bound", coerce=boolean, group="look", help="draw the markers' bound points")
    labels: bool = option(False, flag="--labels", coerce=boolean, group="look",
                          help="write marker names (implies the markers' positions)")
    burnin: bool = option(True, flag="--no-burnin", coerce=boolean, group="look",
                          help="no shot/method/frame/timecode text")
    legend: bool = option(True, flag="--no-legend", coerce=boolean, group="look", help="no region legend or colour bar")
    supersample: int = option(1, flag="--supersample", coerce=in_range(1, 4), metavar="K", group="look",
                              help="anti-aliasing factor 1..4")
    compare: str | None = option(None, flag="--compare", coerce=path, metavar="SHOT", group="side by side",
                                 help="a second shot side by side on the right (aligned in seconds; a shorter one "
                                      "holds its last frame)")
    video: str | None = option(None, flag="--video", coerce=path, metavar="PATH", group="side by side",
                               help="the shot's source video side by side on the right (frame k + trim)")
    workers: int | None = option(None, flag="--workers", coerce=workers_value, metavar="N", group="encoding",
                                 help="render workers (default: the usable cores)")
    parallel: str = option("threads", flag="--parallel", choices=("threads", "processes"), group="encoding",
                           help="how workers run (threads: the renderer releases the GIL)")
    crf: int = option(18, flag="--crf", coerce=in_range(0, 51), group="encoding",
                      help="x264 quality, 0 (lossless) .. 51")
    preset: str = option("veryfast", flag="--preset", choices=X264_PRESETS, group="encoding",
                         help="x264 speed preset")

    def validate(self) -> None:
        super().validate()
        if self.compare is not None and self.video is not None:
            raise OptionError("--compare and --video: one panel on the right, give one of them")

    def style(self):
        """How each panel looks (:class:`usdface.playblast.panel.PanelStyle`)."""
        from ..playblast.panel import PanelStyle

        return PanelStyle(color=self.color, markers=self.markers, bound=self.bound, labels=self.labels,
                          legend=self.legend, burnin=self.burnin, supersample=self.supersample, view=self.view,
                          projection=self.projection, turntable_period=self.turntable_period)

    def parameters(self):
        """What the playblast shows and how (:class:`usdface.playblast.plan.PlayblastParameters`);
        the encoding options (workers, parallel, crf, preset) stay with the command."""
        from ..playblast.plan import PlayblastParameters

        return PlayblastParameters(style=self.style(), size=self.size, frame_range=self.frame_range,
                                   stabilized=self.stabilized, compare=self.compare, reference=self.reference,
                                   video=self.video)


def frames_value(value, flag):
    """One or more time codes (``--frames 0 120 441``)."""
    values = value if isinstance(value, (list, tuple)) else [value]
    if not values:
        raise OptionError(f"{flag}: expected one or more time codes")
    return tuple(number(v, flag, what="time codes") for v in values)


@dataclass(frozen=True)
class PreviewOptions(Options):
    """A software-rendered picture of a layer (`preview`)."""

    frame: float | None = option(None, flag="--frame", coerce=number, type=float, group="frames",
                                 help="time code to show (default: the layer's start)")
    frames: tuple | None = option(None, flag="--frames", coerce=frames_value, type=float, nargs="+",
                                  metavar="F", group="frames", help="several time codes: a contact sheet")
    view: str = option("front", flag="--view", choices=VIEWS, group="look",
                       help="camera (the list playblast shares; turntable turns only in a playblast: a still is "
                            "the front)")
    size: int = option(768, flag="--size", coerce=positive_int, type=int, group="look",
                       help="image size in pixels (square)")
    color: str = option("regions", flag="--color", choices=COLORS, group="look",
                        help="colour the surface by region, by displacement from the rest pose, by error against "
                             "--reference, or by the hybrid weight")
    reference: str | None = option(None, flag="--reference", coerce=path, group="look",
                                   help="a layer with reference points (for --color error)")
    labels: bool = option(False, flag="--labels", coerce=boolean, group="look", help="write marker names")


@dataclass(frozen=True)
class ReportOptions(Options):
    """The HTML QC report of a run's folder (`report`)."""

    playblast: str | None = option(None, flag="--playblast", coerce=path, metavar="MOVIE", group="movie",
                                   help="link this existing movie instead of rendering one")
    no_playblast: bool = option(False, flag="--no-playblast", coerce=boolean, group="movie",
                                help="no movie (faster)")
    playblast_size: tuple = option("640x360", flag="--playblast-size", coerce=movie_size_value, group="movie",
                                   help="size of the rendered playblast")
    workers: int | None = option(None, flag="--workers", coerce=workers_value, type=int, metavar="N",
                                 group="movie", help="playblast render workers (default: the usable cores)")

    def validate(self) -> None:
        super().validate()
        if self.playblast is not None and self.no_playblast:
            raise OptionError("--playblast and --no-playblast: give one of them")
