"""Marker-swap detection on synthetic tracks (real takes: test_conditioning_real.py)."""
from __future__ import annotations

import json

import numpy as np
import pytest

from usdface.model.capture import Capture
from usdface.capture.swaps import SwapEvent, default_min_jump, detect_swaps, fix_swaps
from usdface.errors import MarkerError, OptionError


def grid_capture(n_frames=200, seed=0):
    """Markers 2 cm apart moving smoothly (up to ~1 mm per frame) with 0.05 mm noise."""
    rng = np.random.default_rng(seed)
    base = np.array([[x, y, 0.0] for x in range(0, 8, 2) for y in range(0, 6, 2)])
    f = np.arange(n_frames)[:, None, None]
    motion = 0.4 * np.sin(f / 15.0 + rng.uniform(0, 6, (1, len(base), 3)))
    pos = base[None] + motion + rng.normal(scale=0.005, size=(n_frames, len(base), 3))
    return Capture(names=[f"m{i}" for i in range(len(base))], positions=pos, rate=60.0, units="cm")


def swapped(cap, a, b, start, stop=None):
    pos = cap.positions.copy()
    pos[start:stop, [a, b]] = pos[start:stop, [b, a]]
    return cap.replace(positions=pos)


def test_clean_tracks_have_no_swaps():
    cap = grid_capture()
    assert default_min_jump(cap) == pytest.approx(1.0, abs=0.05)
    assert detect_swaps(cap) == []


def test_swap_is_found_at_its_frame_and_fixed():
    cap = grid_capture()
    bad = swapped(cap, 2, 7, 80)
    events = detect_swaps(bad)
    assert [(e.frame, e.marker_a, e.marker_b) for e in events] == [(80, "m2", "m7")]
    fixed, ev = fix_swaps(bad)
    np.testing.assert_array_equal(fixed.positions, cap.positions)
    assert fixed.history[-1] == {"step": "fix_swaps", "events": [[80, "m2", "m7"]]}
    json.dumps(fixed.history[-1])
    assert json.loads(json.dumps(events[0].summary()))["frame"] == 80


def test_swap_and_swap_back_two_pairs_and_gaps():
    cap = grid_capture()
    pos = swapped(swapped(cap, 0, 1, 50, 120), 5, 9, 90).positions
    pos[10:20, 3] = np.nan  # gaps elsewhere do not create events
    pos[150, 4] = np.nan
    bad = cap.replace(positions=pos)
    events = detect_swaps(bad)
    assert [(e.frame, {e.marker_a, e.marker_b}) for e in events] == [
        (50, {"m0", "m1"}), (90, {"m5", "m9"}), (120, {"m0", "m1"})
    ]
    fixed, _ = fix_swaps(bad, events)
    ok = np.isfinite(pos)
    np.testing.assert_array_equal(fixed.positions[ok], cap.positions[ok])


def test_simultaneous_swaps_in_one_frame():
    cap = grid_capture()
    bad = swapped(swapped(cap, 0, 5, 60), 3, 10, 60)
    events = detect_swaps(bad)
    assert sorted((e.frame, e.marker_a, e.marker_b) for e in events) == [(60, "m0", "m5"), (60, "m3", "m10")]


def test_options_and_events_are_checked():
    cap = grid_capture()
    with pytest.raises(OptionError, match="min_jump"):
        detect_swaps(cap, min_jump=-1)
    with pytest.raises(OptionError, match="ratio"):
        detect_swaps(cap, ratio=2)
    with pytest.raises(MarkerError, match="'zz' not in capture"):
        fix_swaps(cap, [SwapEvent(3, "m0", "zz")])
    with pytest.raises(OptionError, match="outside"):
        fix_swaps(cap, [SwapEvent(999, "m0", "m1")])
