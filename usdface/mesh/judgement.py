"""Judging a binding: is the capture on this face, in these units?

A binding can be computed from almost anything: a layout made for the mesh in other units, a
capture with one marker 50 cm off, a mesh in metres read as centimetres. The numbers that tell
(fit residuals, distances to the surface, the fitted scale) were reported but never judged. These
functions turn them into :class:`~usdface.capture.plausibility.Finding` objects (codes
``face-size``, ``layout-distance``, ``fit-residual``, ``unit-scale``; see that module's table),
relative to the face's own size so they hold in any units and on any head within the bounds.

Calibration on the real data (``sample_assets``): the layout fit of the AnimFace takes to the
MakeHuman layout leaves an rms of 6.2% of the bound points' extent (largest marker 10.4%) in 3D,
and 5.0% (largest 8%) for the rendered video's tracks in the image; layout points lie on the
surface (1e-5 cm); fitted capture-to-mesh scales are 0.87 (MakeHuman) to 1.1.
"""
from __future__ import annotations

import numpy as np

from ..capture.plausibility import Finding, face_size_finding
from ..capture.rigid import fit_rigid

__all__ = [
    "FIT_MARKER_FRACTION",
    "FIT_RMS_FRACTION",
    "LAYOUT_DISTANCE_FRACTION",
    "SCALE_RANGE",
    "robust_similarity",
    "fit_residual_findings",
    "layout_distance_finding",
    "unit_scale_finding",
    "mesh_size_finding",
]

#: a marker farther than this fraction of the face's extent from its layout point is an error
FIT_MARKER_FRACTION = 0.25
#: an rms (over the markers kept by the robust fit) beyond this fraction is an error
FIT_RMS_FRACTION = 0.15
#: a layout point farther than this fraction of the face's extent from the surface is an error
LAYOUT_DISTANCE_FRACTION = 0.15
#: plausible capture-to-mesh scales once the declared units are converted
SCALE_RANGE = (0.25, 4.0)
#: the robust fit never sets aside more than this fraction of the markers
MAX_EXCLUDED_FRACTION = 0.25


def extent(points) -> float:
    """Largest side of the axis-aligned box of ``points`` (N, D), NaN rows ignored."""
    p = np.asarray(points, dtype=np.float64)
    p = p[np.isfinite(p).all(axis=1)]
    return float(np.ptp(p, axis=0).max()) if len(p) else float("nan")


def robust_similarity(src, dst, *, limit: float):
    """Similarity (Umeyama) from ``src`` to ``dst`` that sets aside markers that do not fit.

    One marker 50 cm off drags a least-squares fit so that it shows a residual of 16 cm and the
    others several: the worst marker is set aside while its residual exceeds ``limit``, up to
    :data:`MAX_EXCLUDED_FRACTION` of the markers, and the fit is repeated on the rest.

    Parameters
    ----------
    src, dst : ndarray, shape (M, 3), float64
    limit : float
        Residual (``dst`` units) beyond which a marker is set aside.

    Returns
    -------
    rot (3, 3), scale float, t (3,), residuals (M,) of every marker under the final fit,
    kept (M,) bool (markers the fit used).
    """
    src = np.asarray(src, dtype=np.float64)
    dst = np.asarray(dst, dtype=np.float64)
    kept = np.ones(len(src), dtype=bool)
    max_out = int(MAX_EXCLUDED_FRACTION * len(src))
    while True:
        rot, s, t = fit_rigid(src[kept], dst[kept], scale=True)
        res = np.linalg.norm(s * src @ rot.T + t - dst, axis=1)
        worst = int(np.argmax(np.where(kept, res, -np.inf)))
        if res[worst] <= limit or (~kept).sum() >= max_out or kept.sum() <= 4:
            return rot, s, t, res, kept
        kept[worst] = False


def fit_residual_findings(names, residuals, kept, face_extent: float, *, units: str | None, what: str,
                          kind: str = "layout point") -> list[Finding]:
    """``fit-residual`` findings: markers beyond 25% of the face, or an rms beyond 15%.

    Parameters
    ----------
    names : sequence of str, length M
    residuals : ndarray (M,)
        Distance from each mapped marker to its target, same units as ``face_extent``.
    kept : ndarray (M,) bool
        Markers the fit used (the others were set aside by :func:`robust_similarity`).
    face_extent : float
        The face's size (largest side of the targets' box).
    units : str or None
        Units of the distances, for the message ("px" for image tracks).
    what : str
        Names the files ("capture X vs layout Y").
    kind : str
        What a marker is fitted to ("layout point", "surface").
    """
    res = np.asarray(residuals, dtype=np.float64)
    u = units or "units"
    limit = FIT_MARKER_FRACTION * face_extent
    far = np.flatnonzero(res > limit)
    findings = []
    rms = float(np.sqrt(np.mean(res[kept] ** 2))) if kept.any() else float("nan")
    typical = (f"the other markers: median {np.median(res[kept]):.3g} {u}, max {res[kept].max():.3g} {u}"
               if kept.any() else "")
    if far.size:
        order = far[np.argsort(-res[far])]
        shown = ", ".join(f"{names[i]} {res[i]:.3g} {u}" for i in order[:6]) + (", ..." if far.size > 6 else "")
        findings.append(Finding(
            "fit-residual", "error",
            f"{what}: marker(s) far from their {kind} after the capture-to-mesh fit ({shown}; more than "
            f"{100 * FIT_MARKER_FRACTION:g}% of the face's {face_extent:.3g} {u}; {typical}): a mislabelled or "
            f"misplaced marker, or a layout made for another marker set? (--allow fit-residual accepts it)",
            markers=tuple(names[i] for i in order)))
    if np.isfinite(rms) and rms > FIT_RMS_FRACTION * face_extent:
        findings.append(Finding(
            "fit-residual", "error",
            f"{what}: the capture does not fit the {kind}s: rms {rms:.3g} {u} over the markers, "
            f"{100 * rms / face_extent:.0f}% of the face's {face_extent:.3g} {u} (a matching layout leaves about 6%): "
            f"wrong layout, mirrored left/right names, or another face? (--allow fit-residual accepts it)"))
    return findings


def layout_distance_finding(names, distances, face_extent: float, *, units: str | None, what: str,
                            mesh_extent: float | None = None) -> Finding | None:
    """``layout-distance`` finding: layout points more than 15% of the face off the surface."""
    d = np.asarray(distances, dtype=np.float64)
    # a mesh in the wrong units shrinks the bound points' extent with it: judge against the larger
    # of the bound points' and the mesh's extent so the message reports the real distance
    size = face_extent if mesh_extent is None else max(face_extent, mesh_extent)
    limit = LAYOUT_DISTANCE_FRACTION * size
    far = np.flatnonzero(d > limit)
    if not far.size:
        return None
    u = units or "units"
    order = far[np.argsort(-d[far])]
    shown = ", ".join(f"{names[i]} {d[i]:.3g} {u}" for i in order[:6]) + (", ..." if far.size > 6 else "")
    return Finding(
        "layout-distance", "error",
        f"{what}: {far.size} layout point(s) far off the mesh surface ({shown}; the mesh spans {size:.3g} {u}): the "
        f"layout and the mesh disagree in units or placement (is the mesh in other units? --units / "
        f"--mesh-units; --allow layout-distance accepts it)", markers=tuple(names[i] for i in order))


def unit_scale_finding(scale: float, *, capture_units: str | None, mesh_units: str | None,
                       what: str) -> Finding | None:
    """``unit-scale`` finding: a fitted capture-to-mesh scale outside 0.25..4 after unit conversion."""
    lo, hi = SCALE_RANGE
    if not np.isfinite(scale) or lo <= scale <= hi:
        return None
    from ..units import METERS_PER_UNIT

    hint = ""
    if mesh_units in METERS_PER_UNIT:
        # which unit would make the mesh match the capture at a scale near 1
        # the fitted scale read with the mesh in unit u instead: scale * m(u) / m(mesh units)
        guess = min(METERS_PER_UNIT, key=lambda u: abs(np.log(scale * METERS_PER_UNIT[u] / METERS_PER_UNIT[mesh_units])))
        implied = scale * METERS_PER_UNIT[guess] / METERS_PER_UNIT[mesh_units]
        if guess != mesh_units and lo <= implied <= hi:
            hint = f"; the mesh read as {guess} would give {implied:.3g}: is the mesh in {guess}?"
    return Finding(
        "unit-scale", "error",
        f"{what}: the fitted capture-to-mesh scale is {scale:.3g} after converting {capture_units} to {mesh_units}, "
        f"where matching units give about 1 ({lo:g}-{hi:g} for heads of other sizes){hint} "
        f"(--allow unit-scale accepts it)")


def mesh_size_finding(points, units: str | None, *, what: str, fix: str | None = None) -> Finding | None:
    """``face-size`` finding for a mesh: its largest extent outside 3-80 cm in its units."""
    return face_size_finding(extent(points), units, what=what, kind="mesh", fix=fix)
