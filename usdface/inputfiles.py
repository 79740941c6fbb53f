"""Checks every reader makes before it reads (no pxr, no cv2: cheap to import).

A hostile or broken input must be refused with one line naming it before any work, never hang,
allocate without bound or reach a library that does:

- :func:`check_input_file`: a regular, readable file (a named pipe would block the reader for
  ever; a device or a socket is no file at all; a folder is a usage slip);
- :func:`check_utf8_path`: a path USD can take (Sdf keeps paths as UTF-8 strings: a name with a
  byte that is not UTF-8 would fail inside it);
- :func:`read_text_file`: a text input of bounded size that is UTF-8, read in one go (every
  structured input below starts here);
- :func:`read_json`: a JSON file of bounded size and nesting, without NaN/Infinity or duplicate
  keys (Python's json reads both silently, keeping the last duplicate);
- :func:`parse_toml`: TOML text (a batch manifest) of bounded nesting (tomllib recurses, so
  100000 nested ``[`` raised RecursionError);
- :func:`first_beyond_float32`: values usdface stores as float32 (every point in a USD layer)
  must be finite float32 numbers; 1e308 would become inf.
"""
from __future__ import annotations

import json
import os
import stat
from pathlib import Path

import numpy as np

from .errors import FormatError, InputError

__all__ = ["FLOAT32_MAX", "MAX_JSON_BYTES", "MAX_JSON_DEPTH", "MAX_TEXT_BYTES", "check_input_file", "check_utf8_path",
           "read_text_file", "read_json", "parse_toml", "first_beyond_float32", "display_name"]

#: the largest finite float32 (USD's point and vector arrays are float32)
FLOAT32_MAX = float(np.finfo(np.float32).max)
#: JSON inputs (layouts, seeds, calibrations, landmarks) are small; a larger file is not one of them
MAX_JSON_BYTES = 64 * 1024 * 1024
#: deepest nesting a usdface JSON input needs is 4 ({"markers": {"A": {"point": [..]}}}); 64 is generous
MAX_JSON_DEPTH = 64
#: text inputs (manifests, seeds, timelines...): a manifest of 10,000 shots is about 2 MB
MAX_TEXT_BYTES = 64 * 1024 * 1024

_KINDS = ((stat.S_ISDIR, "is a folder, not a file"), (stat.S_ISFIFO, "is a named pipe (FIFO), not a regular file"),
          (stat.S_ISCHR, "is a character device, not a regular file"),
          (stat.S_ISBLK, "is a block device, not a regular file"), (stat.S_ISSOCK, "is a socket, not a regular file"))


def _label(path, label: str | None) -> str:
    return label if label is not None else os.fspath(path)


def check_input_file(path, *, label: str | None = None) -> Path:
    """Return ``path`` as a Path if it names a readable regular file; else raise InputError.

    Symbolic links are followed. The message is ``"<label>: <problem>"`` (label: the path as
    given), e.g. ``"take.csv: is a named pipe (FIFO), not a regular file"``.
    """
    p = Path(os.fspath(path))
    where = _label(path, label)
    try:
        st = os.stat(p)
    except FileNotFoundError:
        problem = "no such file" if not p.is_symlink() else "a symbolic link to a missing file"
        raise InputError(f"{where}: {problem}") from None
    except NotADirectoryError:
        raise InputError(f"{where}: no such file (a part of the path is not a folder)") from None
    except PermissionError:
        raise InputError(f"{where}: cannot be read (permission denied on its folder)") from None
    except OSError as exc:  # ELOOP (a symbolic link loop), ENAMETOOLONG...
        raise InputError(f"{where}: cannot be read ({exc.strerror or exc})") from None
    for test, problem in _KINDS:
        if test(st.st_mode):
            raise InputError(f"{where}: {problem}")
    if not stat.S_ISREG(st.st_mode):
        raise InputError(f"{where}: not a regular file")
    if not os.access(p, os.R_OK):
        raise InputError(f"{where}: file is not readable (permission denied)")
    return p


def check_utf8_path(path, *, label: str = "") -> str:
    """``path`` as a str USD can take; InputError when it holds a byte that is not UTF-8.

    Python keeps such a byte as a lone surrogate (``'\\udcff'``), which Sdf cannot encode.
    """
    text = os.fspath(path)
    text = os.fsdecode(text) if isinstance(text, bytes) else text
    try:
        text.encode("utf-8")
    except UnicodeEncodeError as exc:
        raw = os.fsencode(text)
        bad = raw[len(text[:exc.start].encode("utf-8", "surrogateescape")):][:1]
        shown = raw.decode("utf-8", "backslashreplace")
        raise InputError(f"{label + ' ' if label else ''}{shown}: the name holds the byte 0x{bad.hex() or '??'}, "
                         f"which is not UTF-8; USD needs UTF-8 file names: rename the file (or folder)") from None
    return text


def display_name(path) -> str:
    """A file name (or path) as text that any UTF-8 consumer accepts: bytes that are not UTF-8
    are written as ``\\xNN`` (for names only recorded, such as a capture's source file)."""
    text = os.fspath(path)
    return os.fsencode(text).decode("utf-8", "backslashreplace")


def _depth(value) -> int:
    """Nesting depth of a parsed JSON value (iterative: no recursion on hostile input)."""
    deepest, todo = 0, [(value, 1)]
    while todo:
        item, level = todo.pop()
        if isinstance(item, (dict, list)):
            deepest = max(deepest, level)
            todo.extend((child, level + 1) for child in (item.values() if isinstance(item, dict) else item))
    return deepest


def read_text_file(path, *, label: str | None = None, max_bytes: int = MAX_TEXT_BYTES, kind: str = "text") -> str:
    """The text of an input file, checked before it is read: a readable regular file (a named pipe
    would block for ever, a device never end: :func:`check_input_file`), at most ``max_bytes``
    bytes (the size is known before reading), UTF-8 (a byte-order mark is dropped).

    Errors name the file as ``"<label>: "`` and say what was expected; ``kind`` names the format in
    them ("JSON", "TOML"). InputError: not a readable regular file; FormatError: too large, not UTF-8.
    """
    where = _label(path, label)
    p = check_input_file(path, label=where)
    size = p.stat().st_size
    if size > max_bytes:
        raise FormatError(f"{where}: {size:,} bytes; a usdface {kind} input is at most {max_bytes:,} bytes")
    try:
        with open(p, "rb") as f:
            data = f.read(max_bytes + 1)  # a file that grows while read stops at the limit too
    except OSError as exc:
        raise InputError(f"{where}: cannot be read ({exc.strerror or exc})") from None
    if len(data) > max_bytes:
        raise FormatError(f"{where}: more than {max_bytes:,} bytes; a usdface {kind} input is at most that")
    try:
        return data.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        line = data.count(b"\n", 0, exc.start) + 1
        raise FormatError(f"{where}: not UTF-8 text (byte 0x{data[exc.start]:02x} at line {line}); "
                          f"{kind} files are UTF-8") from None


def parse_toml(text: str, *, where: str, max_depth: int = MAX_JSON_DEPTH) -> dict:
    """Parse TOML ``text`` (read with :func:`read_text_file`) with bounded nesting.

    FormatError ``"<where>: ..."``: not valid TOML (tomllib's message, with its line and column),
    or nested deeper than ``max_depth`` (arrays, inline tables or dotted keys; tomllib parses
    nested arrays by recursion, which 100000 ``[`` exhausted).
    """
    import tomllib

    too_deep = f"{where}: nested deeper than {max_depth} levels; not a usdface TOML file"
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise FormatError(f"{where}: not valid TOML ({exc})") from None
    except RecursionError:
        raise FormatError(too_deep) from None
    if _depth(data) > max_depth:
        raise FormatError(too_deep)
    return data


def read_json(path, *, label: str | None = None, max_bytes: int = MAX_JSON_BYTES,
              max_depth: int = MAX_JSON_DEPTH):
    """Read a JSON input file, refusing what Python's json would accept but no usdface file holds.

    Refused (FormatError, the message starting ``"<label>: "``): more than ``max_bytes`` bytes;
    text that is not UTF-8; nesting deeper than ``max_depth``; ``NaN``/``Infinity`` or a number
    beyond float64; a key twice in one object; invalid JSON (with its line and column).
    InputError: not a readable regular file (:func:`check_input_file`).
    """
    where = _label(path, label)
    text = read_text_file(path, label=where, max_bytes=max_bytes, kind="JSON")
    if not text.strip():
        raise FormatError(f"{where}: the file is empty (expected a JSON object)")

    def constant(name):
        raise FormatError(f"{where}: {name} is not a number JSON allows (write null or leave the entry out)")

    def number(token):
        value = float(token)
        if not np.isfinite(value):
            raise FormatError(f"{where}: the number {token} is beyond the range of a float")
        return value

    def integer(token):
        if len(token.lstrip("-")) > 18:  # beyond int64 (and beyond any count or index usdface reads)
            raise FormatError(f"{where}: the integer {token[:24]}{'...' if len(token) > 24 else ''} is too large")
        return int(token)

    def pairs(items):
        out = {}
        for key, value in items:
            if key in out:
                raise FormatError(f"{where}: the key {key!r} appears twice in one object (which one is meant?)")
            out[key] = value
        return out

    too_deep = f"{where}: nested deeper than {max_depth} levels; not a usdface JSON file"
    try:
        value = json.loads(text, parse_constant=constant, parse_float=number, parse_int=integer,
                           object_pairs_hook=pairs)
    except json.JSONDecodeError as exc:
        raise FormatError(f"{where}: not valid JSON: {exc.msg} at line {exc.lineno}, column {exc.colno}") from None
    except RecursionError:  # json's scanner stops at Python's recursion limit (about 1000 levels)
        raise FormatError(too_deep) from None
    if _depth(value) > max_depth:
        raise FormatError(too_deep)
    return value


def first_beyond_float32(values) -> tuple | None:
    """Index (a tuple) of the first value beyond float32's finite range (inf included, NaN not),
    or None. ``values`` is any array-like of numbers."""
    a = np.asarray(values, dtype=np.float64)
    with np.errstate(invalid="ignore"):
        bad = np.abs(a) > FLOAT32_MAX
    if not bad.any():
        return None
    return tuple(int(i) for i in np.unravel_index(int(np.argmax(bad)), a.shape))
