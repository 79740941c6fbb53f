"""Connected components from the triangles (union-find) against the edge-list labelling."""
from __future__ import annotations

import numpy as np
import pytest

from usdface.distance import GeodesicSolver
from usdface.distance import graph as G
from usdface.distance.components import triangle_components


def islands(sizes, seed=0):
    """Strips of triangles of the given lengths, their vertices shuffled, plus isolated vertices."""
    rng = np.random.default_rng(seed)
    tris, n = [], 0
    for k in sizes:
        # a strip: triangles (i, i+1, i+2) over k + 2 vertices
        tris.append(np.stack([np.arange(k), np.arange(k) + 1, np.arange(k) + 2], axis=1) + n)
        n += k + 2
    n_isolated = 3
    perm = rng.permutation(n + n_isolated)
    return n + n_isolated, perm[np.concatenate(tris)]


@pytest.mark.parametrize("sizes", [[5], [4, 9, 4, 1], [3, 3, 3], [1, 7, 2, 7]])
def test_same_labels_as_the_edge_list(sizes):
    n, tris = islands(sizes, seed=len(sizes))
    got = triangle_components(n, tris)
    want = G.connected_components(n, tris)
    assert got[0] == want[0] == len(sizes) + 3          # the isolated vertices count too
    np.testing.assert_array_equal(got[1], want[1])


def test_real_face_and_solver(shared_data):
    from usdface.io.meshes import read_mesh
    m = read_mesh(shared_data / "meshes" / "mediapipe_canonical_face_model_holes.obj")
    t = m.triangles()
    # two copies side by side, the second one larger (refined): it becomes component 0
    p2, t2 = G.refine_triangles(m.points, t, 2)
    pts = np.concatenate([m.points, p2 + [30.0, 0.0, 0.0]])
    tris = np.concatenate([t, t2 + len(m.points)])
    n, labels = triangle_components(len(pts), tris)
    assert n == 2 and (labels[:len(m.points)] == 1).all() and (labels[len(m.points):] == 0).all()
    np.testing.assert_array_equal(labels, G.connected_components(len(pts), tris)[1])
    solver = GeodesicSolver(pts, tris, backend="fmm")
    np.testing.assert_array_equal(solver.component_labels, labels)
    assert solver._edges is None                      # fmm never builds the edge list
