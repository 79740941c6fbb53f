"""`usdface detect`: Haar face, eye and mouth detection and, with an active appearance model, the
facial landmarks of the largest face -> a features JSON (seed 001, section 3).

``usdface detect IMAGE -o FEATURES.json [--aam MODEL.npz] [--preview OUT.png]``
"""
from __future__ import annotations

import json
from pathlib import Path

from ..errors import ComputeError, OptionError
from ..fileutil import StagedOutputs, refuse_overwriting_inputs
from ..options import DetectOptions
from ..registry import Result

__all__ = ["detect"]

def detect(image, *, options: DetectOptions, output, preview=None) -> Result:
    """Haar face/eye/mouth detection (and AAM landmarks with ``options.aam``) -> features JSON
    (``output``); ``preview``: a picture of the detections. Nothing is written when no face is found."""
    from ..io.images import check_image_output, read_image, write_image
    from ..scan.detect import detect_faces, draw_detections, features_dict

    aam, min_size = options.aam, options.min_size
    refuse_overwriting_inputs({"-o": output, "--preview": preview}, {"image": image, "--aam": aam})
    out = Path(output)
    if out.suffix.lower() != ".json":
        raise OptionError(f"-o {out}: expected a .json features file")
    if not (out.parent if str(out.parent) else Path(".")).is_dir():
        raise OptionError(f"-o {out}: folder {out.parent} does not exist")
    prev = check_image_output(preview, option="--preview") if preview else None
    model = None
    if aam is not None:
        from ..scan.aam import load_aam

        model = load_aam(aam)
    img = read_image(image)
    faces = detect_faces(img, min_size=min_size)
    h, w = img.shape[:2]
    if not faces:
        raise ComputeError(f"detect: no face found in {image} ({w}x{h}; Haar frontal-face cascade, faces of at least "
                           f"{min_size or max(24, min(h, w) // 12)} px). Nothing written. A face must be frontal and "
                           "upright; try --min-size for small faces")
    landmarks = fit = None
    if model is not None:
        fit = model.fit(img, faces[0].box)
        landmarks = {n: tuple(p) for n, p in zip(model.names, fit.points)}
    data = features_dict(Path(image).name, (w, h), faces, landmarks)
    text = [f"{len(faces)} face(s) in {image}: " + "; ".join(
        f"box {list(f.box)}, {len(f.eyes)} eye(s), mouth {'found' if f.mouth else 'not found'}" for f in faces)]
    if fit is not None:
        text.append(f"  {len(model.names)} landmarks fitted on the largest face (AAM residual {fit.residual:.3f}, "
                    f"{fit.iterations} iterations)")
    pic = draw_detections(img, faces, fit.points if fit is not None else None) if prev else None
    files = {"output": out}
    with StagedOutputs() as staged:  # both files or neither: a failure leaves the old ones as they were
        staged.path(out).write_text(json.dumps(data, indent=1) + "\n", encoding="utf-8")
        if prev is not None:
            write_image(staged.path(prev), pic)
            files["preview"] = prev
            text.append(f"wrote {prev}: preview")
        staged.commit()
    text.insert(0, f"wrote {out}")
    return Result(files=files, summary=dict(data, output=str(out)), text=text)
