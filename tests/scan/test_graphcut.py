"""Graph-cut stereo kernels: census, alpha-expansion (against exhaustive search), occlusions."""
import itertools

import numpy as np
import pytest

from usdface.scan.graphcut import (alpha_expansion, census_transform, labelling_energy, matching_cost,
                                   subpixel_refine, uniqueness_occlusions)


def test_census_bits():
    g = np.array([[1, 2, 3], [4, 5, 6], [7, 8, 9]], dtype=np.float32)
    c = census_transform(g, radius=1)
    # centre 5: neighbours darker are 1, 2, 3, 4 -> the first four bits (row-major order)
    assert int(c[1, 1]) == 0b00001111


def test_matching_cost_finds_a_shift():
    rng = np.random.default_rng(1)
    right = rng.integers(0, 255, (40, 80)).astype(np.uint8)
    left = np.roll(right, 7, axis=1)  # a scene point at x in left is at x - 7 in right
    cost = matching_cost(left, right, num_disparities=16, window=3)
    wta = cost.argmin(axis=2)
    assert (wta[:, 20:] == 7).mean() > 0.99


def _brute_force(cost, wh, wv, lam, trunc):
    h, w, n = cost.shape
    best = (np.inf, None)
    for labels in itertools.product(range(n), repeat=h * w):
        f = np.array(labels).reshape(h, w)
        e = labelling_energy(f, cost, wh, wv, smoothness=lam, truncation=trunc)
        if e < best[0]:
            best = (e, f)
    return best


@pytest.mark.parametrize("trunc", [1.0, 2.0])
def test_alpha_expansion_near_global_optimum(trunc):
    rng = np.random.default_rng(3)
    cost = rng.uniform(0, 1, (2, 4, 3)).astype(np.float32)
    wh = np.ones((2, 3), np.float32)
    wv = np.ones((1, 4), np.float32)
    lam = 0.4
    e_opt, _ = _brute_force(cost, wh, wv, lam, trunc)
    f, info = alpha_expansion(cost, wh=wh, wv=wv, smoothness=lam, truncation=trunc, max_cycles=5, candidates=0)
    e = labelling_energy(f, cost, wh, wv, smoothness=lam, truncation=trunc)
    assert np.all(np.diff(info["energy"]) <= 1e-9)  # monotone
    # Boykov-Veksler-Zabih: within 2 max(V)/min(V) of the optimum (Potts: 2); here it is exact or close
    assert e <= 2 * e_opt + 1e-9
    assert e <= info["energy"][0] + 1e-9


def test_restricted_moves_still_decrease_energy():
    rng = np.random.default_rng(4)
    cost = rng.uniform(0, 1, (12, 15, 8)).astype(np.float32)
    f, info = alpha_expansion(cost, smoothness=0.3, truncation=2, max_cycles=3, candidates=3)
    assert np.all(np.diff(info["energy"]) <= 1e-6)
    assert info["energy"][-1] < info["energy"][0]


def test_subpixel_and_uniqueness():
    c = np.zeros((1, 1, 5), np.float32)
    c[0, 0] = [4, 1, 0.25, 1, 4]  # symmetric parabola-like around 2 -> 2.0
    assert subpixel_refine(np.array([[2]]), c)[0, 0] == pytest.approx(2.0)
    c[0, 0] = [4, 1, 0.5, 0, 1]
    assert 2.5 <= subpixel_refine(np.array([[3]]), c)[0, 0] + 0 <= 3.5
    # background (d 1) with a foreground patch (d 3) at x 4, 5: right columns 1, 2 show the
    # foreground, so the background pixels x 2, 3 that map there are hidden in the right view
    d = np.array([[1.0, 1.0, 1.0, 1.0, 3.0, 3.0, 1.0, 1.0]])
    assert uniqueness_occlusions(d)[0].tolist() == [False, False, True, True, False, False, False, False]
