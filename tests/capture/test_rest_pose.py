"""The rest pose: a robust average over the still stretch around the neutral frame (issue 19, item 1)."""
import numpy as np
import pytest

from usdface.model.capture import Capture
from usdface.capture.neutral import (NEUTRAL_MOTION_WARN_CM, check_neutral_frames, parse_neutral, set_neutral,
                                     set_rest_pose)
from usdface.capture.rest import (HUBER_K, face_size, frame_deviation, robust_rest_pose, still_stretch,
                                  white_noise_level)
from usdface.errors import MarkerError, OptionError

NOISE = 0.03  # cm per coordinate (0.3 mm)


def _face(n_markers=41, seed=0):
    """Marker rest positions on a face-sized ellipsoid cap (cm)."""
    rng = np.random.default_rng(seed)
    u = rng.uniform(-1.2, 1.2, n_markers)
    v = rng.uniform(-1.0, 1.0, n_markers)
    return np.stack([7 * np.sin(u), 9 * v, 6 * np.cos(u) * np.cos(v / 2)], axis=1)


def _take(still=30, moving=60, seed=1, noise=NOISE, rate=60.0):
    """``still`` still frames, then a smooth expression ramping in on a third of the markers."""
    rng = np.random.default_rng(seed)
    rest = _face(seed=seed)
    f_n = still + moving
    ramp = np.zeros(f_n)
    t = np.arange(moving) / moving
    ramp[still:] = 0.5 - 0.5 * np.cos(np.pi * np.minimum(t * 2, 1))
    direction = np.zeros_like(rest)
    direction[: rest.shape[0] // 3] = rng.normal(0, 1, (rest.shape[0] // 3, 3))
    direction *= 1.0 / np.linalg.norm(direction[: rest.shape[0] // 3], axis=1).mean()  # 1 cm at full
    clean = rest[None] + ramp[:, None, None] * direction[None]
    return rest, clean, clean + rng.normal(0, noise, clean.shape), rate


# -- kernels ------------------------------------------------------------------------------------

def test_robust_average_bounds_an_outlier_sample_and_skips_invalid_ones():
    rng = np.random.default_rng(3)
    p = rng.normal(0.0, NOISE, (40, 5, 3))
    clean_rest, _ = robust_rest_pose(p)
    bad = p.copy()
    bad[7, 2] = (5.0, -5.0, 5.0)  # one sample 8.7 cm off
    bad[3:9, 4] = np.nan
    bad[:, 1] = np.nan
    rest, count = robust_rest_pose(bad)
    assert count.tolist() == [40, 0, 40, 40, 34]
    assert np.isnan(rest[1]).all() and np.isfinite(rest[[0, 2, 3, 4]]).all()
    # the outlier's pull is bounded by k * scale / N (Huber), far below the mean's 8.7/40 cm
    scale = 1.5 * NOISE  # generous bound on the robust per-coordinate scale
    assert np.linalg.norm(rest[2] - clean_rest[2]) < HUBER_K * scale / 40 * 1.5
    assert np.linalg.norm(np.nanmean(bad[:, 2], axis=0) - clean_rest[2]) > 0.2
    # Gaussian samples: close to the plain mean (efficiency)
    assert np.abs(rest[0] - p[:, 0].mean(axis=0)).max() < 0.3 * NOISE


def test_white_noise_level_is_measured_and_smooth_motion_does_not_count():
    _rest, clean, noisy, _rate = _take(still=200, moving=400)
    assert white_noise_level(noisy) == pytest.approx(NOISE, rel=0.06)
    assert white_noise_level(clean) < 0.05 * NOISE
    assert white_noise_level(noisy[:2]) == 0.0


def test_still_stretch_stops_where_the_expression_starts():
    rest, clean, noisy, rate = _take(still=30, moving=60)
    s = still_stretch(noisy, 0, rate=rate)
    true_motion = frame_deviation(clean, rest)
    assert s.start == 0 and 28 <= s.end <= 36  # the ramp starts at frame 30
    assert true_motion[s.end - 1] < 0.05  # every frame taken moves the markers < 0.5 mm RMS
    assert s.noise == pytest.approx(NOISE, rel=0.1)
    # grown from a seed in the middle of the still frames, the same stretch
    mid = still_stretch(noisy, 15, rate=rate)
    assert (mid.start, mid.end) == (s.start, s.end)
    # a glitching frame (every marker jumps 1 cm for one frame) does not cut it
    glitch = noisy.copy()
    glitch[12] += 1.0
    assert still_stretch(glitch, 0, rate=rate).end >= s.end - 1
    # noise-free data: the still frames and those moving less than the floor (0.1% of the face size,
    # 3 spreads: 0.2 mm here)
    exact = still_stretch(clean, 0, rate=rate)
    assert exact.threshold == pytest.approx(3e-3 * exact.face_size, rel=0.01)
    assert exact.start == 0 and exact.end >= 30
    assert true_motion[exact.end - 1] <= exact.threshold < true_motion[exact.end]


def test_the_rest_pose_is_nearer_the_truth_than_any_one_frame():
    rest, _clean, noisy, rate = _take(still=30, moving=60, seed=4)
    cap = Capture(tuple(f"m{i}" for i in range(rest.shape[0])), noisy, rate, units="cm")
    out, report = set_rest_pose(cap)
    assert report.how == "first" and report.start == 0 and report.end >= 28
    one = np.sqrt(((noisy[0] - rest) ** 2).sum(axis=1).mean())
    robust = np.sqrt(((out.neutral - rest) ** 2).sum(axis=1).mean())
    assert one == pytest.approx(np.sqrt(3) * NOISE, rel=0.2)
    assert robust < one / 4  # ~ 1 / sqrt(30)
    assert report.motion_rms == pytest.approx(np.sqrt(3) * NOISE, rel=0.15)
    assert not report.warnings
    assert out.neutral_frames == (report.start, report.end) and out.neutral_frame == 0
    assert out.history[-1]["step"] == "rest_pose" and out.history[-1]["frames"] == [0, report.end - 1]
    assert face_size(rest) > 5.0


# -- the option ------------------------------------------------------------------------------------

@pytest.mark.parametrize("value,want", [(None, None), ("auto", "auto"), ("12", 12), (7, 7), ("3:40", (3, 40)),
                                        (" 0 : 5 ", (0, 5)), ((2, 9), (2, 9))])
def test_parse_neutral(value, want):
    assert parse_neutral(value) == want


@pytest.mark.parametrize("value", ["-1", "a", "1:2:3", "5:5", "9:3", "", "1.5", ":4", True])
def test_parse_neutral_refuses(value):
    with pytest.raises(OptionError, match=r"^--neutral .*: expected a frame index F, a range START:END \(0-based frame "
                                          r"indices, END exclusive\) or auto") as e:
        parse_neutral(value)
    assert e.value.exit_code == 2


def test_frames_outside_the_take_are_refused_naming_the_range():
    with pytest.raises(OptionError) as e:
        check_neutral_frames((10, 2000), 902, source="EyebrowsMoCap.ma")
    assert str(e.value) == ("--neutral 10:2000: frames 10-1999 are outside the take of EyebrowsMoCap.ma, which has "
                            "frames 0-901 (expected 0 <= START < END <= 902; 0-based, END exclusive, after --trim)")
    assert e.value.exit_code == 2
    with pytest.raises(OptionError) as e:
        check_neutral_frames(902, 902)
    assert str(e.value) == "--neutral 902: frame 902 is outside the take, which has frames 0-901 (0-based, after --trim)"
    check_neutral_frames((0, 902), 902)
    check_neutral_frames("auto", 3)
    rest, _clean, noisy, rate = _take()
    cap = Capture(tuple(f"m{i}" for i in range(rest.shape[0])), noisy, rate, units="cm", source="t.c3d")
    with pytest.raises(OptionError, match=r"^--neutral 95: frame 95 is outside the take of t.c3d, which has frames 0-89"):
        set_rest_pose(cap, "95")


def test_a_named_range_where_the_face_moves_warns_with_the_motion_in_cm():
    rest, _clean, noisy, rate = _take(still=30, moving=60)
    cap = Capture(tuple(f"m{i}" for i in range(rest.shape[0])), noisy * 10.0, rate, units="mm", source="t.c3d")
    out, report = set_rest_pose(cap, "20:80")
    assert (report.how, report.start, report.end, report.frame) == ("range", 20, 80, 49)
    assert out.neutral_frames == (20, 80)
    rms_cm = report.motion_rms / 10.0
    assert rms_cm > NEUTRAL_MOTION_WARN_CM
    assert report.warnings == (
        f"capture t.c3d: the face moves over the neutral stretch (frames 20-79): markers {rms_cm:.3f} cm RMS from the "
        f"rest pose ({report.motion_max / 10:.3f} cm at most), more than {NEUTRAL_MOTION_WARN_CM:g} cm; name still "
        "frames with --neutral START:END",)
    assert report.summary()["motionRmsCm"] == pytest.approx(rms_cm, abs=1e-5)
    # a named still range: no warning; a single frame: the frame itself
    assert not set_rest_pose(cap, "0:25")[1].warnings
    one, rep1 = set_rest_pose(cap, "4:5")
    assert np.array_equal(one.neutral, cap.positions[4]) and rep1.motion_rms == 0.0


# -- the capture carries it ---------------------------------------------------------------------------

def test_window_is_checked_and_follows_trim_resample_and_a_new_neutral_frame():
    from usdface.capture.timing import resample, trim

    rest, _clean, noisy, rate = _take()
    names = tuple(f"m{i}" for i in range(rest.shape[0]))
    with pytest.raises(MarkerError, match=r"neutral window \[5, 9\) must hold the neutral frame 2"):
        Capture(names, noisy, rate, neutral_frame=2, neutral_window=(5, 9))
    cap = Capture(names, noisy, rate, neutral_frame=4, neutral_window=(0, 20))
    assert cap.describe_neutral() == "neutral frames 0-19"
    with pytest.raises(ValueError):
        cap.neutral[0, 0] = 1.0  # read-only: consumers share it
    t = trim(cap, start=3, end=60)
    assert t.neutral_frames == (0, 17) and t.neutral_frame == 1
    assert np.allclose(t.neutral, robust_rest_pose(noisy[3:20])[0])
    r = resample(cap, rate=120.0)
    assert r.neutral_frames == (0, 39) and r.neutral_frame == 8
    assert set_neutral(cap, 30).neutral_window is None


def test_displacements_and_head_motion_are_taken_from_the_rest_pose():
    from scipy.spatial.transform import Rotation

    from usdface.capture.retarget import marker_displacements, mesh_head_motion
    from usdface.capture.rigid import to_matrix

    rest, _clean, noisy, rate = _take(seed=6)
    names = tuple(f"m{i}" for i in range(rest.shape[0]))
    hm = np.tile(np.eye(4), (noisy.shape[0], 1, 1))
    angles = np.linspace(0, 4, noisy.shape[0])
    hm[:] = to_matrix(Rotation.from_euler("y", angles[:, None], degrees=True).as_matrix(), 1.0, np.zeros((noisy.shape[0], 3)))
    cap, _ = set_rest_pose(Capture(names, noisy, rate, units="cm", head_motion=hm))
    d = marker_displacements(cap, names[::-1], np.eye(3))
    assert np.allclose(d, (noisy - cap.neutral[None])[:, ::-1])
    # the head motion stays relative to the neutral frame, the pose the conditioning stabilises on
    # (the shot places the markers with the binding alone: another reference moves the face off them)
    h = mesh_head_motion(cap, np.eye(4))
    n = cap.neutral_frame
    assert np.allclose(h[n], np.eye(4), atol=1e-12)
    assert np.allclose(h[-1, :3, :3], hm[n, :3, :3].T @ hm[-1, :3, :3], atol=1e-12)
    # a marker with no valid sample over the stretch is named with the stretch
    gap = noisy.copy()
    gap[:40, 5] = np.nan
    cap2 = Capture(names, gap, rate, units="cm", neutral_window=(0, 20), source="t.trc")
    with pytest.raises(MarkerError, match=r"marker\(s\) m5 invalid at the neutral frames 0-19"):
        marker_displacements(cap2, names, np.eye(3))


def test_a_range_named_before_resampling_and_stabilising_is_kept():
    """How the conditioning runs it: the range is set on the capture first, resampling and
    stabilisation carry it, the rest pose is then taken over it (no growing)."""
    from usdface.capture.stabilize import stabilize
    from usdface.capture.timing import resample

    rest, _clean, noisy, rate = _take(still=30, moving=60)
    names = tuple(f"m{i}" for i in range(rest.shape[0]))
    cap = set_neutral(Capture(names, noisy, rate, units="cm"), 5).replace(neutral_window=(2, 9))
    cap = stabilize(resample(cap, rate=120.0))[0]
    assert cap.neutral_frames == (4, 17)
    out, report = set_rest_pose(cap, how="frame")
    assert (report.how, report.start, report.end, report.threshold) == ("frame", 4, 17, None)
    assert out.neutral_frames == (4, 17) and out.neutral_frame == cap.neutral_frame
    # without a window: grown around the neutral frame, labelled as the caller says
    grown = set_rest_pose(set_neutral(cap, 10), how="auto")[1]
    assert grown.how == "auto" and grown.start == 0 and grown.end > 17 and grown.threshold is not None


def test_robust_rest_pose_is_the_huber_estimate_of_a_slow_reference():
    """Against a slow reference: per marker, scipy minimises the Huber loss of the sample distances
    at a fixed scale, and the scale (median distance / median |n| of a 3D normal) is re-measured
    around the minimiser until both stop moving: the M-estimate the fast reweighted average reaches."""
    from scipy.optimize import minimize

    from usdface.model.rest import _MEDIAN_CHI3

    rng = np.random.default_rng(11)
    p = rng.normal(0.0, NOISE, (30, 4, 3))
    p[[2, 9, 17], 1] += (0.6, -0.4, 0.5)  # outlying samples on one marker
    p[5:12, 3] = np.nan
    fast, _ = robust_rest_pose(p, iterations=60)

    def huber(mu, x, s):
        r = np.linalg.norm(x - mu, axis=1) / s
        return np.where(r <= HUBER_K, 0.5 * r ** 2, HUBER_K * r - 0.5 * HUBER_K ** 2).sum()

    for m in range(p.shape[1]):
        x = p[:, m][np.isfinite(p[:, m]).all(axis=1)]
        mu = np.median(x, axis=0)
        for _ in range(50):
            s = np.median(np.linalg.norm(x - mu, axis=1)) / _MEDIAN_CHI3
            new = minimize(huber, mu, args=(x, s), method="Nelder-Mead",
                           options={"xatol": 1e-12, "fatol": 1e-14, "maxiter": 20000}).x
            if np.abs(new - mu).max() < 1e-11:
                break
            mu = new
        np.testing.assert_allclose(fast[m], mu, atol=1e-8)


def test_the_running_median_equals_scipys_median_filter():
    """still_stretch's 3-sample running median (ends repeated) is scipy.ndimage's median_filter,
    without importing scipy.ndimage at every command's start."""
    from scipy.ndimage import median_filter

    from usdface.capture.rest import _median_of_3

    rng = np.random.default_rng(5)
    for n in (3, 4, 11, 500):
        x = rng.normal(size=n)
        x[rng.integers(0, n, 2)] = np.inf  # frames without markers count as never still
        np.testing.assert_array_equal(_median_of_3(x), median_filter(x, size=3, mode="nearest"))
