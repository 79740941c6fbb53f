"""Gap filling on synthetic captures (real takes: test_conditioning_real.py)."""
from __future__ import annotations

import json

import numpy as np
import pytest

from usdface.capture.gaps import fill_gaps, find_gaps
from usdface.model.capture import Capture
from usdface.errors import OptionError


def correlated(n_frames=600, n_markers=10, seed=0, noise=1e-3):
    """Markers driven by 3 smooth latent signals (like facial actions), plus a little noise."""
    rng = np.random.default_rng(seed)
    f = np.arange(n_frames)
    latent = np.c_[np.sin(f / 23.0), np.sin(f / 41.0 + 1) ** 3, np.cos(f / 17.0)]
    mix = rng.normal(size=(3, n_markers, 3)) * 0.5
    rest = rng.normal(size=(n_markers, 3)) * 4
    pos = rest[None] + np.einsum("fl,lmk->fmk", latent, mix) + rng.normal(scale=noise, size=(n_frames, n_markers, 3))
    return Capture(names=[f"M{i}" for i in range(n_markers)], positions=pos, rate=60.0, units="cm")


def with_gaps(cap, gaps):
    pos = cap.positions.copy()
    for m, a, b in gaps:
        pos[a:b, m] = np.nan
    return cap.replace(positions=pos)


def rms(a, b):
    return float(np.sqrt(((a - b) ** 2).sum(-1).mean()))


def test_find_gaps_matches_a_slow_loop():
    rng = np.random.default_rng(3)
    valid = rng.random((50, 4)) > 0.3
    valid[:, 2] = True
    valid[:, 3] = False
    slow = []
    for m in range(4):
        f = 0
        while f < 50:
            if not valid[f, m]:
                g = f
                while g < 50 and not valid[g, m]:
                    g += 1
                slow.append((m, f, g))
                f = g
            else:
                f += 1
    assert find_gaps(valid) == slow


def test_linear_fill_is_exact_on_straight_motion_and_continuous():
    f = np.arange(100, dtype=float)
    pos = np.stack([np.c_[f, 2 * f, -f] * 0.01 + i for i in range(4)], axis=1)
    cap = with_gaps(Capture(names=list("abcd"), positions=pos, rate=30), [(1, 20, 45)])
    out, rep = fill_gaps(cap, method="linear")
    np.testing.assert_allclose(out.positions, pos, atol=1e-12)
    assert [(g.marker, g.start, g.stop, g.method) for g in rep.filled] == [("b", 20, 45, "linear")]


def test_regression_beats_linear_on_correlated_markers():
    cap = correlated()
    gaps = [(2, 100, 160), (5, 300, 330), (7, 420, 430), (0, 50, 110)]
    holed = with_gaps(cap, gaps)
    before = holed.positions.copy()
    lin, _ = fill_gaps(holed, method="linear", max_gap=60)
    reg, rep = fill_gaps(holed, method="regression", max_gap=60)
    np.testing.assert_array_equal(holed.positions, before)  # input untouched
    assert all(g.method == "regression" and len(g.neighbors) >= 1 for g in rep.filled)
    for m, a, b in gaps:
        e_lin = rms(lin.positions[a:b, m], cap.positions[a:b, m])
        e_reg = rms(reg.positions[a:b, m], cap.positions[a:b, m])
        assert e_reg < 0.2 * e_lin, (m, a, b, e_reg, e_lin)
    # the fill meets the valid samples at both ends: no jump larger than the motion per frame
    for m, a, b in gaps:
        steps = np.linalg.norm(np.diff(reg.positions[a - 1:b + 1, m], axis=0), axis=1)
        natural = np.linalg.norm(np.diff(cap.positions[a - 1:b + 1, m], axis=0), axis=1)
        assert steps.max() < 1.5 * natural.max() + 1e-3
    assert not np.isnan(reg.positions).any()
    step = reg.history[-1]
    assert step["step"] == "fill_gaps" and step["method"] == "regression" and step["filled_gaps"] == 4
    json.dumps(step)
    json.dumps(rep.summary())


def test_long_gaps_and_dead_markers_stay_invalid_and_are_reported():
    cap = correlated(n_frames=200)
    pos = cap.positions.copy()
    pos[:, 9] = np.nan
    holed = with_gaps(cap.replace(positions=pos), [(1, 10, 20), (2, 50, 131)])
    out, rep = fill_gaps(holed, max_gap=80)
    assert np.isnan(out.positions[50:131, 2]).all() and np.isnan(out.positions[:, 9]).all()
    assert not np.isnan(out.positions[10:20, 1]).any()
    assert sorted((g.marker, g.method) for g in rep.unfilled) == [("M2", "too_long"), ("M9", "no_data")]
    assert rep.n_unfilled_samples == 81 + 200 and rep.n_filled_samples == 10


def test_edge_gaps_hold_for_linear_and_predict_for_regression():
    cap = correlated()
    gaps = [(3, 0, 40), (4, 570, 600)]
    holed = with_gaps(cap, gaps)
    lin, rep_lin = fill_gaps(holed, method="linear", max_gap=60)
    assert [g.method for g in rep_lin.filled] == ["hold", "hold"]
    np.testing.assert_array_equal(lin.positions[0:40, 3], np.repeat(cap.positions[40:41, 3], 40, axis=0))
    np.testing.assert_array_equal(lin.positions[570:600, 4], np.repeat(cap.positions[569:570, 4], 30, axis=0))
    reg, rep_reg = fill_gaps(holed, method="regression", max_gap=60)
    assert [g.method for g in rep_reg.filled] == ["regression", "regression"]
    for m, a, b in gaps:
        e_hold = rms(lin.positions[a:b, m], cap.positions[a:b, m])
        e_reg = rms(reg.positions[a:b, m], cap.positions[a:b, m])
        assert e_reg < 0.3 * e_hold, (m, e_reg, e_hold)
    # continuous at the one boundary: the step there is like the true motion per frame
    for m, f in ((3, 39), (4, 569)):
        step = np.linalg.norm(reg.positions[f + 1, m] - reg.positions[f, m])
        true = np.linalg.norm(cap.positions[f + 1, m] - cap.positions[f, m])
        assert abs(step - true) < 0.01, (m, step, true)


def test_regression_falls_back_to_linear_without_usable_neighbours():
    cap = correlated(n_markers=3, n_frames=120)
    holed = with_gaps(cap, [(0, 30, 40), (1, 35, 45), (2, 38, 50)])  # overlapping gaps
    out, rep = fill_gaps(holed)
    methods = {g.marker: g.method for g in rep.filled}
    assert methods == {"M0": "linear", "M1": "linear", "M2": "linear"}
    assert not np.isnan(out.positions).any()


def test_bad_options():
    cap = correlated(n_frames=50)
    with pytest.raises(OptionError, match="method"):
        fill_gaps(cap, method="spline")
    with pytest.raises(OptionError, match="max_gap"):
        fill_gaps(cap, max_gap=0)
    with pytest.raises(OptionError, match="neighbors"):
        fill_gaps(cap, neighbors=1.5)
    with pytest.raises(OptionError, match="ridge"):
        fill_gaps(cap, ridge=-1)
