"""Contact sheets and sequences rendered with one camera."""
from __future__ import annotations

import numpy as np
import pytest

from usdface.errors import OptionError
from usdface.preview import Camera, RenderStyle, ScalarColors, SheetLayout, contact_sheet, render_mesh, render_sequence


def cells(n, h=40, w=60):
    return [np.full((h, w, 3), 20 * (k + 1), np.uint8) for k in range(n)]


def test_grid_layout_and_cell_positions():
    imgs = cells(5)
    sheet = contact_sheet(imgs, columns=3, gap=4, background=(0, 0, 0))
    assert sheet.shape == (2 * 40 + 3 * 4, 3 * 60 + 4 * 4, 3)
    for k, im in enumerate(imgs):
        r, c = divmod(k, 3)
        y, x = 4 + r * (40 + 4), 4 + c * (60 + 4)
        np.testing.assert_array_equal(sheet[y:y + 40, x:x + 60], im)
    assert np.all(sheet[48:88, 4 + 2 * 64:4 + 2 * 64 + 60] == 0)  # the sixth cell is empty


def test_captions_and_title_are_drawn_under_each_cell():
    imgs = cells(4)
    plain = contact_sheet(imgs, columns=2, gap=4)
    captioned = contact_sheet(imgs, ["frame 0", "frame 24", "", "frame 72"], columns=2, gap=4, title="Jaw take")
    assert captioned.shape[0] > plain.shape[0] and captioned.shape[1] == plain.shape[1]
    assert captioned.max() > 200  # light text on the dark sheet


def test_default_columns_and_mixed_sizes():
    imgs = cells(3) + [np.zeros((20, 30), np.uint8)]
    sheet = contact_sheet(imgs)
    assert sheet.shape[1] == 2 * 60 + 3 * 6  # ceil(sqrt(4)) = 2 columns, the largest cell size


def test_errors():
    with pytest.raises(OptionError, match="no images"):
        contact_sheet([])
    with pytest.raises(OptionError, match="captions"):
        contact_sheet(cells(2), ["a"])
    with pytest.raises(OptionError, match="uint8"):
        contact_sheet([np.zeros((4, 4, 3), np.float32)])
    with pytest.raises(OptionError, match="frames"):
        render_sequence(np.zeros((2, 5)), np.zeros((0, 3), int))


def test_sequence_uses_one_camera_so_motion_shows():
    # a triangle moving to +X: with one camera it moves across the cells; refitting would re-centre it
    tri = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], dtype=float)
    frames = np.stack([tri + [dx, 0, 0] for dx in (0.0, 1.0, 2.0)])
    t = np.array([[0, 1, 2]])
    cell = (80, 80)
    style = RenderStyle(size=cell, background=(0, 0, 0), supersample=1, shading="unlit")
    sheet = render_sequence(frames, t, style=style, layout=SheetLayout(columns=3, caption="f{}"),
                            frame_numbers=[1, 2, 3])
    cam = Camera.fit(frames, size=cell)
    for k in range(3):
        x = 6 + k * (80 + 6)
        expected = render_mesh(frames[k], t, camera=cam, style=style)
        np.testing.assert_array_equal(sheet[6:86, x:x + 80], expected)
    cols = [np.flatnonzero(sheet[6:86, 6 + k * 86:86 + k * 86].any(axis=(0, 2))) for k in range(3)]
    assert cols[0].mean() < cols[1].mean() < cols[2].mean()


def test_sequence_scalars_share_one_range_and_markers_per_frame():
    tri = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], dtype=float)
    frames = np.stack([tri, tri])
    scal = np.array([[0.0, 0.0, 0.0], [1.0, 1.0, 1.0]])
    markers = np.array([[[0.2, 0.2, 0.1]], [[np.nan, np.nan, np.nan]]])
    sheet = render_sequence(frames, np.array([[0, 1, 2]]), colors=ScalarColors(scal), markers=markers,
                            style=RenderStyle(size=(64, 64), shading="unlit", supersample=1, legend=False))
    a = sheet[6:70, 6:70].reshape(-1, 3)
    b = sheet[6:70, 76:140].reshape(-1, 3)
    # frame 0 shows the low end of the shared range, frame 1 the high end
    assert {tuple(v) for v in a} != {tuple(v) for v in b}
