"""Contact sheets: several frames of an animation in one image, all seen by the same camera."""
from __future__ import annotations

import math

import numpy as np

from ..errors import OptionError
from .camera import Camera
from .render import _cv2, _rgb, _text, fit_camera, render_mesh


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


def render_sequence(frames: np.ndarray, triangles: np.ndarray, *, frame_numbers=None,
                    camera: Camera | None = None, view: str | float = "front", cell_size=(256, 256),
                    projection: str = "orthographic", markers: np.ndarray | None = None,
                    extra_points: np.ndarray | None = None, scalars: np.ndarray | None = None,
                    scalar_range: tuple[float, float] | None = None, columns: int | None = None,
                    title: str = "", caption: str = "frame {}", **render_kwargs) -> np.ndarray:
    """Render frames of an animation with one shared camera and lay them out as a contact sheet.

    Parameters
    ----------
    frames : ndarray, shape (F, N, 3)
        Mesh points of each frame to show (select the frames beforehand, e.g. ``points[::24]``).
    triangles : ndarray, shape (T, 3), int
    frame_numbers : sequence of F numbers, optional
        Frame (time code) of each frame for the captions; default 0..F-1.
    camera : Camera, optional
        Default: fitted to the union of all frames (and markers), so the framing does not jump.
    view, cell_size, projection :
        Passed to :meth:`Camera.fit` when no camera is given.
    markers, extra_points : ndarray, shape (F, M, 3), optional
        Point sets per frame.
    scalars : ndarray, shape (F, N), optional
        A value per vertex and frame; one colour range for every frame (``scalar_range`` or the
        min/max over all frames) so colours compare across cells.
    columns : int, optional
        Grid width.
    title : str
        Sheet title.
    caption : str
        Caption format, ``{}`` replaced by the frame number.
    **render_kwargs :
        Other :func:`render_mesh` options (region_colors, edges, marker_labels, colormap...).

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

    def per_frame(a, what):
        if a is None:
            return None
        a = np.asarray(a, dtype=np.float64)
        if a.ndim == 2 and nf == 1:
            a = a[None]
        if a.ndim != 3 or a.shape[0] != nf or a.shape[2] != 3:
            raise OptionError(f"render_sequence: {what} must have shape ({nf}, M, 3); got {a.shape}")
        return a

    mk = per_frame(markers, "markers")
    ex = per_frame(extra_points, "extra_points")
    if scalars is not None:
        sc = np.asarray(scalars, dtype=np.float64)
        if sc.shape != fr.shape[:2]:
            raise OptionError(f"render_sequence: scalars must have shape {fr.shape[:2]}; got {sc.shape}")
        if scalar_range is None:
            from .colormap import scalar_range as default_range
            scalar_range = default_range(sc, colormap=render_kwargs.get("colormap", "viridis"))
    else:
        sc = None
    numbers = list(range(nf)) if frame_numbers is None else list(frame_numbers)
    if len(numbers) != nf:
        raise OptionError(f"render_sequence: {len(numbers)} frame numbers for {nf} frames")
    if camera is None:
        camera = fit_camera([fr, mk, ex], view=view, size=cell_size, projection=projection,
                            colorbar=sc is not None and render_kwargs.get("legend", True))
    cells = []
    for k in range(nf):
        cells.append(render_mesh(fr[k], triangles, camera=camera,
                                 markers=None if mk is None else mk[k],
                                 extra_points=None if ex is None else ex[k],
                                 scalars=None if sc is None else sc[k], scalar_range=scalar_range,
                                 **render_kwargs))
    caps = [caption.format(_fmt_frame(v)) for v in numbers]
    return contact_sheet(cells, caps, columns=columns, title=title)


def _fmt_frame(v) -> str:
    f = float(v)
    return str(int(f)) if f.is_integer() else f"{f:g}"
