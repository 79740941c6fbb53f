"""usdface capture CSV: round trips on real data, both forms, 2D, declaration/options, bad input."""
from __future__ import annotations

import numpy as np
import pytest

from usdface.model.capture import Capture
from usdface.errors import FormatError, InputError, MarkerError, OptionError
from usdface.io.csv_format import read_csv, write_csv
from usdface.io.maya_ascii import read_maya_ascii


@pytest.fixture(scope="module")
def jaw(shared_data):
    capture = read_maya_ascii(shared_data / "animface" / "JawMoCap.ma")
    # knock out some samples so that invalid cells are part of the round trip
    positions = capture.positions.copy()
    positions[::97, 3] = np.nan
    positions[500:520, 40] = np.nan
    return capture.replace(positions=positions)


def write(tmp_path, text, name="take.csv"):
    path = tmp_path / name
    path.write_text(text)
    return path


@pytest.mark.parametrize("form", ["wide", "long"])
def test_round_trip_real_take(tmp_path, jaw, form):
    path = tmp_path / f"jaw_{form}.csv"
    write_csv(path, jaw, form=form)
    assert path.read_text().startswith("# units=cm rate=60\n")
    back = read_csv(path)
    assert back.names == jaw.names
    assert back.rate == jaw.rate and back.units == "cm" and back.start_frame == 0
    np.testing.assert_array_equal(back.positions, jaw.positions)   # shortest repr: exact
    assert back.history == ({"step": "read", "format": "csv", "dims": 3, "form": form},)
    assert back.source == str(path)


def test_wide_header_and_values(tmp_path):
    capture = Capture(names=("Chin_L2", "B"), positions=[[[1.0, 2.0, 3.0], [np.nan] * 3]] * 2 + [[[0.5, 0.25, 1e-7], [4, 5, 6]]],
                      rate=29.97, units="mm", start_frame=100)
    path = tmp_path / "small.csv"
    write_csv(path, capture)
    lines = path.read_text().splitlines()
    assert lines[0] == "# units=mm rate=29.97"
    assert lines[1] == "frame,Chin_L2_x,Chin_L2_y,Chin_L2_z,B_x,B_y,B_z"
    assert lines[2] == "100,1.0,2.0,3.0,,,"
    assert lines[4] == "102,0.5,0.25,1e-07,4.0,5.0,6.0"
    back = read_csv(path)
    assert back.start_frame == 100 and back.rate == 29.97 and back.names == ("Chin_L2", "B")
    np.testing.assert_array_equal(back.positions, capture.positions)


def test_2d_tracks(tmp_path):
    text = "# rate=30 units=cm\nframe,P1_x,P1_y,P2_x,P2_y\n0,1,2,3,4\n1,1.5,,3.5,4.5\n3,2,3,nan,NaN\n"
    capture = read_csv(write(tmp_path, text))
    assert capture.history[0]["dims"] == 2
    assert capture.n_frames == 4                      # frame 2 missing -> invalid
    np.testing.assert_array_equal(capture.valid, [[True, True], [False, True], [False, False], [True, False]])
    np.testing.assert_array_equal(capture.positions[0], [[1, 2, 0], [3, 4, 0]])
    out = tmp_path / "again.csv"
    write_csv(out, capture)                           # dims 2 remembered from the history
    assert out.read_text().splitlines()[1] == "frame,P1_x,P1_y,P2_x,P2_y"
    np.testing.assert_array_equal(read_csv(out).positions, capture.positions, strict=True)


def test_long_form_unsorted_with_time_column(tmp_path):
    text = ("time,marker,x,y,z\n"
            "0.0333333,B,7,8,9\n"
            "0.0,B,1,1,1\n"
            "0.0,A,2,2,2\n"
            "0.0166667,A,3,3,3\n")
    capture = read_csv(write(tmp_path, text), units="cm", rate=60)
    assert capture.names == ("B", "A")               # order of first appearance
    assert capture.n_frames == 3 and capture.start_frame == 0
    np.testing.assert_array_equal(capture.valid, [[True, True], [False, True], [True, False]])
    np.testing.assert_array_equal(capture.positions[2, 0], [7, 8, 9])
    assert capture.history[0]["form"] == "long"


def test_options_supply_what_the_file_lacks(tmp_path):
    path = write(tmp_path, "frame,A_x,A_y,A_z\n0,1,2,3\n")
    with pytest.raises(OptionError, match=r"take\.csv: the file does not declare its linear units; pass --units"):
        read_csv(path, rate=60)
    with pytest.raises(OptionError, match=r"take\.csv: the file does not declare its capture rate; pass --rate"):
        read_csv(path, units="cm")
    capture = read_csv(path, units="mm", rate=120)
    assert capture.units == "mm" and capture.rate == 120


def test_option_conflicting_with_declaration(tmp_path):
    path = write(tmp_path, "# units=cm rate=60\nframe,A_x,A_y,A_z\n0,1,2,3\n")
    with pytest.raises(OptionError, match=r"take\.csv: the file declares units 'cm' but --units 'mm'"):
        read_csv(path, units="mm")
    with pytest.raises(OptionError, match=r"take\.csv: the file declares a rate of 60 Hz but --rate 30"):
        read_csv(path, rate=30)
    assert read_csv(path, units="centimeter", rate=60.0).units == "cm"


@pytest.mark.parametrize("text, error, message", [
    ("# units=cm rate=60\nframe,A_x,A_y,A_z\n0,1,2,3\n1,1,2\n", FormatError,
     r"take\.csv, line 4: 3 cells where the header \(line 2\) has 4: the file is truncated"),
    ("# units=cm rate=60\nframe,A_x,A_y,A_z\n0,1,2,3\n1,1,abc,3\n", FormatError,
     r"take\.csv, line 4: column 'A_y': 'abc' is not a number"),
    ("# units=cm rate=60\nframe,A_x,A_y,A_z\n0,1,2,3\n1.5,1,2,3\n", FormatError,
     r"take\.csv, line 4: frame '1\.5' is not an integer"),
    ("# units=cm rate=60\ntime,A_x,A_y,A_z\n0,1,2,3\n0.01,1,2,3\n", FormatError,
     r"take\.csv, line 4: time 0\.01 s is 0\.600 frames at 60 Hz, not a whole frame"),
    ("# units=cm rate=60\nframe,A_x,A_y,A_z\n0,1,2,3\n0,1,2,3\n", FormatError,
     r"take\.csv, line 4: frame 0 is listed twice"),
    ("# units=cm rate=60\nframe,marker,x,y,z\n0,A,1,2,3\n0,A,1,2,3\n", FormatError,
     r"take\.csv, line 4: marker 'A' at frame 0 is listed twice"),
    ("# units=cm rate=60\nsample,A_x,A_y,A_z\n0,1,2,3\n", FormatError,
     r"take\.csv, line 2: the first column must be 'frame' or 'time'; got 'sample'"),
    ("# units=cm rate=60\nframe,A_x,A_z,A_y\n0,1,2,3\n", FormatError,
     r"take\.csv, line 2: columns 'A_x,A_z,A_y' should be 'A_x,A_y,A_z'"),
    ("# units=cm rate=60\nframe,A_x,A_y,A_w\n0,1,2,3\n", FormatError,
     r"take\.csv, line 2: column 'A_w' is not '<Marker>_x'"),
    ("# units=cm rate=60\nframe,marker,x,z\n0,A,1,2\n", FormatError,
     r"take\.csv, line 2: long form header must be 'frame,marker,x,y' or 'frame,marker,x,y,z'"),
    ("# units=cm speed=60\nframe,A_x,A_y\n0,1,2\n", FormatError,
     r"take\.csv, line 1: cannot read 'speed=60' in the declaration line"),
    ("# units=furlong rate=60\nframe,A_x,A_y\n0,1,2\n", FormatError,
     r"take\.csv, line 1: unknown unit 'furlong'"),
    ("# units=cm rate=-3\nframe,A_x,A_y\n0,1,2\n", FormatError,
     r"take\.csv, line 1: rate must be a positive number of Hz; got '-3'"),
    ("# units=cm rate=60\n", FormatError, r"take\.csv: no header row"),
    ("# units=cm rate=60\nframe,A_x,A_y,A_z\n", MarkerError, r"take\.csv: the file has a header but zero frames"),
    ("# units=cm rate=60\nframe\n0\n", MarkerError, r"take\.csv, line 2: the header names zero markers"),
    ("# units=cm rate=60\nframe,A_x,A_y,A_x,A_y\n0,1,2,3,4\n", MarkerError,
     r"take\.csv, line 2: duplicate marker names: A"),
    ("# units=cm rate=60\nframe,A_x,A_y,B_x,B_y\n0,1,2,,\n1,1,2,nan,\n", MarkerError,
     r"take\.csv: no valid sample for marker\(s\) B"),
])
def test_bad_input(tmp_path, text, error, message):
    with pytest.raises(error, match=message):
        read_csv(write(tmp_path, text))


def test_missing_file(tmp_path):
    with pytest.raises(InputError, match=r"absent\.csv: no such file"):
        read_csv(tmp_path / "absent.csv")


def test_writer_options(tmp_path, jaw):
    with pytest.raises(OptionError, match=r"--dims: expected 2 or 3; got 4"):
        write_csv(tmp_path / "x.csv", jaw, dims=4)
    with pytest.raises(OptionError, match=r"--form: expected 'wide' or 'long'; got 'tall'"):
        write_csv(tmp_path / "x.csv", jaw, form="tall")


def test_excel_style_file(tmp_path):
    # UTF-8 byte order mark, CRLF line ends, quoted cells, upper-case axis suffixes
    path = tmp_path / "excel.csv"
    path.write_bytes("\ufeff# units=mm rate=25\r\nFrame,\"Lip, upper_X\",\"Lip, upper_Y\"\r\n0,\"1.5\",2\r\n1,,\r\n2,3,4\r\n".encode())
    capture = read_csv(path)
    assert capture.names == ("Lip, upper",) and capture.units == "mm" and capture.rate == 25
    np.testing.assert_array_equal(capture.valid[:, 0], [True, False, True])
    out = tmp_path / "again.csv"
    write_csv(out, capture, form="long")
    assert out.read_text().splitlines()[2] == '0,"Lip, upper",1.5,2.0'
    np.testing.assert_array_equal(read_csv(out).positions, capture.positions)
