"""Plausibility checks: capture data (and bindings) that read fine but cannot be what they claim.

A file can be well formed and still hold nonsense: a marker 50 cm off the face, one sample thrown
to (0, 0, 0) or to 1e30, half the columns of a CSV in mm and half in cm, a capture in metres
declared cm. The pipeline would turn each into a face thrown across the room with exit code 0.
These checks judge the data against what a face is, relative to the face's own size (so they hold
for any units, and for a child, a stylised or a creature head within the stated bounds), and
report each finding with the marker, frame and file it concerns.

Checks, severities and overrides
--------------------------------
Every check has a code. An *error* stops the command (exit 2) unless ``--allow CODE`` accepts it,
which turns it into a warning; a *warning* is printed (``--allow CODE`` silences it). All findings
are recorded in the command's summary (``plausibility``).

=================  ========  ==============================================================  =========================
code               severity  finding                                                         override
=================  ========  ==============================================================  =========================
``zeros``          warning   C3D samples at exactly (0, 0, 0) (the usual gap code) read as    ``--keep-zeros`` keeps
                             gaps                                                            them as positions
``outliers``       error     a sample whose distances to its neighbouring markers differ     ``--drop-outliers`` (make
                             from their usual values by more than 20% of the face's span     them gaps) or
                                                                                             ``--allow outliers``
``far-markers``    error     a marker whose nearest other marker is more than 4x the usual   ``--allow far-markers``
                             marker spacing and half the face's span away, all take long
``mixed-units``    error     some markers are a unit factor (10, 100, 2.54...) larger than   ``--allow mixed-units``
                             the others
``face-size``      error     the markers (or the mesh) span less than 3 cm or more than      ``--allow face-size``
                             80 cm in the declared units (metres declared cm...)
``speed``          warning   a marker moving faster than 6 face spans per second             ``--allow speed``
                             (about 2 m/s on a human face) between two frames
``stabilize``      warning   stabilisation did not reduce the rigid rotation or translation  ``--allow stabilize``
                             of the held-out markers
``layout-distance``  error   a layout point more than 15% of the mesh's size off the         ``--allow layout-distance``
                             surface (layout and mesh disagree in units or placement)
``fit-residual``   error     after fitting the capture to the layout (robustly), a marker    ``--allow fit-residual``
                             more than 25% of the face's size from its layout point, or an
                             overall rms beyond 15% (wrong layout, mirrored names...)
``unit-scale``     error     the fitted capture-to-mesh scale is outside 0.25..4 once the    ``--allow unit-scale``
                             declared units are converted: the units contradict the data
=================  ========  ==============================================================  =========================

The thresholds come from the real AnimFace takes (``sample_assets/capture``): faces span
18.5-18.8 cm; neighbour distances change by at most 1.05 cm (5.6% of the span, the jaw wide
open); markers move at most 23 cm/s (1.2 spans/s); the largest nearest-marker distance is 2.0x the
median; the layout fit leaves an rms of 6.2% of the face (mouth corners 7.3 cm apart on the
performer, 5 cm on the meshes). Each bound leaves a margin of 3x or more over these.

Three more checks bound a capture's timing before a reader allocates anything: ``rate``,
``frame-count`` and ``resample`` (:mod:`usdface.io.limits`). A value beyond float32's range
in any capture file (1e308 would be stored as inf) is a malformed file, refused by the reader.

A Maya key far beyond any position (more than 1 km from the origin, or not finite; e.g. 9.9e30)
is not a finding but a malformed file: :func:`usdface.io.maya_ascii.read_maya_ascii` raises
FormatError naming the curve, key and line.
"""
from __future__ import annotations

import logging

import numpy as np

from ..errors import list_names
from ..units import METERS_PER_UNIT
from ..findings import CHECKS, Check, Finding, parse_allow, refuse, report  # noqa: F401 (the public names)
from ..io.limits import rate_finding
from ..model.capture import Capture

log = logging.getLogger("usdface")

__all__ = [
    "CHECKS",
    "Finding",
    "check_capture",
    "drop_outliers",
    "stabilize_finding",
    "face_size_finding",
    "parse_allow",
    "refuse",
    "report",
    "FACE_SPAN_CM",
]


#: plausible span of a face's markers (or a face mesh), cm
FACE_SPAN_CM = (3.0, 80.0)
#: outliers: change of neighbour distances, as a fraction of the face span
OUTLIER_FRACTION = 0.20
#: far markers: nearest-marker distance over the median one, and over the face span
FAR_NN_RATIO = 4.0
FAR_SPAN_FRACTION = 0.5
#: speed bound, face spans per second
MAX_SPANS_PER_SECOND = 6.0
#: neighbours used by the outlier test
N_NEIGHBOURS = 6
#: held-out rigid motion (deg, or capture units) at or below which there is nothing for stabilisation
#: to reduce: round-off (a 1-frame take measures 1e-14); a micron in metres, far below any head motion
STILL_MOTION = 1e-6
#: how many markers / frames a message lists before abbreviating
_LIST = 6


# -- helpers -----------------------------------------------------------------------------------

def _cm(units: str | None) -> float | None:
    """Centimetres per unit (None when the units are unknown)."""
    return None if units is None or units not in METERS_PER_UNIT else METERS_PER_UNIT[units] / 0.01


def _fmt_len(value: float, units: str | None) -> str:
    return f"{value:.3g} {units or 'units'}"


def _where(capture: Capture) -> str:
    return f"capture {capture.source}" if capture.source else "capture"


def _frames_text(frames, limit: int = _LIST) -> str:
    frames = [int(f) for f in frames]
    if not frames:
        return ""
    runs, start, prev = [], frames[0], frames[0]
    for f in frames[1:]:
        if f == prev + 1:
            prev = f
            continue
        runs.append((start, prev))
        start = prev = f
    runs.append((start, prev))
    text = ", ".join(f"{a}" if a == b else f"{a}-{b}" for a, b in runs[:limit])
    return text + (f", ... ({len(frames)} frames)" if len(runs) > limit else "")


def median_pose(positions: np.ndarray) -> np.ndarray:
    """(M, 3) per-marker median over valid frames (NaN for a marker never valid)."""
    with np.errstate(all="ignore"):
        valid = np.isfinite(positions).all(axis=2)
        out = np.full(positions.shape[1:], np.nan)
        for m in range(positions.shape[1]):
            v = positions[valid[:, m], m]
            if len(v):
                out[m] = np.median(v, axis=0)
    return out


def _pairwise(p: np.ndarray) -> np.ndarray:
    with np.errstate(all="ignore"):
        return np.linalg.norm(p[:, None, :] - p[None, :, :], axis=2)


def _unit_ratios() -> list[float]:
    """Distinct ratios > 1 between the known units (10, 100, 1000, 2.54, 12, 30.48, ...)."""
    values = sorted(METERS_PER_UNIT.values())
    ratios = sorted({round(b / a, 6) for a in values for b in values if b / a > 1.05})
    return ratios


def _unit_for(units: str | None, factor: float) -> str | None:
    """The known unit in which values read ``factor`` times those in ``units`` (None if none)."""
    if units not in METERS_PER_UNIT:
        return None
    want = METERS_PER_UNIT[units] / factor
    return next((u for u, m in METERS_PER_UNIT.items() if abs(m - want) <= 1e-6 * want), None)


# -- capture checks ----------------------------------------------------------------------------

def check_capture(capture: Capture, *, check_speed: bool = True) -> list[Finding]:
    """All capture checks (see the module docstring); returns the findings, raises nothing.

    Parameters
    ----------
    capture : Capture
        Positions (F, M, 3) in ``capture.units`` (None: the face-size check is skipped).
    check_speed : bool
        Run the speed check (needs the capture rate).

    Returns
    -------
    list of Finding
        Rate (:mod:`usdface.io.limits`), zeros read as gaps (from the reader's history),
        mixed units, far markers, outliers, face size, speed; in that order. After a ``mixed-units`` finding the later checks judge
        the data with the odd markers scaled into the declared units, so they report what else
        is wrong rather than the same fault again.
    """
    findings: list[Finding] = []
    rate = rate_finding(capture.rate, what=_where(capture), origin="its rate")
    if rate is not None:
        findings.append(rate)
    findings += _zeros_finding(capture)
    pos = capture.positions
    m_count = capture.n_markers
    pose = median_pose(pos)
    usable = np.isfinite(pose).all(axis=1)
    if m_count < 3 or usable.sum() < 3:
        return findings

    mixed = _mixed_units(capture, pose, usable)
    if mixed is not None:
        finding, scale = mixed
        findings.append(finding)
        pos = pos * scale[None, :, None]
        pose = pose * scale[:, None]
        capture = capture.replace(positions=pos)

    far = _far_markers(capture, pose, usable)
    flagged = np.zeros(m_count, dtype=bool)
    if far is not None:
        findings.append(far)
        flagged |= np.isin(np.array(capture.names), far.markers)

    core = usable & ~flagged
    if core.sum() < 3:
        return findings
    d = _pairwise(pose[core])
    span = float(np.nanmax(d))
    if not span > 0:
        return findings
    out = _outliers(capture, pose, core, span)
    if out is not None:
        findings.append(out)
    size = face_size_finding(span, capture.units, what=_where(capture), kind="markers")
    if size is not None:
        findings.append(size)
    if check_speed:
        sp = _speed(capture, span, core, None if out is None else out.samples)
        if sp is not None:
            findings.append(sp)
    return findings


def _zeros_finding(capture: Capture) -> list[Finding]:
    read = next((h for h in capture.history if h.get("step") == "read"), None)
    if not read or not read.get("zero_samples"):
        return []
    per_marker = read.get("zero_markers", {})
    names = sorted(per_marker, key=lambda n: -per_marker[n])
    shown = ", ".join(f"{n} ({per_marker[n]})" for n in names[:_LIST]) + (", ..." if len(names) > _LIST else "")
    msg = (f"{_where(capture)}: {read['zero_samples']} samples at exactly (0, 0, 0) read as gaps, the C3D gap "
           f"convention (markers: {shown}); --keep-zeros keeps them as positions")
    return [Finding("zeros", "warning", msg, markers=tuple(names))]


#: unit ratios in the order a mixed-units finding prefers them (ties between near ratios, 10 vs 12)
_RATIO_PRIOR = (10.0, 100.0, 1000.0, 2.54, 25.4, 30.48, 12.0, 304.8, 3.048, 3.28084, 3.937008, 39.370079)


def _mixed_units(capture: Capture, pose: np.ndarray, usable: np.ndarray):
    """Markers that become ordinary members of the face once scaled by a unit ratio.

    Candidate groups: markers whose position scaled by a ratio lands next to another marker
    (alternating columns), and the markers outside the main cluster (a block of columns). A group
    is confirmed when, scaled, it joins the others into one face with the usual marker spacing and
    less than half the span of the data as read.

    Returns None, or (finding, scale): ``scale`` (M,) multiplies each marker's positions into the
    declared units (1 for the markers already in them).
    """
    idx = np.flatnonzero(usable)
    p = pose[idx]
    d = _pairwise(p)
    span_raw = float(np.max(d))
    np.fill_diagonal(d, np.inf)
    nn = d.min(axis=1)
    centre = np.median(p, axis=0)
    r = np.linalg.norm(p - centre, axis=1)
    main = r <= 2.0 * np.median(r)
    groups = []
    for ratio in _unit_ratios():
        for factor in (1.0 / ratio, ratio):
            q = p * factor
            dq = np.linalg.norm(q[:, None, :] - p[None, :, :], axis=2)  # scaled i to unscaled j
            np.fill_diagonal(dq, np.inf)
            groups.append((ratio, factor, dq.min(axis=1) < nn / 3.0))
            groups.append((ratio, factor, ~main))
    u = capture.units
    verified = []
    for ratio, factor, cand in groups:
        if cand.sum() == 0 or (~cand).sum() < 3:
            continue
        rest = p[~cand]
        joined = np.concatenate([rest, p[cand] * factor])
        dj = _pairwise(joined)
        span_joined = float(np.max(dj))
        np.fill_diagonal(dj, np.inf)
        dr = _pairwise(rest)
        np.fill_diagonal(dr, np.inf)
        typical = np.median(dr.min(axis=1))
        if (dj.min(axis=1)[len(rest):] <= FAR_NN_RATIO * typical).all() and span_joined < 0.5 * span_raw:
            known = _unit_for(u, 1.0 / factor) is not None or _unit_for(u, factor) is not None
            prior = min(range(len(_RATIO_PRIOR)), key=lambda i: abs(np.log(_RATIO_PRIOR[i] / ratio)))
            verified.append(((not known, prior, span_joined), factor, cand, span_joined))
    if not verified:
        return None
    _, factor, cand, span_joined = min(verified, key=lambda v: v[0])
    # factor scales the candidates into the others' units; decide which group is in the declared ones
    cm = _cm(u)
    lo, hi = FACE_SPAN_CM
    rest_declared = cm is not None and lo <= span_joined * cm <= hi
    cand_declared = cm is not None and not rest_declared and lo <= span_joined / factor * cm <= hi
    if cand_declared or (not rest_declared and cand.sum() > (~cand).sum()):
        odd, k = ~cand, 1.0 / factor  # the others are the odd ones: scale them by 1/factor
    else:
        odd, k = cand, factor
    scale = np.ones(capture.n_markers)
    scale[idx[odd]] = k
    names = [capture.names[i] for i in idx[odd]]
    others = len(idx) - len(names)
    larger = 1.0 / k  # how many times larger the odd markers read
    how = f"{larger:.4g}x larger" if larger > 1 else f"{1 / larger:.4g}x smaller"
    if rest_declared or cand_declared:
        other = _unit_for(u, larger)
        units_text = (f"as if they were in {other} and the others in {u}" if other else f"the others are in {u}")
    else:
        units_text = "the two groups are in different units"
    msg = (f"{_where(capture)}: {len(names)} marker(s) ({list_names(names, _LIST)}) read {how} than the other "
           f"{others}: scaled by {k:.4g} they fall into place on the face, {units_text}: the file mixes units "
           f"(fix the file; --allow mixed-units keeps the data as it is)")
    return Finding("mixed-units", "error", msg, markers=tuple(names)), scale


def _far_markers(capture: Capture, pose: np.ndarray, usable: np.ndarray) -> Finding | None:
    idx = np.flatnonzero(usable)
    if len(idx) < 4:
        return None
    d = _pairwise(pose[idx])
    np.fill_diagonal(d, np.inf)
    nn = d.min(axis=1)
    typical = float(np.median(nn))
    far = nn > FAR_NN_RATIO * typical
    if not far.any() or far.sum() > len(idx) // 2:
        return None
    dr = d[np.ix_(~far, ~far)]
    span_rest = float(np.max(np.where(np.isfinite(dr), dr, 0)))
    far &= nn > FAR_SPAN_FRACTION * span_rest
    if not far.any():
        return None
    names = [capture.names[i] for i in idx[far]]
    u = capture.units
    detail = ", ".join(f"{capture.names[i]} {_fmt_len(n, u)}" for i, n in zip(idx[far], nn[far]))
    msg = (f"{_where(capture)}: marker(s) far from every other marker through the take (nearest other marker: "
           f"{detail}; markers are usually {_fmt_len(typical, u)} apart and the face spans {_fmt_len(span_rest, u)}): "
           f"a mislabelled or misplaced marker? (--allow far-markers keeps it)")
    return Finding("far-markers", "error", msg, markers=tuple(names))


def _neighbour_deviation(pos: np.ndarray, pose: np.ndarray, core: np.ndarray) -> np.ndarray:
    """(F, M) median over each marker's nearest core neighbours of the change of their distance
    from the median pose (NaN where the sample or too many neighbours are invalid)."""
    n_frames, n_markers = pos.shape[:2]
    cidx = np.flatnonzero(core)
    d = _pairwise(pose)
    dev = np.full((n_frames, n_markers), np.nan)
    k = min(N_NEIGHBOURS, len(cidx) - 1)
    if k < 2:
        return dev
    for m in cidx:
        cands = cidx[cidx != m]
        nb = cands[np.argsort(d[m, cands], kind="stable")[:k]]
        with np.errstate(all="ignore"):
            cur = np.linalg.norm(pos[:, [m]] - pos[:, nb], axis=2)  # (F, k)
            change = np.abs(cur - d[m, nb][None])
        ok = np.isfinite(change)
        enough = ok.sum(axis=1) >= max(2, k // 2)
        if enough.any():
            dev[enough, m] = np.nanmedian(change[enough], axis=1)
    return dev


def _outliers(capture: Capture, pose, core, span: float) -> Finding | None:
    dev = _neighbour_deviation(capture.positions, pose, core)
    limit = OUTLIER_FRACTION * span
    bad = np.nan_to_num(dev, nan=0.0) > limit
    if not bad.any():
        return None
    u = capture.units
    per_marker = bad.sum(axis=0)
    order = np.argsort(-np.nanmax(np.where(bad, dev, -np.inf), axis=0))
    parts = []
    for m in order[:_LIST]:
        if not per_marker[m]:
            continue
        frames = capture.start_frame + np.flatnonzero(bad[:, m])
        worst = float(np.nanmax(dev[bad[:, m], m]))
        parts.append(f"{capture.names[m]} at frame {_frames_text(frames, 3)} (off by up to {_fmt_len(worst, u)})")
    names = [capture.names[m] for m in np.flatnonzero(per_marker)]
    frames_all = capture.start_frame + np.flatnonzero(bad.any(axis=1))
    more = f"; {len(names) - _LIST} more marker(s)" if len(names) > _LIST else ""
    msg = (f"{_where(capture)}: {int(bad.sum())} outlier sample(s), where a marker's distances to its neighbours "
           f"differ from their usual values by more than {_fmt_len(limit, u)} (20% of the face's "
           f"{_fmt_len(span, u)}): {'; '.join(parts)}{more}; --drop-outliers makes them gaps, --allow outliers "
           f"keeps them")
    return Finding("outliers", "error", msg, markers=tuple(names), frames=tuple(int(f) for f in frames_all),
                   samples=bad)


def face_size_finding(span: float, units: str | None, *, what: str, kind: str, fix: str | None = None
                      ) -> Finding | None:
    """``face-size`` finding when ``span`` (in ``units``) is outside :data:`FACE_SPAN_CM`.

    ``kind`` says what spans ("markers", "mesh"); the message suggests the unit that would make
    the span a human face's (about 19 cm), and ``fix`` (text with ``{unit}``) how to give it.
    """
    cm = _cm(units)
    if cm is None or not np.isfinite(span):
        return None
    span_cm = span * cm
    lo, hi = FACE_SPAN_CM
    if lo <= span_cm <= hi:
        return None
    guess = min(METERS_PER_UNIT, key=lambda u: abs(np.log(span * METERS_PER_UNIT[u] / 0.01 / 19.0)))
    guess_cm = span * METERS_PER_UNIT[guess] / 0.01
    if guess != units and lo <= guess_cm <= hi:
        hint = f"is it in {guess}? (it would span {guess_cm:.3g} cm{'; ' + fix.format(unit=guess) if fix else ''})"
    else:
        hint = "check its units"
    verb = "spans" if kind == "mesh" else "span"
    in_cm = "" if units == "cm" else f" ({span_cm:.3g} cm)"
    msg = (f"{what}: the {kind} {verb} {span:.3g} {units}{in_cm}; a face spans {lo:g}-{hi:g} cm: {hint}; "
           f"--allow face-size accepts a miniature or giant head")
    return Finding("face-size", "error", msg)


def _speed(capture: Capture, span: float, core, outlier_samples) -> Finding | None:
    pos = capture.positions
    if capture.n_frames < 2:
        return None
    with np.errstate(all="ignore"):
        v = np.linalg.norm(np.diff(pos, axis=0), axis=2) * capture.rate  # (F-1, M) units/s
    if outlier_samples is not None:
        near = outlier_samples[1:] | outlier_samples[:-1]
        v = np.where(near, np.nan, v)
    limit = MAX_SPANS_PER_SECOND * span
    bad = np.nan_to_num(v, nan=0.0) > limit
    if not bad.any():
        return None
    u = capture.units
    cm = _cm(u)
    per = bad.sum(axis=0)
    order = np.argsort(-np.nanmax(np.where(bad, v, -np.inf), axis=0))
    parts = []
    for m in order[:_LIST]:
        if not per[m]:
            continue
        frames = capture.start_frame + np.flatnonzero(bad[:, m])
        worst = float(np.nanmax(v[bad[:, m], m]))
        ms = f" = {worst * cm / 100:.3g} m/s" if cm else ""
        steps = ", ".join(f"{f}->{f + 1}" for f in frames[:3]) + (f", ... ({len(frames)} in all)" if len(frames) > 3 else "")
        parts.append(f"{capture.names[m]} from frame {steps} ({worst:.3g} {u or 'units'}/s{ms})")
    names = [capture.names[m] for m in np.flatnonzero(per)]
    msg = (f"{_where(capture)}: marker(s) moving faster than {MAX_SPANS_PER_SECOND:g} face spans per second "
           f"({limit:.3g} {u or 'units'}/s): {'; '.join(parts)}: a marker swap or a glitch? "
           f"(--allow speed silences this)")
    return Finding("speed", "warning", msg, markers=tuple(names),
                   frames=tuple(int(f) for f in capture.start_frame + np.flatnonzero(bad.any(axis=1))))


def drop_outliers(capture: Capture, findings) -> tuple[Capture, int]:
    """Mark the samples of ``outliers`` findings invalid (NaN); returns (capture, samples dropped)."""
    bad = None
    for f in findings:
        if f.code == "outliers" and f.samples is not None:
            bad = f.samples if bad is None else bad | f.samples
    if bad is None or not bad.any():
        return capture, 0
    pos = capture.positions.copy()
    pos[bad] = np.nan
    step = {"step": "drop-outliers", "samples": int(bad.sum())}
    out = capture.replace(step=step, positions=pos)
    out.check_not_all_invalid()
    return out, int(bad.sum())


def stabilize_finding(report_summary: dict, *, what: str, units: str | None) -> Finding | None:
    """``stabilize`` finding when the held-out markers' rigid rotation or translation did not drop.

    ``report_summary`` is :meth:`usdface.capture.stabilize.StabilizeReport.summary`.
    """
    hold = (report_summary or {}).get("holdout") or {}
    before, after = hold.get("before"), hold.get("after")
    if not before or not after:
        return None
    worse = []
    for key, label, unit in (("max_angle_deg", "rotation", "deg"), ("max_translation", "translation", units or "units")):
        b, a = before.get(key), after.get(key)
        if b is None or a is None or not (np.isfinite(b) and np.isfinite(a)):
            continue
        if b <= STILL_MOTION:  # no motion to reduce (a 1-frame take: round-off, 1e-14, before and after)
            continue
        if a >= b:
            worse.append(f"{label} {b:.2f} -> {a:.2f} {unit}")
    if not worse:
        return None
    msg = (f"{what}: stabilisation did not reduce the rigid motion of the held-out markers "
           f"({', '.join(hold.get('markers', []))}): {', '.join(worse)}; the fit markers "
           f"({', '.join(report_summary.get('markers', []))}) may not move with the head, or the held-out ones move "
           f"with the expression: check the stabilised capture or name head-rigid markers with --stabilize M1,M2,... "
           f"(--allow stabilize silences this)")
    return Finding("stabilize", "warning", msg)
