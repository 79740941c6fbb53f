"""Mesh layers (``/Face`` with the mesh at ``/Face/Geom``), face regions and marker bindings.

Later layers (binding, analysis, animation) are ``over``s on the mesh prim; processors find the
mesh by applied schema or as the default prim's first Mesh, not by a fixed path alone.
"""
from __future__ import annotations

import os
from pathlib import Path

import numpy as np
from pxr import Gf, Sdf, Usd, UsdGeom, Vt

from ..errors import InputError, MeshError, list_names
from ..model.mesh import Binding, FaceMesh, Region
from .capture_layer import _matrix_from_usd, _matrix_to_usd, find_marker_set
from .layers import (add_sublayer, describe, is_in_memory, open_stage, output_layer, relative_asset_path, set_provenance,
                     set_stage_metadata, stage_units)
from .schemas import require_registered

FACE_PRIM = "/Face"
GEOM_PRIM = "/Face/Geom"
REGION_API = "FaceRegionAPI"
BINDING_API = "FaceMarkerBindingAPI"


def author_mesh(stage: Usd.Stage, mesh: FaceMesh, path: str = GEOM_PRIM) -> UsdGeom.Mesh:
    """Define a Mesh prim holding ``mesh`` (polygons as they are, no subdivision, UVs as st)."""
    geom = UsdGeom.Mesh.Define(stage, path)
    geom.CreatePointsAttr(Vt.Vec3fArray.FromNumpy(mesh.points.astype(np.float32)))
    geom.CreateFaceVertexCountsAttr(Vt.IntArray.FromNumpy(mesh.face_vertex_counts.astype(np.int32)))
    geom.CreateFaceVertexIndicesAttr(Vt.IntArray.FromNumpy(mesh.face_vertex_indices.astype(np.int32)))
    geom.CreateSubdivisionSchemeAttr(UsdGeom.Tokens.none)  # USD's default would show an OBJ subdivided
    lo, hi = mesh.points.min(axis=0), mesh.points.max(axis=0)
    geom.CreateExtentAttr(Vt.Vec3fArray([Gf.Vec3f(*lo.tolist()), Gf.Vec3f(*hi.tolist())]))
    geom.CreateDoubleSidedAttr(True)  # open face meshes: the inside shows through the holes
    geom.CreateDisplayColorPrimvar(UsdGeom.Tokens.constant).Set(Vt.Vec3fArray([Gf.Vec3f(0.8, 0.68, 0.6)]))
    if mesh.uvs is not None:
        st = UsdGeom.PrimvarsAPI(geom).CreatePrimvar("st", Sdf.ValueTypeNames.TexCoord2fArray,
                                                     UsdGeom.Tokens.faceVarying)
        st.Set(Vt.Vec2fArray.FromNumpy(mesh.uvs.astype(np.float32)))
        st.SetIndices(Vt.IntArray.FromNumpy(mesh.uv_indices.astype(np.int32)))
    return geom


def author_regions(prim: Usd.Prim, regions: list[Region]) -> None:
    """Apply one FaceRegionAPI instance per region."""
    for region in regions:
        if not Sdf.Path.IsValidIdentifier(region.name):
            raise MeshError(f"region name {region.name!r} is not a valid USD identifier")
        prim.ApplyAPI(REGION_API, region.name)
        ns = f"usdface:region:{region.name}"
        prim.GetAttribute(f"{ns}:indices").Set(Vt.IntArray.FromNumpy(region.indices.astype(np.int32)))
        prim.GetAttribute(f"{ns}:role").Set(region.role)
        if region.loop is not None:
            prim.GetAttribute(f"{ns}:loop").Set(Vt.IntArray.FromNumpy(region.loop.astype(np.int32)))


def read_regions(prim: Usd.Prim) -> list[Region]:
    """Every FaceRegionAPI instance on ``prim``."""
    regions = []
    for schema in prim.GetAppliedSchemas():
        if not schema.startswith(REGION_API + ":"):
            continue
        name = schema.split(":", 1)[1]
        ns = f"usdface:region:{name}"
        idx = prim.GetAttribute(f"{ns}:indices").Get()
        loop = prim.GetAttribute(f"{ns}:loop").Get()
        regions.append(Region(name=name, role=prim.GetAttribute(f"{ns}:role").Get() or "other",
                              indices=np.asarray(idx if idx is not None else [], dtype=np.int64),
                              loop=np.asarray(loop, dtype=np.int64) if loop else None))
    return regions


def write_mesh_layer(path: str | os.PathLike, mesh: FaceMesh, regions: list[Region], *, prov: dict) -> str:
    """Write a mesh layer (default prim /Face, mesh at /Face/Geom) atomically."""
    require_registered()
    with output_layer(path) as stage:
        set_stage_metadata(stage, units=mesh.units, default_prim="Face")
        UsdGeom.Xform.Define(stage, FACE_PRIM)
        geom = author_mesh(stage, mesh)
        author_regions(geom.GetPrim(), regions)
        set_provenance(stage, prov)
    return str(path)


MESH_SCHEMAS = ("FaceRegionAPI", "FaceMarkerBindingAPI", "FaceTransferAPI", "FaceDistanceMatrixAPI")


def find_mesh(stage: Usd.Stage, *, what: str = "mesh", prim_path: str | None = None) -> Usd.Prim:
    """The face mesh prim: ``prim_path`` when given; else the prim with usdface schemas applied
    (also an ``over`` in a layer of its own, such as an analysis layer); else the only Mesh under
    the default prim (or, without one, on the stage).

    Several Mesh prims with nothing to tell the face (a character file with eyes, teeth and
    lashes) is an InputError naming them: taking the first would bind a capture to an eyeball
    with exit code 0, and a batch would repeat that in every shot. The fix is a file with the
    face mesh alone, a default prim holding only it, or ``prim_path``.
    """
    where = f"{what} {stage.GetRootLayer().identifier}"
    if prim_path is not None:
        prim = stage.GetPrimAtPath(str(prim_path))
        if not prim or not prim.IsA(UsdGeom.Mesh):
            meshes = [str(p.GetPath()) for p in stage.Traverse() if p.IsA(UsdGeom.Mesh)]
            raise InputError(f"{where}: {prim_path} is not a Mesh prim; its Mesh prims: {list_names(meshes) or 'none'}")
        return prim
    every = list(Usd.PrimRange.Stage(stage, Usd.PrimAllPrimsPredicate))
    for prim in every:
        if any(s.startswith(MESH_SCHEMAS) for s in prim.GetAppliedSchemas()):
            return prim
    root = stage.GetDefaultPrim()
    scope = Usd.PrimRange(root) if root else stage.Traverse()
    meshes = [prim for prim in scope if prim.IsA(UsdGeom.Mesh)]
    if not meshes and root:
        meshes = [prim for prim in stage.Traverse() if prim.IsA(UsdGeom.Mesh)]
    if len(meshes) == 1:
        return meshes[0]
    if not meshes:
        raise InputError(f"{where}: no Mesh prim (expected {GEOM_PRIM})")
    shown = [f"{p.GetPath()} ({len(UsdGeom.Mesh(p).GetPointsAttr().Get() or [])} points)" for p in meshes]
    inside = f" under the default prim {root.GetPath()}" if root else ""
    raise InputError(f"{where}: {len(meshes)} Mesh prims{inside} and none marked as the face: {list_names(shown, 6)}; "
                     f"usdface reads one face mesh: export it alone, or make a prim holding only the face mesh the "
                     f"default prim")


def mesh_from_prim(prim: Usd.Prim, *, units: str | None, source: str, time=Usd.TimeCode.Default()) -> FaceMesh:
    """Read a UsdGeom.Mesh prim into a FaceMesh (points in the prim's local space)."""
    geom = UsdGeom.Mesh(prim)
    points = geom.GetPointsAttr().Get(time)
    counts = geom.GetFaceVertexCountsAttr().Get()
    indices = geom.GetFaceVertexIndicesAttr().Get()
    if points is None or counts is None or indices is None or len(counts) == 0:
        raise MeshError(f"mesh {source}: {prim.GetPath()} has no faces")
    uvs = uv_idx = None
    st = UsdGeom.PrimvarsAPI(prim).GetPrimvar("st")
    if st and st.HasValue() and st.GetInterpolation() in (UsdGeom.Tokens.faceVarying, UsdGeom.Tokens.vertex):
        vals = np.asarray(st.Get(), dtype=np.float64)
        if st.GetInterpolation() == UsdGeom.Tokens.faceVarying:
            ind = st.GetIndices()
            uv_idx = np.asarray(ind, dtype=np.int64) if ind else np.arange(len(indices))
        else:
            uv_idx = np.asarray(indices, dtype=np.int64)
        uvs = vals
    return FaceMesh(points=np.asarray(points, dtype=np.float64), face_vertex_counts=np.asarray(counts),
                    face_vertex_indices=np.asarray(indices), units=units, uvs=uvs, uv_indices=uv_idx,
                    name=prim.GetName(), source=source)


def read_mesh_layer(path: str | os.PathLike, *, stage: Usd.Stage | None = None,
                    prim_path: str | None = None) -> tuple[FaceMesh, list[Region]]:
    """Read the face mesh and its regions from a USD file (``prim_path``: which Mesh prim, when
    the file holds several; see :func:`find_mesh`)."""
    stage = stage or open_stage(path, what="mesh")
    prim = find_mesh(stage, prim_path=prim_path)
    mesh = mesh_from_prim(prim, units=stage_units(stage), source=describe(path))
    return mesh, read_regions(prim)


# -- marker binding -------------------------------------------------------------------------------

def _asset_path(source, output) -> str:
    """How ``output`` refers to ``source``: relative between files; a file from an in-memory
    layer by its absolute path; an in-memory layer by its identifier (valid in this session)."""
    if is_in_memory(source):
        layer = source.GetRootLayer() if isinstance(source, Usd.Stage) else source
        return layer.identifier
    if is_in_memory(output):
        return str(Path(source).resolve())
    return relative_asset_path(source, output)


def write_binding_layer(path: str | os.PathLike, binding: Binding, *, mesh_path: str | os.PathLike,
                        capture_path: str | os.PathLike, mesh_units: str | None, prov: dict) -> str:
    """Write a binding layer: the mesh layer as a sublayer, the capture referenced at /Capture
    (placed over the face by the binding's capture-to-mesh similarity, so usdview shows the
    markers on the face), and FaceMarkerBindingAPI applied in an over on the mesh prim."""
    require_registered()
    mesh_stage = open_stage(mesh_path, what="mesh")
    mesh_prim_path = find_mesh(mesh_stage).GetPath()
    cap_stage = open_stage(capture_path, what="capture")
    marker_path = find_marker_set(cap_stage).GetPath()
    cap_root = cap_stage.GetDefaultPrim()
    if not cap_root:
        raise InputError(f"capture {capture_path}: no default prim")
    # in memory, a stage that already holds the capture (a DCC's scene) keeps it where it is
    same_stage = cap_stage is mesh_stage
    with output_layer(path) as stage:
        add_sublayer(stage, mesh_path, path)
        set_stage_metadata(stage, units=mesh_units, default_prim=mesh_stage.GetDefaultPrim().GetName(),
                           rate=cap_stage.GetTimeCodesPerSecond(), start=cap_stage.GetStartTimeCode(),
                           end=cap_stage.GetEndTimeCode())
        if same_stage:
            marker_target = marker_path
        else:
            cap = stage.DefinePrim("/Capture", "Xform")
            cap.GetReferences().AddReference(_asset_path(capture_path, path))
            xf = UsdGeom.Xformable(cap)
            place = xf.AddTransformOp(opSuffix="captureToMesh")
            place.Set(_matrix_to_usd(binding.capture_to_mesh))
            # the referenced head-motion op stays after the placement: world = C2M @ head @ local
            xf.SetXformOpOrder([place, UsdGeom.XformOp(cap.GetAttribute("xformOp:transform"))])
            marker_target = Sdf.Path("/Capture").AppendPath(marker_path.MakeRelativePath(cap_root.GetPath()))
        prim = stage.OverridePrim(mesh_prim_path)
        prim.ApplyAPI(BINDING_API)
        ns = "usdface:binding"
        prim.GetAttribute(f"{ns}:markerNames").Set(Vt.StringArray(list(binding.names)))
        prim.GetAttribute(f"{ns}:faceIndices").Set(Vt.IntArray.FromNumpy(binding.face_indices.astype(np.int32)))
        prim.GetAttribute(f"{ns}:triangleVertexIndices").Set(
            Vt.Vec3iArray.FromNumpy(binding.triangle_vertices.astype(np.int32)))
        prim.GetAttribute(f"{ns}:barycentrics").Set(Vt.Vec3dArray.FromNumpy(binding.barycentrics))
        prim.GetAttribute(f"{ns}:nearestVertices").Set(Vt.IntArray.FromNumpy(binding.nearest_vertices.astype(np.int32)))
        prim.GetAttribute(f"{ns}:residuals").Set(Vt.DoubleArray.FromNumpy(binding.residuals))
        prim.GetAttribute(f"{ns}:retarget").Set(binding.retarget)
        prim.GetAttribute(f"{ns}:method").Set(binding.method)
        prim.GetAttribute(f"{ns}:captureToMesh").Set(_matrix_to_usd(binding.capture_to_mesh))
        prim.GetAttribute(f"{ns}:unitScale").Set(float(binding.unit_scale))
        prim.GetRelationship(f"{ns}:markerSet").SetTargets([marker_target])
        set_provenance(stage, prov)
    return str(path)


def read_binding(stage: Usd.Stage, *, source: str = "") -> Binding:
    """The Binding authored on the stage's face mesh (FaceMarkerBindingAPI)."""
    prim = find_mesh(stage, what="binding")
    if not prim.HasAPI(BINDING_API):
        raise InputError(f"binding {source or stage.GetRootLayer().identifier}: {prim.GetPath()} has no {BINDING_API} "
                         "(write one with `usdface bind`)")
    ns = "usdface:binding"
    get = lambda n: prim.GetAttribute(f"{ns}:{n}").Get()  # noqa: E731
    return Binding(
        names=list(get("markerNames")),
        face_indices=np.asarray(get("faceIndices")),
        triangle_vertices=np.asarray(get("triangleVertexIndices")),
        barycentrics=np.asarray(get("barycentrics")),
        nearest_vertices=np.asarray(get("nearestVertices")),
        residuals=np.asarray(get("residuals")),
        retarget=get("retarget"),
        capture_to_mesh=_matrix_from_usd(get("captureToMesh")),
        unit_scale=float(get("unitScale")),
        method=get("method"),
    )
