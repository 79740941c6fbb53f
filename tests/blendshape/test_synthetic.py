"""Synthetic weight curves for the solver's benchmarks: the layered generator's guarantees."""
import numpy as np
import pytest

from usdface.blendshape.synthetic import layered_weight_curves


@pytest.mark.parametrize("layers,still,seed", [(3, 5, 0), (3, 5, 7), (4, 2, 1), (1, 1, 3)])
def test_layered_curves_keep_layers_active_after_a_still_start(layers, still, seed):
    w = layered_weight_curves(1800, 52, shapes=range(3, 40), layers=layers, still=still, seed=seed)
    active = (w > 0).sum(axis=1)
    assert (w[:still] == 0).all()
    assert active[still:].min() >= layers
    assert active.max() <= 2 * layers
    assert w.min() >= 0 and w.max() <= 1
    assert (w[:, :3] == 0).all() and (w[:, 40:] == 0).all()  # only the shapes offered
    # smooth: no step larger than a 2-frame raised-cosine ramp of amplitude 1 can make
    assert np.abs(np.diff(w, axis=0)).max() <= 1.0


def test_layered_curves_are_reproducible_and_refuse_impossible_pools():
    a = layered_weight_curves(600, 20, seed=5)
    assert np.array_equal(a, layered_weight_curves(600, 20, seed=5))
    assert not np.array_equal(a, layered_weight_curves(600, 20, seed=6))
    with pytest.raises(ValueError, match="cannot keep 3 layers"):
        layered_weight_curves(600, 6, layers=3)
