"""`usdface transfer`: RBF transfer of capture motion onto the face -> animation layer (.usdc)."""
from __future__ import annotations

import json
import logging
import time
import warnings
from pathlib import Path

import numpy as np

from ..errors import MarkerError, OptionError, list_names
from ..progress import progress
from ..rbf.stability import DEFAULT_MAX_AMPLIFICATION
from ..rbf.transfer import check_chunk_frames
from ..usd.layers import check_output_path, open_stage, provenance

log = logging.getLogger("usdface")

DEFAULT_CHUNK_FRAMES = 64
#: largest chunk of float32 points (bytes): 64 frames up to 175k vertices, fewer above
CHUNK_BYTES = 128 << 20
#: output buffers cycled by the transfer: the chunk being written, the one computed ahead
#: (write_animation_layer's prefetch) and the next (fresh arrays per chunk cost their page faults)
PREFETCH_BUFFERS = 3


def parse_stiffness(value):
    """--stiffness: None, a number (mesh units, every marker), or a JSON file {marker: width}."""
    if value is None or isinstance(value, (int, float, dict)):
        return value
    try:
        return float(value)
    except ValueError:
        pass
    path = Path(value)
    if not path.is_file():
        raise OptionError(f"--stiffness {value}: expected a width in mesh units or a JSON file {{marker: width}}")
    try:
        data = json.loads(path.read_text())
    except json.JSONDecodeError as exc:
        raise OptionError(f"--stiffness {value}: not valid JSON ({exc})") from None
    if not isinstance(data, dict):
        raise OptionError(f"--stiffness {value}: expected a JSON object {{marker: width}}")
    return data


def check_capture_units(capture, binding, mesh, *, capture_path, binding_path) -> None:
    """The binding converts capture displacements with the unit scale of the capture it was made
    with; a capture in other units would be scaled wrongly (10x for mm against cm)."""
    from ..errors import MarkerError
    from ..units import scale_between

    if capture.units is None or mesh.units is None:
        return
    expected = scale_between(capture.units, mesh.units)
    if abs(expected - binding.unit_scale) > 1e-9 * max(expected, 1.0):
        raise MarkerError(
            f"capture {capture_path} is in {capture.units} ({expected:g} {mesh.units} per {capture.units}) but binding "
            f"{binding_path} was made for a capture converting at {binding.unit_scale:g}; bind this capture again "
            "(`usdface bind`) or import it in the units of the bound one")


def load_transfer_inputs(mesh_path, capture_path, binding_path, analysis_path, *, method=None):
    """Read and cross-check the inputs of a transfer: (mesh, capture, binding, distance matrix).

    Raises MarkerError / OptionError / InputError naming the file at fault when the analysis was
    computed for other markers or another mesh.
    """
    from ..usd.analysis_layer import read_distance_matrix
    from ..usd.capture_layer import read_capture_layer
    from ..usd.mesh_layer import read_binding, read_mesh_layer

    mesh, _ = read_mesh_layer(mesh_path)
    capture = read_capture_layer(capture_path)
    binding = read_binding(open_stage(binding_path, what="binding"), source=str(binding_path))
    dm = read_distance_matrix(analysis_path, method=method)
    if tuple(dm.marker_names) != tuple(binding.names):
        raise MarkerError(f"analysis {analysis_path} was computed for markers {list_names(dm.marker_names)}, "
                          f"binding {binding_path} binds {list_names(binding.names)}; recompute the distances")
    if dm.vertex_to_centre.shape[0] != mesh.n_points:
        raise OptionError(f"analysis {analysis_path} has {dm.vertex_to_centre.shape[0]} vertices, mesh {mesh_path} "
                          f"has {mesh.n_points}: they belong to different meshes")
    check_capture_units(capture, binding, mesh, capture_path=capture_path, binding_path=binding_path)
    return mesh, capture, binding, dm


def build_transfer_solver(mesh, binding, dm, *, rbf="interpolate", kernel="gaussian", stiffness=None,
                          regularization="auto", polynomial=False, all_invalid="error",
                          max_amplification=DEFAULT_MAX_AMPLIFICATION):
    """The fitted RBF transfer with `usdface transfer`'s option handling (one place for it).

    Parameters are `transfer()`'s options; ``mesh`` (FaceMesh), ``binding`` (Binding) and ``dm``
    (DistanceMatrix) as returned by :func:`load_transfer_inputs`.

    Returns
    -------
    solver : RBFTransfer
        Fitted; ``solver.transfer_matrix`` is the N x M matrix B (vertex displacement = B @ marker
        displacements when every marker is valid).
    info : dict
        ``regularization`` (the lambda used), ``choice`` (RegularizationChoice or None),
        ``amplification``, ``markerResidual``, ``advice``, ``settings`` (FaceTransferAPI values).
    """
    from ..rbf.stability import amplification, fit_stable, marker_residual
    from ..rbf.stiffness import DEFAULT_WIDTH_FACTOR, median_marker_spacing_from_points
    from ..rbf.transfer import RBFTransfer

    centre_points = np.concatenate([binding.surface_points(mesh.points), mesh.points[dm.constraint_vertices]])
    widths = parse_stiffness(stiffness)
    # the default rule on Euclidean marker spacing, whatever the distance method; a partial
    # {marker: width} dict keeps that default for every other centre
    default = DEFAULT_WIDTH_FACTOR * median_marker_spacing_from_points(binding.surface_points(mesh.points))
    if widths is None:
        widths = default
    elif isinstance(widths, dict):
        from ..rbf.stiffness import resolve_widths

        n_centres = dm.vertex_to_centre.shape[1]
        widths = resolve_widths(widths, np.full((n_centres, n_centres), default / DEFAULT_WIDTH_FACTOR),
                                binding.n_markers, marker_names=binding.names)

    def make_solver(lam):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)  # the same advice is logged once below
            return RBFTransfer(dm.vertex_to_centre, dm.centre_to_centre, mode=rbf, kernel=kernel, widths=widths,
                               polynomial=polynomial, regularization=lam, n_markers=binding.n_markers,
                               centre_points=centre_points, vertex_points=mesh.points,
                               marker_names=binding.names, all_invalid=all_invalid,
                               collocation=(binding.triangle_vertices, binding.barycentrics)
                               if rbf == "interpolate" else None).fit()

    choice = None
    if rbf == "interpolate" and regularization == "auto":
        solver, choice = fit_stable(make_solver, max_amplification=max_amplification)
        regularization = choice.regularization
        if choice.regularized:
            log.warning("the exact interpolant on %s distances amplifies marker motion %.0fx (the kernel matrix is "
                        "not positive definite on these distances); regularization %.3g chosen automatically "
                        "(amplification %.1fx; markers are then reproduced approximately)", dm.method,
                        choice.exact_amplification, choice.regularization, choice.amplification)
    else:
        regularization = 0.0 if regularization == "auto" else float(regularization)
        solver = make_solver(regularization)
    amp = amplification(solver.transfer_matrix)
    miss = marker_residual(solver, binding.triangle_vertices, binding.barycentrics)
    if amp > max_amplification and (choice is None or not choice.regularized):
        log.warning("the transfer amplifies marker motion up to %.0fx at some vertices; consider "
                    "--regularization auto, a smaller --stiffness, or --method euclidean", amp)
    advice = solver.advice
    if advice:
        log.warning("%s", advice)
    settings = {
        "mode": rbf, "kernel": _schema_kernel(solver.kernel), "distanceMethod": dm.method,
        "markerNames": list(binding.names), "widths": solver.widths[: binding.n_markers],
        "regularization": regularization, "polynomial": polynomial,
        "conditionNumber": solver.condition_number,
        "parameters": {"constraintVertices": int(dm.constraint_vertices.size), "allInvalid": all_invalid,
                       "amplification": amp, "markerResidual": miss,
                       "regularizationAuto": None if choice is None else {
                           "exactAmplification": choice.exact_amplification,
                           "tried": {str(k): v for k, v in choice.tried.items()}},
                       "retarget": binding.retarget, "distanceBackend": dm.backend},
    }
    return solver, {"regularization": regularization, "choice": choice, "amplification": amp,
                    "markerResidual": miss, "advice": advice, "settings": settings}


def transfer(mesh_path, capture_path, binding_path, analysis_path, output, *, rbf="interpolate",
             kernel="gaussian", stiffness=None, regularization="auto", polynomial=False, method=None,
             all_invalid="error", chunk_frames=DEFAULT_CHUNK_FRAMES,
             max_amplification=DEFAULT_MAX_AMPLIFICATION, head_motion=True) -> dict:
    """Transfer the capture's marker displacements to every vertex; write the animation layer.

    ``head_motion``: when the capture was stabilised, deliver the head motion it removed as the
    time-sampled transform of the face's root prim (:mod:`usdface.usd.motion`); False leaves the
    face head-stabilised.
    """
    chunk_frames = check_chunk_frames(chunk_frames)
    from ..capture.retarget import marker_displacements, mesh_head_motion
    from ..usd.analysis_layer import write_animation_layer

    out = check_output_path(output, inputs={"--mesh": mesh_path, "--capture": capture_path,
                                            "--binding": binding_path, "--analysis": analysis_path})
    mesh, capture, binding, dm = load_transfer_inputs(mesh_path, capture_path, binding_path, analysis_path,
                                                      method=method)
    disp = marker_displacements(capture, binding.names, binding.displacement_transform())
    t0 = time.perf_counter()
    solver, info = build_transfer_solver(mesh, binding, dm, rbf=rbf, kernel=kernel, stiffness=stiffness,
                                         regularization=regularization, polynomial=polynomial,
                                         all_invalid=all_invalid, max_amplification=max_amplification)
    regularization, choice = info["regularization"], info["choice"]
    amp, miss, advice, settings = info["amplification"], info["markerResidual"], info["advice"], info["settings"]
    motion = mesh_head_motion(capture, binding.capture_to_mesh) if head_motion else None
    options = {"rbf": rbf, "kernel": kernel, "stiffness": stiffness, "regularization": regularization,
               "polynomial": polynomial, "method": dm.method, "all_invalid": all_invalid,
               "head_motion": motion is not None}
    prov = provenance("transfer", options=options, inputs={"mesh": mesh_path, "capture": capture_path,
                                                           "binding": binding_path, "analysis": analysis_path})
    bar = progress(total=capture.n_frames, desc="transfer", unit="frame")
    try:
        # the rest points and the extents come out of the RBF's matrix product (the producer thread):
        # the writer thread only writes. One BLAS thread: the producer runs beside the writer, and
        # OpenBLAS's spinning second thread took the writer's core (2.4x the CPU, 2x the wall time
        # of the product on 2 cores). Big meshes: fewer frames per chunk (CHUNK_BYTES per buffer)
        frames_per_chunk = max(1, min(int(chunk_frames), CHUNK_BYTES // (12 * mesh.n_points)))
        chunks = solver.iter_chunks(disp, chunk_frames=frames_per_chunk, offset=mesh.points, extents=True,
                                    blas_threads=1, buffers=PREFETCH_BUFFERS)
        write_animation_layer(out, chunks, mesh_path=mesh_path, rest_points=None, start=capture.start_frame,
                              rate=capture.rate, n_frames=capture.n_frames, units=mesh.units, transfer=settings,
                              prov=prov, progress=bar, head_motion=motion)
    finally:
        bar.close()
    seconds = time.perf_counter() - t0
    cache = solver.cache_info() if hasattr(solver, "cache_info") else {}
    invalid_frames = int((~np.isfinite(disp).all(axis=2)).any(axis=1).sum())
    summary = {
        "output": str(out), "frames": capture.n_frames, "vertices": mesh.n_points, "markers": binding.n_markers,
        "constraintCentres": int(dm.constraint_vertices.size), "mode": rbf, "kernel": solver.kernel,
        "distanceMethod": dm.method, "conditionNumber": solver.condition_number, "advice": advice,
        "widthMedian": float(np.median(solver.widths[: binding.n_markers])), "units": mesh.units,
        "regularization": regularization, "amplification": amp, "markerResidual": miss,
        "exactAmplification": None if choice is None else choice.exact_amplification,
        "framesWithInvalidMarkers": invalid_frames, "validityPatterns": cache, "seconds": round(seconds, 3),
        "headMotion": motion is not None,
    }
    cond = f", condition number {solver.condition_number:.3g}" if solver.condition_number else ""
    cond += f", amplification {amp:.1f}x" + (f", regularization {regularization:.3g} chosen automatically: "
                                              f"markers reproduced within {100 * miss:.0f}%"
                                              if choice is not None and choice.regularized else "")
    summary["_text"] = [
        f"wrote {out}: {capture.n_frames} frames x {mesh.n_points} points ({rbf} {solver.kernel} on {dm.method} "
        f"distances, width {summary['widthMedian']:.3g} {mesh.units}{cond}) in {seconds:.2f} s",
    ] + ([f"  {invalid_frames} frames re-solved with their valid markers"] if invalid_frames else []) \
      + ([f"  advice: {advice}"] if advice else [])
    return summary


def _schema_kernel(name: str) -> str:
    """RBF engine kernel name -> the FaceTransferAPI token."""
    return {"inverse_multiquadric": "inverseMultiquadric", "thin_plate_spline": "thinPlate",
            "thin_plate": "thinPlate"}.get(name, name)
