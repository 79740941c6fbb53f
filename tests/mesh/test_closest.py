"""usdface.mesh.closest: exact closest points, checked against brute force over all triangles."""
from __future__ import annotations

import numpy as np
import pytest

from usdface.errors import MeshError, OptionError
from usdface.io.meshes import read_mesh
from usdface.mesh.closest import SurfaceLocator, closest_point_on_triangles, closest_points


def brute_force(points, tris, queries):
    """(Q, T) distances from every query to every triangle (the obvious way)."""
    nq, nt = len(queries), len(tris)
    qi = np.repeat(np.arange(nq), nt)
    ti = np.tile(np.arange(nt), nq)
    _, _, d = closest_point_on_triangles(queries[qi], points[tris[ti, 0]], points[tris[ti, 1]], points[tris[ti, 2]])
    return d.reshape(nq, nt)


@pytest.mark.parametrize("name", ["makehuman_hm08_face_cm.obj", "mediapipe_canonical_face_model_holes.obj"])
def test_locator_matches_brute_force_on_a_real_mesh(shared_data, name):
    m = read_mesh(shared_data / "meshes" / name)
    p, tris = m.points, m.triangles()
    rng = np.random.default_rng(7)
    near = p[rng.integers(0, len(p), 250)] + rng.normal(0, 0.8, (250, 3))
    far = rng.uniform(p.min(0) - 15, p.max(0) + 15, (30, 3))
    q = np.vstack([near, far, p[:20]])  # also exact vertices
    tri, bary, cp, dist = SurfaceLocator(p, tris).closest(q)
    d_all = brute_force(p, tris, q)
    best = d_all.min(axis=1)
    np.testing.assert_allclose(dist, best, rtol=0, atol=1e-12)
    np.testing.assert_allclose(d_all[np.arange(len(q)), tri], best, rtol=0, atol=1e-12)
    np.testing.assert_allclose(np.linalg.norm(q - cp, axis=1), dist, atol=1e-12)
    np.testing.assert_allclose(np.einsum("qk,qkd->qd", bary, p[tris[tri]]), cp, atol=1e-12)
    assert (bary >= -1e-12).all()
    np.testing.assert_allclose(bary.sum(axis=1), 1.0)
    np.testing.assert_allclose(dist[-20:], 0.0, atol=1e-12)


def test_point_triangle_kernel_against_dense_sampling():
    rng = np.random.default_rng(3)
    k = 120
    a, b, c = rng.normal(size=(3, k, 3))
    # some degenerate triangles: a point, and collinear vertices
    b[:10] = a[:10]
    c[:10] = a[:10]
    c[10:20] = a[10:20] + 0.3 * (b[10:20] - a[10:20])
    q = rng.normal(size=(k, 3)) * 1.5
    pt, bary, d = closest_point_on_triangles(q, a, b, c)
    assert np.isfinite(pt).all() and np.isfinite(bary).all()
    u, v = np.meshgrid(np.linspace(0, 1, 151), np.linspace(0, 1, 151))
    keep = u + v <= 1
    u, v = u[keep], v[keep]
    samples = a[:, None] + u[None, :, None] * (b - a)[:, None] + v[None, :, None] * (c - a)[:, None]
    sampled = np.linalg.norm(samples - q[:, None], axis=2).min(axis=1)
    assert (d <= sampled + 1e-12).all()  # never worse than any point of the triangle
    assert (sampled - d < 0.02).all()  # and the sampled minimum converges to it
    np.testing.assert_allclose(bary[:, :1] * a + bary[:, 1:2] * b + bary[:, 2:] * c, pt, atol=1e-12)
    np.testing.assert_allclose(bary.sum(axis=1), 1.0)


def test_one_large_triangle_among_small_ones_is_still_found():
    # many tiny triangles far away and one huge one: the radius classes keep the search exact
    rng = np.random.default_rng(5)
    small = rng.uniform(0, 1, (200, 3)) + np.array([50.0, 0, 0])
    pts = np.vstack([small, small + [0.01, 0, 0], small + [0, 0.01, 0], [[-100, -100, 0], [100, -100, 0], [0, 100, 0]]])
    tris = np.vstack([np.stack([np.arange(200), 200 + np.arange(200), 400 + np.arange(200)], 1), [[600, 601, 602]]])
    q = np.vstack([rng.uniform(-20, 20, (50, 3)), small[:10] + [0, 0, 0.5]])
    loc = SurfaceLocator(pts, tris)
    tri, _, _, dist = loc.closest(q)
    best = brute_force(pts, tris, q).min(axis=1)
    np.testing.assert_allclose(dist, best, atol=1e-12)
    assert (tri[:50] == 200).all()


def test_one_call_form_and_chunking_agree(shared_data):
    m = read_mesh(shared_data / "meshes" / "mediapipe_canonical_face_model_holes.obj")
    q = np.random.default_rng(1).normal(0, 5, (300, 3))
    a = closest_points(m.points, m.triangles(), q)
    b = SurfaceLocator(m.points, m.triangles()).closest(q, chunk=7)
    for x, y in zip(a, b):
        np.testing.assert_array_equal(x, y)


def test_bad_inputs():
    with pytest.raises(MeshError, match="points must have shape"):
        SurfaceLocator(np.zeros((3, 2)), [[0, 1, 2]])
    with pytest.raises(MeshError, match="triangle indices outside 0..2"):
        SurfaceLocator(np.eye(3), [[0, 1, 3]])
    loc = SurfaceLocator(np.eye(3), [[0, 1, 2]])
    with pytest.raises(OptionError, match=r"queries must have shape \(Q, 3\)"):
        loc.closest(np.zeros(3))
    with pytest.raises(OptionError, match="NaN"):
        loc.closest([[np.nan, 0, 0]])
