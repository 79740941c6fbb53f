"""`usdface import-capture`: a capture file -> conditioned capture layer (.usdc)."""
from __future__ import annotations

import logging
from pathlib import Path


from ..capture.conditioning import Conditioning, condition_capture
from ..errors import OptionError
from ..options import CaptureOptions
from ..registry import Result
from ..usd.identity import capture_record, identity
from ..usd.inputs import load_capture
from ..usd.layers import check_output_path, provenance

log = logging.getLogger("usdface")


def import_capture(source, *, options: CaptureOptions, output, cache=None) -> Result:
    """Import and condition a capture (a file, or a capture layer / stage); write the capture layer.

    Plausibility (:mod:`usdface.capture.plausibility`): ``allow`` (check codes) accepts findings
    that would stop the import; ``keep_zeros`` keeps C3D samples at exactly (0, 0, 0) as positions
    (default: gaps); ``drop_outliers`` turns outlier samples into gaps (fill them with
    ``fill_gaps``). Findings are in the summary's ``reports["plausibility"]``.

    ``cache`` (a :class:`usdface.cache.ContentCache`, default None: no cache) reuses a capture
    layer written before from the same file bytes, file name, options and usdface version: the
    layer is copied, byte for byte what this call would write.
    """
    from ..capture import plausibility
    from ..usd.layers import is_in_memory

    input = source
    o = options.to_dict()  # plain types (lists): as recorded in provenance and the cache key
    units, rate, up_axis, stabilize, fill_gaps = o["units"], o["rate"], o["up_axis"], o["stabilize"], o["fill_gaps"]
    filter, cutoff, trim, start_frame, resample = o["filter"], o["cutoff"], o["trim"], o["start_frame"], o["resample"]
    neutral, allow, keep_zeros, drop_outliers = o["neutral"], o["allow"], o["keep_zeros"], o["drop_outliers"]
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
        return _result(_import_capture(input, out, options, fill_gaps), out)
    from ..cache import content_key
    from ..model.identity import IDENTITY_VERSION
    from ..usd.layers import file_digest

    if not Path(input).is_file():
        from ..errors import InputError

        raise InputError(f"capture {input}: no such file")
    # the identity's version: entries of layers written before identities (or with other ones) are not reused
    key = content_key("capture", Path(input).name, file_digest(input), out.suffix.lower(), options,
                      {"identity": IDENTITY_VERSION})
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
    return _result(summary, out)


def _result(summary: dict, out) -> Result:
    return Result.from_summary(summary, layers={"output": out})


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
    capture = load_capture(input, units=units, rate=rate, up_axis=up_axis, keep_zeros=bool(options.get("keep_zeros")),
                           allow=options.get("allow", ()))
    capture, reports = condition_capture(capture, Conditioning(
        trim=tuple(trim) if trim is not None else None, fill_gaps=fill_gaps, filter=filter, cutoff=cutoff,
        resample=resample, neutral=neutral, stabilize=stabilize, start_frame=start_frame,
        allow=tuple(options.get("allow", ())), drop_outliers=bool(options.get("drop_outliers"))))
    prov = provenance("import-capture", options=options, inputs={"capture": input},
                      identity=identity(capture=capture_record(capture)))  # the take as the layer holds it
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
    text.append(f"  {reports['restPose']['text']}")
    for s in reports.get("swaps", []):
        text.append(f"  possible marker swap: {s}")
    if reports.get("plausibility"):
        # the messages themselves went to the log (stderr) as warnings
        text.append("  plausibility: " + ", ".join(
            f"{f['code']} ({'accepted ' if f['allowed'] else ''}{f['severity']})" for f in reports["plausibility"]))
    summary["_text"] = text
    return summary
