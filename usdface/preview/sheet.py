"""Contact sheets: several frames of an animation in one image, all seen by the same camera."""
from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from ..errors import OptionError
from .camera import Camera
from .render import _cv2, _rgb, _text, fit_camera, render_mesh
from .style import PointSet, RenderStyle, ScalarColors

__all__ = ["SEQUENCE_STYLE", "SheetLayout", "contact_sheet", "render_sequence"]


def contact_sheet(images, captions=None, *, columns: int | None = None, gap: int = 6,
                  background=(24, 25, 28), title: str = "", caption_scale: float = 0.45) -> np.ndarray:
    """Arrange images in a grid with a caption under each.

    Parameters
    ----------
    images : sequence of ndarray (H_i, W_i, 3) uint8, BGR
        Cells, in reading order (left to right, then top to bottom). Smaller images are centred
        in cells of the largest size.
    captions : sequence of str, optional
        One per image (e.g. ``"frame 120"``); empty strings allowed. Without captions there is no
        caption band.
    columns : int, optional
        Grid width; default ``ceil(sqrt(len(images)))``.
    gap : int
        Pixels between cells and around the sheet.
    background : (r, g, b)
        Sheet colour, 0..255.
    title : str
        A line of text above the grid.
    caption_scale : float
        Font scale of captions.

    Returns
    -------
    ndarray, shape (H, W, 3), uint8, BGR
    """
    cv2 = _cv2()
    imgs = [np.asarray(im) for im in images]
    if not imgs:
        raise OptionError("contact sheet: no images")
    for k, im in enumerate(imgs):
        if im.dtype != np.uint8 or not (im.ndim == 2 or (im.ndim == 3 and im.shape[2] == 3)):
            raise OptionError(f"contact sheet: image {k} must be uint8 (H, W) or (H, W, 3); "
                              f"got {im.dtype} {im.shape}")
    imgs = [cv2.cvtColor(im, cv2.COLOR_GRAY2BGR) if im.ndim == 2 else im for im in imgs]
    if captions is not None:
        captions = [str(c) for c in captions]
        if len(captions) != len(imgs):
            raise OptionError(f"contact sheet: {len(captions)} captions for {len(imgs)} images")
    n = len(imgs)
    cols = int(columns) if columns is not None else math.ceil(math.sqrt(n))
    if cols < 1:
        raise OptionError(f"contact sheet: columns must be >= 1; got {columns}")
    cols = min(cols, n)
    rows = math.ceil(n / cols)
    ch = max(im.shape[0] for im in imgs)
    cw = max(im.shape[1] for im in imgs)
    (_, th), base = cv2.getTextSize("Ag", 0, caption_scale, 1)
    cap_h = (th + base + 8) if captions is not None else 0
    title_h = int(round(th * 1.6 + base + 12)) if title else 0
    gap = max(int(gap), 0)
    h = title_h + rows * (ch + cap_h) + (rows + 1) * gap
    w = cols * cw + (cols + 1) * gap
    bg = _rgb(background, "background")
    sheet = np.empty((h, w, 3), dtype=np.uint8)
    sheet[:] = (bg[2], bg[1], bg[0])
    if title:
        _text(sheet, title, (gap + 2, gap + th * 1.3 + 2), caption_scale * 1.3, (245, 245, 245), outline=False)
    for k, im in enumerate(imgs):
        r, c = divmod(k, cols)
        y = title_h + gap + r * (ch + cap_h + gap)
        x = gap + c * (cw + gap)
        oy, ox = (ch - im.shape[0]) // 2, (cw - im.shape[1]) // 2
        sheet[y + oy:y + oy + im.shape[0], x + ox:x + ox + im.shape[1]] = im
        if captions is not None and captions[k]:
            (tw, _), _ = cv2.getTextSize(captions[k], 0, caption_scale, 1)
            _text(sheet, captions[k], (x + (cw - tw) / 2, y + ch + th + 4), caption_scale, (225, 225, 225),
                  outline=False)
    return sheet


@dataclass(frozen=True)
class SheetLayout:
    """How :func:`render_sequence` lays out its cells: ``columns`` (default
    ``ceil(sqrt(frames))``), a ``title`` above the grid, and the ``caption`` format under each
    cell (``{}`` replaced by the frame number)."""

    columns: int | None = None
    title: str = ""
    caption: str = "frame {}"


#: the cell size of :func:`render_sequence` without a style
SEQUENCE_STYLE = RenderStyle(size=(256, 256))


def render_sequence(frames: np.ndarray, triangles: np.ndarray, *, frame_numbers=None, camera: Camera | None = None,
                    style: RenderStyle = SEQUENCE_STYLE, colors=None, markers=None, extra=None,
                    edges: np.ndarray | None = None, layout: SheetLayout = SheetLayout()) -> np.ndarray:
    """Render frames of an animation with one shared camera and lay them out as a contact sheet.

    Parameters
    ----------
    frames : ndarray, shape (F, N, 3)
        Mesh points of each frame to show (select the frames beforehand, e.g. ``points[::24]``).
    triangles : ndarray, shape (T, 3), int
    frame_numbers : sequence of F numbers, optional
        Frame (time code) of each frame for the captions; default 0..F-1.
    camera : Camera, optional
        Default: fitted to the union of all frames (and markers) with the style's view, size
        (the cell's) and projection, so the framing does not jump.
    style : RenderStyle
        Every cell's look (:func:`render_mesh`); its ``size`` is the cell size (default 256 x 256).
    colors : ScalarColors with values (F, N), or RegionColors / VertexColors, optional
        A value per vertex and frame shares one colour range over every frame (its ``range``, or
        the min/max over all frames) so colours compare across cells; regions or vertex colours
        are the same in every cell.
    markers, extra : PointSet or ndarray, shape (F, M, 3), optional
        Point sets per frame (a PointSet's labels, colour and name apply to every frame).
    edges : ndarray (E, 2), optional
        Wireframe edges (:func:`polygon_edges`).
    layout : SheetLayout
        Columns, title and captions.

    Returns
    -------
    ndarray, shape (H, W, 3), uint8, BGR
    """
    fr = np.asarray(frames, dtype=np.float64)
    if fr.ndim == 2:
        fr = fr[None]
    if fr.ndim != 3 or fr.shape[2] != 3 or fr.shape[0] == 0:
        raise OptionError(f"render_sequence: frames must have shape (F, N, 3); got {fr.shape}")
    nf = fr.shape[0]
    mk = _per_frame(markers, nf, "markers")
    ex = _per_frame(extra, nf, "extra_points")
    colors = _shared_scalar_range(colors, fr.shape[:2])
    numbers = list(range(nf)) if frame_numbers is None else list(frame_numbers)
    if len(numbers) != nf:
        raise OptionError(f"render_sequence: {len(numbers)} frame numbers for {nf} frames")
    scalars = isinstance(colors, ScalarColors)
    if camera is None:
        camera = fit_camera([fr, None if mk is None else mk.points, None if ex is None else ex.points],
                            view=style.view, size=style.size, projection=style.projection, pitch=style.pitch,
                            colorbar=scalars and style.legend)
    cells = []
    for k in range(nf):
        cell_colors = replace(colors, values=colors.values[k]) if scalars else colors
        cells.append(render_mesh(fr[k], triangles, camera=camera, style=style, colors=cell_colors,
                                 markers=None if mk is None else replace(mk, points=mk.points[k]),
                                 extra=None if ex is None else replace(ex, points=ex.points[k]), edges=edges))
    caps = [layout.caption.format(_fmt_frame(v)) for v in numbers]
    return contact_sheet(cells, caps, columns=layout.columns, title=layout.title)


def _per_frame(points, nf: int, what: str) -> PointSet | None:
    """A point set with (F, M, 3) points (one frame may be given as (M, 3))."""
    ps = PointSet.of(points)
    if ps is None:
        return None
    a = np.asarray(ps.points, dtype=np.float64)
    if a.ndim == 2 and nf == 1:
        a = a[None]
    if a.ndim != 3 or a.shape[0] != nf or a.shape[2] != 3:
        raise OptionError(f"render_sequence: {what} must have shape ({nf}, M, 3); got {a.shape}")
    return replace(ps, points=a)


def _shared_scalar_range(colors, shape):
    """Scalars (F, N) checked, with one range over every frame."""
    if not isinstance(colors, ScalarColors):
        return colors
    sc = np.asarray(colors.values, dtype=np.float64)
    if sc.shape != shape:
        raise OptionError(f"render_sequence: scalars must have shape {shape}; got {sc.shape}")
    rng = colors.range
    if rng is None:
        from .colormap import scalar_range as default_range

        rng = default_range(sc, colormap=colors.colormap)
    return replace(colors, values=sc, range=rng)


def _fmt_frame(v) -> str:
    f = float(v)
    return str(int(f)) if f.is_integer() else f"{f:g}"
