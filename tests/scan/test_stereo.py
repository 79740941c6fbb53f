"""Disparity maps: the real Middlebury pair (crops) and rendered faces with exact depth."""
import numpy as np
import pytest

from usdface.errors import InputError, OptionError
from usdface.scan.calibration import calibration_from_dict
from usdface.scan.graphcut import GraphCutParameters
from usdface.scan.stereo import MatchingParameters, bad_pixel_rate, check_rectified, compute_disparity, disparity_range

CROP = (slice(120, 300), slice(180, 460))  # 280 x 180, disparities 7-60 inside


@pytest.fixture(scope="module")
def moto(shared_data):
    import cv2

    d = shared_data / "images" / "stereo"
    left = cv2.imread(str(d / "motorcycle_left.png"))
    right = cv2.imread(str(d / "motorcycle_right.png"))
    gt = np.load(d / "motorcycle_disp.npz")["arr_0"]
    return left, right, gt


def test_bad_pixel_rate_definition():
    gt = np.array([[10.0, 10.0, np.inf, 10.0]])
    d = np.array([[10.5, 13.0, 0.0, np.nan]])
    r = bad_pixel_rate(d, gt)
    assert r["pixels"] == 3
    assert r["bad"] == pytest.approx(2 / 3)  # one wrong, one missing
    assert r["bad_known"] == pytest.approx(1 / 2)
    assert r["density"] == pytest.approx(2 / 3)


def test_graphcut_beats_sgbm_on_middlebury_crop(moto):
    left, right, gt = moto
    L, R, G = left[CROP], right[CROP], gt[CROP]
    sgbm = compute_disparity(L, R, MatchingParameters(method="sgbm", num_disparities=64, min_texture=0))
    wls = compute_disparity(L, R, MatchingParameters(method="sgbm-wls", num_disparities=64, min_texture=0))
    gc = compute_disparity(L, R, MatchingParameters(method="graphcut", num_disparities=64, min_texture=0,
                                                    graphcut=GraphCutParameters(max_cycles=1)))
    b_sgbm = bad_pixel_rate(sgbm.disparity, G)["bad"]
    b_wls = bad_pixel_rate(wls.disparity, G)["bad"]
    b_gc = bad_pixel_rate(gc.disparity, G)["bad"]
    assert b_gc < b_sgbm
    assert b_gc < 0.25 and b_wls < 0.35
    assert gc.valid.mean() > 0.7 and wls.valid.mean() > 0.6 and sgbm.valid.mean() > 0.65


def _plain_opencv_sgbm(left, right):
    """The fixed baseline: cv2.StereoSGBM with 64 disparities, block 5, its other defaults."""
    import cv2

    raw = cv2.StereoSGBM_create(minDisparity=0, numDisparities=64, blockSize=5).compute(left, right)
    d = raw.astype(np.float32) / 16
    d[raw < 0] = np.nan
    return d


def test_cli_default_beats_plain_opencv_sgbm_on_the_motorcycle(moto, shared_data, tmp_path, capsys):
    """`usdface stereo L R --ground-truth GT` prints the score; its default beats the baseline."""
    from usdface.cli import main
    from usdface.io.images import read_float_map

    left, right, gt = moto
    d = shared_data / "images" / "stereo"
    plain = bad_pixel_rate(_plain_opencv_sgbm(left, right), gt)["bad"]
    assert plain == pytest.approx(0.205, abs=0.002)
    out = tmp_path / "disp.pfm"
    assert main([
        "stereo", str(d / "motorcycle_left.png"), str(d / "motorcycle_right.png"),
        "--ground-truth", str(d / "motorcycle_disp.npz"), "--disparity", str(out), "--json"]) == 0
    import json

    summary = json.loads(capsys.readouterr().out)
    score = summary["groundTruth"]
    assert score["pixels"] == int(np.isfinite(gt).sum())
    assert score["bad"] < 0.5 * plain  # 9.1% vs 20.5%
    assert score["bad"] == pytest.approx(0.091, abs=0.003)
    # the score is the map written: recomputed independently from the file
    written = read_float_map(out)
    assert np.isfinite(written).all()
    assert bad_pixel_rate(written, gt)["bad"] == pytest.approx(score["bad"], abs=1e-9)
    # --fill none leaves rejected pixels empty, and they count as bad
    assert main(["stereo", str(d / "motorcycle_left.png"), str(d / "motorcycle_right.png"),
                 "--ground-truth", str(d / "motorcycle_disp.npz"), "--fill", "none"]) == 0
    text = capsys.readouterr().out
    assert "missing counted bad): 20.6%" in text


def test_fill_background_takes_the_farther_neighbour():
    from usdface.scan.stereo import fill_background

    d = np.array([[20.0, 20.0, np.nan, np.nan, 8.0, 8.0], [np.nan, 5.0, 5.0, 30.0, np.nan, np.nan],
                  [np.nan] * 6])
    valid = np.isfinite(d)
    valid[0, 0] = False  # rejected: filled although it has a value
    f = fill_background(d, valid)
    np.testing.assert_array_equal(f[0], [20, 20, 8, 8, 8, 8])
    np.testing.assert_array_equal(f[1], [5, 5, 5, 30, 30, 30])
    assert np.isnan(f[2]).all()
    np.testing.assert_array_equal(fill_background(d.T, valid.T, vertical=True), f.T)


def test_ground_truth_of_another_size_is_refused(shared_data, tmp_path, capsys):
    from usdface.cli import main

    d = shared_data / "images" / "stereo"
    bad = tmp_path / "gt.npy"
    np.save(bad, np.zeros((10, 10), np.float32))
    assert main(["stereo", str(d / "motorcycle_left.png"), str(d / "motorcycle_right.png"),
                 "--ground-truth", str(bad)]) == 2
    assert "gt.npy: 10x10 but the images are 741x500" in capsys.readouterr().err


def test_vertical_pair_is_the_transposed_horizontal_one(moto):
    left, right, _ = moto
    L, R = left[CROP], right[CROP]
    h = compute_disparity(L, R, MatchingParameters(method="sgbm", num_disparities=64))
    v = compute_disparity(np.ascontiguousarray(L.transpose(1, 0, 2)), np.ascontiguousarray(R.transpose(1, 0, 2)),
                          MatchingParameters(method="sgbm", num_disparities=64, vertical=True))
    assert np.allclose(np.nan_to_num(v.disparity.T), np.nan_to_num(h.disparity))


def test_rectification_check(moto):
    import cv2

    left, right, _ = moto
    assert check_rectified(left, right)["rectified"] is True
    M = cv2.getRotationMatrix2D((370, 250), 3.0, 1.0)
    rot = cv2.warpAffine(right, M, (right.shape[1], right.shape[0]))
    r = check_rectified(left, rot)
    assert r["rectified"] is False and r["median_offset"] > 2


def test_bad_pairs():
    a = np.zeros((100, 120), np.uint8)
    with pytest.raises(InputError, match="differ in size"):
        compute_disparity(a, np.zeros((100, 121), np.uint8))
    with pytest.raises(OptionError, match="--method"):
        compute_disparity(a, a, MatchingParameters(method="magic"))
    with pytest.raises(OptionError, match="do not fit"):
        compute_disparity(a, a, MatchingParameters(num_disparities=128))


@pytest.fixture(scope="module")
def face_pair(sample_assets, shared_data):
    from usdface.scan.synthetic import render_stereo_pair, sample_face

    _, _, _, scene = sample_face(sample_assets, "stylized", photo=shared_data / "images" / "astronaut.png")
    return render_stereo_pair(scene, size=(320, 240)), render_stereo_pair(scene, size=(240, 320), vertical=True)


@pytest.mark.parametrize("method, median_mm, p95_mm", [("sgbm", 1.5, 6.0), ("sgbm-wls", 2.5, 10.0),
                                                       ("graphcut", 1.5, 6.0)])
def test_rendered_face_depth_error(face_pair, method, median_mm, p95_mm):
    for pair in face_pair:
        cal = calibration_from_dict(pair["calibration"])
        lo, n = disparity_range(cal, 500, 700)
        r = compute_disparity(pair["first"], pair["second"],
                              MatchingParameters(method=method, min_disparity=lo, num_disparities=n,
                                                 vertical=cal.vertical, graphcut=GraphCutParameters(max_cycles=2)))
        z = cal.depth(np.where(r.valid, r.disparity, np.nan))
        face = np.isfinite(pair["depth"])
        ok = face & np.isfinite(z)
        assert ok.sum() > 0.8 * face.sum()
        err = np.abs(z - pair["depth"])[ok]
        assert np.median(err) < median_mm and np.percentile(err, 95) < p95_mm
        # the flat background is not matched
        assert (np.isfinite(z) & ~face).mean() < 0.05
