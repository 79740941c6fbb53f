"""TRC and C3D readers/writers: round trips of the real Jaw take, axes, hand-made files, bad input.

C3D stores coordinates as float32: round trips are compared within 1e-3 cm (the actual error on
these face coordinates, below 100 cm, is about 5e-6 cm).
"""
from __future__ import annotations

import ezc3d
import numpy as np
import pytest

from usdface.model.capture import Capture
from usdface.errors import FormatError, InputError, MarkerError, OptionError
from usdface.io.c3d import read_c3d, write_c3d
from usdface.io.maya_ascii import read_maya_ascii
from usdface.io.trc import read_trc, write_trc

C3D_TOLERANCE_CM = 1e-3


@pytest.fixture(scope="module")
def jaw(shared_data):
    capture = read_maya_ascii(shared_data / "animface" / "JawMoCap.ma")
    positions = capture.positions.copy()
    positions[100:130, 7] = np.nan                   # an occluded stretch
    positions[::211, 20] = np.nan
    return capture.replace(positions=positions)


@pytest.fixture(scope="module")
def jaw_c3d(tmp_path_factory, jaw):
    path = tmp_path_factory.mktemp("c3d") / "jaw.c3d"
    write_c3d(path, jaw)
    return path


# -- TRC ------------------------------------------------------------------------------------------

def test_trc_round_trip_real_take(tmp_path, jaw):
    path = tmp_path / "jaw.trc"
    write_trc(path, jaw)
    back = read_trc(path)
    assert back.names == jaw.names
    assert back.rate == 60.0 and back.units == "cm" and back.start_frame == 0
    np.testing.assert_array_equal(back.positions, jaw.positions)
    np.testing.assert_array_equal(back.valid, jaw.valid)
    assert back.history == ({"step": "read", "format": "trc", "up_axis": "Y"},)


def test_trc_header_written(tmp_path, jaw):
    path = tmp_path / "jaw.trc"
    write_trc(path, jaw)
    lines = path.read_text().split("\n")
    assert lines[0] == "PathFileType\t4\t(X/Y/Z)\tjaw.trc"
    assert lines[1].split("\t") == ["DataRate", "CameraRate", "NumFrames", "NumMarkers", "Units", "OrigDataRate",
                                    "OrigDataStartFrame", "OrigNumFrames"]
    assert lines[2].split("\t") == ["60", "60", "1590", "41", "cm", "60", "1", "1590"]
    assert lines[3].split("\t")[:6] == ["Frame#", "Time", "ForeHead_M", "", "", "ForeHead_L"]
    assert lines[4].split("\t")[:5] == ["", "", "X1", "Y1", "Z1"]
    first_row = lines[6].split("\t")
    assert first_row[:2] == ["1", "0"] and float(first_row[2]) == jaw.positions[0, 0, 0]


OPENSIM_TRC = (
    "PathFileType\t4\t(X/Y/Z)\tsubject01.trc\n"
    "DataRate\tCameraRate\tNumFrames\tNumMarkers\tUnits\tOrigDataRate\tOrigDataStartFrame\tOrigNumFrames\n"
    "100.00\t100.00\t4\t2\tmm\t100.00\t1\t4\n"
    "Frame#\tTime\tR.ASIS\t\t\tL.ASIS\t\t\n"
    "\t\tX1\tY1\tZ1\tX2\tY2\tZ2\n"
    "\n"
    "11\t0.100\t1.5\t2.5\t3.5\t4\t5\t6\n"
    "12\t0.110\t1.6\t2.6\t3.6\t\t\t\n"
    "13\t0.120\t1.7\t2.7\t3.7\n"
    "15\t0.140\t1.9\t2.9\t3.9\t7\t8\t9\n"
)


def test_trc_opensim_style_file(tmp_path):
    path = tmp_path / "subject01.trc"
    path.write_text(OPENSIM_TRC)
    capture = read_trc(path)
    assert capture.names == ("R.ASIS", "L.ASIS")
    assert capture.rate == 100.0 and capture.units == "mm"
    assert capture.start_frame == 10                 # Time 0.100 s at 100 Hz
    assert capture.n_frames == 5                     # Frame# 14 missing -> invalid
    np.testing.assert_array_equal(capture.valid, [[1, 1], [1, 0], [1, 0], [0, 0], [1, 1]])
    np.testing.assert_array_equal(capture.positions[4], [[1.9, 2.9, 3.9], [7, 8, 9]])


def test_trc_z_up_source(tmp_path):
    path = tmp_path / "subject01.trc"
    path.write_text(OPENSIM_TRC)
    capture = read_trc(path, up_axis="Z")
    np.testing.assert_array_equal(capture.positions[0, 0], [1.5, 3.5, -2.5])
    assert capture.history[0]["up_axis"] == "Z"


@pytest.mark.parametrize("edit, error, message", [
    (lambda t: t.rsplit("\n", 2)[0] + "\n", FormatError,
     r"subject01\.trc: header says NumFrames 4 but the file has 3 data rows: the file is truncated"),
    (lambda t: t[:-9], FormatError, r"subject01\.trc, line 10: the last row is incomplete: the file is truncated"),
    (lambda t: t.replace("\t4\t2\tmm", "\t4\t3\tmm"), FormatError,
     r"subject01\.trc: header says NumMarkers 3 but line 4 names 2 markers"),
    (lambda t: t.replace("PathFileType", "Whatever"), FormatError, r"subject01\.trc, line 1: not a TRC file"),
    (lambda t: t.replace("\tmm\t", "\tparsec\t"), FormatError, r"subject01\.trc, line 3: unknown Units 'parsec'"),
    (lambda t: t.replace("L.ASIS", "R.ASIS"), MarkerError, r"subject01\.trc, line 4: duplicate marker names: R\.ASIS"),
    (lambda t: t.replace("2.7", "2.7.1"), FormatError, r"subject01\.trc, line 9: column 'R\.ASIS\.Y': '2\.7\.1' is not a number"),
    (lambda t: t.replace("\n13\t", "\n12\t"), FormatError, r"subject01\.trc, line 9: Frame# 12 is listed twice"),
    (lambda t: t.replace("100.00\t100.00", "fast\t100.00"), FormatError,
     r"subject01\.trc, line 3: DataRate must be a positive number; got 'fast'"),
    (lambda t: t.replace("\t4\t5\t6\n", "\t\t\t\n").replace("\t7\t8\t9\n", "\t\t\t\n"), MarkerError,
     r"subject01\.trc: no valid sample for marker\(s\) L\.ASIS"),
])
def test_trc_bad_input(tmp_path, edit, error, message):
    path = tmp_path / "subject01.trc"
    path.write_text(edit(OPENSIM_TRC))
    with pytest.raises(error, match=message):
        read_trc(path)


def test_trc_options(tmp_path):
    path = tmp_path / "subject01.trc"
    path.write_text(OPENSIM_TRC)
    with pytest.raises(OptionError, match=r"subject01\.trc: the file declares units 'mm' but --units 'cm'"):
        read_trc(path, units="cm")
    with pytest.raises(OptionError, match=r"subject01\.trc: the file declares a rate of 100 Hz but --rate 60"):
        read_trc(path, rate=60)
    path.write_text(OPENSIM_TRC.replace("\tmm\t", "\t\t"))
    with pytest.raises(OptionError, match=r"does not declare its linear units; pass --units"):
        read_trc(path)
    assert read_trc(path, units="mm").units == "mm"


def test_trc_writer_needs_units(tmp_path):
    capture = Capture(names=("A",), positions=np.zeros((2, 1, 3)), rate=30.0)
    with pytest.raises(FormatError, match=r"cannot write .*nounits\.trc: the capture has no units"):
        write_trc(tmp_path / "nounits.trc", capture)


# -- C3D ------------------------------------------------------------------------------------------

def test_c3d_round_trip_real_take(jaw, jaw_c3d):
    back = read_c3d(jaw_c3d)
    assert back.names == jaw.names
    assert back.rate == 60.0 and back.units == "cm" and back.start_frame == 0 and back.n_frames == 1590
    np.testing.assert_array_equal(back.valid, jaw.valid)
    np.testing.assert_allclose(back.positions, jaw.positions, atol=C3D_TOLERANCE_CM, rtol=0)
    assert back.history == ({"step": "read", "format": "c3d", "up_axis": "Z"},)


def test_c3d_file_is_z_up(jaw, jaw_c3d):
    raw = ezc3d.c3d(str(jaw_c3d))
    points = raw["data"]["points"][:3].transpose(2, 1, 0)       # (F, M, 3) as stored
    x, y, z = (jaw.positions[..., i] for i in range(3))
    np.testing.assert_allclose(points, np.stack([x, -z, y], -1), atol=C3D_TOLERANCE_CM)
    assert list(raw["parameters"]["POINT"]["LABELS"]["value"]) == list(jaw.names)
    as_stored = read_c3d(jaw_c3d, up_axis="Y")                  # no rotation
    np.testing.assert_allclose(as_stored.positions, np.stack([x, -z, y], -1), atol=C3D_TOLERANCE_CM)


def test_c3d_start_frame_and_units(tmp_path):
    capture = Capture(names=("A", "B"), positions=np.arange(24, dtype=float).reshape(4, 2, 3), rate=250.0,
                      units="mm", start_frame=37)
    path = tmp_path / "small.C3D"                                # upper-case suffix is fine
    write_c3d(path, capture)
    assert path.is_file() and not (tmp_path / "small.C3D.c3d").exists()
    back = read_c3d(path)
    assert back.start_frame == 37 and back.rate == 250.0 and back.units == "mm"
    np.testing.assert_allclose(back.positions, capture.positions, atol=1e-4)


def test_c3d_truncated(tmp_path, jaw_c3d):
    data = jaw_c3d.read_bytes()
    path = tmp_path / "cut.c3d"
    path.write_bytes(data[: len(data) // 2])
    with pytest.raises(FormatError, match=r"cut\.c3d: the header announces 1,590 frames of 41 points \(1,045,088 "
                                          r"bytes\) but the file has 522,752 bytes: it is truncated"):
        read_c3d(path)
    path.write_bytes(data[:600])
    with pytest.raises(FormatError, match=r"cut\.c3d: the header announces 1,590 frames of 41 points \(1,045,088 "
                                          r"bytes\) but the file has 600 bytes"):
        read_c3d(path)


def test_c3d_not_c3d(tmp_path):
    path = tmp_path / "text.c3d"
    path.write_text("this is not a c3d file\n" * 40)
    with pytest.raises(FormatError, match=r"text\.c3d: not a C3D file \(no C3D header: byte 2 must be 0x50\)"):
        read_c3d(path)
    with pytest.raises(InputError, match=r"gone\.c3d: no such file"):
        read_c3d(tmp_path / "gone.c3d")


def test_c3d_options(jaw_c3d):
    with pytest.raises(OptionError, match=r"jaw\.c3d: the file declares units 'cm' but --units 'mm'"):
        read_c3d(jaw_c3d, units="mm")
    with pytest.raises(OptionError, match=r"jaw\.c3d: the file declares a rate of 60 Hz but --rate 120"):
        read_c3d(jaw_c3d, rate=120)
    with pytest.raises(OptionError, match=r"--up-axis: expected 'Y' or 'Z'; got 'X'"):
        read_c3d(jaw_c3d, up_axis="X")


def test_c3d_without_units_needs_option(tmp_path):
    capture = Capture(names=("A",), positions=np.ones((3, 1, 3)), rate=100.0)
    path = tmp_path / "nounits.c3d"
    write_c3d(path, capture)
    with pytest.raises(OptionError, match=r"nounits\.c3d: the file does not declare its linear units; pass --units"):
        read_c3d(path)
    assert read_c3d(path, units="m").units == "m"


def test_c3d_all_invalid_marker(tmp_path):
    positions = np.ones((3, 2, 3))
    positions[:, 1] = np.nan
    path = tmp_path / "dead.c3d"
    write_c3d(path, Capture(names=("A", "Dead"), positions=positions, rate=100.0, units="mm"))
    with pytest.raises(MarkerError, match=r"dead\.c3d: no valid sample for marker\(s\) Dead"):
        read_c3d(path)
