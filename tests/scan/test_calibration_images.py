"""Calibration files, rectification and float-map files."""
import json

import numpy as np
import pytest

from usdface.errors import FormatError, InputError, OptionError
from usdface.io.images import read_float_map, read_image, write_float_map, write_image
from usdface.scan.calibration import calibration_from_dict, read_calibration, rectify_pair

MOTO = {"f": 994.978, "cx": 311.193, "cy": 254.877, "baseline": 193.001, "doffs": 31.086}


def test_rectified_calibration_depth_round_trip(tmp_path):
    p = tmp_path / "c.json"
    p.write_text(json.dumps(MOTO))
    c = read_calibration(p)
    assert c.rectified and not c.vertical and c.units == "mm"
    d = np.array([[7.2, 59.9], [np.nan, 20.0]])
    z = c.depth(d)
    assert np.isnan(z[1, 0])
    assert np.allclose(c.disparity(z)[np.isfinite(d)], d[np.isfinite(d)])
    assert z[0, 0] == pytest.approx(994.978 * 193.001 / (7.2 + 31.086))
    pts = c.points(np.full((2, 3), 1000.0))
    assert pts[0, 0] == pytest.approx([(0 - 311.193) * 1000 / 994.978, (0 - 254.877) * 1000 / 994.978, 1000])


@pytest.mark.parametrize("data, msg", [
    ({"f": 1, "cx": 0, "cy": 0}, "missing baseline"),
    ({"f": 1, "cx": 0, "cy": 0, "baseline": 1, "focal": 3}, "unknown key"),
    ({"f": -1, "cx": 0, "cy": 0, "baseline": 1}, "'f' must be > 0"),
    ({"f": 1, "cx": 0, "cy": 0, "baseline": 1, "vertical": "yes"}, "'vertical' must be true or false"),
    ({"K1": np.eye(3).tolist(), "D1": [], "K2": np.eye(3).tolist(), "D2": [], "R": (2 * np.eye(3)).tolist(),
      "T": [1, 0, 0]}, "not a rotation"),
    ({"K1": np.eye(3).tolist(), "R": np.eye(3).tolist(), "T": [1, 0, 0]}, "lacks"),
    ({"f": 1, "cx": 0, "cy": 0, "baseline": 1, "units": "furlong"}, "unknown units"),
])
def test_bad_calibrations(data, msg):
    with pytest.raises(FormatError, match=msg):
        calibration_from_dict(data, source="c.json")


def test_missing_and_invalid_calibration_file(tmp_path):
    with pytest.raises(InputError, match="no such file"):
        read_calibration(tmp_path / "none.json")
    (tmp_path / "bad.json").write_text("{nope")
    with pytest.raises(FormatError, match="not valid JSON"):
        read_calibration(tmp_path / "bad.json")


def _full(T):
    K = [[500.0, 0, 160.0], [0, 500.0, 120.0], [0, 0, 1]]
    return calibration_from_dict({"K1": K, "D1": [0, 0, 0, 0, 0], "K2": K, "D2": [0, 0, 0, 0, 0],
                                  "R": np.eye(3).tolist(), "T": T})


@pytest.mark.parametrize("T, vertical", [([-60.0, 0, 0], False), ([0, -60.0, 0], True)])
def test_rectify_full_calibration(T, vertical):
    rng = np.random.default_rng(0)
    a = rng.integers(0, 255, (240, 320), dtype=np.uint8)
    pair = rectify_pair(a, a, _full(T))
    c = pair.calibration
    assert c.rectified and c.vertical is vertical
    assert c.baseline == pytest.approx(60.0)
    assert c.f == pytest.approx(500.0, rel=0.05)
    assert pair.first.shape == a.shape
    # a point maps into the rectified image (identity rotation: nearly where it was)
    moved = pair.rectify_points([[100.0, 80.0]], _full(T))
    assert np.abs(moved - [[100.0, 80.0]]).max() < 0.1 * 320


def test_rectify_swapped_cameras():
    a = np.zeros((240, 320), np.uint8)
    with pytest.raises(OptionError, match="left of the first"):
        rectify_pair(a, a, _full([60.0, 0, 0]))


@pytest.mark.parametrize("suffix", [".exr", ".pfm", ".npy", ".tif"])
def test_float_map_round_trip(tmp_path, suffix):
    if suffix == ".exr":
        pytest.importorskip("OpenImageIO")
    a = np.arange(12, dtype=np.float32).reshape(3, 4) / 7
    a[1, 2] = np.nan
    p = write_float_map(tmp_path / f"d{suffix}", a)
    b = read_float_map(p)
    assert b.shape == a.shape and np.array_equal(np.isnan(a), np.isnan(b))
    assert np.allclose(a[~np.isnan(a)], b[~np.isnan(b)])
    assert [f.name for f in tmp_path.iterdir()] == [p.name]  # no temporary file left


def test_image_round_trip_and_errors(tmp_path):
    img = (np.arange(60, dtype=np.uint8).reshape(4, 5, 3) * 4)
    p = write_image(tmp_path / "a.png", img)
    assert np.array_equal(read_image(p), img)
    assert read_image(p, gray=True).shape == (4, 5)
    with pytest.raises(InputError, match="no such file"):
        read_image(tmp_path / "none.png")
    (tmp_path / "x.png").write_bytes(b"not a png")
    with pytest.raises(InputError, match="cannot be read"):
        read_image(tmp_path / "x.png")
    with pytest.raises(OptionError, match="expected a file ending"):
        write_float_map(tmp_path / "d.png", np.zeros((2, 2)))
