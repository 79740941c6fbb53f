"""Hybrid distance (paper Eq. 8): weights, blend, S x S rows, bounded geodesic search."""
from __future__ import annotations

import numpy as np
import pytest

from usdface.distance import (GeodesicSolver, euclidean_distances, hybrid_distances, hybrid_weights,
                              region_mask)
from usdface.errors import InputError, OptionError


@pytest.fixture(scope="module")
def face(shared_data):
    from usdface.io.meshes import read_mesh
    from usdface.mesh.topology import find_hole_regions
    m = read_mesh(shared_data / "meshes" / "makehuman_hm08_face_cm.obj")
    loops = [r.loop for r in find_hole_regions(m) if r.role in ("mouth", "eye")]
    rng = np.random.default_rng(11)
    tris = m.triangles()
    tri = tris[rng.choice(len(tris), 41, replace=False)]
    bary = rng.dirichlet([2.0, 2.0, 2.0], size=41)
    return m.points, tris, loops, tri, bary


def test_weights(face):
    pts, _, loops, tri, bary = face
    w, inside = hybrid_weights(pts, loops, radius=1.0, sigma=2.0)
    seeds = np.concatenate(loops)
    assert inside[seeds].all() and (w[inside] == 1.0).all()
    # w = exp(-g^2 / sigma^2), g = distance to the nearest region vertex
    out = np.flatnonzero(~inside)
    g = np.linalg.norm(pts[out][:, None] - pts[inside][None], axis=2).min(axis=1)
    np.testing.assert_allclose(w[out], np.exp(-g ** 2 / 4.0), rtol=1e-12)
    ds = np.linalg.norm(pts[:, None] - pts[seeds][None], axis=2).min(axis=1)
    np.testing.assert_array_equal(region_mask(pts, loops, radius=1.0), ds <= 1.0)
    # the paper's cut: w > 0.6 <=> g < sigma sqrt(ln(1/0.6)) = 1.43 cm
    expected = inside.copy()
    expected[out] = g < 2.0 * np.sqrt(np.log(1 / 0.6))
    np.testing.assert_array_equal(w > 0.6, expected)
    # a source point gets its own weight (w = 1 within the radius of a seed)
    ws, ins = hybrid_weights(pts, loops, radius=1.0, sigma=2.0, query_points=pts[seeds[:3]] + 0.01)
    assert ins.all() and (ws == 1.0).all()


@pytest.mark.parametrize("backend", ["graph", "fmm"])
def test_hybrid_blend_matches_definition(face, backend):
    pts, tris, loops, tri, bary = face
    solver = GeodesicSolver(pts, tris, backend=backend)
    r = hybrid_distances(solver, tri, bary, loops, radius=1.0, sigma=2.0)
    full = GeodesicSolver(pts, tris, backend=backend).solve(tri, bary)
    euc = euclidean_distances(pts, tri, bary)
    w = r.weights[:, None]
    ref = np.where(w > 0.6, w * full.vertex + (1 - w) * euc, euc)
    np.testing.assert_allclose(r.vertex, ref, rtol=0, atol=1e-12)
    assert 0 < r.geodesic_vertices.sum() < len(pts)
    # S x S: the row source's weight, so not symmetric
    q = np.einsum("sk,skd->sd", bary, pts[tri])
    es = np.linalg.norm(q[:, None] - q[None], axis=2)
    ws = r.source_weights[:, None]
    ref_s = np.where(ws > 0.6, ws * full.sources + (1 - ws) * es, es)
    np.testing.assert_allclose(r.sources, ref_s, rtol=0, atol=1e-12)
    i, j = np.argwhere((r.source_weights[:, None] > 0.6) & (r.source_weights[None, :] <= 0.6))[0]
    assert r.sources[i, j] > r.sources[j, i]
    np.testing.assert_array_equal(np.diag(r.sources), 0.0)


@pytest.mark.parametrize("backend", ["graph", "fmm"])
def test_bounded_equals_unbounded_and_saves_work(face, backend):
    pts, tris, loops, tri, bary = face
    b = hybrid_distances(GeodesicSolver(pts, tris, backend=backend), tri, bary, loops, radius=1.0, sigma=2.0)
    u = hybrid_distances(GeodesicSolver(pts, tris, backend=backend), tri, bary, loops, radius=1.0, sigma=2.0,
                         bounded=False)
    np.testing.assert_array_equal(b.vertex, u.vertex)
    np.testing.assert_array_equal(b.sources, u.sources)
    assert u.geodesic.settled_fraction == 1.0
    assert b.geodesic.settled_fraction < 1.0
    assert b.geodesic.needed_vertices >= b.geodesic_vertices.sum()


def test_exact_backend_bounded(face):
    pts, tris, loops, tri, bary = face
    tri, bary = tri[:3], bary[:3]
    b = hybrid_distances(GeodesicSolver(pts, tris, backend="exact"), tri, bary, loops, radius=1.0, sigma=2.0)
    u = hybrid_distances(GeodesicSolver(pts, tris, backend="exact"), tri, bary, loops, radius=1.0, sigma=2.0,
                         bounded=False)
    np.testing.assert_allclose(b.vertex, u.vertex, rtol=1e-9, atol=1e-9)


def test_euclidean_where_weight_is_low(face):
    pts, tris, loops, tri, bary = face
    r = hybrid_distances(GeodesicSolver(pts, tris), tri, bary, loops, radius=0.0, sigma=0.05, threshold=0.99)
    # radius 0: the region is the loops themselves; a tiny sigma leaves nothing else above 0.99
    np.testing.assert_array_equal(np.flatnonzero(r.geodesic_vertices), np.unique(np.concatenate(loops)))
    euc = euclidean_distances(pts, tri, bary)
    np.testing.assert_array_equal(r.vertex[~r.geodesic_vertices], euc[~r.geodesic_vertices])
    assert (r.vertex[r.geodesic_vertices] >= euc[r.geodesic_vertices] - 1e-12).all()


def test_bad_options(face):
    pts, tris, loops, tri, bary = face
    s = GeodesicSolver(pts, tris)
    with pytest.raises(OptionError):
        hybrid_distances(s, tri, bary, loops, radius=1.0, sigma=0.0)
    with pytest.raises(OptionError):
        hybrid_distances(s, tri, bary, loops, radius=1.0, sigma=2.0, threshold=1.5)
    with pytest.raises(InputError):
        hybrid_distances(s, tri, bary, [np.array([10**7])], radius=1.0, sigma=2.0)
    with pytest.raises(InputError):
        hybrid_distances(s, tri, bary, [], radius=1.0, sigma=2.0)


def test_refuses_before_any_work_when_memory_is_short(face):
    from usdface.errors import ResourceError
    pts, tris, loops, tri, bary = face
    solver = GeodesicSolver(pts, tris, backend="fmm", memory_limit=1 << 20)
    with pytest.raises(ResourceError, match=r"hybrid \(fmm\) distances of 2020 vertices x 41 sources .* needs about "
                                            r".*Euclidean matrix \+ matrix 662.6 KB.* but only 1.0 MB is allowed"):
        hybrid_distances(solver, tri, bary, loops, radius=1.0, sigma=2.0)
    assert solver._marching is None          # refused before the search tables were built


@pytest.mark.parametrize("dtype", [np.float64, np.float32])
def test_blend_is_the_same_in_either_memory_order(dtype):
    """The blend walks a source-major geodesic matrix (graph) by columns and a vertex-major one
    (fmm) by blocks of rows: the same numbers either way, +inf entries (not searched) included."""
    from usdface.distance.hybrid import _blend
    rng = np.random.default_rng(0)
    n, s = 20000, 7
    euc = np.asfortranarray(rng.random((n, s)).astype(dtype))
    geo = rng.random((n, s)) + 1.0
    inside = rng.random(n) > 0.4
    geo[~inside & (np.arange(n) % 3 == 0)] = np.inf        # outside the geodesic region: not searched
    w = np.where(inside, rng.random(n), 0.0).astype(dtype)
    by_column, by_rows = euc.copy(order="F"), euc.copy(order="F")
    _blend(by_column, np.asfortranarray(geo), inside, w)
    _blend(by_rows, np.ascontiguousarray(geo), inside, w)
    np.testing.assert_array_equal(by_rows, by_column)
    np.testing.assert_array_equal(by_column[~inside], euc[~inside])
    assert np.isfinite(by_column).all()
