"""Writing and opening layers: atomic output, stage metadata, provenance.

Every layer usdface writes goes through :class:`AtomicLayer`: the layer is created at a temporary
path in the destination folder (same extension, so the same file format), saved (as often as the
caller likes, which keeps memory flat for long time-sampled .usdc writes), then renamed over the
destination in one ``os.replace``. A failure leaves the destination as it was.
"""
from __future__ import annotations

import json
import os
import secrets
from pathlib import Path

from pxr import Sdf, Usd, UsdGeom

from .. import __version__
from ..fileutil import file_digest, fsync_dir, fsync_file  # noqa: F401  (file_digest re-exported)
from ..errors import InputError, OptionError
from ..units import meters_per_unit, unit_name

USD_SUFFIXES = (".usd", ".usda", ".usdc", ".usdz")


#: usdface writes plain layers; .usdz packages are read-only archives (package them afterwards)
OUTPUT_SUFFIXES = (".usd", ".usda", ".usdc")


def check_output_path(path: str | os.PathLike, *, suffixes=OUTPUT_SUFFIXES, option: str = "-o") -> Path:
    """Validate an output path before any work: existing folder, known suffix."""
    p = Path(path)
    if p.suffix.lower() not in suffixes:
        raise OptionError(f"{option} {p}: expected a file ending in {' or '.join(suffixes)}")
    folder = p.parent if str(p.parent) else Path(".")
    if not folder.is_dir():
        raise OptionError(f"{option} {p}: folder {folder} does not exist")
    if not os.access(folder, os.W_OK):
        raise OptionError(f"{option} {p}: folder {folder} is not writable")
    return p


class AtomicLayer:
    """Create a USD layer that replaces ``path`` atomically when the ``with`` block succeeds.

    Examples
    --------
    >>> with AtomicLayer("anim.usdc") as stage:          # doctest: +SKIP
    ...     author(stage); stage.GetRootLayer().Save()    # intermediate saves are fine
    """

    def __init__(self, path: str | os.PathLike):
        self.path = check_output_path(path)
        token = secrets.token_hex(4)
        self.tmp_path = self.path.with_name(f".{self.path.stem}.tmp-{os.getpid()}-{token}{self.path.suffix}")
        self.stage: Usd.Stage | None = None

    def __enter__(self) -> Usd.Stage:
        layer = Sdf.Layer.CreateNew(str(self.tmp_path))
        if layer is None:
            raise InputError(f"cannot create {self.tmp_path}")
        self.stage = Usd.Stage.Open(layer)
        return self.stage

    def __exit__(self, exc_type, exc, tb) -> bool:
        layer = self.stage.GetRootLayer() if self.stage is not None else None
        try:
            if exc_type is None:
                if not layer.Save():
                    raise InputError(f"could not write {self.tmp_path}")
                fsync_file(self.tmp_path)
                os.replace(self.tmp_path, self.path)
                fsync_dir(self.path.parent)
                mask = os.umask(0)
                os.umask(mask)
                os.chmod(self.path, 0o666 & ~mask)  # temp files come out 0600
        finally:
            self.stage = None
            del layer
            if self.tmp_path.exists():
                self.tmp_path.unlink()
        return False


def set_stage_metadata(stage: Usd.Stage, *, units: str | None, default_prim: str,
                       rate: float | None = None, start: float | None = None, end: float | None = None,
                       up_axis: str = "Y") -> None:
    """Set the metadata every usdface layer carries (root-layer metadata is not inherited)."""
    if units is not None:
        UsdGeom.SetStageMetersPerUnit(stage, meters_per_unit(units))
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.y if up_axis.upper() == "Y" else UsdGeom.Tokens.z)
    if rate is not None:
        stage.SetTimeCodesPerSecond(rate)
        stage.SetFramesPerSecond(rate)
    if start is not None:
        stage.SetStartTimeCode(start)
    if end is not None:
        stage.SetEndTimeCode(end)
    stage.GetRootLayer().defaultPrim = default_prim


def stage_units(stage: Usd.Stage) -> str | None:
    """The stage's linear unit name, or None when metersPerUnit is not authored or not a named unit."""
    if not stage.HasAuthoredMetadata(UsdGeom.Tokens.metersPerUnit):
        return None
    return unit_name(UsdGeom.GetStageMetersPerUnit(stage))


def provenance(processor: str, *, options: dict, inputs: dict[str, str | os.PathLike | None]) -> dict:
    """Provenance for customLayerData: usdface version, processor, options, input names and hashes.

    No timestamps, host names or absolute paths, so the same inputs give byte-identical layers.
    """
    recorded = {}
    for role, path in inputs.items():
        if path is None:
            continue
        recorded[role] = {"file": Path(path).name, "sha256": file_digest(path)}
    return {
        "usdfaceVersion": __version__,
        "processor": processor,
        "options": json.dumps(options, sort_keys=True, default=str),
        "inputs": json.dumps(recorded, sort_keys=True),
    }


def set_provenance(stage: Usd.Stage, prov: dict) -> None:
    data = dict(stage.GetRootLayer().customLayerData)
    data["usdface"] = prov
    stage.GetRootLayer().customLayerData = data


def get_provenance(layer_or_stage) -> dict:
    layer = layer_or_stage.GetRootLayer() if isinstance(layer_or_stage, Usd.Stage) else layer_or_stage
    return dict(layer.customLayerData.get("usdface", {}))


def open_stage(path: str | os.PathLike, *, what: str = "layer") -> Usd.Stage:
    """Open a USD file, with an error naming it when it is missing or unreadable."""
    p = Path(path)
    if not p.exists():
        raise InputError(f"{what} {p}: no such file")
    if p.suffix.lower() not in USD_SUFFIXES:
        raise InputError(f"{what} {p}: not a USD file (expected {', '.join(USD_SUFFIXES)})")
    try:
        stage = Usd.Stage.Open(str(p), Usd.Stage.LoadAll)
    except Exception as exc:  # pxr raises Tf.ErrorException with a long C++ message
        raise InputError(f"{what} {p}: cannot be read as USD ({str(exc).strip().splitlines()[-1]})") from None
    if stage is None:
        raise InputError(f"{what} {p}: cannot be read as USD")
    return stage


def relative_asset_path(target: str | os.PathLike, from_layer: str | os.PathLike) -> str:
    """Asset path of ``target`` relative to the folder of ``from_layer`` ("./name" style)."""
    rel = os.path.relpath(Path(target).resolve(), Path(from_layer).resolve().parent)
    rel = rel.replace(os.sep, "/")
    return rel if rel.startswith(".") else "./" + rel
