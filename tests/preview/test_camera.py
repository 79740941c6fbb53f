"""Preview cameras: views, framing, fixed framing for sequences."""
from __future__ import annotations

import numpy as np
import pytest

from usdface.errors import OptionError
from usdface.preview import Camera

BOX = np.array([[x, y, z] for x in (-3.0, 3.0) for y in (60.0, 80.0) for z in (8.0, 16.0)])


@pytest.mark.parametrize("projection", ["orthographic", "perspective"])
@pytest.mark.parametrize("view", ["front", "left", "right", "side", "side_right", 20.0])
def test_fit_frames_all_points_inside_the_margin(view, projection):
    cam = Camera.fit(BOX, view=view, size=(320, 240), projection=projection, margin=0.1)
    xy, depth = cam.project(BOX)
    assert np.all(depth > 0)
    assert xy[:, 0].min() >= 32 - 1e-6 and xy[:, 0].max() <= 288 + 1e-6
    assert xy[:, 1].min() >= 24 - 1e-6 and xy[:, 1].max() <= 216 + 1e-6
    # tight on at least one axis and centred
    span = np.ptp(xy, axis=0)
    assert span[0] == pytest.approx(256, rel=2e-3) or span[1] == pytest.approx(192, rel=2e-3)
    centre = (xy.min(axis=0) + xy.max(axis=0)) / 2
    np.testing.assert_allclose(centre, [160, 120], atol=1.0)


def test_front_view_orientation():
    cam = Camera.fit(BOX, view="front")
    np.testing.assert_allclose(cam.forward, [0, 0, -1], atol=1e-12)  # looking along -Z
    np.testing.assert_allclose(cam.up, [0, 1, 0], atol=1e-12)
    xy, depth = cam.project(np.array([[0, 70, 16], [0, 70, 8], [2, 70, 12], [0, 75, 12]]))
    assert depth[0] < depth[1]  # the face (+Z) is nearer than the back
    assert xy[2, 0] > xy[0, 0]  # +X (performer's left) is on the image right
    assert xy[3, 1] < xy[0, 1]  # +Y up is image up


def test_three_quarter_and_side_views_turn_toward_the_named_side():
    nose, left_cheek, right_cheek = np.array([[0, 70, 16], [5, 70, 12], [-5, 70, 12]])
    for view, near in (("left", left_cheek), ("side", left_cheek), ("right", right_cheek),
                       ("side_right", right_cheek)):
        cam = Camera.fit(BOX, view=view)
        _, d = cam.project(np.stack([left_cheek, right_cheek]))
        assert (d[0] < d[1]) == (near is left_cheek), view
    rot = Camera.view_rotation("left")
    assert np.degrees(np.arccos(-rot[2] @ np.array([0, 0, 1.0]))) == pytest.approx(35.0)
    assert np.degrees(np.arccos(-Camera.view_rotation("side")[2] @ np.array([0, 0, 1.0]))) == pytest.approx(90.0)


def test_pitch_puts_the_camera_above():
    cam = Camera.fit(BOX, view="front", pitch=20)
    assert cam.forward[1] < 0  # looking down
    assert cam.eye[1] > BOX[:, 1].mean()


def test_z_up_asset():
    pts = BOX[:, [0, 2, 1]] * np.array([1, -1, 1])  # Y-up +Z-forward -> Z-up -Y-forward
    cam = Camera.fit(pts, view="front", up=(0, 0, 1), forward=(0, -1, 0))
    np.testing.assert_allclose(cam.forward, [0, 1, 0], atol=1e-12)
    np.testing.assert_allclose(cam.up, [0, 0, 1], atol=1e-12)


def test_sequence_framing_union_and_reuse():
    rng = np.random.default_rng(0)
    frames = BOX[None] + np.array([[0, 0, 0], [4, 0, 0], [0, -3, 0]], dtype=float)[:, None, :]
    frames = frames + rng.normal(0, 0.01, frames.shape)
    cam = Camera.fit(frames, size=(256, 256))
    for f in frames:  # every frame stays in view with the union camera
        xy, _ = cam.project(f)
        assert np.all((xy >= 0) & (xy <= 256))
    first = Camera.fit(frames[0], size=(256, 256))
    xy0, _ = first.project(frames[0])
    xy1, _ = first.project(frames[1])
    # same camera: a 4 cm move to +X shows as a pixel shift of 4 * scale
    np.testing.assert_allclose((xy1 - xy0)[:, 0].mean(), 4 * first.scale, rtol=1e-2)


def test_list_of_point_sets_and_nan_rows_are_framed():
    markers = np.array([[0, 90, 12], [np.nan, np.nan, np.nan]])
    cam = Camera.fit([BOX, markers], size=(200, 200))
    xy, _ = cam.project(np.array([[0, 90, 12]]))
    assert 0 <= xy[0, 1] < 20  # the marker above the box sets the top of the frame


def test_resized_camera_scales_image_coordinates():
    cam = Camera.fit(BOX, size=(100, 80), projection="perspective")
    big = cam.resized(3)
    assert big.size == (300, 240)
    np.testing.assert_allclose(big.project(BOX)[0], cam.project(BOX)[0] * 3)


def test_perspective_points_behind_the_camera_are_nan():
    cam = Camera.fit(BOX, projection="perspective")
    xy, depth = cam.project(cam.eye - 5 * cam.forward)
    assert depth < 0 and np.isnan(xy).all()


def test_degenerate_inputs():
    cam = Camera.fit(np.array([[1.0, 2.0, 3.0]]))  # a single point still gives a camera
    np.testing.assert_allclose(cam.project(np.array([1.0, 2.0, 3.0]))[0], [256, 256])
    with pytest.raises(OptionError, match="view"):
        Camera.fit(BOX, view="top")
    with pytest.raises(OptionError, match="finite"):
        Camera.fit(np.full((3, 3), np.nan))
    with pytest.raises(OptionError, match="margin"):
        Camera.fit(BOX, margin=0.5)
    with pytest.raises(OptionError, match="projection"):
        Camera.fit(BOX, projection="fisheye")
    with pytest.raises(OptionError, match="size"):
        Camera.fit(BOX, size=(0, 10))
