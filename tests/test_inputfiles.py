"""The checks every reader makes first (usdface.inputfiles)."""
from __future__ import annotations

import os
import socket

import numpy as np
import pytest

from usdface.errors import FormatError, InputError
from usdface.inputfiles import check_input_file, check_utf8_path, display_name, first_beyond_float32, read_json


def test_only_readable_regular_files_pass(tmp_path):
    ok = tmp_path / "ok.txt"
    ok.write_text("x")
    assert check_input_file(ok) == ok
    os.mkfifo(tmp_path / "pipe")
    with pytest.raises(InputError, match=r"pipe: is a named pipe \(FIFO\), not a regular file"):
        check_input_file(tmp_path / "pipe")
    with pytest.raises(InputError, match=r"^/dev/null: is a character device, not a regular file$"):
        check_input_file("/dev/null")
    with socket.socket(socket.AF_UNIX) as s:
        s.bind(str(tmp_path / "sock"))
        with pytest.raises(InputError, match=r"sock: is a socket, not a regular file"):
            check_input_file(tmp_path / "sock")
    (tmp_path / "loop").symlink_to(tmp_path / "loop")
    with pytest.raises(InputError, match=r"loop: cannot be read \(Too many levels of symbolic links\)"):
        check_input_file(tmp_path / "loop")
    (tmp_path / "dangling").symlink_to(tmp_path / "gone")
    with pytest.raises(InputError, match=r"dangling: a symbolic link to a missing file"):
        check_input_file(tmp_path / "dangling", label=str(tmp_path / "dangling"))
    with pytest.raises(InputError, match=r"^layout x: is a folder, not a file$"):
        check_input_file(tmp_path, label="layout x")


def test_non_utf8_names_are_refused_for_usd_and_escaped_for_display():
    name = os.fsdecode(b"take\xff.usdc")
    with pytest.raises(InputError, match=r"^capture take\\xff\.usdc: the name holds the byte 0xff, which is not "
                                         r"UTF-8; USD needs UTF-8 file names"):
        check_utf8_path(name, label="capture")
    assert check_utf8_path("tête.usda") == "tête.usda"
    assert display_name(name) == "take\\xff.usdc" and display_name("tête.ma") == "tête.ma"


def test_json_depth_is_checked_after_parsing_too(tmp_path):
    p = tmp_path / "a.json"
    p.write_text("[" * 65 + "]" * 65)
    with pytest.raises(FormatError, match="nested deeper than 64 levels"):
        read_json(p)
    p.write_text("[" * 64 + "]" * 64)
    assert read_json(p) is not None
    p.write_text("x" * 100)
    with pytest.raises(FormatError, match=r"a\.json: 100 bytes; a usdface JSON input is at most 10 bytes"):
        read_json(p, max_bytes=10)


def test_first_beyond_float32():
    assert first_beyond_float32(np.array([[1.0, np.nan], [3e38, -3e38]])) is None
    assert first_beyond_float32(np.array([[1.0, np.nan], [3.5e38, np.inf]])) == (1, 0)
    assert first_beyond_float32([0.0, -np.inf]) == (1,)


# -- text, TOML: the bounded readers every structured input goes through ---------------------------

def test_text_inputs_are_bounded_before_they_are_read(tmp_path):
    from usdface.inputfiles import MAX_TEXT_BYTES, read_text_file

    huge = tmp_path / "huge.toml"
    with open(huge, "wb") as f:  # sparse: the size is refused before a byte is read
        f.truncate(MAX_TEXT_BYTES + 1)
    with pytest.raises(FormatError, match=r"^manifest .*huge\.toml: 67,108,865 bytes; a usdface TOML input is at most "
                                          r"67,108,864 bytes$"):
        read_text_file(huge, label=f"manifest {huge}", kind="TOML")
    latin = tmp_path / "latin.toml"
    latin.write_bytes(b'[batch]\nsummary = "s\xe9.json"\n')
    with pytest.raises(FormatError, match=r"latin\.toml: not UTF-8 text \(byte 0xe9 at line 2\); TOML files are UTF-8"):
        read_text_file(latin, kind="TOML")
    bom = tmp_path / "bom.toml"
    bom.write_bytes(b"\xef\xbb\xbfa = 1\n")
    assert read_text_file(bom) == "a = 1\n"
    os.mkfifo(tmp_path / "pipe.toml")
    with pytest.raises(InputError, match=r"pipe\.toml: is a named pipe \(FIFO\), not a regular file"):
        read_text_file(tmp_path / "pipe.toml")


@pytest.mark.parametrize("text", ["a = " + "[" * 100000, "a = " + "{b = " * 100000,
                                  "[" + ".".join(["a"] * 100) + "]\nx = 1\n", "a = " + "[" * 65 + "]" * 65])
def test_toml_nesting_is_bounded(text):
    from usdface.inputfiles import parse_toml

    with pytest.raises(FormatError, match=r"^manifest m\.toml: nested deeper than 64 levels; not a usdface TOML file$"):
        parse_toml(text, where="manifest m.toml")


def test_toml_errors_keep_tomllib_s_line():
    from usdface.inputfiles import parse_toml

    assert parse_toml("[batch]\nworkers = 2\n", where="m") == {"batch": {"workers": 2}}
    with pytest.raises(FormatError, match=r"^m: not valid TOML \(.*line 2, column"):
        parse_toml("[batch]\nworkers = \n", where="m")
