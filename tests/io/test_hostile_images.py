"""Hostile images, float maps and NumPy archives: headers that lie, pipes, zip bombs; and the JSON
files of the scan pipeline (calibration, landmarks) read through usdface.inputfiles."""
from __future__ import annotations

import os
import struct
import zipfile

import numpy as np
import pytest

from usdface.errors import FormatError, InputError
from usdface.io.images import read_float_map, read_image


def _npy_header(shape, descr="<f8") -> bytes:
    text = repr({"descr": descr, "fortran_order": False, "shape": tuple(shape)}).encode()
    text += b" " * (-(10 + len(text) + 1) % 64) + b"\n"
    return b"\x93NUMPY\x01\x00" + struct.pack("<H", len(text)) + text


def test_npz_member_announcing_80_gb_is_refused_before_loading(tmp_path):
    from usdface.io.npz import npz_members

    bomb = tmp_path / "model.npz"
    with zipfile.ZipFile(bomb, "w") as z:
        z.writestr("meta.npy", _npy_header((100000, 100000)) + b"\0" * 64)
    with pytest.raises(FormatError, match=r"model\.npz: member 'meta' announces shape \(100000, 100000\) of float64 "
                                          r"\(80,000,000,000 bytes\) but holds \d+ bytes"):
        npz_members(bomb, label=str(bomb))
    from usdface.scan.aam import load_aam

    with pytest.raises(FormatError, match=r"AAM model .*model\.npz: member 'meta' announces"):
        load_aam(bomb)


def test_npz_of_objects_and_not_a_zip(tmp_path):
    from usdface.io.npz import load_npz

    objects = tmp_path / "o.npz"
    with zipfile.ZipFile(objects, "w") as z:
        z.writestr("a.npy", _npy_header((2,), descr="|O") + b"\0" * 16)
    with pytest.raises(FormatError, match=r"member 'a' holds Python objects"):
        load_npz(objects, label="o.npz")
    text = tmp_path / "t.npz"
    text.write_text("hello")
    with pytest.raises(FormatError, match=r"t\.npz: not a \.npz archive"):
        load_npz(text, label="t.npz")
    good = tmp_path / "g.npz"
    np.savez(good, a=np.arange(3.0), b=np.eye(2))
    arrays = load_npz(good, label="g.npz")
    assert sorted(arrays) == ["a", "b"] and arrays["b"].shape == (2, 2)


def test_float_maps_with_lying_headers(tmp_path):
    pfm = tmp_path / "d.pfm"
    pfm.write_bytes(b"Pf\n100000 100000\n-1.0\n" + b"\0" * 16)
    with pytest.raises(FormatError, match=r"d\.pfm: the header announces 100000x100000x1 floats "
                                          r"\(40,000,000,000 bytes\) but the file holds 16 bytes"):
        read_float_map(pfm)
    pfm.write_bytes(b"Pf\nwide tall\n-1.0\n")
    with pytest.raises(FormatError, match=r"d\.pfm: PFM header needs 'width height'"):
        read_float_map(pfm)
    npy = tmp_path / "d.npy"
    npy.write_bytes(_npy_header((100000, 100000)) + b"\0" * 16)
    with pytest.raises(FormatError, match=r"d\.npy: not a readable \.npy array"):
        read_float_map(npy)
    good = tmp_path / "g.npy"
    np.save(good, np.ones((2, 3), np.float32))
    assert read_float_map(good).shape == (2, 3)


def test_named_pipes_and_folders_as_images(tmp_path):
    os.mkfifo(tmp_path / "p.png")
    with pytest.raises(InputError, match=r"image .*p\.png: is a named pipe \(FIFO\)"):
        read_image(tmp_path / "p.png")
    (tmp_path / "d.pfm").mkdir()
    with pytest.raises(InputError, match=r"float map .*d\.pfm: is a folder, not a file"):
        read_float_map(tmp_path / "d.pfm")


def test_scan_json_inputs_refuse_what_python_would_read(tmp_path):
    from usdface.scan.calibration import read_calibration
    from usdface.scan.landmarks import read_landmarks

    deep = tmp_path / "calib.json"
    deep.write_text("{\"a\": " * 5000 + "1" + "}" * 5000)
    with pytest.raises(FormatError, match=r"calibration .*calib\.json: nested deeper than 64 levels"):
        read_calibration(deep)
    dup = tmp_path / "lm.json"
    dup.write_text('{"nose": {"image": [1, 2]}, "nose": {"image": [3, 4]}}')
    with pytest.raises(FormatError, match=r"landmarks file .*lm\.json: the key 'nose' appears twice"):
        read_landmarks(dup)
    far = tmp_path / "far.json"
    far.write_text('{"nose": {"scan": [1e39, 0, 0]}}')
    with pytest.raises(FormatError, match=r"landmark 'nose': scan must be 3 finite numbers \(float32\)"):
        read_landmarks(far)


# -- what C libraries print (issue 20, item 13): never on the user's stderr before usdface's line --

def test_libpng_chatter_goes_to_the_debug_log_not_stderr(tmp_path, capfd, caplog):
    """OpenCV's libpng prints "libpng warning: iCCP: known incorrect sRGB profile" for the shared
    astronaut photo and "libpng error: PNG input buffer is incomplete" for a cut PNG, straight to
    descriptor 2; usdface logs them at debug level instead, naming the file."""
    import logging

    from tests.conftest import SHARED_DATA

    photo = SHARED_DATA / "images" / "astronaut.png"
    if not photo.is_file():
        pytest.skip(f"{photo} not present")
    caplog.set_level(logging.DEBUG, logger="usdface.io")
    capfd.readouterr()
    assert read_image(photo).shape == (512, 512, 3)
    assert capfd.readouterr().err == ""
    assert any("libpng warning: iCCP" in r.getMessage() and "astronaut.png" in r.getMessage() for r in caplog.records)
    cut = tmp_path / "cut.png"
    cut.write_bytes(photo.read_bytes()[:20000])
    with pytest.raises(InputError, match=r"image .*cut\.png: cannot be read as an image"):
        read_image(cut)
    assert capfd.readouterr().err == ""


def test_native_stderr_is_restored_and_nested_blocks_share_one_capture(capfd, caplog):
    import logging

    from usdface.io.native_output import native_stderr_to_log

    caplog.set_level(logging.DEBUG, logger="usdface.io")
    capfd.readouterr()
    with native_stderr_to_log("outer"):
        os.write(2, b"from C, outer\n")
        with native_stderr_to_log("inner"):
            os.write(2, b"from C, inner\n")
        os.write(2, b"")
    os.write(2, b"after\n")
    assert capfd.readouterr().err == "after\n"
    assert [r.getMessage() for r in caplog.records if r.name == "usdface.io"] == \
        ["outer: from C, outer", "outer: from C, inner"]
