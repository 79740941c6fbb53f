"""`usdface register`: the generic face warped onto a scan, keeping its topology, regions and marker
layout (seed 001, section 4.2).

``usdface register --generic MESH.usd --scan SCAN.usd --landmarks L.json -o REGISTERED.usdc``
"""
from __future__ import annotations

import logging
import time
from pathlib import Path

import numpy as np

from ..errors import ComputeError, InputError, MeshError, OptionError, list_names
from ..fileutil import StagedOutputs, refuse_overwriting_inputs
from ..options import RegisterOptions
from ..registry import Result
from ..usd.layers import check_output_path, describe, is_in_memory, provenance

log = logging.getLogger("usdface")

__all__ = ["register"]


def register(generic, scan, *, options: RegisterOptions, output, layout_output=None) -> Result:
    """Warp the generic face onto a scan (similarity, thin-plate RBF, closest-point projection).

    Parameters
    ----------
    generic : path, Sdf.Layer or Usd.Stage
        Generic mesh layer with regions (from ``import-mesh``).
    scan : path, Sdf.Layer or Usd.Stage
        Scan mesh layer (from ``stereo``, or any mesh layer).
    options : RegisterOptions
        ``landmarks``: the scan's landmarks, ``{"name": {"image": [u, v]}}`` (on the first image
        of the stereo pair, lifted through the scan) or ``{"name": {"scan": [x, y, z]}}``, or a
        ``detect`` features file; without them ``image`` and ``aam`` detect them.
        ``generic_landmarks``: the generic's, a marker layout (default
        ``<generic stem>.landmarks.layout.json`` beside the generic). ``layout``: the generic's
        marker layout, carried over. ``iterations``, ``border``, ``field``: the registration
        (:meth:`RegisterOptions.registration`).
    output : path, Sdf.Layer or Usd.Stage
        Registered mesh layer: the generic's topology, UVs and regions, the scan's space, the
        generic's units.
    layout_output : path, optional
        Where the carried layout goes (default ``<output stem>.layout.json``).
    """
    from ..mesh.layout import read_layout
    from ..scan.register import HOLE_RINGS, GenericRegistration
    from ..usd.identity import identity, mesh_record
    from ..usd.mesh_layer import read_mesh_layer

    o = options
    t0 = time.perf_counter()
    inputs = {"--generic": generic, "--scan": scan, "--landmarks": o.landmarks,
              "--generic-landmarks": o.generic_landmarks, "--layout": o.layout, "--image": o.image, "--aam": o.aam}
    out = check_output_path(output, inputs=inputs)
    refuse_overwriting_inputs({"--layout-output": layout_output},
                              {k: v for k, v in inputs.items() if not is_in_memory(v)})
    mesh, regions = read_mesh_layer(generic)
    if not regions:
        raise MeshError(f"register: generic mesh {describe(generic)} has no regions; registration needs its eye and "
                        "mouth hole regions and carries its regions over (make the layer with `usdface import-mesh`)")
    generic_landmarks = o.generic_landmarks or _generic_landmarks_beside(generic)
    glay = read_layout(generic_landmarks)
    lay_in = read_layout(o.layout) if o.layout is not None else None
    lay_out = _layout_output(layout_output, out, lay_in)
    smesh, _ = read_mesh_layer(scan)
    names, points3 = _scan_landmarks(o, scan, smesh, glay)
    # scan -> generic units
    factor = 1.0
    if smesh.units and mesh.units and smesh.units != mesh.units:
        from ..units import scale_between

        factor = scale_between(smesh.units, mesh.units)
    S = smesh.points * factor
    SL = np.array([points3[n] for n in names]) * factor
    loc = _check_on_surface(S, smesh, SL, names, factor)
    reg = GenericRegistration(mesh, regions, glay.positions(mesh, names), hole_rings=HOLE_RINGS)
    res = reg.register(S, smesh.triangles(), SL, o.registration(), locator=loc)
    registered = mesh.with_points(res.points)
    # a new mesh (the generic's topology in the scan's place): the layer records its own identity
    prov = provenance("register", options={"iterations": o.iterations, "border": o.border, "field": o.field,
                                           "holeRings": HOLE_RINGS, "landmarks": names},
                      inputs={"generic": generic, "scan": scan, "landmarks": o.landmarks,
                              "genericLandmarks": generic_landmarks, "layout": o.layout},
                      identity=identity(mesh=mesh_record(registered)))
    carried = (lay_out, _carried_layout(lay_in, mesh, res.points)) if lay_in is not None else None
    _write(out, registered, regions, prov, carried)
    return _result(out, generic, scan, mesh, regions, res, names, o.iterations, carried, t0)


def _generic_landmarks_beside(generic) -> Path:
    """GENERIC_STEM.landmarks.layout.json beside the generic layer."""
    if is_in_memory(generic):
        raise OptionError(f"register: give the generic's landmarks with --generic-landmarks G.layout.json "
                          f"(the generic is {describe(generic)}: no file beside it)")
    gpath = Path(generic)
    cand = gpath.with_name(gpath.name.split(".")[0] + ".landmarks.layout.json")
    if not cand.is_file():
        raise OptionError(f"register: give the generic's landmarks with --generic-landmarks G.layout.json "
                          f"(no {cand.name} beside {generic})")
    return cand


def _layout_output(layout_output, out, lay_in) -> Path | None:
    """Where the carried layout goes: as given, else beside the output (OUTPUT_STEM.layout.json)."""
    if layout_output:
        if lay_in is None:
            raise OptionError("--layout-output needs --layout (the generic's marker layout)")
        return Path(layout_output)
    if lay_in is None:
        return None
    if is_in_memory(out):
        raise OptionError("register: the output is in memory; say where the carried layout goes (layout_output=)")
    return out.with_name(out.name.split(".")[0] + ".layout.json")


def _scan_landmarks(o: RegisterOptions, scan, smesh, glay) -> tuple[list, dict]:
    """(names shared with the generic's landmarks, in its order; {name: 3-D scan point}): read
    from ``o.landmarks`` or fitted with ``o.aam`` on ``o.image``; image points are lifted
    through the camera the scan records."""
    from ..scan.image_landmarks import lift_image_landmarks
    from ..scan.landmarks import read_landmarks
    from ..usd.scan_inputs import scan_camera

    cam = scan_camera(scan)
    if o.landmarks is not None:
        lm = read_landmarks(o.landmarks)
    elif o.image is not None and o.aam is not None:
        lm = _fitted_landmarks(o.image, o.aam)
    else:
        raise OptionError("register: give the scan's landmarks with --landmarks L.json (image points on the first "
                          "stereo image, e.g. from `usdface detect IMAGE --aam MODEL`, or scan points), or --image "
                          "and --aam to detect them")
    points3 = {n: np.asarray(p, dtype=np.float64) for n, p in lm.scan.items()}
    img_only = {n: p for n, p in lm.image.items() if n not in points3 and n in glay.names}
    if img_only:
        if cam is None:
            raise InputError(f"register: landmarks {o.landmarks} has image points but {describe(scan)} records no "
                             "camera (it was not made by `usdface stereo`); give scan points "
                             "{\"name\": {\"scan\": [x, y, z]}}")
        points3.update(lift_image_landmarks(img_only, smesh.points, smesh.triangles(), cam,
                                            scan_source=describe(scan)))
    names = [n for n in glay.names if n in points3]
    unknown = [n for n in list(lm.image) + list(lm.scan) if n not in glay.names]
    if len(names) < 4:
        raise InputError(f"register: only {len(names)} landmark(s) shared by the scan landmarks and the generic's "
                         f"({list_names(glay.names)}); at least 4 are needed (20 recommended)")
    if unknown:
        log.warning("register: landmarks not on the generic, ignored: %s", list_names(sorted(set(unknown))))
    return names, points3


def _fitted_landmarks(image, aam):
    """The AAM's landmarks fitted on the largest face detected in ``image``."""
    from ..io.images import read_image
    from ..scan.aam import load_aam
    from ..scan.detect import detect_faces
    from ..scan.landmarks import Landmarks

    model = load_aam(aam)
    img = read_image(image)
    faces = detect_faces(img, features=False)
    if not faces:
        raise ComputeError(f"register: no face found in {image}; give --landmarks")
    fit = model.fit(img, faces[0].box)
    return Landmarks.from_image_points(model.names, fit.points, source=f"AAM fit on {image}")


def _check_on_surface(S, smesh, SL, names, factor):
    """The scan's locator, after checking that the scan landmarks sit on the scan (3-D ones may be
    typed in or come from elsewhere)."""
    from ..mesh.closest import SurfaceLocator

    loc = SurfaceLocator(S, smesh.triangles())
    _, _, _, dl = loc.closest(SL)
    diag = float(np.linalg.norm(np.ptp(S, axis=0)))
    far = [f"{n} ({d / factor:.2f} {smesh.units or 'units'})" for n, d in zip(names, dl) if d > 0.03 * diag]
    if far:
        raise InputError(f"register: scan landmark(s) away from the scan surface (a hole, or the wrong units?): "
                         f"{list_names(far)}")
    return loc


def _carried_layout(lay_in, mesh, registered_points):
    """The generic's marker layout on the registered mesh: vertex entries as they are, point
    entries moved with the surface point they sit on."""
    from ..mesh.layout import Layout, LayoutMarker
    from ..scan.synthetic import evaluate_locations, surface_locations

    pnames = [m.name for m in lay_in.markers if m.point is not None]
    moved_by = {}
    if pnames:
        tri, bary = surface_locations(mesh.points, mesh.triangles(), lay_in.positions(mesh, pnames))
        moved_by = dict(zip(pnames, evaluate_locations(registered_points, mesh.triangles(), tri, bary)))
    entries = [LayoutMarker(m.name, vertex=m.vertex) if m.vertex is not None else
               LayoutMarker(m.name, point=tuple(float(x) for x in moved_by[m.name])) for m in lay_in.markers]
    return Layout(tuple(entries), units=mesh.units)


def _write(out, registered, regions, prov, carried) -> None:
    """The carried layout (``carried``: (path, layout) or None) and the registered mesh layer, both
    or neither (a failure or an interruption leaves the old files as they were)."""
    from ..mesh.layout import write_layout
    from ..usd.mesh_layer import write_mesh_layer

    with StagedOutputs() as staged:
        if carried is not None:
            write_layout(staged.path(carried[0]), carried[1], decimals=5)
        write_mesh_layer(staged.path(out), registered, regions, prov=prov)
        staged.commit()


def _result(out, generic, scan, mesh, regions, res, names, iterations: int, carried, t0) -> Result:
    """The summary and the lines `usdface register` prints."""
    sd = res.surface_distance[np.isfinite(res.surface_distance)]
    u = mesh.units or "units"
    where = describe(out) if is_in_memory(out) else str(out)
    summary = {"output": where, "generic": describe(generic), "scan": describe(scan), "landmarks": names,
               "points": mesh.n_points, "units": mesh.units, "scale": float(res.similarity[0]),
               "landmarkResidualMean": float(res.landmark_residuals.mean()),
               "landmarkResidualMax": float(res.landmark_residuals.max()),
               "surfaceDistanceMedian": float(np.median(sd)) if sd.size else None,
               "surfaceDistanceP95": float(np.percentile(sd, 95)) if sd.size else None,
               "dataVertices": int(res.data_vertices.sum()), "regions": [r.name for r in regions],
               "layout": str(carried[0]) if carried is not None else None,
               "seconds": round(time.perf_counter() - t0, 3)}
    text = [
        f"wrote {where}: {mesh.n_points} generic vertices registered onto {describe(scan)} from {len(names)} "
        f"landmarks (scale {res.similarity[0]:.3f}, {iterations} closest-point iterations), regions "
        f"{', '.join(r.name for r in regions)} carried over",
        f"  landmark residual mean {summary['landmarkResidualMean']:.3f} {u}, max "
        f"{summary['landmarkResidualMax']:.3f} {u}; "
        + (f"distance to the scan median {summary['surfaceDistanceMedian']:.3f} {u}, 95% "
           f"{summary['surfaceDistanceP95']:.3f} {u}" if sd.size else "no closest-point pairs"),
    ]
    files = {}
    if carried is not None:
        files["layout_output"] = carried[0]
        text.append(f"wrote {carried[0]}: marker layout ({carried[1].n_markers} markers) on the registered mesh")
    return Result(layers={"output": out}, files=files, summary=summary, text=text)
