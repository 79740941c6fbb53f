"""`usdface transfer`: RBF transfer of capture motion onto the face -> animation layer (.usdc)."""
from __future__ import annotations

import logging
import time

import numpy as np

from ..model.timing import FrameRange
from ..options import TransferOptions
from ..progress import progress
from ..registry import Result
from ..usd.layers import check_output_path, provenance

log = logging.getLogger("usdface")

DEFAULT_CHUNK_FRAMES = 64
#: largest chunk of float32 points (bytes): 64 frames up to 175k vertices, fewer above
CHUNK_BYTES = 128 << 20
#: output buffers cycled by the transfer: the chunk being written, the one computed ahead
#: (write_animation_layer's prefetch) and the next (fresh arrays per chunk cost their page faults)
PREFETCH_BUFFERS = 3


def transfer(mesh_path, capture_path, binding_path, analysis_path, *, options: TransferOptions, output) -> Result:
    """Transfer the capture's marker displacements to every vertex; write the animation layer.

    ``options.head_motion``: when the capture was stabilised, deliver the head motion it removed
    as the time-sampled transform of the face's root prim (:mod:`usdface.usd.motion`); False leaves
    the face head-stabilised. ``options.method`` picks the analysis layer's matrix (default: its
    only one).
    """
    from ..capture.retarget import marker_displacements, mesh_head_motion
    from ..rbf.fitting import fit_transfer
    from ..rbf.stiffness import width_source
    from ..usd.analysis_layer import write_animation_layer
    from ..usd.identity import capture_record, identity, markers_record, mesh_record
    from ..usd.inputs import load_transfer_inputs

    params = options.parameters()
    rbf, kernel, stiffness = params.rbf, params.kernel, params.stiffness
    method, head_motion, all_invalid = options.method, options.head_motion, params.all_invalid

    out = check_output_path(output, inputs={"--mesh": mesh_path, "--capture": capture_path,
                                            "--binding": binding_path, "--analysis": analysis_path})
    mesh, capture, binding, dm = load_transfer_inputs(mesh_path, capture_path, binding_path, analysis_path,
                                                      method=method)
    disp = marker_displacements(capture, binding.names, binding.displacement_transform())
    t0 = time.perf_counter()
    from ..usd.layers import describe

    solver, info = fit_transfer(mesh, binding, dm, params, method_source=describe(analysis_path))
    regularization, choice = info["regularization"], info["choice"]
    amp, miss, advice, settings = info["amplification"], info["markerResidual"], info["advice"], info["settings"]
    motion = mesh_head_motion(capture, binding.capture_to_mesh) if head_motion else None
    recorded = {"rbf": rbf, "kernel": kernel, "stiffness": stiffness, "regularization": regularization,
               "polynomial": info["polynomial"], "method": dm.method, "all_invalid": all_invalid,
               "head_motion": motion is not None}
    prov = provenance("transfer", options=recorded, inputs={"mesh": mesh_path, "capture": capture_path,
                                                           "binding": binding_path, "analysis": analysis_path},
                      identity=identity(mesh=mesh_record(mesh), markers=markers_record(binding),
                                        capture=capture_record(capture)))
    bar = progress(total=capture.n_frames, desc="transfer", unit="frame")
    try:
        # the rest points and the extents come out of the RBF's matrix product (the producer thread):
        # the writer thread only writes. One BLAS thread: the producer runs beside the writer, and
        # OpenBLAS's spinning second thread took the writer's core (2.4x the CPU, 2x the wall time
        # of the product on 2 cores). Big meshes: fewer frames per chunk (CHUNK_BYTES per buffer)
        frames_per_chunk = max(1, min(DEFAULT_CHUNK_FRAMES, CHUNK_BYTES // (12 * mesh.n_points)))
        chunks = solver.iter_chunks(disp, chunk_frames=frames_per_chunk, offset=mesh.points, extents=True,
                                    blas_threads=1, buffers=PREFETCH_BUFFERS)
        write_animation_layer(out, chunks, mesh_path=mesh_path,
                              frames=FrameRange(capture.start_frame, capture.rate, capture.n_frames), units=mesh.units,
                              transfer=settings, prov=prov, progress=bar, head_motion=motion)
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
        "regularization": regularization, "polynomial": info["polynomial"], "widthRule": info["widthRule"],
        "amplification": amp, "markerResidual": miss,
        "exactAmplification": None if choice is None else choice.exact_amplification,
        "framesWithInvalidMarkers": invalid_frames, "validityPatterns": cache, "seconds": round(seconds, 3),
        "headMotion": motion is not None,
    }
    cond = f", condition number {solver.condition_number:.3g}" if solver.condition_number else ""
    cond += f", amplification {amp:.1f}x" + (f", regularization {regularization:.3g} chosen automatically: "
                                              f"markers reproduced within {100 * miss:.0f}%"
                                              if choice is not None and choice.regularized else "")
    text = [
        f"wrote {out}: {capture.n_frames} frames x {mesh.n_points} points ({rbf} {solver.kernel}"
        f"{' + linear polynomial' if info['polynomial'] else ''} on {dm.method} distances, width "
        f"{summary['widthMedian']:.3g} {mesh.units} ({width_source(stiffness, info['widthRule'])}){cond}) "
        f"in {seconds:.2f} s",
    ] + ([f"  {invalid_frames} frames re-solved with their valid markers"] if invalid_frames else []) \
      + ([f"  advice: {advice}"] if advice else [])
    return Result(layers={"output": out}, summary=summary, text=text)
