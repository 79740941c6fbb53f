"""Trim, offset and resample."""
from __future__ import annotations

import json

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from usdface.model.capture import Capture
from usdface.capture.rigid import rotation_angle, to_matrix
from usdface.capture.timing import offset, resample, trim
from usdface.errors import OptionError


def sine_capture(n_frames=121, rate=60.0, start_frame=10, neutral=0):
    t = (start_frame + np.arange(n_frames)) / rate
    pos = np.stack([np.c_[np.sin(2 * np.pi * 1.0 * t), np.cos(2 * np.pi * 0.5 * t), t] + m for m in range(3)], axis=1)
    return Capture(names=["a", "b", "c"], positions=pos, rate=rate, units="cm", start_frame=start_frame, neutral_frame=neutral)


def test_trim_is_half_open_and_keeps_time_codes():
    cap = sine_capture(neutral=20)
    out = trim(cap, start=10, end=50)
    assert out.n_frames == 40 and out.start_frame == 20 and out.neutral_frame == 10
    np.testing.assert_array_equal(out.times, cap.times[10:50])
    np.testing.assert_array_equal(out.positions, cap.positions[10:50])
    assert out.history[-1] == {"step": "trim", "start": 10, "end": 50, "start_frame": 20}
    assert trim(cap, end=30).n_frames == 30 and trim(cap, start=5).n_frames == cap.n_frames - 5


def test_trim_errors():
    cap = sine_capture(neutral=20)
    with pytest.raises(OptionError, match="neutral frame"):
        trim(cap, start=21)
    with pytest.raises(OptionError, match="start < end"):
        trim(cap, start=30, end=30)
    with pytest.raises(OptionError, match="start < end"):
        trim(cap, start=0, end=1000)
    with pytest.raises(OptionError, match="integer"):
        trim(cap, start=1.5)


def test_trim_slices_head_motion():
    cap = sine_capture()
    hm = to_matrix(np.repeat(np.eye(3)[None], cap.n_frames, 0), 1.0, np.arange(cap.n_frames)[:, None] * [1.0, 0, 0])
    out = trim(cap.replace(head_motion=hm, neutral_frame=4), start=3, end=8)
    np.testing.assert_array_equal(out.head_motion, hm[3:8])


def test_offset():
    cap = sine_capture()
    out = offset(cap, start_frame=-5)
    assert out.start_frame == -5 and out.times[0] == -5
    np.testing.assert_array_equal(out.positions, cap.positions)
    assert out.history[-1] == {"step": "offset", "from": 10, "to": -5}
    with pytest.raises(OptionError):
        offset(cap, start_frame=1.5)


@pytest.mark.parametrize("method", ["cubic", "linear"])
def test_downsampling_keeps_the_samples_on_the_coarser_grid(method):
    cap = sine_capture(n_frames=121, start_frame=10)  # time codes 10..130 at 60 Hz
    out = resample(cap, rate=30.0, method=method)
    assert out.rate == 30.0 and out.start_frame == 5 and out.n_frames == 61
    np.testing.assert_allclose(out.positions, cap.positions[::2], atol=1e-12)
    step = out.history[-1]
    assert step["step"] == "resample" and step["from_rate"] == 60.0 and step["rate"] == 30.0
    json.dumps(step)


def test_upsampling_cubic_is_accurate_and_better_than_linear():
    cap = sine_capture(n_frames=61, rate=30.0, start_frame=0)
    cub = resample(cap, rate=120.0, method="cubic")
    lin = resample(cap, rate=120.0, method="linear")
    assert cub.n_frames == 241 and cub.start_frame == 0
    t = cub.times / 120.0
    truth = np.c_[np.sin(2 * np.pi * t), np.cos(np.pi * t), t]
    err_c = np.abs(cub.positions[:, 0] - truth).max()
    err_l = np.abs(lin.positions[:, 0] - truth).max()
    assert err_c < 1e-3 and err_c < 0.2 * err_l


def test_resampling_never_bridges_invalid_spans_and_moves_the_neutral_frame():
    cap = sine_capture(n_frames=121, start_frame=0, neutral=61)
    pos = cap.positions.copy()
    pos[40:45, 1] = np.nan
    pos[100, 2] = np.nan
    cap = cap.replace(positions=pos)
    out = resample(cap, rate=25.0)  # 60 -> 25 Hz: new frame k at old index 2.4 k
    u = np.arange(out.n_frames) * 2.4
    valid = out.valid
    # marker 1: invalid exactly when the new time falls strictly between old frames 39 and 45
    expect_b = ~((u > 39) & (u < 45))
    np.testing.assert_array_equal(valid[:, 1], expect_b)
    expect_c = ~((u > 99) & (u < 101))
    np.testing.assert_array_equal(valid[:, 2], expect_c)
    assert valid[:, 0].all()
    assert out.neutral_frame == int(np.argmin(np.abs(u - 61)))


def test_head_motion_rotations_are_slerped():
    n = 11
    cap = sine_capture(n_frames=n, rate=10.0, start_frame=0)
    angles = np.radians(np.linspace(0, 40, n))
    rots = Rotation.from_rotvec(np.c_[0 * angles, angles, 0 * angles]).as_matrix()
    hm = to_matrix(rots, 1.0, np.c_[np.linspace(0, 1, n), np.zeros(n), np.zeros(n)])
    cap = cap.replace(head_motion=hm)
    for method in ("linear", "cubic"):
        out = resample(cap, rate=40.0, method=method)
        r = out.head_motion[:, :3, :3]
        np.testing.assert_allclose(np.einsum("fij,fkj->fik", r, r), np.broadcast_to(np.eye(3), r.shape), atol=1e-12)
        # constant-speed rotation about one axis: the angle at every new frame is exact
        expect = np.linspace(0, 40, out.n_frames)
        np.testing.assert_allclose(rotation_angle(r), expect, atol=1e-6)
        np.testing.assert_allclose(out.head_motion[:, 0, 3], np.linspace(0, 1, out.n_frames), atol=1e-9)
        np.testing.assert_allclose(out.world_positions()[::4], cap.world_positions(), atol=1e-9)


def test_resample_errors():
    cap = sine_capture()
    with pytest.raises(OptionError, match="rate"):
        resample(cap, rate=0)
    with pytest.raises(OptionError, match="method"):
        resample(cap, rate=30.0, method="quintic")
    one = Capture(names=["a"], positions=np.zeros((1, 1, 3)), rate=60.0, start_frame=1)
    with pytest.raises(OptionError, match="no frame"):
        resample(one, rate=25.0)
