"""What a USD layer holds, for `usdface info`."""
from __future__ import annotations

import os

import numpy as np
from pxr import Usd, UsdGeom, UsdSkel

from ..model.identity import short
from .identity import describe_identity, marker_set_take, prim_markers_record, prim_mesh_record
from .layers import get_provenance, open_stage, stage_units


def describe(path: str | os.PathLike) -> dict:
    """A JSON-serialisable summary of the stage opened from ``path``."""
    stage = open_stage(path, what="file", composition="warn")
    layer = stage.GetRootLayer()
    out = {
        "file": str(path),
        "defaultPrim": layer.defaultPrim or None,
        "metersPerUnit": UsdGeom.GetStageMetersPerUnit(stage) if stage.HasAuthoredMetadata("metersPerUnit") else None,
        "units": stage_units(stage),
        "upAxis": UsdGeom.GetStageUpAxis(stage),
        "timeCodesPerSecond": stage.GetTimeCodesPerSecond(),
        "framesPerSecond": stage.GetFramesPerSecond(),
        "startTimeCode": stage.GetStartTimeCode() if stage.HasAuthoredTimeCodeRange() else None,
        "endTimeCode": stage.GetEndTimeCode() if stage.HasAuthoredTimeCodeRange() else None,
        "subLayers": list(layer.subLayerPaths),
        "provenance": get_provenance(stage) or None,
        "prims": [],
    }
    for prim in stage.Traverse():
        entry = {"path": str(prim.GetPath()), "type": prim.GetTypeName() or None,
                 "schemas": list(prim.GetAppliedSchemas())}
        if prim.HasAPI("FaceMarkerSetAPI"):
            names = list(prim.GetAttribute("usdface:markerSet:names").Get() or [])
            pts = UsdGeom.Points(prim).GetPointsAttr()
            samples = pts.GetTimeSamples()
            valid = prim.GetAttribute("primvars:usdface:valid")
            invalid = 0
            if valid and valid.HasValue():
                invalid = int(sum(int((~np.asarray(valid.Get(t), dtype=bool)).sum()) for t in valid.GetTimeSamples()))
            entry["markerSet"] = {
                "markers": len(names), "names": names, "frames": len(samples),
                "captureRate": prim.GetAttribute("usdface:markerSet:captureRate").Get(),
                "sourceFile": prim.GetAttribute("usdface:markerSet:sourceFile").Get(),
                "sourceUnits": prim.GetAttribute("usdface:markerSet:sourceUnits").Get(),
                "neutralTime": prim.GetAttribute("usdface:markerSet:neutralTime").Get(),
                **_neutral_stretch(prim, stage),
                "invalidSamples": invalid,
                **_head_motion(prim),
                "take": (marker_set_take(prim) or {}).get("sha256"),  # computed from its capture layer
            }
        elif prim.IsA(UsdGeom.Xformable):
            timed = [op.GetOpName() for op in UsdGeom.Xformable(prim).GetOrderedXformOps() if op.GetNumTimeSamples() > 1]
            if timed:
                entry["animatedTransform"] = {op: UsdGeom.Xformable(prim).GetPrim().GetAttribute(op).GetNumTimeSamples()
                                              for op in timed}
        if prim.IsA(UsdGeom.Mesh):
            mesh = UsdGeom.Mesh(prim)
            pts_attr = mesh.GetPointsAttr()
            counts = mesh.GetFaceVertexCountsAttr().Get()
            entry["mesh"] = {
                "points": len(pts_attr.Get(Usd.TimeCode.EarliestTime()) or []),
                "faces": len(counts or []),
                "faceSizes": {int(k): int(v) for k, v in zip(*np.unique(np.asarray(counts or []), return_counts=True))},
                "animatedFrames": pts_attr.GetNumTimeSamples(),
                "subdivisionScheme": mesh.GetSubdivisionSchemeAttr().Get(),
                "uvs": bool(UsdGeom.PrimvarsAPI(prim).GetPrimvar("st")),
                "identity": (prim_mesh_record(prim) or ({},))[0].get("sha256"),  # computed from its rest points
            }
            regions = [s.split(":", 1)[1] for s in prim.GetAppliedSchemas() if s.startswith("FaceRegionAPI:")]
            if regions:
                entry["regions"] = {r: {"role": prim.GetAttribute(f"usdface:region:{r}:role").Get(),
                                        "vertices": len(prim.GetAttribute(f"usdface:region:{r}:indices").Get() or [])}
                                    for r in regions}
            if prim.HasAPI("FaceMarkerBindingAPI"):
                res = np.asarray(prim.GetAttribute("usdface:binding:residuals").Get() or [], dtype=float)
                entry["binding"] = {
                    "markers": len(prim.GetAttribute("usdface:binding:markerNames").Get() or []),
                    "method": prim.GetAttribute("usdface:binding:method").Get(),
                    "retarget": prim.GetAttribute("usdface:binding:retarget").Get(),
                    "residualMedian": float(np.median(res)) if res.size else None,
                    "residualMax": float(res.max()) if res.size else None,
                    "boundPoints": (prim_markers_record(prim) or {}).get("boundPoints"),  # computed
                }
            matrices = [s.split(":", 1)[1] for s in prim.GetAppliedSchemas() if s.startswith("FaceDistanceMatrixAPI:")]
            if matrices:
                entry["distanceMatrices"] = {
                    m: {"method": prim.GetAttribute(f"usdface:distanceMatrix:{m}:method").Get(),
                        "backend": prim.GetAttribute(f"usdface:distanceMatrix:{m}:backend").Get(),
                        "markers": len(prim.GetAttribute(f"usdface:distanceMatrix:{m}:markerNames").Get() or [])}
                    for m in matrices}
            if prim.HasAPI("FaceTransferAPI"):
                entry["transfer"] = {k: prim.GetAttribute(f"usdface:transfer:{k}").Get()
                                     for k in ("mode", "kernel", "distanceMethod", "regularization", "conditionNumber")}
        if prim.IsA(UsdSkel.Skeleton):
            entry["joints"] = len(UsdSkel.Skeleton(prim).GetJointsAttr().Get() or [])
        out["prims"].append(entry)
    return out


def _neutral_stretch(prim, stage) -> dict:
    """The neutral stretch (time codes, inclusive) and the motion over it in cm; a layer of
    usdface 0.2 records none: its neutral time alone, motion unknown."""
    from ..units import METERS_PER_UNIT, scale_between

    t = prim.GetAttribute("usdface:markerSet:neutralTime").Get()
    first, last = (prim.GetAttribute(f"usdface:markerSet:neutral{k}Time") for k in ("Start", "End"))
    if not (first and first.HasAuthoredValue() and last and last.HasAuthoredValue()):
        return {"neutralTimes": [t, t], "neutralMotionRmsCm": None, "neutralMotionMaxCm": None}
    units = prim.GetAttribute("usdface:markerSet:sourceUnits").Get()
    to_cm = scale_between(units, "cm") if units in METERS_PER_UNIT else None
    out = {"neutralTimes": [first.Get(), last.Get()]}
    for key in ("Rms", "Max"):
        value = prim.GetAttribute(f"usdface:markerSet:neutralMotion{key}").Get()
        out[f"neutralMotion{key}Cm"] = None if value is None or to_cm is None else round(float(value) * to_cm, 5)
    return out


def _format_neutral(m: dict) -> str:
    a, b = m["neutralTimes"]
    frames = f"neutral time {a:g}" if a == b else f"neutral times {a:g}-{b:g} (around neutral frame {m['neutralTime']:g})"
    if m.get("neutralMotionRmsCm") is None:
        return frames + ("" if a == b else ", motion there unknown")
    return (f"{frames}, markers move {m['neutralMotionRmsCm']:.3f} cm RMS ({m['neutralMotionMaxCm']:.3f} cm at most) "
            "there")


def _head_motion(marker_prim) -> dict:
    """Whether the capture carries head motion (its /Capture xformOp:transform is time-sampled),
    and whether this stage applies it (a shot drops it from the op order to show the markers on
    the stabilised face)."""
    parent = marker_prim.GetParent()
    attr = parent.GetAttribute("xformOp:transform") if parent else None
    has = bool(attr) and attr.GetNumTimeSamples() > 1
    applied = has and "xformOp:transform" in [op.GetOpName() for op in UsdGeom.Xformable(parent).GetOrderedXformOps()]
    return {"headMotion": has, "headMotionApplied": applied,
            "headMotionFrames": attr.GetNumTimeSamples() if has else 0}


def format_description(d: dict) -> list[str]:
    """Human-readable lines for :func:`describe`'s result."""
    lines = [f"{d['file']}"]
    units = d["units"] or (f"metersPerUnit={d['metersPerUnit']}" if d["metersPerUnit"] else "not authored")
    lines.append(f"  units: {units}   upAxis: {d['upAxis']}   defaultPrim: {d['defaultPrim']}")
    if d["startTimeCode"] is not None:
        lines.append(f"  time: {d['startTimeCode']:g}..{d['endTimeCode']:g} at {d['timeCodesPerSecond']:g} "
                     f"timeCodes/s ({d['framesPerSecond']:g} fps)")
    if d["subLayers"]:
        lines.append(f"  subLayers: {', '.join(d['subLayers'])}")
    if d["provenance"]:
        prov = d["provenance"]
        # revision: how many times the processor's algorithms or defaults changed (usdface.revisions)
        made_by = f", revision {prov['revision']}" if prov.get("revision") else ""
        lines.append(f"  written by usdface {prov.get('usdfaceVersion')} ({prov.get('processor')}{made_by})")
        recorded = describe_identity(d["provenance"].get("identity"))
        if recorded:
            lines.append(f"  belongs to: {recorded}")
    for p in d["prims"]:
        schemas = f"  [{', '.join(p['schemas'])}]" if p["schemas"] else ""
        lines.append(f"  {p['path']} ({p['type'] or 'over'}){schemas}")
        if "markerSet" in p:
            m = p["markerSet"]
            lines.append(f"      {m['markers']} markers, {m['frames']} frames at {m['captureRate']:g} Hz, "
                         f"source units {m['sourceUnits']}, {m['invalidSamples']} invalid samples, head motion: "
                         + ("no" if not m["headMotion"] else
                            "yes (removed by stabilisation; applied to the markers here)" if m["headMotionApplied"] else
                            "yes (removed by stabilisation; markers shown stabilised here)"))
            lines.append(f"      {_format_neutral(m)}")
            lines.append(f"      from {m['sourceFile']}: {', '.join(m['names'][:8])}{', ...' if m['markers'] > 8 else ''}")
            if m.get("take"):
                lines.append(f"      take {short(m['take'])}")
        for op, n in p.get("animatedTransform", {}).items():
            lines.append(f"      {op}: {n} time samples" + (" (head motion)" if p["path"] == f"/{d['defaultPrim']}" else ""))
        if "mesh" in p:
            m = p["mesh"]
            sizes = ", ".join(f"{v} {'tris' if k == 3 else 'quads' if k == 4 else f'{k}-gons'}" for k, v in m["faceSizes"].items())
            anim = f", animated over {m['animatedFrames']} frames" if m["animatedFrames"] else ""
            lines.append(f"      {m['points']} points, {m['faces']} faces ({sizes}), "
                         f"subdivision {m['subdivisionScheme']}, uvs {'yes' if m['uvs'] else 'no'}{anim}")
            if m.get("identity"):
                lines.append(f"      mesh {short(m['identity'])}")
        for name, r in p.get("regions", {}).items():
            lines.append(f"      region {name}: role {r['role']}, {r['vertices']} vertices")
        if "binding" in p:
            b = p["binding"]
            u = d["units"] or "mesh units"  # the binding's residuals are in the mesh's units
            lines.append(f"      binding: {b['markers']} markers ({b['method']}, retarget {b['retarget']}), surface residual median "
                         f"{b['residualMedian']:.3g} {u}, max {b['residualMax']:.3g} {u}"
                         + (f", bound points {short(b['boundPoints'])}" if b.get("boundPoints") else ""))
        for name, m in p.get("distanceMatrices", {}).items():
            lines.append(f"      distance matrix {name}: {m['method']}/{m['backend']}, {m['markers']} markers")
        if "transfer" in p:
            t = p["transfer"]
            lines.append(f"      transfer: {t['mode']} {t['kernel']} on {t['distanceMethod']} distances")
        if "joints" in p:
            lines.append(f"      {p['joints']} joints")
    return lines
