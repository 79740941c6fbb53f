"""The test-data renderer: projection, exact depth, texture, caps."""
import numpy as np
import pytest

from usdface.scan.render import PinholeCamera, cap_holes, render_view, skin_albedo, stereo_cameras


def test_projection_and_exact_depth_of_a_tilted_plane():
    cam = PinholeCamera.look_at([0, 0, 100.0], [0, 0, 0], f=200.0, size=(64, 48))
    # plane z = 0.2 x, a big quad
    pts = np.array([[-50, -50, -10], [50, -50, 10], [50, 50, 10], [-50, 50, -10]], dtype=float)
    tris = np.array([[0, 1, 2], [0, 2, 3]])
    r = render_view(pts, tris, cam, vertex_colors=np.full((4, 3), 0.5))
    assert r.mask.all()
    # camera at z = 100 looking down -z: depth = 100 - z, pixel column x -> world x = (u - cx) * depth / f
    u = np.arange(64)[None, :].repeat(48, 0)
    cx = cam.K[0, 2]
    # ray x = (u - cx)/f * t, surface z = 0.2 x, depth t = 100 - z  ->  t = 100 / (1 + 0.2 (u - cx) / f)
    expect = 100.0 / (1 + 0.2 * (u - cx) / 200.0)
    assert np.allclose(r.depth, expect, atol=1e-9)
    xy, z = cam.project(np.array([[0.0, 0.0, 0.0]]))
    assert np.allclose(xy, [[cam.K[0, 2], cam.K[1, 2]]]) and z[0] == pytest.approx(100)


def test_stereo_cameras_give_the_rectified_disparity():
    cam = PinholeCamera.look_at([0, 0, 500.0], [0, 0, 0], f=400.0, size=(80, 60))
    a, b, calib = stereo_cameras(cam, 50.0)
    p = np.array([[10.0, 5.0, 0.0]])
    (ua, va), za = a.project(p)[0][0], a.project(p)[1][0]
    (ub, vb), _ = b.project(p)[0][0], None
    assert va == pytest.approx(vb)
    assert ua - ub == pytest.approx(calib["f"] * calib["baseline"] / za)
    _, c, cal_v = stereo_cameras(cam, 50.0, vertical=True)
    (uc, vc) = c.project(p)[0][0]
    assert uc == pytest.approx(ua) and va - vc == pytest.approx(cal_v["f"] * 50.0 / za)


def test_skin_texture_is_solid_and_deterministic():
    p = np.random.default_rng(0).uniform(0, 5, (100, 3))
    a = skin_albedo(p, seed=3)
    assert np.array_equal(a, skin_albedo(p, seed=3))
    assert not np.array_equal(a, skin_albedo(p, seed=4))
    assert a.min() >= 0 and a.max() <= 1 and a.std() > 0.01


def test_cap_holes_closes_a_loop():
    pts = np.array([[np.cos(t), np.sin(t), 0] for t in np.linspace(0, 2 * np.pi, 8, endpoint=False)])
    p2, t2 = cap_holes(pts, np.zeros((0, 3), int), [np.arange(8)], depth=0.5)
    assert p2.shape == (9, 3) and t2.shape == (8, 3)
    assert p2[8] == pytest.approx([0, 0, -0.5])


def test_photo_textured_face_render(sample_assets, shared_data):
    from usdface.scan.synthetic import render_annotated_faces, sample_face

    _, _, lm, scene = sample_face(sample_assets, "neutral", photo=shared_data / "images" / "astronaut.png")
    imgs, marks = render_annotated_faces(scene, 2, size=(120, 120), seed=0)
    assert imgs[0].shape == (120, 120, 3) and marks.shape == (2, 20, 2)
    assert ((marks > 0) & (marks < 120)).all()
