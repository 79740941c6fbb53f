"""Rasteriser: exact coverage, z-buffer, no cracks; checked against a slow obvious rasteriser."""
from __future__ import annotations

import numpy as np
import pytest

from usdface.preview import Camera, rasterize, render_buffers


def slow_rasterize(xy, zkey, tris, size):
    """Reference: every pixel centre against every triangle (edge-inclusive), nearest wins."""
    w, h = size
    tri_index = np.full((h, w), -1)
    zbuf = np.full((h, w), np.inf)
    for t, (a, b, c) in enumerate(tris):
        (x0, y0), (x1, y1), (x2, y2) = xy[a], xy[b], xy[c]
        area = (x1 - x0) * (y2 - y0) - (x2 - x0) * (y1 - y0)
        if area == 0:
            continue
        for i in range(h):
            for j in range(w):
                px, py = j + 0.5, i + 0.5
                w0 = ((x1 - px) * (y2 - py) - (x2 - px) * (y1 - py)) / area
                w1 = ((x2 - px) * (y0 - py) - (x0 - px) * (y2 - py)) / area
                w2 = ((x0 - px) * (y1 - py) - (x1 - px) * (y0 - py)) / area
                if min(w0, w1, w2) >= 0:
                    z = w0 * zkey[a] + w1 * zkey[b] + w2 * zkey[c]
                    if z < zbuf[i, j]:
                        zbuf[i, j] = z
                        tri_index[i, j] = t
    return tri_index, zbuf


def test_known_triangle_covers_exactly_the_expected_pixels():
    xy = np.array([[2.0, 2.0], [10.0, 2.0], [2.0, 10.0]])
    tri_index, zbuf = rasterize(xy, np.zeros(3), np.array([[0, 1, 2]]), (14, 12))
    i, j = np.mgrid[0:12, 0:14]
    # pixel centre (j+.5, i+.5) inside x >= 2, y >= 2, x + y <= 12 (centres on the hypotenuse count)
    expected = (j >= 2) & (i >= 2) & (i + j <= 11)
    assert expected.sum() == 36
    np.testing.assert_array_equal(tri_index >= 0, expected)
    assert tri_index[4, 4] == 0 and tri_index[0, 0] == -1 and tri_index[9, 9] == -1
    assert np.all(zbuf[expected] == 0) and np.all(np.isinf(zbuf[~expected]))


def test_both_windings_cover_the_same_pixels():
    xy = np.array([[1.3, 0.7], [12.6, 3.2], [4.1, 9.8]])
    a, _ = rasterize(xy, np.zeros(3), np.array([[0, 1, 2]]), (16, 12))
    b, _ = rasterize(xy, np.zeros(3), np.array([[0, 2, 1]]), (16, 12))
    np.testing.assert_array_equal(a >= 0, b >= 0)
    assert (a >= 0).sum() > 20


def test_random_triangles_match_slow_reference():
    rng = np.random.default_rng(7)
    size = (23, 17)
    xy = rng.uniform(-4, 26, size=(30, 2))
    z = rng.uniform(0, 10, size=30)
    tris = rng.integers(0, 30, size=(12, 3))
    fast_idx, fast_z = rasterize(xy, z, tris, size)
    ref_idx, ref_z = slow_rasterize(xy, z, tris, size)
    np.testing.assert_array_equal(fast_idx >= 0, ref_idx >= 0)
    cov = ref_idx >= 0
    np.testing.assert_allclose(fast_z[cov], ref_z[cov], rtol=0, atol=1e-9)
    same = fast_idx == ref_idx
    # ties in depth may go to either triangle; everywhere else the winner is the same
    assert np.all(same | np.isclose(fast_z, ref_z, atol=1e-9))


def test_small_chunks_give_the_same_result():
    rng = np.random.default_rng(3)
    xy = rng.uniform(0, 64, size=(200, 2))
    z = rng.uniform(0, 1, size=200)
    tris = rng.integers(0, 200, size=(150, 3))
    a, za = rasterize(xy, z, tris, (64, 64))
    b, zb = rasterize(xy, z, tris, (64, 64), max_candidates=64)
    np.testing.assert_array_equal(a, b)
    np.testing.assert_array_equal(za, zb)


@pytest.mark.parametrize("order", [[0, 1], [1, 0]])
def test_near_triangle_occludes_far_one_whatever_the_order(order):
    # far triangle (z=5) big, near triangle (z=1) small, inside it
    xy = np.array([[0, 0], [30, 0], [0, 30], [5, 5], [15, 5], [5, 15]], dtype=float)
    z = np.array([5, 5, 5, 1, 1, 1], dtype=float)
    tris = np.array([[0, 1, 2], [3, 4, 5]])[order]
    near = order.index(1)
    idx, zbuf = rasterize(xy, z, tris, (32, 32))
    assert idx[7, 7] == near and zbuf[7, 7] == 1.0  # inside the near triangle
    assert idx[2, 2] == 1 - near and zbuf[2, 2] == 5.0  # far triangle only


def test_interpenetrating_triangles_resolved_per_pixel():
    # the same footprint twice, depth planes crossing at x = 20: A (z = x/4) is in front on the left,
    # B (z = 10 - x/4) on the right; no triangle order (painter's algorithm) can draw this
    xy = np.array([[0, 0], [40, 0], [0, 40]] * 2, dtype=float)
    z = np.concatenate([xy[:3, 0] / 4, 10 - xy[3:, 0] / 4])
    for tris in (np.array([[0, 1, 2], [3, 4, 5]]), np.array([[3, 4, 5], [0, 1, 2]])):
        idx, zbuf = rasterize(xy, z, tris, (40, 40))
        a_id = int(np.flatnonzero(tris[:, 0] == 0)[0])
        assert idx[5, 5] == a_id and idx[5, 30] == 1 - a_id
        ref_idx, ref_z = slow_rasterize(xy, z, tris, (40, 40))
        cov = ref_idx >= 0
        np.testing.assert_array_equal(idx >= 0, cov)
        np.testing.assert_allclose(zbuf[cov], ref_z[cov], atol=1e-9)
        np.testing.assert_allclose(zbuf[cov], np.minimum((np.mgrid[0:40, 0:40][1] + 0.5) / 4,
                                                         10 - (np.mgrid[0:40, 0:40][1] + 0.5) / 4)[cov])


def test_no_cracks_between_triangles_of_a_jittered_grid():
    rng = np.random.default_rng(11)
    n = 25
    gx, gy = np.meshgrid(np.linspace(3, 93, n), np.linspace(3, 93, n))
    pts = np.stack([gx, gy], axis=-1)
    pts[1:-1, 1:-1] += rng.uniform(-1.2, 1.2, size=(n - 2, n - 2, 2))
    xy = pts.reshape(-1, 2)
    k = np.arange(n * n).reshape(n, n)
    a, b, c, d = k[:-1, :-1].ravel(), k[:-1, 1:].ravel(), k[1:, 1:].ravel(), k[1:, :-1].ravel()
    tris = np.concatenate([np.stack([a, b, c], 1), np.stack([a, c, d], 1)])
    idx, _ = rasterize(xy, np.zeros(len(xy)), tris, (96, 96))
    # every pixel whose centre lies inside the (convex) outer square is covered
    i, j = np.mgrid[0:96, 0:96]
    inside = (j + 0.5 > 3) & (j + 0.5 < 93) & (i + 0.5 > 3) & (i + 0.5 < 93)
    assert np.all(idx[inside] >= 0)


def test_offscreen_and_degenerate_triangles_are_ignored():
    xy = np.array([[-50, -50], [-40, -50], [-50, -40], [5, 5], [5, 5], [9, 9], [np.nan, 0], [3, 3], [3, 8]])
    tris = np.array([[0, 1, 2], [3, 4, 5], [6, 7, 8]])
    idx, zbuf = rasterize(xy, np.zeros(len(xy)), tris, (16, 16))
    assert np.all(idx == -1) and np.all(np.isinf(zbuf))


def test_partly_offscreen_triangle_is_clipped():
    xy = np.array([[-100.0, -100.0], [300.0, -100.0], [-100.0, 300.0]])
    idx, _ = rasterize(xy, np.zeros(3), np.array([[0, 1, 2]]), (20, 10))
    assert np.all(idx == 0)


def test_render_buffers_depth_and_facing_through_a_camera():
    # a front-facing (counter-clockwise seen from +Z) square at z=0 and a back-facing one behind it
    pts = np.array([[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0],
                    [-2, -2, -1], [2, -2, -1], [2, 2, -1], [-2, 2, -1]], dtype=float)
    tris = np.array([[0, 1, 2], [0, 2, 3], [4, 6, 5], [4, 7, 6]])
    for projection in ("orthographic", "perspective"):
        cam = Camera.fit(pts, size=(64, 64), projection=projection)
        buf = render_buffers(pts, tris, cam)
        f = buf.facing()
        assert f[32, 32] == 1 and buf.triangle[32, 32] in (0, 1)
        assert f[6, 32] == -1 and buf.triangle[6, 32] in (2, 3)  # only the far square out there
        d_near = float(np.dot(np.array([0, 0, 0]) - cam.eye, cam.forward))
        assert buf.depth[32, 32] == pytest.approx(d_near, rel=1e-6)
        assert buf.depth[6, 32] == pytest.approx(d_near + 1, rel=1e-6)
