"""`usdface landmarks train`: an active appearance model from annotated face images (seed 001,
section 3).

``usdface landmarks train IMAGES... -o MODEL.npz`` (point files beside the images) or
``usdface landmarks train IMAGE --landmarks L.json -o MODEL.npz`` (one hand-annotated image,
augmented with jittered copies).
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from ..errors import InputError, OptionError, list_names
from ..fileutil import refuse_overwriting_inputs
from ..options import LandmarksTrainOptions
from ..registry import Result

__all__ = ["landmarks_train"]


def landmarks_train(images, *, options: LandmarksTrainOptions, output) -> Result:
    """Train an AAM from annotated images (point files beside them, or in ``options.points_dir``)
    or from one image and its landmarks file (``options.landmarks``); write the model (.npz)."""
    from ..scan.aam import train_aam
    from ..scan.detect import largest_face_box

    refuse_overwriting_inputs({"-o": output}, {"images": [str(p) for p in images], "--landmarks": options.landmarks})
    out = Path(output)
    if out.suffix != ".npz":
        raise OptionError(f"-o {out}: an AAM model is written as .npz")
    if not (out.parent if str(out.parent) else Path(".")).is_dir():
        raise OptionError(f"-o {out}: folder {out.parent} does not exist")
    images = [Path(p) for p in images]
    if not images:
        raise OptionError("landmarks train: give at least one image")
    if options.landmarks is not None:
        imgs, shapes, names = _single_image(images, options)
    else:
        imgs, shapes, names = _annotated_images(images, options)
    model = train_aam(imgs, shapes, names=names, detector=largest_face_box)
    model.save(out)
    m = model.meta
    summary = {"output": str(out), "images": len(imgs), "points": len(names), "names": list(names),
               "shapeModes": m["shape_modes"], "appearanceModes": m["appearance_modes"], "seconds": m["seconds"]}
    text = [f"wrote {out}: AAM of {len(names)} landmarks from {len(imgs)} image(s) ({m['shape_modes']} shape modes, "
            f"appearance modes {m['appearance_modes']}, {m['template_pixels']} template pixels, {m['seconds']:.1f} s)"]
    return Result(files={"output": out}, summary=summary, text=text)


def _single_image(images, options: LandmarksTrainOptions):
    """(images, shapes, names): one hand-annotated image and its jittered copies."""
    from ..io.images import read_image
    from ..scan.aam import augment_sample
    from ..scan.landmarks import FACE_LANDMARKS, read_landmarks
    from ..scan.methods import SINGLE_IMAGE_COPIES

    if len(images) != 1:
        raise OptionError("landmarks train --landmarks L.json takes exactly one image (the one the file annotates)")
    lm = read_landmarks(options.landmarks)
    if not lm.image:
        raise InputError(f"landmarks {options.landmarks}: no image points")
    img = read_image(images[0])
    lm.check_inside((img.shape[1], img.shape[0]), what=f"image {images[0]}")
    names = [n for n in FACE_LANDMARKS if n in lm.image] + [n for n in lm.image if n not in FACE_LANDMARKS]
    pts = lm.image_array(names)
    copies = SINGLE_IMAGE_COPIES if options.augment is None else int(options.augment)
    ai, ap = augment_sample(img, pts, copies)
    return [img] + ai, np.concatenate([pts[None], ap]), names


def _annotated_images(images, options: LandmarksTrainOptions):
    """(images, shapes, names): images with point files, the same landmarks in the same order on
    each, plus ``options.augment`` jittered copies of each."""
    from ..io.images import read_image
    from ..scan.aam import augment_sample

    imgs, shapes, names = [], [], None
    points_dir = Path(options.points_dir) if options.points_dir else None
    for p in images:
        img = read_image(p)
        nm, pts = _annotation_for(p, points_dir)
        if nm is not None:
            if names is None:
                names = nm
            elif nm != names:
                raise InputError(f"landmarks train: {p}'s points are {list_names(nm)}, expected "
                                 f"{list_names(names)} (every image needs the same landmarks in the same order)")
            pts = np.array([pts[nm.index(n)] for n in names])
        if names is None:
            names = [f"p{k}" for k in range(len(pts))]
        if len(pts) != len(names):
            raise InputError(f"landmarks train: {p} has {len(pts)} points, the others {len(names)}")
        bad = ((pts[:, 0] < -0.5) | (pts[:, 0] > img.shape[1] - 0.5) | (pts[:, 1] < -0.5)
               | (pts[:, 1] > img.shape[0] - 0.5))
        if bad.any():
            raise InputError(f"landmarks train: {int(bad.sum())} point(s) of {p} lie outside the "
                             f"{img.shape[1]}x{img.shape[0]} image: {list_names(np.array(names)[bad])}")
        imgs.append(img)
        shapes.append(pts)
    shapes = np.asarray(shapes)
    if options.augment:
        extra_i, extra_p = [], []
        for k, (im, pt) in enumerate(zip(list(imgs), shapes)):
            ai, ap = augment_sample(im, pt, int(options.augment), seed=k)
            extra_i += ai
            extra_p.append(ap)
        imgs += extra_i
        shapes = np.concatenate([shapes] + extra_p)
    return imgs, shapes, names


def _annotation_for(image: Path, points_dir: Path | None):
    """(names or None, (P, 2) points) from the point file of ``image``: STEM.pts (unnamed),
    STEM.landmarks.json or STEM.json, beside it or in ``points_dir``."""
    from ..scan.landmarks import read_landmarks, read_pts

    folder = points_dir or image.parent
    for cand in (folder / f"{image.stem}.pts", folder / f"{image.stem}.landmarks.json", folder / f"{image.stem}.json"):
        if cand.is_file():
            if cand.suffix == ".pts":
                return None, read_pts(cand)
            lm = read_landmarks(cand)
            return list(lm.image), lm.image_array()
    raise InputError(f"landmarks train: no point file for {image} (looked for {image.stem}.pts, "
                     f"{image.stem}.landmarks.json, {image.stem}.json in {folder})")
