"""`usdface check`: USD's own validators (UsdValidation) plus rules for usdface's schemas.

usdface's rules are registered as UsdValidation prim validators (keyword ``usdface``), so they run
through the same framework and report the same way as USD's built-in ones.
"""
from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from pxr import Usd, UsdGeom, UsdValidation

from .diagnostics import trapped
from .layers import open_stage

KEYWORD = "usdface"


@dataclass(frozen=True)
class Finding:
    """One problem found by a validator."""

    severity: str  # "error" | "warning" | "info"
    rule: str      # validator name, e.g. "usdface:MarkerSetConsistency"
    site: str      # prim or layer path
    message: str

    def __str__(self) -> str:
        return f"{self.severity.upper()} [{self.rule}] {self.site}: {self.message}"


def _err(prim: Usd.Prim, name: str, message: str, kind=UsdValidation.ValidationErrorType.Error):
    site = UsdValidation.ValidationErrorSite(prim.GetStage(), prim.GetPath())
    return UsdValidation.ValidationError(name, kind, [site], message)


def _time_samples(attr) -> list:
    samples = attr.GetTimeSamples()
    return samples if samples else [Usd.TimeCode.Default()]


def _check_marker_set(prim: Usd.Prim, time_range=None):
    errors = []
    names = prim.GetAttribute("usdface:markerSet:names").Get()
    if not names:
        return [_err(prim, "NoMarkerNames", "usdface:markerSet:names is empty")]
    if len(set(names)) != len(names):
        dups = sorted({n for n in names if list(names).count(n) > 1})
        errors.append(_err(prim, "DuplicateMarkerNames", f"duplicate marker names: {', '.join(dups)}"))
    points_attr = UsdGeom.Points(prim).GetPointsAttr()
    valid_attr = prim.GetAttribute("primvars:usdface:valid")
    bad_len, nan_frames = [], []
    for t in _time_samples(points_attr):
        pts = points_attr.Get(t)
        if pts is None:
            continue
        arr = np.asarray(pts)
        if len(arr) != len(names):
            bad_len.append(t)
        if not np.isfinite(arr).all():
            nan_frames.append(t)
    if bad_len:
        errors.append(_err(prim, "MarkerCountMismatch",
                           f"{len(bad_len)} time samples have a point count other than the {len(names)} marker names "
                           f"(first at time {bad_len[0]})"))
    if nan_frames:
        errors.append(_err(prim, "NaNPoints", f"points hold NaN or inf at {len(nan_frames)} time samples "
                           f"(first at time {nan_frames[0]}); invalid samples must hold the last valid value"))
    if valid_attr and valid_attr.HasValue():
        for t in _time_samples(valid_attr):
            v = valid_attr.Get(t)
            if v is not None and len(v) != len(names):
                errors.append(_err(prim, "ValidityLength", f"primvars:usdface:valid has {len(v)} entries at time {t}, expected {len(names)}"))
                break
    rate = prim.GetAttribute("usdface:markerSet:captureRate").Get()
    stage = prim.GetStage()
    if rate and abs(rate - stage.GetTimeCodesPerSecond()) > 1e-9 and stage.GetRootLayer().HasTimeCodesPerSecond():
        errors.append(_err(prim, "RateMismatch", f"captureRate {rate} differs from the stage's timeCodesPerSecond "
                           f"{stage.GetTimeCodesPerSecond()}"))
    return errors


def _mesh_sizes(prim: Usd.Prim) -> tuple[int, int]:
    mesh = UsdGeom.Mesh(prim)
    pts = mesh.GetPointsAttr().Get()
    counts = mesh.GetFaceVertexCountsAttr().Get()
    return (len(pts) if pts is not None else 0), (len(counts) if counts is not None else 0)


def _check_binding(prim: Usd.Prim, time_range=None):
    errors = []
    ns = "usdface:binding"
    names = prim.GetAttribute(f"{ns}:markerNames").Get() or []
    m = len(names)
    n_points, n_faces = _mesh_sizes(prim)
    arrays = {k: prim.GetAttribute(f"{ns}:{k}").Get() for k in
              ("faceIndices", "triangleVertexIndices", "barycentrics", "nearestVertices", "residuals")}
    for key, value in arrays.items():
        if value is None or len(value) != m:
            errors.append(_err(prim, "BindingLength", f"{ns}:{key} has {0 if value is None else len(value)} entries, "
                               f"expected one per marker ({m})"))
    if errors:
        return errors
    bary = np.asarray(arrays["barycentrics"], dtype=np.float64)
    if (np.abs(bary.sum(axis=1) - 1) > 1e-6).any() or (bary < -1e-6).any():
        bad = [names[i] for i in np.flatnonzero((np.abs(bary.sum(axis=1) - 1) > 1e-6) | (bary < -1e-6).any(axis=1))]
        errors.append(_err(prim, "BadBarycentrics", f"barycentrics do not sum to 1 or are negative for markers {', '.join(bad[:8])}"))
    tri = np.asarray(arrays["triangleVertexIndices"])
    near = np.asarray(arrays["nearestVertices"])
    if n_points and (tri.max() >= n_points or near.max() >= n_points or tri.min() < 0 or near.min() < 0):
        errors.append(_err(prim, "BindingIndexRange", f"binding vertex indices outside 0..{n_points - 1}"))
    faces = np.asarray(arrays["faceIndices"])
    if n_faces and (faces.max() >= n_faces or faces.min() < 0):
        errors.append(_err(prim, "BindingIndexRange", f"binding face indices outside 0..{n_faces - 1}"))
    targets = prim.GetRelationship(f"{ns}:markerSet").GetTargets()
    if targets:
        target = prim.GetStage().GetPrimAtPath(targets[0])
        if target and target.HasAPI("FaceMarkerSetAPI"):
            capture_names = list(target.GetAttribute("usdface:markerSet:names").Get() or [])
            missing = [n for n in names if n not in capture_names]
            if missing:
                errors.append(_err(prim, "BindingMarkersMissing",
                                   f"bound markers not in marker set {targets[0]}: {', '.join(missing[:8])}"))
        elif target:
            errors.append(_err(prim, "BindingTarget", f"{ns}:markerSet target {targets[0]} has no FaceMarkerSetAPI"))
    return errors


def _check_regions(prim: Usd.Prim, time_range=None):
    errors = []
    n_points, _ = _mesh_sizes(prim)
    for schema in prim.GetAppliedSchemas():
        if not schema.startswith("FaceRegionAPI:"):
            continue
        name = schema.split(":", 1)[1]
        idx = prim.GetAttribute(f"usdface:region:{name}:indices").Get()
        if idx is None or len(idx) == 0:
            errors.append(_err(prim, "EmptyRegion", f"region {name!r} has no indices"))
            continue
        arr = np.asarray(idx)
        if n_points and (arr.min() < 0 or arr.max() >= n_points):
            errors.append(_err(prim, "RegionIndexRange", f"region {name!r} indices outside 0..{n_points - 1}"))
    return errors


def _check_distance_matrices(prim: Usd.Prim, time_range=None):
    errors = []
    n_points, _ = _mesh_sizes(prim)
    for schema in prim.GetAppliedSchemas():
        if not schema.startswith("FaceDistanceMatrixAPI:"):
            continue
        name = schema.split(":", 1)[1]
        ns = f"usdface:distanceMatrix:{name}"
        names = prim.GetAttribute(f"{ns}:markerNames").Get() or []
        m = len(names) + len(prim.GetAttribute(f"{ns}:constraintVertices").Get() or [])
        from .analysis_layer import vertex_distances

        values = vertex_distances(prim, name)
        if values is None:
            errors.append(_err(prim, "DistanceMatrixMissing",
                               f"distance matrix {name!r}: {ns}:vertexDistances missing"))
            continue
        legacy = UsdGeom.PrimvarsAPI(prim).GetPrimvar(f"usdface:distance:{name}")
        size_ok = values.size == n_points * m and (not legacy or not legacy.HasValue()
                                                    or legacy.GetElementSize() == m)
        if not size_ok:
            errors.append(_err(prim, "DistanceMatrixShape",
                               f"distance matrix {name!r}: {values.size} values, expected {n_points} vertices x "
                               f"{m} centres"))
        elif not np.isfinite(values).all() or (values < 0).any():
            errors.append(_err(prim, "DistanceMatrixValues", f"distance matrix {name!r} has negative, NaN or inf entries"))
        mm = prim.GetAttribute(f"{ns}:centreDistances").Get()
        if mm is None or len(mm) != m * m:
            errors.append(_err(prim, "DistanceMatrixShape", f"distance matrix {name!r}: centreDistances must have {m}x{m} entries"))
    return errors


def _check_transfer(prim: Usd.Prim, time_range=None):
    errors = []
    mesh = UsdGeom.Mesh(prim)
    n_points = len(mesh.GetFaceVertexIndicesAttr().Get() and mesh.GetPointsAttr().Get(Usd.TimeCode.EarliestTime()) or [])
    points_attr = mesh.GetPointsAttr()
    samples = points_attr.GetTimeSamples()
    if not samples:
        errors.append(_err(prim, "TransferNotAnimated", "FaceTransferAPI applied but points have no time samples"))
        return errors
    extent_samples = set(mesh.GetExtentAttr().GetTimeSamples())
    missing_extent = [t for t in samples if t not in extent_samples]
    if missing_extent:
        errors.append(_err(prim, "TransferExtent", f"{len(missing_extent)} points samples have no extent sample (first at {missing_extent[0]})"))
    for t in samples[:: max(1, len(samples) // 50)]:
        arr = np.asarray(points_attr.Get(t))
        if len(arr) != n_points or not np.isfinite(arr).all():
            errors.append(_err(prim, "TransferPoints", f"points at time {t} have {len(arr)} entries or non-finite values"))
            break
    normals = mesh.GetNormalsAttr()
    if normals.HasAuthoredValue() and not normals.GetTimeSamples():
        errors.append(_err(prim, "StaleNormals", "static normals authored on animated points (block or animate them)"))
    return errors


_RULES = (
    ("usdface:MarkerSetConsistency", "UsdFaceMarkerSetAPI", _check_marker_set,
     "Marker names unique and one per point, no NaN points, validity per marker, rate = timeCodesPerSecond."),
    ("usdface:BindingConsistency", "UsdFaceMarkerBindingAPI", _check_binding,
     "Binding arrays one per marker, barycentrics valid, indices in range, markers in the marker set."),
    ("usdface:RegionConsistency", "UsdFaceRegionAPI", _check_regions, "Regions non-empty with indices in range."),
    ("usdface:DistanceMatrixConsistency", "UsdFaceDistanceMatrixAPI", _check_distance_matrices,
     "Distance matrices N x C with elementSize C (markers + constraint vertices), finite and non-negative."),
    ("usdface:TransferConsistency", "UsdFaceTransferAPI", _check_transfer,
     "Animated points with extent at every sample, finite, no stale normals."),
)
_registered = False


def register_validators() -> None:
    """Register usdface's rules with UsdValidation (once per process)."""
    global _registered
    if _registered:
        return
    reg = UsdValidation.ValidationRegistry()
    if not hasattr(reg, "RegisterPrimValidator"):  # UsdValidation's Python registration came in USD 25.05
        from ..errors import DependencyError

        raise DependencyError(f"usdface check needs USD 25.05 or newer (UsdValidation with Python validators); this "
                              f"USD is {Usd.GetVersion()[1]}.{Usd.GetVersion()[2]:02d} (Blender 4.5 ships 25.02): check the "
                              "layers with usd-core (pip install usd-core)")
    for name, schema_type, fn, doc in _RULES:
        if reg.HasValidator(name):
            continue
        md = UsdValidation.ValidatorMetadata(name=name, keywords=[KEYWORD], doc=doc, schemaTypes=[schema_type],
                                             isTimeDependent=False, isSuite=False)
        reg.RegisterPrimValidator(md, fn)
    _registered = True


_SEVERITY = {
    UsdValidation.ValidationErrorType.Error: "error",
    UsdValidation.ValidationErrorType.Warn: "warning",
    UsdValidation.ValidationErrorType.Info: "info",
}


def _is_image_track_layer(stage: Usd.Stage) -> bool:
    """Whether the stage's marker sets are 2D image tracks (usdface:markerSet:dimensions = 2)."""
    sets = [p for p in stage.Traverse() if p.HasAPI("FaceMarkerSetAPI")]
    return bool(sets) and all(p.GetAttribute("usdface:markerSet:dimensions").Get() == 2 for p in sets)


SHOT_RULE = "usdface:ShotIntegrity"


def check_shot_integrity(path: str | os.PathLike) -> list[Finding]:
    """A shot stage written by `usdface run` against the files beside it: every file it lists
    present, with the sha256 and provenance id it was committed with (no mix of two runs, nothing
    missing); a shot stage missing because a commit was interrupted is an error too."""
    from .shot_record import interrupted_commit, read_shot_record, verify_shot

    p = Path(path)
    folder = p.parent
    pending = interrupted_commit(folder) if folder.is_dir() else None
    if not p.exists():
        if pending is not None and p.name in pending.get("files", []):
            return [Finding("error", SHOT_RULE, str(p),
                            f"{p.name} is missing: a run (id {pending.get('runId')}) was stopped while committing "
                            f"{folder} ({len(pending['pending'])} file(s) not yet in place); the next `usdface run` "
                            "into this folder completes the commit (or run it again)")]
        return []
    findings = []
    problems = verify_shot(p)
    if problems:
        run = (read_shot_record(p) or {}).get("runId")
        findings.append(Finding("error", SHOT_RULE, str(p),
                                f"mixed or incomplete shot (run {run}): {'; '.join(problems)}; run `usdface run` "
                                f"into {folder} again to repair it"))
    if pending is not None and read_shot_record(p) is not None:
        findings.append(Finding("warning", SHOT_RULE, str(p),
                                f"{folder} holds an interrupted commit of run {pending.get('runId')} "
                                f"({pending['folder']}); the next `usdface run` into this folder completes it"))
    return findings


IDENTITY_RULE = "usdface:LayerIdentity"


def identity_findings(stage: Usd.Stage, *, folder=None) -> list[Finding]:
    """Layers of the stage (its root, sublayers and references) made for another mesh, other
    bound points or another take than the ones the stage holds (errors), and usdface layers that
    record no identity (warnings): :func:`usdface.usd.identity.stage_findings`."""
    from .identity import stage_findings

    return [Finding(severity, IDENTITY_RULE, site, message)
            for severity, site, message in stage_findings(stage, folder=folder)]


def check_layer(path: str | os.PathLike) -> list[Finding]:
    """Run every UsdValidation validator (USD's and usdface's) on the stage opened from ``path``,
    :func:`identity_findings` on the layers it composes, and, for a shot stage written by
    `usdface run`, :func:`check_shot_integrity`."""
    from .layers import is_in_memory

    integrity = [] if is_in_memory(path) else check_shot_integrity(path)  # shots are files
    if any(f.severity == "error" and ("missing" in f.message) for f in integrity):
        return integrity  # composing a shot with missing layers adds nothing but USD's warnings
    register_validators()
    stage = open_stage(path, what="file", composition="ignore")  # its validators report composition errors
    validators = UsdValidation.ValidationRegistry().GetOrLoadAllValidators()
    image_space = _is_image_track_layer(stage)
    findings = []
    # the validators' own warnings on stderr (an in-memory layer's anon: references) repeat what
    # their findings say
    with trapped():
        errors = UsdValidation.ValidationContext(validators).Validate(stage)
    for error in errors:
        if error.HasNoError():
            continue
        sites = error.GetSites()
        site = ""
        if sites:
            s = sites[0]
            site = str(s.GetPrim().GetPath()) if s.IsPrim() else (s.GetLayer().identifier if s.GetLayer() else "")
        severity, message = _SEVERITY.get(error.GetType(), "error"), error.GetMessage()
        if "UnresolvableDependency" in error.GetIdentifier() and "'anon:" in message:
            # an in-memory layer (Python API) resolves in this session, not through the asset resolver
            severity, message = "warning", message + " (an in-memory layer: resolvable in this session only)"
        if image_space and "MissingMetersPerUnit" in error.GetIdentifier():
            # 2D tracks are in pixels: no metric scale exists, and a made-up one would mislead
            severity, message = "warning", message + " (a 2D image-track layer: pixels have no metric scale)"
        findings.append(Finding(severity, error.GetIdentifier(), site, message))
    findings += identity_findings(stage, folder=None if is_in_memory(path) else Path(path).resolve().parent)
    findings += integrity
    findings.sort(key=lambda f: (f.severity != "error", f.rule, f.site))
    return findings
