"""Hostile capture files: values beyond float32, absurd frame numbers and rates, lying C3D
headers, named pipes. Each is refused with one line naming the file (and line, column or key)
before anything is allocated; the limits are plausibility checks that --allow accepts."""
from __future__ import annotations

import os
import struct

import numpy as np
import pytest

from usdface.errors import FormatError, InputError, PlausibilityError, ResourceError
from usdface.io.captures import read_capture, write_capture

from ..hostile import assert_one_line, digest, run_in_process, run_subprocess

HEADER = "frame,A_x,A_y,A_z,B_x,B_y,B_z,C_x,C_y,C_z,D_x,D_y,D_z"
BASE = np.array([[0, 0, 0], [15, 0, 0], [0, 15, 0], [15, 15, 3.0]])


def _csv(path, *, declaration="# units=cm rate=60", frames=range(200), change=None):
    rng = np.random.default_rng(0)
    rows = [declaration, HEADER] if declaration else [HEADER]
    for f in frames:
        p = BASE + rng.normal(0, 0.01, BASE.shape)
        rows.append(",".join([str(f)] + [f"{v:.4f}" for v in p.ravel()]))
    if change:
        change(rows)
    path.write_text("\n".join(rows) + "\n")
    return path


def _outputs(folder, *inputs):
    return sorted(p.name for p in folder.iterdir() if p.name not in {i.name for i in inputs})


def test_value_beyond_float32_names_line_and_column(tmp_path, capsys):
    # issue 20 (3): a cell 1e308 gave exit 0, three RuntimeWarnings and inf in the layer
    def big(rows):
        cells = rows[11].split(",")
        cells[1] = "1e308"
        rows[11] = ",".join(cells)
    csv = _csv(tmp_path / "big.csv", change=big)
    before = digest(csv)
    rc, lines = run_in_process(capsys, "import-capture", csv, "-o", tmp_path / "c.usdc")
    assert_one_line(rc, lines, code=2, command="import-capture",
                    contains=(f"{csv}, line 12: column 'A_x': 1e+308 is beyond the range of the float32 positions "
                              "USD stores",))
    assert digest(csv) == before and _outputs(tmp_path, csv) == []


def test_inf_cell_is_refused_too(tmp_path):
    def inf(rows):
        rows[5] = rows[5].replace(rows[5].split(",")[4], "-inf", 1)
    with pytest.raises(FormatError, match=r"line 6: column 'B_x': -inf is beyond the range"):
        read_capture(_csv(tmp_path / "inf.csv", change=inf))


def test_absurd_last_frame_is_refused_before_allocating(tmp_path, capsys):
    # issue 20 (4): "out of memory: Unable to allocate 1.79 TiB", no file named
    def far(rows):
        rows[-1] = "2000000000," + rows[-1].split(",", 1)[1]
    csv = _csv(tmp_path / "far.csv", change=far)
    rc, lines = run_in_process(capsys, "import-capture", csv, "-o", tmp_path / "c.usdc")
    assert_one_line(rc, lines, code=2, command="import-capture",
                    contains=(f"{csv}: its frame numbers span 2,000,000,001 frames but it holds 200 rows (line 202: "
                              "frame 2000000000): a typo'd frame number? (--allow frame-count",))
    # accepted, the memory it needs is estimated before anything is allocated
    with pytest.raises(ResourceError, match=r"far\.csv: 2,000,000,001 frames x 4 markers needs about .* of memory"):
        read_capture(csv, allow={"frame-count"})


def test_frame_numbers_beyond_any_time_code(tmp_path):
    def huge(rows):
        rows[-1] = "1e300," + rows[-1].split(",", 1)[1]
    with pytest.raises(FormatError, match=r"huge\.csv, line 202: frame 1e300 is beyond the time codes usdface stores"):
        read_capture(_csv(tmp_path / "huge.csv", change=huge))


def test_long_takes_up_to_the_limit_are_read(tmp_path):
    # a dense take is judged by its length: one row per frame, so no sparse-frame finding
    from usdface.io.limits import MAX_CAPTURE_FRAMES

    csv = _csv(tmp_path / "dense.csv", frames=range(3000))
    assert read_capture(csv).n_frames == 3000
    assert MAX_CAPTURE_FRAMES == 1_000_000


def test_implausible_rate_is_refused(tmp_path, capsys):
    # issue 20 (14): rate=1e300 imported with exit 0 and a speed warning
    csv = _csv(tmp_path / "fast.csv", declaration="# units=cm rate=1e300")
    rc, lines = run_in_process(capsys, "import-capture", csv, "-o", tmp_path / "c.usdc")
    assert_one_line(rc, lines, code=2, command="import-capture",
                    contains=(f"{csv}: a capture rate of 1e+300 Hz (declared) is outside the plausible 1-10000 Hz",
                              "--allow rate"))
    slow = _csv(tmp_path / "slow.csv", declaration="# units=cm")
    with pytest.raises(PlausibilityError, match=r"a capture rate of 0\.01 Hz \(given with --rate\)"):
        read_capture(slow, rate=0.01)
    assert read_capture(csv, allow={"rate"}).rate == 1e300  # the reader accepts it when allowed


def test_maya_keys_a_nanoframe_apart(tmp_path, capsys):
    # issue 20 (14): keys 1e-9 frame apart (2.4e10 Hz) imported with exit 0
    from .test_maya_ascii import maya_scene

    times = [1.0 + 1e-9 * k for k in range(4)]
    text = maya_scene({"A": {"X": (times, [0.0, 1.0, 2.0, 3.0])}, "B": {"X": (times, [5.0, 6.0, 7.0, 8.0])},
                       "C": {"Y": (times, [1.0, 2.0, 3.0, 4.0])}})
    ma = tmp_path / "fast.ma"
    ma.write_text(text)
    rc, lines = run_in_process(capsys, "import-capture", ma, "-o", tmp_path / "c.usdc")
    assert_one_line(rc, lines, code=2, command="import-capture",
                    contains=(f"{ma}: a capture rate of 2.4e+10 Hz (inferred from keys 1e-09 film frames apart) is "
                              "outside the plausible 1-10000 Hz",))


def test_resample_to_a_nanohertz_is_refused(sample_assets, tmp_path, capsys):
    # issue 20 (14): --resample 1e-9 silently made 200 frames into 1
    rc, lines = run_in_process(capsys, "import-capture", sample_assets / "capture" / "JawMoCap.ma", "--trim", 0, 200,
                               "--resample", "1e-9", "-o", tmp_path / "c.usdc")
    assert_one_line(rc, lines, code=2, command="import-capture",
                    contains=("--resample 1e-09 Hz from 60 Hz (200 frames -> 1): 1e-09 Hz is outside the plausible "
                              "1-10000 Hz", "--allow resample"))
    assert not (tmp_path / "c.usdc").exists()


def test_resample_limits(sample_assets):
    from usdface.capture.timing import resample

    capture = read_capture(sample_assets / "capture" / "JawMoCap.ma")
    with pytest.raises(PlausibilityError, match=r"--resample 6000\.1 Hz from 60 Hz \(1590 frames -> 158903\): a "
                                                r"factor of 100, beyond 100x either way"):
        resample(capture, rate=6000.1)
    short = capture.replace(positions=capture.positions[:3])
    with pytest.raises(PlausibilityError, match=r"\(3 frames -> 1\): it leaves 1 frame\(s\) of 3"):
        resample(short, rate=1.0)
    assert resample(short, rate=1.0, allow={"resample"}).n_frames == 1
    assert resample(capture, rate=24.0).n_frames == 636  # film rate from 60 Hz: an ordinary request


def test_trc_frame_number_and_value_limits(tmp_path):
    capture = read_capture(_csv(tmp_path / "ok.csv"))
    trc = tmp_path / "t.trc"
    write_capture(trc, capture)
    lines = trc.read_text().splitlines()
    lines[-1] = "\t".join(["900000"] + lines[-1].split("\t")[1:])
    trc.write_text("\n".join(lines) + "\n")
    with pytest.raises(PlausibilityError, match=r"t\.trc: its frame numbers span 900,000 frames but it holds 200 rows "
                                                r"\(line 206: Frame# 900000\)"):
        read_capture(trc)
    lines[-1] = "\t".join(["200", "3.3"] + ["3e39"] + lines[-1].split("\t")[3:])
    trc.write_text("\n".join(lines) + "\n")
    with pytest.raises(FormatError, match=r"t\.trc, line 206: column 'A\.X': 3e\+39 is beyond the range"):
        read_capture(trc)


def _c3d(tmp_path):
    capture = read_capture(_csv(tmp_path / "ok.csv"))
    path = tmp_path / "ok.c3d"
    write_capture(path, capture)
    return path


def _patch_parameter(path, group, name, fmt, value):
    from usdface.io.c3d_header import _parameters

    data = bytearray(path.read_bytes())
    base = (data[0] - 1) * 512
    params, order, _ = _parameters(bytes(data[base:base + 512 * data[base + 2]]), str(path))
    _, _, offset = params[(group, name)]
    struct.pack_into(order + fmt, data, base + offset, value)
    path.write_bytes(bytes(data))


def test_c3d_analog_rate_that_made_ezc3d_allocate_12_gb(tmp_path):
    c3d = _c3d(tmp_path)
    _patch_parameter(c3d, "ANALOG", "RATE", "f", 1e9)
    before = digest(c3d)
    rc, lines = run_subprocess("import-capture", c3d, "-o", tmp_path / "c.usdc", timeout=60)
    assert_one_line(rc, lines, code=2, command="import-capture",
                    contains=(f"{c3d}: ANALOG:RATE 1e+09 Hz is 1.67e+07 times POINT:RATE 60 Hz",))
    assert digest(c3d) == before


@pytest.mark.parametrize("group, name, value, match", [
    ("POINT", "FRAMES", 32000, r"announces 32,000 frames of 4 points \(2,049,536 bytes\) but the file has 14,848 bytes"),
    ("POINT", "USED", 30000, r"announces 200 frames of 30,000 points \(96,001,536 bytes\) but the file has 14,848"),
])
def test_c3d_counts_beyond_the_file(tmp_path, group, name, value, match):
    c3d = _c3d(tmp_path)
    _patch_parameter(c3d, group, name, "H", value)
    with pytest.raises(FormatError, match=r"ok\.c3d: the header " + match):
        read_capture(c3d)


def test_c3d_rate_is_judged(tmp_path):
    c3d = _c3d(tmp_path)
    _patch_parameter(c3d, "POINT", "RATE", "f", 1e6)
    _patch_parameter(c3d, "ANALOG", "RATE", "f", 1e6)
    with pytest.raises(PlausibilityError, match=r"a capture rate of 1e\+06 Hz \(POINT:RATE\) is outside"):
        read_capture(c3d)


@pytest.mark.parametrize("suffix", [".csv", ".trc", ".c3d", ".ma"])
def test_named_pipe_capture_is_refused(tmp_path, suffix):
    fifo = tmp_path / f"take{suffix}"
    os.mkfifo(fifo)
    with pytest.raises(InputError, match=rf"take\{suffix}: is a named pipe \(FIFO\), not a regular file"):
        read_capture(fifo, units="cm", rate=60)
