"""`usdface import-capture`: a capture file -> conditioned capture layer (.usdc)."""
from __future__ import annotations

import logging
from pathlib import Path


from ..capture.model import Capture
from ..errors import OptionError
from ..usd.layers import USD_SUFFIXES, check_output_path, provenance

log = logging.getLogger("usdface")


def load_capture(path, *, units=None, rate=None, up_axis=None, keep_zeros=False) -> Capture:
    """Read any capture usdface understands: a capture file (.ma .c3d .trc .csv), a capture layer,
    or (Python API) an in-memory stage or layer holding a marker set.

    ``keep_zeros``: C3D samples at exactly (0, 0, 0) stay positions instead of gaps."""
    from ..usd.layers import is_in_memory

    if is_in_memory(path) or Path(path).suffix.lower() in USD_SUFFIXES:
        from ..usd.capture_layer import read_capture_layer

        capture = read_capture_layer(path)
        if units is not None and capture.units is not None and units != capture.units:
            raise OptionError(f"--units {units} conflicts with capture layer {path} (in {capture.units}); "
                              "layers are never rescaled on import")
        if rate is not None and abs(rate - capture.rate) > 1e-9 * capture.rate:
            raise OptionError(f"--rate {rate:g} conflicts with capture layer {path} ({capture.rate:g} Hz); "
                              "use --resample to change the rate")
        return capture
    from ..io.captures import read_capture

    return read_capture(path, units=units, rate=rate, up_axis=up_axis, keep_zeros=keep_zeros)


def condition_capture(capture: Capture, *, trim=None, fill_gaps=None, filter=None, cutoff=8.0, resample=None,
                      neutral=None, stabilize=None, start_frame=None, allow=(), drop_outliers=False
                      ) -> tuple[Capture, dict]:
    """Apply the optional conditioning steps in a fixed order; returns (capture, reports).

    Order: trim -> plausibility checks (:mod:`usdface.capture.plausibility`; ``drop_outliers``
    turns outlier samples into gaps; ``allow`` accepts findings by code) -> marker-swap detection
    (reported) -> gap filling -> noise filter -> resample -> neutral frame -> head stabilisation
    (relative to the neutral frame; judged on held-out markers) -> time offset (time code = frame
    index from 0, or from ``start_frame``).

    Raises PlausibilityError on a plausibility error that ``allow`` does not accept.
    """
    from ..capture import gaps, neutral as neutral_mod, plausibility, swaps, timing

    reports: dict = {}
    # how the conditioned frames map to the source's (a playblast beside the source video needs it)
    timing_report = {"sourceRate": float(capture.rate), "sourceFrames": int(capture.n_frames),
                     "trimStart": int(trim[0]) if trim is not None else 0}
    if trim is not None:
        start, end = trim
        stop = capture.n_frames if end is None else end
        if not (0 <= start < stop <= capture.n_frames):
            raise OptionError(f"--trim {start} {end}: expected 0 <= START < END <= {capture.n_frames} "
                              f"(the capture {capture.source} has {capture.n_frames} frames)")
        if not (start <= capture.neutral_frame < stop):
            # the file's neutral (its first frame) is cut away: start from the first kept frame;
            # --neutral, applied below, still overrides
            capture = neutral_mod.set_neutral(capture, max(int(start), 0), how="trim")
        capture = timing.trim(capture, start=start, end=end)
    allow = plausibility.parse_allow(allow)
    findings = plausibility.check_capture(capture)
    if drop_outliers:
        capture, dropped = plausibility.drop_outliers(capture, findings)
        if dropped:
            reports["droppedOutliers"] = dropped
            # dropped samples are gaps now: the finding is reported, not raised
            allow = allow | {"outliers"}
            findings = [f if f.code != "outliers" else plausibility.Finding(
                "outliers", "warning", f.message.replace("; --drop-outliers makes them gaps, --allow outliers keeps them",
                                                         f": {dropped} sample(s) made gaps (--drop-outliers)"),
                f.markers, f.frames) for f in findings]
    checked = plausibility.report(findings, allow=allow)
    events = swaps.detect_swaps(capture)
    if events:
        reports["swaps"] = [e.summary() if hasattr(e, "summary") else e.__dict__ for e in events]
        for e in events:
            log.warning("possible marker swap at frame %s: %s <-> %s", e.frame, e.marker_a, e.marker_b)
    if fill_gaps is not None:
        capture, report = gaps.fill_gaps(capture, max_gap=fill_gaps)
        reports["gaps"] = report.summary()
    if filter is not None:
        from ..capture import filtering

        # a Savitzky-Golay filter is set by its window, not a cutoff frequency
        cutoff_option = {"cutoff_hz": cutoff} if filter == "butterworth" else {}
        capture = filtering.filter_noise(capture, method=filter, **cutoff_option)
    # the neutral frame is chosen on the capture's own frames (after trimming), then resampling
    # carries it to the nearest new frame
    if neutral == "auto":
        index, report = neutral_mod.choose_neutral(capture)
        capture = neutral_mod.set_neutral(capture, index, how="auto")
        reports["neutral"] = report.summary()
    elif neutral is not None:
        if not 0 <= neutral < capture.n_frames:
            raise OptionError(f"--neutral {neutral}: expected a frame index 0..{capture.n_frames - 1} "
                              "(0-based, after --trim) or 'auto'")
        capture = neutral_mod.set_neutral(capture, neutral, how="option")
    if resample is not None:
        capture = timing.resample(capture, rate=resample)
    if stabilize is not None:
        from ..capture.stabilize import stabilize as stabilize_fn

        markers = None if stabilize == "auto" else list(stabilize)
        capture, report = stabilize_fn(capture, markers=markers)
        reports["stabilize"] = report.summary()
        finding = plausibility.stabilize_finding(reports["stabilize"], what=plausibility._where(capture),
                                                 units=capture.units)
        if finding is not None:
            checked += plausibility.report([finding], allow=allow)
    if checked:
        reports["plausibility"] = checked
    # one time-code convention for every output: frame index from 0 unless --start-frame says
    # otherwise (C3D counts from 1, TRC from its first time; the source's number is in the history)
    target = 0 if start_frame is None else start_frame
    if capture.start_frame != target:
        reports["timeCodes"] = {"sourceStart": int(capture.start_frame), "start": int(target)}
        capture = timing.offset(capture, start_frame=target)
    timing_report.update(rate=float(capture.rate), frames=int(capture.n_frames),
                         startTimeCode=int(capture.start_frame))
    reports["timing"] = timing_report
    return capture, reports


def import_capture(input, output, *, units=None, rate=None, up_axis=None, stabilize=None, fill_gaps=None,
                   filter=None, cutoff=8.0, trim=None, start_frame=None, resample=None, neutral=None,
                   allow=(), keep_zeros=False, drop_outliers=False, cache=None) -> dict:
    """Import and condition a capture; write the capture layer. Returns a summary dict.

    Plausibility (:mod:`usdface.capture.plausibility`): ``allow`` (check codes) accepts findings
    that would stop the import; ``keep_zeros`` keeps C3D samples at exactly (0, 0, 0) as positions
    (default: gaps); ``drop_outliers`` turns outlier samples into gaps (fill them with
    ``fill_gaps``). Findings are in the summary's ``reports["plausibility"]``.

    ``cache`` (a :class:`usdface.batch.cache.ContentCache`, default None: no cache) reuses a capture
    layer written before from the same file bytes, file name, options and usdface version: the
    layer is copied, byte for byte what this call would write.
    """
    from ..capture import plausibility
    from ..usd.layers import is_in_memory

    out = check_output_path(output, inputs={"input": input})
    if not is_in_memory(out) and out.suffix.lower() not in (".usdc", ".usd", ".usda"):
        raise OptionError(f"-o {out}: a capture layer is a .usdc (or .usd/.usda) file")
    options = dict(units=units, rate=rate, up_axis=up_axis, stabilize=stabilize, fill_gaps=fill_gaps,
                   filter=filter, cutoff=cutoff if filter else None, trim=trim, start_frame=start_frame,
                   resample=resample, neutral=neutral)
    # plausibility options enter the provenance (and the cache key) only when they change something
    allow = sorted(plausibility.parse_allow(allow))
    for key, value in (("allow", allow), ("keep_zeros", bool(keep_zeros)), ("drop_outliers", bool(drop_outliers))):
        if value:
            options[key] = value
    if cache is None:
        return _import_capture(input, out, options, fill_gaps)
    from ..batch.cache import content_key
    from ..usd.layers import file_digest

    if not Path(input).is_file():
        from ..errors import InputError

        raise InputError(f"capture {input}: no such file")
    key = content_key("capture", Path(input).name, file_digest(input), out.suffix.lower(), options)
    name = "capture" + out.suffix.lower()
    with cache.lock("capture", key):
        entry = cache.get("capture", key)
        if entry is None:
            summary = _import_capture(input, out, options, fill_gaps)
            stored = {k: v for k, v in summary.items() if k not in ("output", "source", "_text")}
            stored["_text"] = [line.replace(str(out), "{output}") for line in summary["_text"]]
            cache.put("capture", key, files={name: out}, meta={"summary": stored})
            status = "miss"
        else:
            _copy_atomic(entry.file(name), out)
            stored = entry.meta["summary"]
            summary = {"output": str(out), "source": str(input)}
            summary.update({k: v for k, v in stored.items() if k != "_text"})
            summary["_text"] = [line.replace("{output}", str(out)) for line in stored["_text"]]
            summary["_text"][0] += " (from the cache)"
            status = "hit"
            # the findings were logged when the entry was made: say them again for this shot
            for f in summary.get("reports", {}).get("plausibility", []):
                if not (f["allowed"] and f["severity"] == "warning"):
                    log.warning("%s", f["message"])
    summary["cache"] = {"status": status, "key": key}
    return summary


def _copy_atomic(src: Path, dst: Path) -> None:
    """Copy ``src`` over ``dst`` through a temporary file in ``dst``'s folder and one rename."""
    import shutil

    from ..fileutil import atomic_write

    with open(src, "rb") as fi, atomic_write(dst, "wb") as fo:
        shutil.copyfileobj(fi, fo, 1 << 20)


def _import_capture(input, out, options, fill_gaps) -> dict:
    from ..usd.capture_layer import write_capture_layer

    units, rate, up_axis = options["units"], options["rate"], options["up_axis"]
    trim, filter, resample = options["trim"], options["filter"], options["resample"]
    neutral, stabilize, start_frame = options["neutral"], options["stabilize"], options["start_frame"]
    cutoff = options["cutoff"] if filter else 8.0
    capture = load_capture(input, units=units, rate=rate, up_axis=up_axis, keep_zeros=bool(options.get("keep_zeros")))
    capture, reports = condition_capture(capture, trim=trim, fill_gaps=fill_gaps, filter=filter, cutoff=cutoff,
                                         resample=resample, neutral=neutral, stabilize=stabilize,
                                         start_frame=start_frame, allow=options.get("allow", ()),
                                         drop_outliers=bool(options.get("drop_outliers")))
    prov = provenance("import-capture", options=options, inputs={"capture": input})
    write_capture_layer(out, capture, prov=prov)
    valid = capture.valid
    summary = {
        "output": str(out), "source": str(input), "markers": capture.n_markers, "frames": capture.n_frames,
        "rate": capture.rate, "units": capture.units, "startTimeCode": capture.start_frame,
        "neutralFrame": capture.neutral_frame, "invalidSamples": int((~valid).sum()),
        "stabilized": capture.head_motion is not None, "reports": reports,
    }
    text = [f"wrote {out}: {capture.n_markers} markers, {capture.n_frames} frames at {capture.rate:g} Hz, "
            f"units {capture.units}, {int((~valid).sum())} invalid samples, neutral frame {capture.neutral_frame}"]
    st = reports.get("stabilize")
    if st:
        text.append(f"  stabilised on {', '.join(st.get('markers', []))}")
        if "holdout" in st:
            text.append(f"  residual rigid motion on held-out markers {', '.join(st['holdout'].get('markers', []))}: "
                        f"{st['holdout'].get('before', {}).get('max_angle_deg', float('nan')):.2f} deg / "
                        f"{st['holdout'].get('before', {}).get('max_translation', float('nan')):.2f} {capture.units} before, "
                        f"{st['holdout'].get('after', {}).get('max_angle_deg', float('nan')):.2f} deg / "
                        f"{st['holdout'].get('after', {}).get('max_translation', float('nan')):.2f} {capture.units} after")
    if "gaps" in reports:
        g = reports["gaps"]
        text.append(f"  gaps: filled {g['filled_gaps']} ({g['filled_samples']} samples); "
                    f"{g['unfilled_gaps']} longer than {fill_gaps} frames left invalid ({g['unfilled_samples']} samples)")
    if "neutral" in reports:
        n = reports["neutral"]
        text.append(f"  neutral: frame {n['frame']} chosen automatically (calm and nearest the median pose; "
                    f"the calmest window alone was frame {n['calmest_frame']})")
    for s in reports.get("swaps", []):
        text.append(f"  possible marker swap: {s}")
    if reports.get("plausibility"):
        # the messages themselves went to the log (stderr) as warnings
        text.append("  plausibility: " + ", ".join(
            f"{f['code']} ({'accepted ' if f['allowed'] else ''}{f['severity']})" for f in reports["plausibility"]))
    summary["_text"] = text
    return summary
