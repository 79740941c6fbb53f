"""Zero-phase noise filtering."""
from __future__ import annotations

import json

import numpy as np
import pytest

from usdface.capture.filtering import filter_array, filter_noise
from usdface.model.capture import Capture
from usdface.errors import OptionError

RATE = 60.0


def noisy_sines(n_frames=600, seed=0, noise=0.05):
    rng = np.random.default_rng(seed)
    t = np.arange(n_frames) / RATE
    freqs = np.array([0.7, 1.5, 2.5])  # Hz, one per axis
    clean = np.stack([np.sin(2 * np.pi * freqs[None, :] * t[:, None] + m) for m in range(4)], axis=1)
    return clean, clean + rng.normal(scale=noise, size=clean.shape)


def _lag(a, b, max_lag=8):
    """Lag (frames) maximising the correlation of a against b."""
    lags = np.arange(-max_lag, max_lag + 1)
    n = len(a)
    c = [np.dot(a[max_lag + k:n - max_lag + k], b[max_lag:n - max_lag]) for k in lags]
    return int(lags[int(np.argmax(c))])


@pytest.mark.parametrize("options", [dict(method="butterworth", cutoff_hz=6.0), dict(method="savgol", window=15, order=3)])
def test_noise_is_removed_without_phase_lag(options):
    clean, noisy = noisy_sines()
    cap = Capture(names=list("abcd"), positions=noisy, rate=RATE, units="cm")
    out = filter_noise(cap, **options)
    np.testing.assert_array_equal(cap.positions, noisy)  # input untouched
    inner = slice(30, -30)
    err_before = np.sqrt(((noisy - clean)[inner] ** 2).mean())
    err_after = np.sqrt(((out.positions - clean)[inner] ** 2).mean())
    assert err_after < 0.6 * err_before, (err_after, err_before)  # white noise, ~1/4 of the band kept
    for m in range(4):
        for k in range(3):
            assert _lag(out.positions[:, m, k], clean[:, m, k]) == 0
    # phase of the fitted sinusoid: zero-phase filtering keeps it (a causal filter would not)
    t = np.arange(len(clean)) / RATE
    w = 2 * np.pi * 2.5
    basis = np.c_[np.sin(w * t), np.cos(w * t)]
    coef = np.linalg.lstsq(basis[inner], out.positions[inner, 0, 2], rcond=None)[0]
    assert abs(np.arctan2(coef[1], coef[0])) < 0.02
    step = out.history[-1]
    assert step["step"] == "filter_noise" and step["method"] == options["method"]
    json.dumps(step)


def test_invalid_samples_never_spread_and_short_runs_are_kept():
    clean, noisy = noisy_sines()
    pos = noisy.copy()
    pos[100:110, 0] = np.nan  # gap splits marker 0 into two long runs
    pos[300, 1, 2] = np.nan  # one coordinate invalid -> whole sample invalid
    pos[:200, 2] = np.nan
    pos[205:, 2] = np.nan  # marker 2: a 5-frame run, too short to filter
    cap = Capture(names=list("abcd"), positions=pos, rate=RATE)
    out = filter_noise(cap, cutoff_hz=6.0)
    invalid = ~np.isfinite(pos).all(axis=2)
    assert np.array_equal(~np.isfinite(out.positions).all(axis=2), invalid)
    assert np.isnan(out.positions[invalid]).all()
    np.testing.assert_array_equal(out.positions[200:205, 2], pos[200:205, 2])
    assert out.history[-1]["short_runs"] == 1
    # each run is filtered on its own: the run before a gap is the same as filtering it alone
    alone, _, _ = filter_array(noisy[:100, :1], rate=RATE, cutoff_hz=6.0)
    np.testing.assert_allclose(out.positions[:100, :1], alone, atol=1e-12)
    # filtered samples actually changed, towards the clean signal
    assert np.abs(out.positions[120:290, 0] - clean[120:290, 0]).mean() < np.abs(pos[120:290, 0] - clean[120:290, 0]).mean()


def test_bad_options_are_named():
    cap = Capture(names=["a"], positions=np.zeros((50, 1, 3)), rate=RATE)
    with pytest.raises(OptionError, match="Nyquist"):
        filter_noise(cap, cutoff_hz=30.0)
    with pytest.raises(OptionError, match="cutoff_hz"):
        filter_noise(cap, cutoff_hz="fast")
    with pytest.raises(OptionError, match="odd"):
        filter_noise(cap, method="savgol", window=10)
    with pytest.raises(OptionError, match="smaller than window"):
        filter_noise(cap, method="savgol", window=5, order=5)
    with pytest.raises(OptionError, match="butterworth filter only"):
        filter_noise(cap, method="savgol", cutoff_hz=5.0)
    with pytest.raises(OptionError, match="unknown filter"):
        filter_noise(cap, method="kalman")
