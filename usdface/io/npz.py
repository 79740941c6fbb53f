"""NumPy archives (``.npz``) read with their size known first.

``np.load`` trusts each member's header: a few kilobytes of compressed zeros can announce
gigabytes (a zip bomb), and a member whose header claims more data than it holds fails only
after the allocation. :func:`load_npz` reads every member's header (shape, dtype) first, refuses
object arrays and members that hold fewer bytes than they announce, checks the total against the
memory available, and only then loads.
"""
from __future__ import annotations

import math
import zipfile

import numpy as np

from ..errors import FormatError
from ..inputfiles import check_input_file

__all__ = ["npz_members", "load_npz"]


def npz_members(path, *, label: str) -> dict[str, tuple[tuple, np.dtype]]:
    """``{name: (shape, dtype)}`` of an .npz archive's arrays, from their headers only."""
    check_input_file(path, label=label)
    try:
        archive = zipfile.ZipFile(path)
    except (zipfile.BadZipFile, OSError) as exc:
        raise FormatError(f"{label}: not a .npz archive ({exc})") from None
    members = {}
    with archive:
        for info in archive.infolist():
            name = info.filename[:-4] if info.filename.endswith(".npy") else info.filename
            try:
                with archive.open(info) as handle:
                    version = np.lib.format.read_magic(handle)
                    reader = (np.lib.format.read_array_header_1_0 if version == (1, 0)
                              else np.lib.format.read_array_header_2_0)
                    shape, _, dtype = reader(handle)
            except (ValueError, OSError, zipfile.BadZipFile, EOFError) as exc:
                raise FormatError(f"{label}: member {name!r} is not a NumPy array ({exc})") from None
            if dtype.hasobject:
                raise FormatError(f"{label}: member {name!r} holds Python objects; usdface reads numeric arrays only")
            need = math.prod(shape) * dtype.itemsize
            if need > info.file_size:
                raise FormatError(f"{label}: member {name!r} announces shape {shape} of {dtype} ({need:,} bytes) but "
                                  f"holds {info.file_size:,} bytes: the archive is corrupt")
            members[name] = (tuple(shape), dtype)
    return members


def load_npz(path, *, label: str) -> dict[str, np.ndarray]:
    """Every array of an .npz archive, after :func:`npz_members` and a memory check."""
    from ..fileutil import format_bytes
    from ..memory import check_memory

    members = npz_members(path, label=label)
    total = sum(math.prod(shape) * dtype.itemsize for shape, dtype in members.values())
    check_memory(total, what=f"{label}: {len(members)} arrays of {format_bytes(total)}")
    try:
        with np.load(path, allow_pickle=False) as archive:
            return {name: archive[name] for name in archive.files}
    except (ValueError, OSError, zipfile.BadZipFile, EOFError) as exc:
        raise FormatError(f"{label}: cannot be read ({exc})") from None
