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
import logging
import os
from pathlib import Path

from pxr import Sdf, Tf, Usd, UsdGeom

from .. import __version__
from ..errors import InputError, OptionError
from ..fileutil import (check_output_file, file_digest, fsync_dir, fsync_file,  # noqa: F401 (file_digest re-exported)
                        inject_fault, refuse_overwriting_inputs, set_default_mode, temporary_path, write_error)
from ..inputfiles import check_input_file, check_utf8_path, display_name
from ..units import meters_per_unit, unit_name
from .diagnostics import error_text, trapped

log = logging.getLogger("usdface")

USD_SUFFIXES = (".usd", ".usda", ".usdc", ".usdz")


#: usdface writes plain layers; .usdz packages are read-only archives (package them afterwards)
OUTPUT_SUFFIXES = (".usd", ".usda", ".usdc")


#: errors USD raises (a C++ TF_ERROR surfaces as Tf.ErrorException, a RuntimeError)
USD_ERRORS = (Tf.ErrorException,)


def check_output_path(path: str | os.PathLike, *, suffixes=OUTPUT_SUFFIXES, option: str = "-o",
                      inputs: dict | None = None) -> Path:
    """Validate an output path before any work: existing folder, known suffix, and not one of the
    ``inputs`` (``{option: path}``), nor a file a USD input composes (see
    :func:`usdface.fileutil.same_file_problems`). An in-memory target (an Sdf.Layer or a
    Usd.Stage, from the Python API) is returned as it is."""
    if is_in_memory(path):
        return path
    p = Path(path)
    check_utf8_path(p, label=option)
    if inputs:
        refuse_overwriting_inputs({option: p}, with_composed_files(inputs))
    check_output_file(p, suffixes=suffixes, option=option, joiner=" or ",
                      unwritable=lambda bad: write_error(bad, PermissionError(13, "not writable")))
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


def provenance(processor: str, *, options: dict, inputs: dict[str, str | os.PathLike | None],
               identity: dict | None = None) -> dict:
    """Provenance for customLayerData: usdface version, processor, the algorithms' revision
    (:mod:`usdface.revisions`: recorded above 1), options, input names and hashes, and
    ``identity``: what the layer belongs to (:func:`usdface.usd.identity.identity`).

    No timestamps, host names or absolute paths, so the same inputs give byte-identical layers.
    """
    from ..revisions import provenance_revision

    recorded = {}
    for role, path in inputs.items():
        if path is None:
            continue
        if is_in_memory(path):  # the Python API's in-memory input: no file, no digest
            layer = path.GetRootLayer() if isinstance(path, Usd.Stage) else path
            recorded[role] = {"layer": layer.GetDisplayName() or "anonymous", "inMemory": True}
            continue
        recorded[role] = {"file": Path(path).name, "sha256": file_digest(path)}
    prov = {
        "usdfaceVersion": __version__,
        "processor": processor,
        **provenance_revision(processor),
        "options": json.dumps(options, sort_keys=True, default=str),
        "inputs": json.dumps(recorded, sort_keys=True),
    }
    if identity is not None:
        prov["identity"] = identity
    return prov


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
        check_input_file(p)
        text = check_utf8_path(p)
        layer = Sdf.Layer.OpenAsAnonymous(text, metadataOnly=True) if p.suffix.lower() == ".usdc" else \
            Sdf.Layer.FindOrOpen(text)
    except (InputError, *USD_ERRORS):
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
    check_utf8_path(p, label="USD file")  # the reader would refuse it later, after other checks
    seen, todo, found = set(), [str(p.resolve())], []
    while todo and len(seen) < limit:
        current = todo.pop()
        if current in seen:
            continue
        seen.add(current)
        try:
            with trapped():
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
    out = {label: path for label, path in inputs.items() if not is_in_memory(path)}  # no file to clash with
    for label, path in list(out.items()):
        if path is None or isinstance(path, (list, tuple)):
            continue
        deps = composed_files(path)
        if deps:
            out[f"composed by {label} {path}"] = deps
    return out


def _usd_input(path, what: str) -> tuple[Path, str, str]:
    """(Path, str for USD, label for messages) of a USD input file, after the checks every USD
    input gets: a readable regular file (a named pipe would block USD for ever), a USD suffix, a
    UTF-8 name (Sdf cannot take another), not empty."""
    p = Path(path)
    label = f"{what} {display_name(p)}"
    check_input_file(p, label=label)
    if p.suffix.lower() not in USD_SUFFIXES:
        raise InputError(f"{label}: not a USD file (expected {', '.join(USD_SUFFIXES)})")
    text = check_utf8_path(p, label=what)
    if p.stat().st_size == 0:
        raise InputError(f"{label}: the file is empty (0 bytes), not a USD layer")
    return p, text, label


def open_layer(path: str | os.PathLike, *, what: str = "layer") -> Sdf.Layer:
    """Open one USD file as an Sdf.Layer (no composition), with the checks and messages of
    :func:`open_stage`."""
    _, text, label = _usd_input(path, what)
    try:
        with trapped():
            layer = Sdf.Layer.FindOrOpen(text)
    except USD_ERRORS as exc:
        raise InputError(f"{label}: cannot be read as USD ({error_text(exc)})") from None
    if layer is None:
        raise InputError(f"{label}: cannot be read as USD")
    return layer


#: at most this many layers are opened ahead of a stage to check what it composes
MAX_COMPOSED_LAYERS = 512


def _open_composed_layers(root: str, label: str) -> list:
    """Open the layers ``root`` composes (sublayers, references, payloads), before the stage does.

    A named pipe among them would block USD for ever; a parse error in a sublayer would reach the
    user only as a warning, and a missing or cyclic sublayer as a misleading error later. Returns
    the opened layers (keep them until the stage is open: USD then reuses them).
    """
    opened, done = [], set()
    todo = [(root, (root,), None)]  # (path, chain of sublayers down to it, how it is composed)
    while todo and len(done) < MAX_COMPOSED_LAYERS:
        path, chain, via = todo.pop()
        if path in done:
            continue
        done.add(path)
        if via is not None:
            if not os.path.exists(path):
                continue  # the stage reports it, unless the asset resolver finds it elsewhere
            check_input_file(path, label=f"{label}: {via}")
        try:
            with trapped():
                layer = Sdf.Layer.FindOrOpen(path)
        except USD_ERRORS as exc:
            raise InputError(f"{label}: {via + ' ' if via else ''}cannot be read as USD ({error_text(exc)})") from None
        if layer is None:
            continue
        opened.append(layer)
        name = os.path.basename(path)
        subs = set()
        for sub in layer.subLayerPaths:
            target = layer.ComputeAbsolutePath(sub)
            subs.add(target)
            if target in chain:
                loop = " -> ".join(os.path.basename(c) for c in chain[chain.index(target):] + (target,))
                raise InputError(f"{label}: its sublayers form a cycle ({loop}); a layer cannot sublayer itself")
            todo.append((target, chain + (target,), f"sublayer {sub} of {name}"))
        for asset in layer.GetCompositionAssetDependencies():
            target = layer.ComputeAbsolutePath(asset)
            if target and target not in subs:
                todo.append((target, (target,), f"{asset} (referenced by {name})"))
    return opened


def open_stage(path: str | os.PathLike, *, what: str = "layer", composition: str = "error") -> Usd.Stage:
    """Open a USD file as a stage, with one line naming it when it cannot be used.

    Refused (InputError): a missing, unreadable or non-regular file (a named pipe, a device), a
    name that is not UTF-8, an empty file, a file USD cannot parse (USD's own message kept, e.g.
    ``shot.usda:7:1: parse error ... at '}'``, without its C++ source location), a composed layer
    that is a named pipe or cannot be parsed, sublayers that form a cycle. USD's warnings never
    reach stderr raw: a composition problem (a missing sublayer, reference or payload) is an error
    with ``composition="error"`` (readers: the stage would lack what they read), a usdface warning
    with ``"warn"`` (``info``), dropped with ``"ignore"`` (``check``, whose validators report it);
    other warnings become usdface warnings. A Usd.Stage is returned as it is and an Sdf.Layer
    opened as a stage (in-memory input from the Python API).
    """
    if isinstance(path, Usd.Stage):
        return path
    if isinstance(path, Sdf.Layer):
        return Usd.Stage.Open(path, Usd.Stage.LoadAll)
    if composition not in ("error", "warn", "ignore"):
        raise ValueError(f"open_stage: composition must be 'error', 'warn' or 'ignore'; got {composition!r}")
    p, text, label = _usd_input(path, what)
    keep = _open_composed_layers(os.path.abspath(text), label)
    try:
        with trapped() as found:
            stage = Usd.Stage.Open(text, Usd.Stage.LoadAll)
    except USD_ERRORS as exc:
        raise InputError(f"{label}: cannot be read as USD ({error_text(exc)})") from None
    finally:
        del keep
    if stage is None:
        raise InputError(f"{label}: cannot be read as USD")
    problems = [d.text for d in found if d.composition]
    for d in found:
        if not d.composition:
            log.warning("%s: %s", label, d.text)
    if problems and composition == "error":
        more = f" (and {len(problems) - 1} more: `usdface check` lists them)" if len(problems) > 1 else ""
        raise InputError(f"{label}: {problems[0]}{more}")
    if composition == "warn":
        for text in problems:
            log.warning("%s: %s", label, text)
    return stage


def relative_asset_path(target: str | os.PathLike, from_layer: str | os.PathLike) -> str:
    """Asset path of ``target`` relative to the folder of ``from_layer`` ("./name" style)."""
    rel = os.path.relpath(Path(target).resolve(), Path(from_layer).resolve().parent)
    rel = rel.replace(os.sep, "/")
    return rel if rel.startswith(".") else "./" + rel


# -- in-memory targets (the Python API) -----------------------------------------------------------

def is_in_memory(target) -> bool:
    """Whether ``target`` is a layer or stage object rather than a file path."""
    return isinstance(target, (Sdf.Layer, Usd.Stage))


def new_anonymous_layer(name: str) -> Sdf.Layer:
    """A new in-memory layer (the Python API's default output)."""
    return Sdf.Layer.CreateAnonymous(name)


def describe(source) -> str:
    """A file path as given, or an in-memory stage/layer by its root layer's name (for messages)."""
    if isinstance(source, Usd.Stage):
        return f"in-memory stage {source.GetRootLayer().GetDisplayName() or source.GetRootLayer().identifier}"
    if isinstance(source, Sdf.Layer):
        return f"in-memory layer {source.GetDisplayName() or source.identifier}"
    return str(source)


def target_layer(target) -> Sdf.Layer:
    """The layer an in-memory target means: the layer itself, or a stage's edit target layer."""
    if isinstance(target, Sdf.Layer):
        return target
    edit = target.GetEditTarget()
    if not edit.GetMapFunction().isIdentity:
        raise OptionError("into: the stage's edit target maps paths (a variant or reference edit target); "
                          "pass the Sdf.Layer to author into instead")
    return edit.GetLayer()


class InMemoryLayer:
    """Author into an existing layer, all or nothing (the Python API's counterpart of AtomicLayer).

    The processor authors into a private anonymous layer; only when the ``with`` block succeeds
    are its opinions merged into the target (:func:`merge_layer`), so an error leaves the target
    exactly as it was.
    """

    path = None

    def __init__(self, target):
        self.into = target_layer(target)
        self.stage: Usd.Stage | None = None

    def __enter__(self) -> Usd.Stage:
        self.staged = Sdf.Layer.CreateAnonymous("usdface.usda")
        self.stage = Usd.Stage.Open(self.staged)
        return self.stage

    def __exit__(self, exc_type, exc, tb) -> bool:
        if exc_type is None:
            merge_layer(self.staged, self.into)
        self.stage = None
        return False


def output_layer(target):
    """The context manager a writer authors through: :class:`AtomicLayer` for a file path,
    :class:`InMemoryLayer` for an Sdf.Layer or a Usd.Stage."""
    return InMemoryLayer(target) if is_in_memory(target) else AtomicLayer(target)


def checkpoint(stage: Usd.Stage) -> None:
    """Save what a long write has authored so far (flat memory on long .usdc writes); nothing
    to do for an in-memory target."""
    layer = stage.GetRootLayer()
    if not layer.anonymous:
        layer.Save()


def add_sublayer(stage: Usd.Stage, source, output) -> None:
    """Sublayer ``source`` (the layer an output builds on, e.g. the mesh) by a path relative to
    ``output``, so the output opens alone. In memory (either side) the caller composes: nothing."""
    if is_in_memory(source) or is_in_memory(output) or output is None:
        return
    stage.GetRootLayer().subLayerPaths.append(relative_asset_path(source, output))


def new_stage(layers) -> Usd.Stage:
    """An in-memory stage sublayering ``layers`` (Sdf.Layer, Usd.Stage or file paths), with the
    first one's units, up axis and default prim and the first time range found (see
    :func:`usdface.api.new_stage`)."""
    stage = Usd.Stage.CreateInMemory()
    root = stage.GetRootLayer()
    opened = []
    for item in layers:
        layer = item.GetRootLayer() if isinstance(item, Usd.Stage) else item if isinstance(item, Sdf.Layer) \
            else open_layer(Path(item).resolve(), what="layer")
        if layer is None:
            raise InputError(f"{item}: cannot be read as USD")
        root.subLayerPaths.append(layer.identifier)
        opened.append(layer)
    if opened:
        first = opened[0].pseudoRoot
        for key in ("metersPerUnit", "upAxis", "defaultPrim"):
            if first.HasInfo(key):
                root.pseudoRoot.SetInfo(key, first.GetInfo(key))
        timed = next((lay for lay in opened if lay.HasStartTimeCode() or lay.HasTimeCodesPerSecond()), None)
        if timed is not None:
            for key in ("timeCodesPerSecond", "framesPerSecond", "startTimeCode", "endTimeCode"):
                if timed.pseudoRoot.HasInfo(key):
                    root.pseudoRoot.SetInfo(key, timed.pseudoRoot.GetInfo(key))
    stage._usdface_layers = opened  # keep anonymous sublayers alive as long as the stage
    return stage


_LAYER_FIELDS = ("defaultPrim", "metersPerUnit", "upAxis", "timeCodesPerSecond", "framesPerSecond",
                 "startTimeCode", "endTimeCode")


def merge_layer(src: Sdf.Layer, dst: Sdf.Layer) -> None:
    """Merge the opinions of ``src`` into ``dst``: every property ``src`` authors replaces the same
    property in ``dst`` (time samples included), prims and their metadata are added or updated
    (applied schemas are unioned), everything else in ``dst`` stays. ``dst`` is replaced in one
    step at the end (``TransferContent``), so a failure part-way leaves it unchanged."""
    work = Sdf.Layer.CreateAnonymous("merge.usda")
    work.TransferContent(dst)
    for key in _LAYER_FIELDS:
        if src.pseudoRoot.HasInfo(key):
            work.pseudoRoot.SetInfo(key, src.pseudoRoot.GetInfo(key))
    if src.customLayerData:
        data = dict(work.customLayerData)
        data.update(src.customLayerData)
        work.customLayerData = data
    for sub in src.subLayerPaths:
        if sub not in work.subLayerPaths:
            work.subLayerPaths.append(sub)

    def merge_prim(spec: Sdf.PrimSpec) -> None:
        path = spec.path
        target = work.GetPrimAtPath(path)
        if target is None:
            Sdf.CopySpec(src, path, work, path)  # a new prim: its whole subtree
            return
        for key in spec.ListInfoKeys():
            if key == "specifier":
                if spec.specifier == Sdf.SpecifierDef:
                    target.specifier = Sdf.SpecifierDef
            elif key == "typeName":
                if spec.typeName:
                    target.typeName = spec.typeName
            elif key == "apiSchemas":
                have = list(target.GetInfo(key).GetAddedOrExplicitItems()) if target.HasInfo(key) else []
                new = [s for s in spec.GetInfo(key).GetAddedOrExplicitItems() if s not in have]
                op = Sdf.TokenListOp()
                op.prependedItems = have + new
                target.SetInfo(key, op)
            else:
                target.SetInfo(key, spec.GetInfo(key))
        for prop in spec.properties:
            if work.GetPropertyAtPath(prop.path) is not None:
                work.GetPrimAtPath(path).RemoveProperty(work.GetPropertyAtPath(prop.path))
            Sdf.CopySpec(src, prop.path, work, prop.path)
        for child in spec.nameChildren:
            merge_prim(child)

    for root in src.rootPrims:
        merge_prim(root)
    dst.TransferContent(work)
