"""Neutral frame choice on a synthetic take (real Eyebrows take: test_conditioning_real.py)."""
from __future__ import annotations

import numpy as np
import pytest

from usdface.model.capture import Capture
from usdface.capture.neutral import choose_neutral, set_neutral
from usdface.errors import OptionError


def holds_take(rate=60.0, seed=0):
    """Neutral, a perfectly still held expression, neutral, another expression, neutral.

    The neutral stretches have a little breathing motion, so the calmest window is the first
    held expression.
    """
    rng = np.random.default_rng(seed)
    n_m = 12
    rest = rng.normal(size=(n_m, 3)) * 4
    expr1 = rng.normal(size=(n_m, 3)) * 0.5
    expr2 = -rng.normal(size=(n_m, 3)) * 0.5
    # segments (frames): neutral 60, ramp 30, hold 150, ramp 30, neutral 120, ramp 30, hold 90, ramp 30, neutral 60
    w1 = np.concatenate([np.zeros(60), np.linspace(0, 1, 30), np.ones(150), np.linspace(1, 0, 30), np.zeros(120),
                         np.zeros(30), np.zeros(90), np.zeros(30), np.zeros(60)])
    w2 = np.concatenate([np.zeros(60), np.zeros(30), np.zeros(150), np.zeros(30), np.zeros(120),
                         np.linspace(0, 1, 30), np.ones(90), np.linspace(1, 0, 30), np.zeros(60)])
    f = np.arange(w1.size)
    breathing = (w1 + w2 == 0)[:, None, None] * 0.03 * np.sin(f / 9.0)[:, None, None] * rng.normal(size=(1, n_m, 3))
    pos = rest[None] + w1[:, None, None] * expr1 + w2[:, None, None] * expr2 + breathing
    return Capture(names=[f"m{i}" for i in range(n_m)], positions=pos, rate=rate, units="cm"), w1, w2


def test_auto_neutral_is_not_the_calmest_hold():
    cap, w1, w2 = holds_take()
    frame, rep = choose_neutral(cap)
    assert w1[rep.calmest_frame] == 1.0  # the calmest window is the held expression
    assert w1[frame] == 0 and w2[frame] == 0  # the choice is a neutral frame
    assert rep.distance[frame] < rep.distance[rep.calmest_frame]
    assert rep.window == 30
    assert set(rep.summary()) >= {"frame", "calmest_frame", "speed", "distance_to_median"}


def test_set_neutral_by_index_and_auto():
    cap, w1, w2 = holds_take()
    out = set_neutral(cap, 5)
    assert out.neutral_frame == 5 and out.history[-1] == {"step": "set_neutral", "from": 0, "to": 5, "method": "index"}
    auto = set_neutral(cap, "auto", window=20)
    assert auto.history[-1]["method"] == "auto" and auto.history[-1]["window"] == 20
    assert w1[auto.neutral_frame] == 0 and w2[auto.neutral_frame] == 0
    assert set_neutral(cap, 7, how="auto").history[-1]["method"] == "auto"
    with pytest.raises(OptionError, match="outside"):
        set_neutral(cap, 10_000)
    with pytest.raises(OptionError, match="'auto'"):
        set_neutral(cap, "first")
    with pytest.raises(OptionError, match="only apply"):
        set_neutral(cap, 3, window=10)
    with pytest.raises(OptionError, match="window"):
        choose_neutral(cap, window=0)
