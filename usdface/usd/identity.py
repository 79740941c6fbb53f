"""Which mesh, take and bound markers each layer belongs to, and the checks wherever layers meet.

Every layer usdface writes records, in its own ``customLayerData["usdface"]["identity"]``, the
identities (:mod:`usdface.model.identity`) of what it was made for or from::

    identity = {version: 1,
                mesh:    {sha256, points, faces}       # every layer built on (or holding) a mesh
                markers: {names, boundPoints, count}   # binding, analysis and what is made from them
                capture: {sha256, markers, frames}}    # the capture layer, and layers made from a take

A mesh layer's ``mesh`` and a capture layer's ``capture`` are their own; the others say what the
layer was made for. Layers that depend on the character only (binding, analysis) carry no take,
so an analysis, and the distance cache, serve every take of a character.

Why layer metadata and not attributes: (1) composition cannot confuse it. An attribute on the
mesh prim authored by the mesh, binding, analysis and animation layers resolves to the strongest
opinion in a shot, hiding the claims of the weaker layers, which is exactly what a check must
compare; each layer's customLayerData is its own (root-layer metadata is never composed) and is
read per input layer, without composing or loading samples (``metadataOnly`` for .usdc). (2) A
DCC round trip cannot leave a stale claim: DCCs re-export a new layer without customLayerData
(Blender drops it, and usdface attributes with it), whereas a custom attribute kept by a DCC on a
mesh whose points were edited would vouch for geometry it no longer describes. The identity of the
mesh and the take themselves is never taken from metadata: it is computed from their content
wherever they are inputs, so edited geometry is caught too.

Layers without a record (written by usdface 0.2, or by another tool) are accepted with one
warning naming the file.
"""
from __future__ import annotations

import logging
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from pxr import Sdf, Usd, UsdGeom

from ..errors import InputError, MixedLayersError
from ..model.identity import (IDENTITY_VERSION, bound_points_identity, capture_identity, marker_names_identity,
                              mesh_identity, short)
from ..units import METERS_PER_UNIT, unit_name
from .diagnostics import trapped
from .layers import USD_ERRORS, describe, is_in_memory, layer_provenance

log = logging.getLogger("usdface")

__all__ = ["mesh_record", "markers_record", "capture_record", "identity", "Claims", "claims_of", "verify",
           "agreeing_identity", "with_composed_layers", "composed_take", "describe_identity", "prim_mesh_record",
           "marker_set_take", "stage_findings", "mixed_layers", "mixed_layers_warning", "KINDS"]

KEY = "identity"
#: the kinds of identity, the field compared, and how a message names the value
KINDS = ("mesh", "markers", "capture")
COMPARED = {"mesh": "sha256", "markers": "boundPoints", "capture": "sha256"}
UNVERIFIED = {"mesh": "its mesh", "markers": "its bound markers", "capture": "its take"}
#: the processors whose layer holds what its identity of a kind describes (the others record what
#: their layer was made for or from)
HOLDERS = {"mesh": frozenset({"import-mesh", "stereo", "register", "shapes transfer"}),
           "capture": frozenset({"import-capture", "lift", "track"})}


# -- records --------------------------------------------------------------------------------------

def meters_per_unit(units) -> float | None:
    """metersPerUnit of a unit name or value, named units normalised (None: unknown)."""
    if units is None:
        return None
    if isinstance(units, str):
        return METERS_PER_UNIT.get(units)
    name = unit_name(float(units))
    return METERS_PER_UNIT[name] if name else float(units)


def mesh_record(mesh) -> dict:
    """The mesh identity record of a :class:`usdface.model.FaceMesh`."""
    return {"sha256": mesh_identity(mesh.face_vertex_counts, mesh.face_vertex_indices, mesh.points,
                                    meters_per_unit(mesh.units)),
            "points": int(mesh.n_points), "faces": int(mesh.n_faces)}


def markers_record(binding) -> dict:
    """The markers record of a :class:`usdface.model.Binding`: its names and its bound points."""
    return {"names": marker_names_identity(binding.names),
            "boundPoints": bound_points_identity(binding.names, binding.triangle_vertices, binding.barycentrics),
            "count": len(binding.names)}


def capture_record(capture) -> dict:
    """The take identity record of a :class:`usdface.model.Capture`."""
    return {"sha256": capture_identity(capture), "markers": int(capture.n_markers), "frames": int(capture.n_frames)}


def identity(*, mesh=None, markers=None, capture=None) -> dict:
    """The identity a layer records, from the records of what it belongs to (None: not recorded)."""
    out = {"version": IDENTITY_VERSION}
    for kind, record in (("mesh", mesh), ("markers", markers), ("capture", capture)):
        if record is not None:
            out[kind] = dict(record)
    return out


#: how a message joins an input's name to its value ("mesh m.usdc is 9be03d1a2b3c (2020 points)")
IS = {"mesh": "is", "markers": "has", "capture": "is"}


def _value_text(kind: str, record: dict, *, named: bool = True, names: bool = False) -> str:
    """How a message shows an identity; ``names``: a markers record by its marker names (when the
    names differ) rather than by its bound points."""
    if kind == "mesh":
        return f"{'mesh ' if named else ''}{short(record.get('sha256'))} ({record.get('points')} points)"
    if kind == "markers":
        field, what = ("names", "marker names") if names else ("boundPoints", "bound points")
        return f"{what} {short(record.get(field))} ({record.get('count')} markers)"
    return f"take {short(record.get('sha256'))} ({record.get('markers')} markers, {record.get('frames')} frames)"


def _names_differ(kind: str, a: dict, b: dict) -> bool:
    """Whether two markers records differ in their marker names (not only in the bound points)."""
    return kind == "markers" and a.get("names") != b.get("names")


def describe_identity(ident: dict | None) -> str | None:
    """One line of the identities a record holds, short hex (for `usdface info`)."""
    if not ident:
        return None
    return "; ".join(_value_text(kind, ident[kind]) for kind in KINDS if kind in ident) or None


# -- the claims of one input layer ------------------------------------------------------------------

@dataclass(frozen=True)
class Claims:
    """What one layer says it belongs to: ``label`` names it in messages ("binding b.usda"),
    ``identity`` its record (None: none), ``version`` the usdface version that wrote it (None: not
    written by usdface)."""

    label: str
    identity: dict | None
    version: str | None
    processor: str | None = None

    def get(self, kind: str) -> dict | None:
        return None if self.identity is None else self.identity.get(kind)

    def holds(self, kind: str) -> bool:
        """Whether the layer holds what its ``kind`` identity describes (a mesh layer its mesh, a
        capture or track layer its take) rather than having been made for it."""
        return self.processor in HOLDERS.get(kind, ())

    def phrase(self, kind: str, record: dict, *, names: bool = False, short_verb: bool = False) -> str:
        """``"is mesh 9be0… (2020 points)"`` for a layer holding it, else ``"was made for …"``
        (``short_verb``: ``"for …"``, after a first claim in the same sentence)."""
        value = _value_text(kind, record, names=names)
        if self.holds(kind):
            return f"is {value}"
        verb = "from" if kind == "capture" else "for"
        return f"{verb} {value}" if short_verb else f"was made {verb} {value}"


def _provenance_of(source) -> dict | None:
    if is_in_memory(source):
        layer = source.GetRootLayer() if isinstance(source, Usd.Stage) else source
        data = dict(layer.customLayerData)
        return data.get("usdface")
    return layer_provenance(source)


def _readable(ident) -> dict | None:
    """A record this usdface can compare (another identity version cannot be)."""
    if not isinstance(ident, dict) or ident.get("version") != IDENTITY_VERSION:
        return None
    return ident


def claims_of(source, what: str) -> Claims:
    """The claims of the input ``source`` (a path, or an in-memory layer or stage: its root layer),
    named ``"{what} {source}"`` in messages."""
    prov = _provenance_of(source) or {}
    return Claims(label=f"{what} {describe(source)}", identity=_readable(prov.get(KEY)),
                  version=prov.get("usdfaceVersion"), processor=prov.get("processor"))


def _unverified_text(label: str, version: str | None, kinds) -> str:
    what = " and ".join(UNVERIFIED[k] for k in kinds)
    if version:
        return f"{label} was written by usdface {version}: {what} cannot be verified"
    return (f"{label} carries no usdface identity (written by another tool, or re-exported): {what} cannot be "
            "verified")


def verify(claims: Claims, *, remedy: str = "", **actual) -> None:
    """Check what ``claims`` says against the actual inputs it is combined with.

    ``actual``: ``mesh=(label, record)``, ``markers=(label, record)``, ``capture=(label, record)``
    (None entries are skipped). Raises MixedLayersError at the first kind that differs, naming
    both inputs and both identities; when the layer records none of the kinds asked, one warning
    names the file (a layer of usdface 0.2 is accepted).
    """
    unverified = []
    for kind in KINDS:
        given = actual.get(kind)
        if given is None:
            continue
        label, record = given
        claim = claims.get(kind)
        if claim is None:
            unverified.append(kind)
            continue
        key = COMPARED[kind]
        if claim.get(key) != record.get(key):
            names = _names_differ(kind, claim, record)
            raise MixedLayersError(f"{claims.label} {claims.phrase(kind, claim, names=names)}, {label} {IS[kind]} "
                                   f"{_value_text(kind, record, named=kind != 'mesh', names=names)}"
                                   + (f"; {remedy}" if remedy else ""))
    if unverified:
        log.warning("%s", _unverified_text(claims.label, claims.version, unverified))


def agreeing_identity(paths, *, what: str) -> dict:
    """The identity the layers ``paths`` (strongest first) and the files they compose agree on
    (each kind from the layers that record it); MixedLayersError naming two layers that disagree
    and what differs (``what`` names the file combining them, e.g. ``"shot OUTDIR/shot.usda"``).

    Only what the layers record is read (their metadata; no samples): the mesh and capture layers
    under a shot record their own content, so a deliverable made from another take than the
    capture its binding references is caught here too.
    """
    merged, first = {}, {}
    for path in with_composed_layers(paths):
        claims = claims_of(path, "layer")
        for kind in KINDS:
            claim = claims.get(kind)
            if claim is None:
                continue
            if kind not in merged:
                merged[kind], first[kind] = claim, claims
            elif claim.get(COMPARED[kind]) != merged[kind].get(COMPARED[kind]):
                names = _names_differ(kind, merged[kind], claim)
                ref = first[kind]
                raise MixedLayersError(f"{what}: {ref.label} {ref.phrase(kind, merged[kind], names=names)}, "
                                       f"{claims.label} {claims.phrase(kind, claim, names=names, short_verb=True)}; "
                                       "they cannot be combined")
    return identity(**merged)


def composed_take(source) -> tuple[str, dict] | None:
    """(file, take record) of the first layer under ``source`` (itself, or a file it composes) that
    holds a take and records its identity: the markers a binding shows. None when there is none
    (an in-memory layer, a capture layer of usdface 0.2)."""
    if is_in_memory(source):
        return None
    for path in with_composed_layers([source]):
        claims = claims_of(path, "layer")
        if claims.holds("capture") and claims.get("capture") is not None:
            return str(path), claims.get("capture")
    return None


#: most files followed under one layer (a shot composes five or six)
_MAX_COMPOSED = 64


def with_composed_layers(paths) -> list:
    """``paths`` (strongest first), each followed by the local layers it composes (sublayers,
    references, payloads; recursively), each file once. A composed file is named relative to the
    folder of the path that led to it (``OUTDIR/mesh.usdc`` under ``OUTDIR/anim.usdc``), as the
    caller named that path. In-memory layers are kept as they are (they compose no file)."""
    seen, out = set(), []
    for path in paths:
        if is_in_memory(path):
            out.append(path)
            continue
        base = Path(path)
        for found in [base, *(base.parent / rel for rel in _composed_relative(base))]:
            key = os.path.realpath(found)
            if key not in seen:
                seen.add(key)
                out.append(found)
    return out


def _composed_relative(path: Path) -> list[str]:
    """The local layer files ``path`` composes, recursively, relative to its folder. A .usdc is
    opened for its metadata only (its sublayers; usdface's binary layers compose nothing else),
    a .usda fully (a binding references its capture)."""
    root = os.path.realpath(path)
    folder = os.path.dirname(root)
    seen, todo, found = {root}, [root], []
    while todo and len(seen) < _MAX_COMPOSED:
        current = todo.pop(0)
        for target in _dependencies(current):
            if target not in seen:
                seen.add(target)
                todo.append(target)
                found.append(os.path.relpath(target, folder))
    return found


def _dependencies(path: str) -> list[str]:
    """Absolute paths of the existing local files one layer file composes ([] when it cannot be read:
    the reader of that layer says why)."""
    try:
        with trapped():
            layer = Sdf.Layer.OpenAsAnonymous(path, metadataOnly=True) if path.lower().endswith(".usdc") else \
                Sdf.Layer.FindOrOpen(path)
    except USD_ERRORS:
        return []
    if layer is None:
        return []
    assets = list(layer.subLayerPaths) if path.lower().endswith(".usdc") else \
        list(layer.GetCompositionAssetDependencies())
    found = []
    for asset in assets:
        target = os.path.normpath(os.path.join(os.path.dirname(path), asset)) if not os.path.isabs(asset) else asset
        if os.path.isfile(target):
            found.append(os.path.realpath(target))
    return found


# -- identities of a composed stage (usdface check) -----------------------------------------------

def _points_layer(attr, *, sampled: bool = False) -> Sdf.Layer | None:
    """The layer whose default value of ``attr`` wins (the rest points' layer); with ``sampled``,
    the strongest one holding a default value or time samples."""
    for spec in attr.GetPropertyStack(Usd.TimeCode.Default()):
        if spec.HasDefaultValue() or (sampled and spec.layer.GetNumTimeSamplesForPath(spec.path)):
            return spec.layer
    return None


def marker_set_take(prim: Usd.Prim) -> dict | None:
    """The take record of the capture layer holding a composed marker set's points (None when
    none can be read)."""
    layer = _points_layer(UsdGeom.Points(prim).GetPointsAttr(), sampled=True)
    return None if layer is None else layer_capture_record(layer)


def _layer_units(layer: Sdf.Layer):
    return layer.pseudoRoot.GetInfo("metersPerUnit") if layer.pseudoRoot.HasInfo("metersPerUnit") else None


def prim_mesh_record(prim: Usd.Prim) -> tuple[dict, Sdf.Layer] | None:
    """(mesh record, layer holding its rest points) of a Mesh prim on a composed stage; None when it
    has no rest points or faces. The units are the points' layer's (USD never converts them)."""
    geom = UsdGeom.Mesh(prim)
    points_attr = geom.GetPointsAttr()
    points = points_attr.Get(Usd.TimeCode.Default())
    counts = geom.GetFaceVertexCountsAttr().Get()
    indices = geom.GetFaceVertexIndicesAttr().Get()
    layer = _points_layer(points_attr)
    if points is None or counts is None or indices is None or layer is None:
        return None
    record = {"sha256": mesh_identity(np.asarray(counts), np.asarray(indices), np.asarray(points),
                                      meters_per_unit(_layer_units(layer))),
              "points": len(points), "faces": len(counts)}
    return record, layer


def prim_markers_record(prim: Usd.Prim) -> dict | None:
    """The markers record of a composed FaceMarkerBindingAPI (None: not bound, or incomplete)."""
    from .mesh_layer import BINDING_API, read_binding

    if not prim.HasAPI(BINDING_API):
        return None
    try:
        return markers_record(read_binding(prim.GetStage(), source=str(prim.GetPath())))
    except (InputError, TypeError, ValueError):
        return None  # the validators report a malformed binding


def layer_capture_record(layer: Sdf.Layer) -> dict | None:
    """The take record of a capture layer read alone (None: it defines no marker set, or one that
    cannot be read: the validators say why)."""
    from .capture_layer import MARKER_SET_API, read_capture_layer

    if not any(MARKER_SET_API in (spec.GetInfo("apiSchemas").GetAddedOrExplicitItems()
                                  if spec.HasInfo("apiSchemas") else ()) for spec in _prim_specs(layer)):
        return None
    try:
        stage = Usd.Stage.Open(layer)
        capture = read_capture_layer(layer.identifier, stage=stage)
    except (InputError, ValueError):
        return None
    if _pixel_units(stage):
        capture = capture.replace(units="px")  # a 2D track layer: pixels, as `track` records and `lift` reads it
    return capture_record(capture)


def _pixel_units(stage: Usd.Stage) -> bool:
    """Whether the stage's marker set declares pixels (a 2D track layer, which has no metersPerUnit)."""
    from .capture_layer import find_marker_set

    try:
        prim = find_marker_set(stage, what="track layer")
    except InputError:
        return False
    return prim.GetAttribute("usdface:markerSet:sourceUnits").Get() == "px"


def _prim_specs(layer: Sdf.Layer):
    todo = list(layer.rootPrims)
    while todo:
        spec = todo.pop()
        yield spec
        todo.extend(spec.nameChildren)


def _name(layer: Sdf.Layer, folder) -> str:
    if layer.anonymous or not layer.realPath:
        return layer.GetDisplayName() or layer.identifier
    if folder is None:
        return os.path.basename(layer.realPath)
    rel = os.path.relpath(layer.realPath, folder)
    return rel if not rel.startswith("..") else layer.realPath


def _references(stage: Usd.Stage, folder, captures) -> dict:
    """{kind: (text, record, holder, named)} of what the stage actually holds, computed from
    content: its face mesh, its binding, its (first) capture; ``holder`` is the layer holding the
    data, ``text`` names it in messages ("the stage's mesh /Face/Geom (points from mesh.usdc) is"),
    ``named``: whether the value says its kind ("take 3fa…" but "9be03d…" after "mesh ... is")."""
    from .mesh_layer import find_mesh

    found = {}
    try:
        prim = find_mesh(stage, what="file")
    except InputError:
        prim = None
    if prim is not None:
        mesh = prim_mesh_record(prim)
        if mesh is not None:
            found["mesh"] = (f"the stage's mesh {prim.GetPath()} (points from {_name(mesh[1], folder)}) is",
                             mesh[0], mesh[1], False)
        markers = prim_markers_record(prim)
        if markers is not None:
            holder = _points_layer(prim.GetAttribute("usdface:binding:triangleVertexIndices"))
            where = f" ({_name(holder, folder)})" if holder is not None else ""
            found["markers"] = (f"the stage's binding on {prim.GetPath()}{where} has", markers, holder, True)
    if captures:
        layer, record = captures[0]
        found["capture"] = (f"capture {_name(layer, folder)} is", record, layer, True)
    return found


def _claim_finding(name: str, kind: str, claim: dict, reference: tuple, layer) -> str | None:
    """The message when ``claim`` (of layer ``name``) differs from ``reference``; None when equal."""
    text, record, holder, named = reference
    if claim.get(COMPARED[kind]) == record.get(COMPARED[kind]):
        return None
    names = _names_differ(kind, claim, record)
    if holder is not None and holder == layer:
        return (f"{name} records {_value_text(kind, claim, names=names)} but holds "
                f"{_value_text(kind, record, names=names)} (changed after usdface wrote it)")
    verb = "made from" if kind == "capture" else "made for"
    return (f"{name} was {verb} {_value_text(kind, claim, names=names)}, {text} "
            f"{_value_text(kind, record, named=named, names=names)}")


def stage_findings(stage: Usd.Stage, *, folder=None) -> list[tuple[str, str, str]]:
    """(severity, layer, message) for every layer of ``stage`` (root, sublayers, references) whose
    recorded identity differs from what the stage holds (its mesh's rest points and topology, its
    binding's bound points, its captures' takes) or, where the stage holds none, from the first
    (strongest) layer recording one; a warning for each usdface layer that records none and does
    not hold its own mesh or take (:data:`HOLDERS`: their identity is their content)."""
    session = stage.GetSessionLayer()
    layers = [layer for layer in stage.GetUsedLayers(includeClipLayers=False) if layer != session]
    order = {layer.identifier: i for i, layer in enumerate(stage.GetLayerStack(includeSessionLayers=False))}
    layers.sort(key=lambda layer: (order.get(layer.identifier, len(order)), layer.identifier))
    captures = [(layer, rec) for layer in layers for rec in [layer_capture_record(layer)] if rec is not None]
    reference = _references(stage, folder, captures)
    takes = {rec["sha256"] for _, rec in captures}
    findings = []
    for layer in layers:
        prov = dict(layer.customLayerData).get("usdface")
        if not isinstance(prov, dict):
            continue
        name = _name(layer, folder)
        ident = _readable(prov.get(KEY))
        if ident is None:
            if prov.get("processor") not in HOLDERS["mesh"] | HOLDERS["capture"]:  # content is identity
                findings.append(("warning", name, _unverified_text(name, prov.get("usdfaceVersion"), ("mesh",))))
            continue
        for kind in KINDS:
            claim = ident.get(kind)
            if claim is None:
                continue
            own = next((rec for lay, rec in captures if lay == layer), None) if kind == "capture" else None
            if own is not None:
                ref = ("", own, layer, True)
            elif kind == "capture" and claim.get("sha256") in takes:
                continue  # several takes composed: the one it was made from is among them
            elif kind in reference:
                ref = reference[kind]
            else:
                reference[kind] = (f"{name} {'from' if kind == 'capture' else 'for'}", claim, None, True)
                continue
            message = _claim_finding(name, kind, claim, ref, layer)
            if message is not None:
                findings.append(("error", name, message))
    return findings


def mixed_layers(path) -> list[str]:
    """The errors :func:`stage_findings` reports on the stage at ``path`` (layers made for another
    mesh, other bound points or another take than the ones it composes), in the order `check` lists
    them, for the commands that only read a shot (`playblast`, `report`) and warn; [] for a
    consistent shot."""
    from .layers import open_stage

    path = Path(path)
    stage = open_stage(path, what="shot")
    findings = stage_findings(stage, folder=path.resolve().parent)
    return [message for severity, _, message in sorted(findings, key=lambda f: f[1]) if severity == "error"]  # as check


def mixed_layers_warning(path, messages: list[str]) -> str:
    """One line for a shot whose layers disagree: the first finding, how many more, where to look."""
    more = f" (and {len(messages) - 1} more)" if len(messages) > 1 else ""
    return f"shot {path} mixes layers: {messages[0]}{more}; `usdface check {path}` lists every finding"
