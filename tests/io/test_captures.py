"""The capture format registry: dispatch by suffix, shared errors, up-axis override, writing."""
from __future__ import annotations

import os
import shutil

import numpy as np
import pytest

from usdface.model.capture import Capture
from usdface.errors import FormatError, InputError, MarkerError, OptionError
from usdface.io.captures import (
    CAPTURE_SUFFIXES, WRITABLE_CAPTURE_SUFFIXES, read_capture, write_capture, y_up_to_z_up, z_up_to_y_up,
)


@pytest.fixture(scope="module")
def nose(shared_data):
    return read_capture(shared_data / "animface" / "NoseMoCap.ma")


@pytest.fixture(scope="module")
def small():
    rng = np.random.default_rng(7)
    positions = rng.normal(size=(6, 3, 3)) * 10
    positions[2, 1] = np.nan
    return Capture(names=("A", "B_1", "C"), positions=positions, rate=120.0, units="mm", start_frame=4)


def test_suffixes():
    assert CAPTURE_SUFFIXES == (".ma", ".c3d", ".trc", ".csv")
    assert set(WRITABLE_CAPTURE_SUFFIXES) == {".c3d", ".trc", ".csv"}


def test_reads_maya_by_suffix_any_case(tmp_path, shared_data, nose):
    assert nose.n_frames == 962 and nose.n_markers == 41 and nose.rate == 60
    assert nose.history[0]["format"] == "maya_ascii" and len(nose.history) == 1
    upper = tmp_path / "NOSE.MA"
    shutil.copyfile(shared_data / "animface" / "NoseMoCap.ma", upper)
    again = read_capture(str(upper))
    assert again.source == str(upper)
    np.testing.assert_array_equal(again.positions, nose.positions)


@pytest.mark.parametrize("suffix", [".csv", ".trc", ".c3d", ".CSV", ".Trc", ".C3D"])
def test_write_then_read_by_suffix(tmp_path, small, suffix):
    path = tmp_path / f"take{suffix}"
    assert write_capture(path, small) == path
    back = read_capture(path)
    assert back.names == small.names and back.rate == small.rate and back.units == "mm"
    assert back.start_frame == small.start_frame
    np.testing.assert_array_equal(back.valid, small.valid)
    tolerance = 1e-4 if suffix.lower() == ".c3d" else 0.0     # C3D stores float32
    np.testing.assert_allclose(back.positions, small.positions, atol=tolerance, rtol=0)
    assert back.source == str(path)
    assert len(back.history) == 1 and back.history[0]["step"] == "read"
    assert back.history[0]["format"] == {".csv": "csv", ".trc": "trc", ".c3d": "c3d"}[suffix.lower()]


def test_up_axis_override(tmp_path, small, nose):
    path = tmp_path / "take.csv"
    write_capture(path, small)
    z_up = read_capture(path, up_axis="z")
    np.testing.assert_array_equal(z_up.positions, z_up_to_y_up(small.positions))
    c3d = tmp_path / "take.c3d"
    write_capture(c3d, small)
    stored = read_capture(c3d, up_axis="Y")                      # as stored: Z-up
    np.testing.assert_allclose(stored.positions, y_up_to_z_up(small.positions), atol=1e-4)
    np.testing.assert_array_equal(z_up_to_y_up(y_up_to_z_up(small.positions)), small.positions)


def test_up_axis_z_for_maya(shared_data, nose):
    rotated = read_capture(shared_data / "animface" / "NoseMoCap.ma", up_axis="Z")
    np.testing.assert_array_equal(rotated.positions, z_up_to_y_up(nose.positions))


def test_unknown_suffix(tmp_path):
    path = tmp_path / "take.bvh"
    path.write_text("HIERARCHY\n")
    with pytest.raises(InputError, match=r"take\.bvh: unknown capture file type \(\.bvh\); known suffixes: "
                                         r"\.ma, \.c3d, \.trc, \.csv"):
        read_capture(path)
    with pytest.raises(InputError, match=r"noext: unknown capture file type \(no suffix\)"):
        read_capture(tmp_path / "noext")
    with pytest.raises(InputError, match=r"out\.ma: unknown capture file type \(\.ma\); known suffixes: "
                                         r"\.c3d, \.trc, \.csv"):
        write_capture(tmp_path / "out.ma", Capture(names=("A",), positions=np.zeros((1, 1, 3)), rate=1.0))


@pytest.mark.parametrize("suffix", CAPTURE_SUFFIXES)
def test_missing_and_unreadable(tmp_path, suffix):
    with pytest.raises(InputError, match=rf"missing{suffix}: no such file"):
        read_capture(tmp_path / f"missing{suffix}")
    folder = tmp_path / f"folder{suffix}"
    folder.mkdir()
    with pytest.raises(InputError, match=rf"folder{suffix}: is a folder, not a file"):
        read_capture(folder)


@pytest.mark.skipif(os.name != "posix" or os.geteuid() == 0, reason="root can read any file")
def test_permission_denied(tmp_path, small):
    path = tmp_path / "locked.csv"
    write_capture(path, small)
    path.chmod(0)
    with pytest.raises(InputError, match=r"locked\.csv: file is not readable"):
        read_capture(path)


@pytest.mark.parametrize("suffix, content, error, message", [
    (".csv", "", FormatError, r"empty\.csv: no header row"),
    (".trc", "", FormatError, r"empty\.trc, line 1: not a TRC file"),
    (".ma", "", FormatError, r"empty\.ma, line 1: not a Maya ASCII file"),
    (".c3d", "", FormatError, r"empty\.c3d: not a C3D file \(no C3D header"),
])
def test_empty_files(tmp_path, suffix, content, error, message):
    path = tmp_path / f"empty{suffix}"
    path.write_text(content)
    with pytest.raises(error, match=message):
        read_capture(path, units="cm", rate=60)


def test_zero_frames_and_duplicates(tmp_path):
    path = tmp_path / "zero.csv"
    path.write_text("# units=cm rate=60\nframe,A_x,A_y,A_z\n")
    with pytest.raises(MarkerError, match=r"zero\.csv: the file has a header but zero frames"):
        read_capture(path)
    path = tmp_path / "dup.csv"
    path.write_text("# units=cm rate=60\nframe,marker,x,y\n0,A,1,2\n0,A,1,2\n")
    with pytest.raises(FormatError, match=r"dup\.csv, line 4: marker 'A' at frame 0 is listed twice"):
        read_capture(path)


def test_bad_options(tmp_path, small):
    path = tmp_path / "take.csv"
    write_capture(path, small)
    with pytest.raises(OptionError, match=r"--up-axis: expected 'Y' or 'Z'; got 'X'"):
        read_capture(path, up_axis="X")
    with pytest.raises(OptionError, match=r"--rate: expected a positive number of Hz; got 'fast'"):
        read_capture(path, rate="fast")
    with pytest.raises(OptionError, match=r"--units: unknown unit 'league'"):
        read_capture(path, units="league")
