"""The outputs of one call checked together, before any work: each one's suffix and folder, none of
them an input, no two of them the same file (`solve`, `run`'s blend-shape step, `shapes transfer`)."""
from __future__ import annotations

from pathlib import Path

from ..errors import OptionError
from .layers import check_output_path, is_in_memory

__all__ = ["check_outputs"]


def check_outputs(inputs: dict, outputs: dict) -> dict:
    """Validate output paths before any work.

    Parameters
    ----------
    inputs : dict
        ``{option: path or None}`` of the files read (``"--mesh"``: the mesh file); in-memory
        inputs (the Python API's layers) are skipped.
    outputs : dict
        ``{option: (path or None, kind)}``, kind ``"usd"`` (a layer: a USD suffix, or in memory an
        ``Sdf.Layer`` / ``Usd.Stage``) or ``"csv"``; None paths are not written and skipped.

    Returns
    -------
    dict
        ``{option: Path}`` (in-memory layers as they are) of the outputs given.

    Raises
    ------
    OptionError
        Naming the option: a wrong suffix, a missing folder, an output that is an input, or two
        outputs naming the same file.
    """
    checked = {}
    for option, (path, kind) in outputs.items():
        if path is None:
            continue
        if kind == "csv":
            p = Path(path)
            if p.suffix.lower() != ".csv":
                raise OptionError(f"{option} {p}: expected a file ending in .csv")
            folder = p.parent if str(p.parent) else Path(".")
            if not folder.is_dir():
                raise OptionError(f"{option} {p}: folder {folder} does not exist")
        else:
            p = check_output_path(path, option=option)
        checked[option] = p
    resolved = {}
    for option, p in checked.items():
        if is_in_memory(p):
            continue
        r = p.resolve()
        for in_opt, in_path in inputs.items():
            if in_path is not None and not is_in_memory(in_path) and Path(in_path).exists() \
                    and Path(in_path).resolve() == r:
                raise OptionError(f"{option} {p} is the input {in_opt} {in_path}: outputs never replace inputs")
        if r in resolved:
            raise OptionError(f"{option} {p} and {resolved[r]} name the same file")
        resolved[r] = option
    return checked
