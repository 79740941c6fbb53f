"""Writing and opening layers: atomic output, stage metadata, provenance.

Every layer usdface writes goes through :class:`AtomicLayer`: the layer is created at a temporary
path in the destination folder (same extension, so the same file format), saved (as often as the
caller likes, which keeps memory flat for long time-sampled .usdc writes), then renamed over the
destination in one ``os.replace``. A failure leaves the destination as it was, and a failure of
the file system (disk full, read-only, permission; USD's own errors included) becomes one
:class:`~usdface.errors.WriteError` naming the destination and the cause.
"""
from __future__ import annotations

import contextlib
import hashlib
import json
import os
from pathlib import Path

from pxr import Sdf, Tf, Usd, UsdGeom

from .. import __version__
from ..errors import InputError, OptionError
from ..fileutil import (file_digest, fsync_dir, fsync_file, inject_fault, refuse_overwriting_inputs,  # noqa: F401
                        set_default_mode, temporary_path, write_error)  # (file_digest re-exported)
from ..units import meters_per_unit, unit_name

USD_SUFFIXES = (".usd", ".usda", ".usdc", ".usdz")


#: usdface writes plain layers; .usdz packages are read-only archives (package them afterwards)
OUTPUT_SUFFIXES = (".usd", ".usda", ".usdc")


#: errors USD raises (a C++ TF_ERROR surfaces as Tf.ErrorException, a RuntimeError)
USD_ERRORS = (Tf.ErrorException,)


def check_output_path(path: str | os.PathLike, *, suffixes=OUTPUT_SUFFIXES, option: str = "-o",
                      inputs: dict | None = None) -> Path:
    """Validate an output path before any work: existing folder, known suffix, and not one of the
    ``inputs`` (``{option: path}``), nor a file a USD input composes (see
    :func:`usdface.fileutil.same_file_problems`)."""
    p = Path(path)
    if inputs:
        refuse_overwriting_inputs({option: p}, with_composed_files(inputs))
    if p.suffix.lower() not in suffixes:
        raise OptionError(f"{option} {p}: expected a file ending in {' or '.join(suffixes)}")
    folder = p.parent if str(p.parent) else Path(".")
    if not folder.is_dir():
        raise OptionError(f"{option} {p}: folder {folder} does not exist")
    if not os.access(folder, os.W_OK):
        raise write_error(p, PermissionError(13, "not writable"))
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
        self.tmp_path = temporary_path(self.path)  # names its owner (pid@host): see usdface.shot_commit
        self.stage: Usd.Stage | None = None

    def __enter__(self) -> Usd.Stage:
        try:
            inject_fault("create", self.path)
            layer = Sdf.Layer.CreateNew(str(self.tmp_path))
        except (OSError, *USD_ERRORS) as exc:
            self._remove_tmp()
            raise write_error(self.path, exc) from None
        if layer is None:
            raise write_error(self.path, None)
        self.stage = Usd.Stage.Open(layer)
        return self.stage

    def __exit__(self, exc_type, exc, tb) -> bool:
        layer = self.stage.GetRootLayer() if self.stage is not None else None
        try:
            if exc_type is None:
                inject_fault("save", self.path)
                if not layer.Save():
                    raise write_error(self.path, None)
                fsync_file(self.tmp_path)
                inject_fault("replace", self.path)
                os.replace(self.tmp_path, self.path)
                fsync_dir(self.path.parent)
                set_default_mode(self.path)  # temp files come out 0600
            elif self._is_own_write_failure(exc):
                # a failure inside the block while saving this layer (intermediate saves of long .usdc writes)
                raise write_error(self.path, exc) from None
        except (OSError, *USD_ERRORS) as err:
            raise write_error(self.path, err) from None
        finally:
            self.stage = None
            del layer
            self._remove_tmp()
        return False

    def _is_own_write_failure(self, exc) -> bool:
        if isinstance(exc, USD_ERRORS):
            return True
        if isinstance(exc, OSError):
            name = exc.filename
            return name is None or Path(os.fspath(name)).name in (self.tmp_path.name, self.path.name)
        return False

    def _remove_tmp(self) -> None:
        with contextlib.suppress(OSError):
            self.tmp_path.unlink()


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


def layer_provenance(path: str | os.PathLike) -> dict | None:
    """The usdface provenance of a layer file (metadata only: large .usdc files are not loaded),
    or None when the file cannot be opened or has none."""
    p = Path(path)
    try:
        layer = Sdf.Layer.OpenAsAnonymous(str(p), metadataOnly=True) if p.suffix.lower() == ".usdc" else \
            Sdf.Layer.FindOrOpen(str(p))
    except USD_ERRORS:
        return None
    if layer is None:
        return None
    data = dict(layer.customLayerData)
    return _plain(data["usdface"]) if "usdface" in data else None


def _plain(value):
    """customLayerData values as plain Python (VtDictionary -> dict, arrays -> lists)."""
    if hasattr(value, "items"):
        return {str(k): _plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_plain(v) for v in value]
    return value


def provenance_id(prov: dict | None) -> str | None:
    """A short id of a layer's provenance (sha256 of its canonical JSON): equal ids, same job on the
    same input bytes."""
    if prov is None:
        return None
    return hashlib.sha256(json.dumps(prov, sort_keys=True, default=str).encode()).hexdigest()[:16]


def composed_files(path: str | os.PathLike, *, limit: int = 64) -> list[str]:
    """The local files a USD file composes (sublayers, references, payloads), recursively; [] for a
    file that is not USD or cannot be opened (the processor reports that later)."""
    p = Path(path)
    if p.suffix.lower() not in USD_SUFFIXES or not p.is_file():
        return []
    seen, todo, found = set(), [str(p.resolve())], []
    while todo and len(seen) < limit:
        current = todo.pop()
        if current in seen:
            continue
        seen.add(current)
        try:
            layer = Sdf.Layer.FindOrOpen(current)
        except USD_ERRORS:
            continue
        if layer is None:
            continue
        for asset in layer.GetCompositionAssetDependencies():
            target = layer.ComputeAbsolutePath(asset)
            if target and os.path.isfile(target):
                if target not in seen:
                    found.append(target)
                    todo.append(target)
    return found


def with_composed_files(inputs: dict) -> dict:
    """``inputs`` ({option: path}) plus, for each USD input, the files it composes."""
    out = dict(inputs)
    for label, path in inputs.items():
        if path is None or isinstance(path, (list, tuple)):
            continue
        deps = composed_files(path)
        if deps:
            out[f"composed by {label} {path}"] = deps
    return out


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
