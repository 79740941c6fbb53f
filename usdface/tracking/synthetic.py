"""Rendered test videos of a face wearing coloured dots, with exact ground truth.

No public video of a face wearing painted markers exists, so the tracker is tested on videos
rendered from real data: a real marker capture (AnimFace ``JawMoCap.ma``, 41 markers, cm,
60 Hz; CC BY-SA 4.0) is given a rigid head motion (sway, nods and a sudden jerk), projected
orthographically from the front, and drawn as anti-aliased, motion-blurred dots over a real
face photo (NASA astronaut portrait, public domain) whose face region is enlarged and warped
with a thin-plate spline driven by the projected markers, so skin, eyes and mouth follow the
motion. Nuisances of real footage: lighting that dims and swings across the clip, motion blur
(background and dots), optical blur, sensor noise, lossy MPEG-4 compression (when written with
:func:`write_clip`), a hand-shaped occluder passing over some markers, skin-coloured moles
(dot-sized distractors) and blue non-dots (a line and a large patch).

Ground truth (:attr:`SyntheticClip.truth`) is the coverage-weighted centroid of each dot as
drawn (sub-pixel exact, motion blur included), in OpenCV's pixel convention (integer = pixel
centre, y down); :attr:`SyntheticClip.visible` is the fraction of each dot not hidden by the hand.
"""
from __future__ import annotations

import json
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import InputError, OptionError

__all__ = ["SyntheticClip", "ClipStyle", "render_marker_video", "animface_clip", "write_clip", "write_truth_csv"]


def _cv2():
    import cv2

    return cv2


@dataclass
class SyntheticClip:
    """A rendered clip and its ground truth.

    Attributes
    ----------
    frames : ndarray, shape (F, H, W, 3), uint8
        BGR frames before compression.
    names : tuple of str, length M
    truth : ndarray, shape (F, M, 2), float64
        Dot centres as drawn (pixels, OpenCV convention).
    visible : ndarray, shape (F, M), float64
        Fraction of each dot's coverage not hidden by the occluder (1 = fully visible).
    rate : float
        Frames per second.
    radius : float
        Dot radius (pixels).
    """

    frames: np.ndarray
    names: tuple
    truth: np.ndarray
    visible: np.ndarray
    rate: float
    radius: float

    @property
    def size(self) -> tuple[int, int]:
        return self.frames.shape[2], self.frames.shape[1]

    def seeds(self, frame: int = 0, *, jitter: float = 0.0, seed: int = 0) -> dict:
        """Seed points ``{name: [x, y]}`` at ``frame`` (optionally jittered, as a user would click)."""
        rng = np.random.default_rng(seed)
        xy = self.truth[frame] + rng.uniform(-jitter, jitter, size=self.truth[frame].shape)
        return {n: [round(float(x), 2), round(float(y), 2)] for n, (x, y) in zip(self.names, xy)}


def _head_motion(t: np.ndarray, *, sway: float, jerk_at: float | None, jerk: float, nod: float):
    """Rigid head motion at (fractional) frames ``t``: yaw (rad), roll (rad), translation (px)."""
    yaw = np.deg2rad(6.0) * np.sin(2 * np.pi * t / 70.0)
    roll = np.deg2rad(3.0) * np.sin(2 * np.pi * t / 53.0 + 0.7)
    tx = sway * np.sin(2 * np.pi * t / 45.0)
    ty = nod * np.sin(2 * np.pi * t / 31.0 + 1.3)
    if jerk_at is not None:
        # a sudden shift of `jerk` px over ~3 frames (smoothstep), then back over ~3 frames later
        s = np.clip((t - jerk_at) / 3.0, 0, 1)
        b = np.clip((t - jerk_at - 18.0) / 3.0, 0, 1)
        tx = tx + jerk * (s * s * (3 - 2 * s) - b * b * (3 - 2 * b))
        ty = ty - 0.15 * jerk * (s * s * (3 - 2 * s) - b * b * (3 - 2 * b))
    return yaw, roll, np.stack([tx, ty], axis=-1)


def _project(points: np.ndarray, yaw, roll, shift, *, centre3, scale, centre2) -> np.ndarray:
    """Orthographic front view of (..., M, 3) cm points -> (..., M, 2) pixels (y down)."""
    p = points - centre3
    cy, sy = np.cos(yaw), np.sin(yaw)
    x = cy * p[..., 0] + sy * p[..., 2]
    y = p[..., 1]
    cr, sr = np.cos(roll), np.sin(roll)
    u = cr * x - sr * y
    v = sr * x + cr * y
    return np.stack([centre2[0] + scale * u + shift[..., 0], centre2[1] - scale * v + shift[..., 1]], axis=-1)


def _disc_coverage(centres: np.ndarray, radius: float, x0: int, y0: int, w: int, h: int, ss: int = 4) -> np.ndarray:
    """Mean coverage over several disc positions (motion blur) on a (h, w) patch, ``ss x ss`` supersampling."""
    o = (np.arange(ss) + 0.5) / ss - 0.5
    xs = (np.arange(w)[:, None] + o[None, :]).ravel() + x0  # (w*ss,)
    ys = (np.arange(h)[:, None] + o[None, :]).ravel() + y0
    cov = np.zeros((h * ss, w * ss))
    r2 = radius * radius
    for cx, cy in centres:
        cov += ((ys[:, None] - cy) ** 2 + (xs[None, :] - cx) ** 2) <= r2
    cov /= len(centres)
    return cov.reshape(h, ss, w, ss).mean(axis=(1, 3))


@dataclass(frozen=True)
class ClipStyle:
    """How :func:`render_marker_video` films the markers.

    Attributes
    ----------
    size : (W, H)
        Frame size in pixels.
    rate : float
        Frames per second of the clip.
    px_per_cm : float
        Image scale at the face.
    radius : float
        Dot radius, pixels.
    colour : (B, G, R)
        Dot paint colour before lighting.
    sway, nod, jerk : float
        Head motion amplitudes in pixels (horizontal sway, vertical nod, sudden jerk).
    jerk_at : float, optional
        Where the jerk happens, as a fraction of the clip (None: no jerk).
    shutter : float
        Exposure as a fraction of the frame interval (motion blur length).
    noise : float
        Sensor noise standard deviation, 8-bit levels.
    lighting : bool
        Dim the light by 25% across the clip, with a side gradient that swings.
    occluder : (start, end), optional
        A hand passes over the lower right face between these fractions of the clip.
    distractors : bool
        Add skin-coloured moles and blue non-dots.
    seed : int
        Random seed (noise, textures).
    """

    size: tuple = (512, 640)
    rate: float = 30.0
    px_per_cm: float = 30.0
    radius: float = 6.0
    colour: tuple = (215, 70, 20)
    sway: float = 15.0
    nod: float = 3.0
    jerk: float = 30.0
    jerk_at: float | None = 0.45
    shutter: float = 0.5
    noise: float = 2.5
    lighting: bool = True
    occluder: tuple | None = (0.6, 0.85)
    distractors: bool = True
    seed: int = 0


def _thin_plate(src, dst, smoothing):
    """Thin-plate spline with an affine term, mapping src (K, 2) onto dst (K, 2)."""
    from scipy.interpolate import RBFInterpolator

    return RBFInterpolator(src, dst, kernel="thin_plate_spline", degree=1, smoothing=smoothing)


class _Filming:
    """The markers as the camera sees them: capture frames interpolated at fractional times, the
    head motion, the orthographic front view, centred in the frame."""

    def __init__(self, pos: np.ndarray, style: ClipStyle):
        w, h = int(style.size[0]), int(style.size[1])
        self.pos, self.style = pos, style
        self.f_count = pos.shape[0]
        self.centre3 = np.nanmean(pos[0], axis=0)
        self.centre3[1] = 0.5 * (pos[:, :, 1].min() + pos[:, :, 1].max())
        self.centre2 = np.array([w / 2.0, h / 2.0])
        self.jerk_at = None if style.jerk_at is None else style.jerk_at * self.f_count
        # centre the motion's bounding box in the frame; every dot must stay inside
        everywhere = self.at(np.arange(self.f_count, dtype=np.float64))
        lo, hi = everywhere.min(axis=(0, 1)), everywhere.max(axis=(0, 1))
        self.centre2 = self.centre2 - 0.5 * (lo + hi) + np.array([w / 2.0, h / 2.0])
        margin = style.radius + 2
        if (hi - lo)[0] > w - 2 * margin or (hi - lo)[1] > h - 2 * margin:
            raise OptionError(f"render_marker_video: the markers span {hi[0] - lo[0]:.0f}x{hi[1] - lo[1]:.0f} px at "
                              f"{style.px_per_cm:g} px/cm; a {w}x{h} frame is too small (lower px_per_cm or the "
                              "motion)")

    def at(self, t) -> np.ndarray:
        """Projected markers (len(t), M, 2) at fractional frames t."""
        st, pos = self.style, self.pos
        t = np.asarray(t, dtype=np.float64)
        i0 = np.clip(np.floor(t).astype(int), 0, self.f_count - 1)
        i1 = np.clip(i0 + 1, 0, self.f_count - 1)
        a = np.clip(t - i0, 0, 1)[:, None, None]
        p = pos[i0] * (1 - a) + pos[i1] * a
        yaw, roll, shift = _head_motion(t, sway=st.sway, jerk_at=self.jerk_at, jerk=st.jerk, nod=st.nod)
        return _project(p, yaw[:, None], roll[:, None], shift[:, None, :], centre3=self.centre3, scale=st.px_per_cm,
                        centre2=self.centre2)

    def rest(self) -> np.ndarray:
        """The first frame projected without head motion (M, 2)."""
        return _project(self.pos[0], 0.0, 0.0, np.zeros(2), centre3=self.centre3, scale=self.style.px_per_cm,
                        centre2=self.centre2)


class _Backdrop:
    """The face photo warped (thin-plate spline through the markers) into each frame."""

    step = 8

    def __init__(self, photo: np.ndarray, photo_points: np.ndarray, size):
        w, h = int(size[0]), int(size[1])
        self.w, self.h = w, h
        self.gx, self.gy = np.meshgrid(np.arange(0, w + self.step, self.step, dtype=np.float64),
                                       np.arange(0, h + self.step, self.step, dtype=np.float64))
        self.grid = np.stack([self.gx.ravel(), self.gy.ravel()], axis=1)
        self.photo = photo.astype(np.float32)
        self.photo_points = photo_points

    def frame(self, q: np.ndarray, q_all: np.ndarray) -> np.ndarray:
        """(H, W, 3) float32: the photo warped onto markers ``q``, blurred along their motion ``q_all``."""
        cv2 = _cv2()
        warp = _thin_plate(q, self.photo_points, 5.0)  # backward map output -> photo
        src = warp(self.grid).astype(np.float32).reshape(self.gy.shape + (2,))
        full = (self.gx.shape[1] * self.step, self.gx.shape[0] * self.step)
        mapx = cv2.resize(src[..., 0], full, interpolation=cv2.INTER_LINEAR)[:self.h, :self.w]
        mapy = cv2.resize(src[..., 1], full, interpolation=cv2.INTER_LINEAR)[:self.h, :self.w]
        img = cv2.remap(self.photo, mapx, mapy, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REFLECT)
        # background motion blur along the head's image velocity
        v = (q_all[-1] - q_all[0]).mean(axis=0)
        blur_len = float(np.hypot(*v))
        if blur_len > 1.0:
            k = int(math.ceil(blur_len)) | 1
            ker = np.zeros((k, k), np.float32)
            c0 = (k - 1) / 2
            cv2.line(ker, (int(round(c0 - v[0] / 2)), int(round(c0 - v[1] / 2))),
                     (int(round(c0 + v[0] / 2)), int(round(c0 + v[1] / 2))), 1.0, 1)
            img = cv2.filter2D(img, -1, ker / ker.sum())
        return img


def _draw_distractors(img, q, moles, style: ClipStyle) -> None:
    """Moles (skin-coloured dots between two markers), a blue pen line and a blue patch."""
    cv2 = _cv2()
    h, w = img.shape[:2]
    for a, b, t_ in moles:
        p = q[a] * (1 - t_) + q[b] * t_
        d = q[b] - q[a]
        p = p + np.array([-d[1], d[0]]) / max(np.hypot(*d), 1e-9) * 14.0
        cv2.circle(img, (int(round(p[0] * 16)), int(round(p[1] * 16))), int(style.radius * 16),
                   (70, 95, 140), -1, cv2.LINE_AA, shift=4)
    # a blue line (a pen stroke on the neck) and a big blue patch (clothing) - not dots
    p0 = np.array([0.03 * w, 0.95 * h])
    cv2.line(img, tuple(int(v) for v in p0), tuple(int(v) for v in p0 + np.array([60, 14])),
             tuple(float(c) for c in style.colour), 4, cv2.LINE_AA)
    cv2.circle(img, (int(w * 0.9), int(h * 0.92)), int(4 * style.radius), tuple(float(c) for c in style.colour), -1,
               cv2.LINE_AA)


def _draw_dots(img, q_all, style: ClipStyle, rng, truth) -> None:
    """Paint each dot with its exact anti-aliased, motion-blurred coverage; ``truth`` (M, 2)
    receives the coverage-weighted centroids."""
    h, w = img.shape[:2]
    pad = int(math.ceil(style.radius + 2))
    for j in range(q_all.shape[1]):
        cs = q_all[:, j, :]
        x0 = int(math.floor(cs[:, 0].min())) - pad
        y0 = int(math.floor(cs[:, 1].min())) - pad
        x1 = int(math.ceil(cs[:, 0].max())) + pad + 1
        y1 = int(math.ceil(cs[:, 1].max())) + pad + 1
        cov = _disc_coverage(cs, style.radius, x0, y0, x1 - x0, y1 - y0, 4)
        yy, xx = np.mgrid[y0:y1, x0:x1]
        tot = cov.sum()
        truth[j] = ((cov * xx).sum() / tot, (cov * yy).sum() / tot)
        cx0, cy0, cx1, cy1 = max(x0, 0), max(y0, 0), min(x1, w), min(y1, h)
        if cx1 <= cx0 or cy1 <= cy0:
            continue
        cc = cov[cy0 - y0:cy1 - y0, cx0 - x0:cx1 - x0, None].astype(np.float32)
        # paint with a little texture: a real dot is not a flat colour
        paint = np.asarray(style.colour, np.float32) * (1.0 + 0.03 * rng.standard_normal((cy1 - cy0, cx1 - cx0, 1)))
        img[cy0:cy1, cx0:cx1] = img[cy0:cy1, cx0:cx1] * (1 - cc) + paint * cc


def _hand_mask(centre, w: int, h: int) -> np.ndarray:
    """(H, W) float32 coverage of a hand (palm and five fingers) at ``centre``."""
    cv2 = _cv2()
    hand = np.zeros((h * 4, w * 4), np.uint8)
    sc = 4 * 16
    c = centre
    cv2.ellipse(hand, (int(c[0] * sc), int(c[1] * sc)), (int(70 * sc), int(80 * sc)), 20, 0, 360, 255, -1,
                cv2.LINE_8, shift=4)
    for ang, ln in ((-150, 120), (-125, 140), (-100, 135), (-78, 115), (-30, 90)):
        a = math.radians(ang)
        fc = c + np.array([math.cos(a), math.sin(a)]) * (60 + ln / 2)
        cv2.ellipse(hand, (int(fc[0] * sc), int(fc[1] * sc)), (int(ln / 2 * sc), int(17 * sc)), ang, 0, 360,
                    255, -1, cv2.LINE_8, shift=4)
    return cv2.resize(hand, (w, h), interpolation=cv2.INTER_AREA).astype(np.float32) / 255.0


def _occlude(img, s: float, q, names, style: ClipStyle, rng, truth, visible):
    """The hand at stage ``s`` (0..1) of its pass over the lower face; ``visible`` (M,) receives
    the visible fraction of each dot. Returns the new image."""
    h, w = img.shape[:2]
    mouth = q[[names.index(n) for n in names if n.startswith("Mouth") or n.startswith("Chin")]] \
        if any(n.startswith("Mouth") for n in names) else q
    target = mouth.mean(axis=0) + np.array([0.12 * w, 0.0])
    start_pt = target + np.array([0.75 * w, 0.25 * h])
    hm = _hand_mask(start_pt + (target - start_pt) * math.sin(math.pi * s) * 1.05, w, h)
    skin = np.array([105, 140, 190], np.float32) * (1 + 0.05 * rng.standard_normal((h, w, 1))).astype(np.float32)
    img = img * (1 - hm[..., None]) + skin * hm[..., None]
    radius = style.radius
    for j in range(q.shape[0]):
        x, y = truth[j]
        xi, yi = int(round(x)), int(round(y))
        r = int(math.ceil(radius)) + 1
        ya, yb, xa, xb = max(yi - r, 0), min(yi + r + 1, h), max(xi - r, 0), min(xi + r + 1, w)
        if yb <= ya or xb <= xa:
            continue
        yy, xx = np.mgrid[ya:yb, xa:xb]
        disc = ((xx - x) ** 2 + (yy - y) ** 2) <= radius * radius
        visible[j] = 1.0 - float(hm[ya:yb, xa:xb][disc].mean()) if disc.any() else 1.0
    return img


def _expose(img, s: float, style: ClipStyle, rng) -> np.ndarray:
    """Lighting at stage ``s`` (0..1) of the clip, optical blur, sensor noise -> uint8 frame."""
    cv2 = _cv2()
    w = img.shape[1]
    if style.lighting:
        gain = 1.05 - 0.28 * s
        swing = 0.18 * math.sin(2 * math.pi * s)
        ramp = (1.0 + swing * (np.arange(w, dtype=np.float32) / w - 0.5))[None, :, None]
        img = img * (gain * ramp)
    img = cv2.GaussianBlur(img, (0, 0), 0.6)
    if style.noise > 0:
        img = img + rng.normal(0.0, style.noise, img.shape).astype(np.float32)
    return np.clip(img + 0.5, 0, 255).astype(np.uint8)


def render_marker_video(positions: np.ndarray, names, photo: np.ndarray, photo_landmarks: dict,
                        style: ClipStyle = ClipStyle()) -> SyntheticClip:
    """Render a clip of coloured dots on a warped face photo (module docstring).

    Parameters
    ----------
    positions : ndarray, shape (F, M, 3)
        Marker positions in cm (Y up, face looking down +Z), one row per output frame.
    names : sequence of str, length M
    photo : ndarray, shape (h, w, 3), uint8 BGR
        The face photo.
    photo_landmarks : dict
        ``{marker name: (x, y)}`` photo pixels of some of the markers (at least 6) at rest.
    style : ClipStyle
        Frame size, rate, scale, dots, head motion and the nuisances of real footage.
    """
    pos = np.asarray(positions, dtype=np.float64)
    names = tuple(names)
    f_count, m = pos.shape[:2]
    if pos.ndim != 3 or pos.shape[2] != 3 or len(names) != m:
        raise OptionError(f"render_marker_video: positions must be (F, {len(names)}, 3); got {pos.shape}")
    if np.isnan(pos).any():
        raise InputError("render_marker_video: positions contain invalid (NaN) samples; fill them first")
    w, h = int(style.size[0]), int(style.size[1])
    rng = np.random.default_rng(style.seed)
    filming = _Filming(pos, style)
    # photo positions of all markers: TPS from the rest pose (projected, no head motion) to the photo
    rest = filming.rest()
    known = [i for i, n in enumerate(names) if n in photo_landmarks]
    if len(known) < 6:
        raise InputError(f"render_marker_video: {len(known)} photo landmarks match the markers; need 6")
    to_photo = _thin_plate(rest[known], np.array([photo_landmarks[names[i]] for i in known], float), 50.0)
    backdrop = _Backdrop(photo, to_photo(rest), (w, h))
    # moles (skin-coloured dots) at fixed places between two markers
    moles = [(*rng.choice(m, 2, replace=False), rng.uniform(0.35, 0.65)) for _ in range(6)] \
        if style.distractors else []
    sub = np.linspace(-0.5 * style.shutter, 0.5 * style.shutter, 5)
    truth = np.zeros((f_count, m, 2))
    visible = np.ones((f_count, m))
    frames = np.zeros((f_count, h, w, 3), np.uint8)
    for f in range(f_count):
        q_all = filming.at(f + sub)  # (5, M, 2)
        q = q_all[2]
        img = backdrop.frame(q, q_all)
        if style.distractors:
            _draw_distractors(img, q, moles, style)
        _draw_dots(img, q_all, style, rng, truth[f])
        if style.occluder is not None:
            t0, t1 = style.occluder[0] * f_count, style.occluder[1] * f_count
            if t0 <= f <= t1:
                img = _occlude(img, (f - t0) / max(t1 - t0, 1.0), q, names, style, rng, truth[f], visible[f])
        frames[f] = _expose(img, f / max(f_count - 1, 1), style, rng)
    return SyntheticClip(frames=frames, names=names, truth=truth, visible=visible, rate=float(style.rate),
                         radius=float(style.radius))


def animface_clip(sample_assets, shared_data=None, *, n_frames: int = 90, step: int = 2, start: int = 300,
                  **style) -> SyntheticClip:
    """Render a clip from the real AnimFace JawMoCap capture over the astronaut photo.

    Parameters
    ----------
    sample_assets : path
        The repository's sample_assets folder (``capture/JawMoCap.ma``, ``landmarks/astronaut.landmarks.json``).
    shared_data : path, optional
        Folder with ``images/astronaut.png`` (default: ``sample_assets/../../shared/data``).
    n_frames, step, start : int
        Capture frames ``start, start + step, ...`` (60 Hz capture; step 2 = 30 fps real time).
    **style
        Fields of :class:`ClipStyle` (size, rate, px_per_cm, radius, ...); the rate defaults to the
        capture's rate divided by ``step``.
    """
    from ..io.maya_ascii import read_maya_ascii

    sample_assets = Path(sample_assets)
    shared = Path(shared_data) if shared_data else sample_assets.resolve().parents[1] / "shared" / "data"
    cap = read_maya_ascii(sample_assets / "capture" / "JawMoCap.ma")
    idx = start + step * np.arange(n_frames)
    if idx[-1] >= cap.n_frames:
        raise OptionError(f"animface_clip: frames up to {idx[-1]} asked; the capture has {cap.n_frames}")
    from ..io.images import read_image

    photo = read_image(shared / "images" / "astronaut.png")  # libpng's iCCP warning kept off stderr
    lms = json.loads((sample_assets / "landmarks" / "astronaut.landmarks.json").read_text())
    lms = {k: v["image"] for k, v in lms.items()}
    style = ClipStyle(**{"rate": cap.rate / step, **style})
    return render_marker_video(cap.positions[idx], cap.names, photo, lms, style)


def write_clip(path, clip: SyntheticClip, *, fourcc: str = "mp4v") -> Path:
    """Write the clip's frames as a movie (lossy MPEG-4 Part 2 by default, as pip OpenCV can)."""
    cv2 = _cv2()
    p = Path(path)
    w, h = clip.size
    vw = cv2.VideoWriter(str(p), cv2.VideoWriter_fourcc(*fourcc), clip.rate, (w, h))
    if not vw.isOpened():
        raise InputError(f"{p}: cannot write a {fourcc} video")
    try:
        for fr in clip.frames:
            vw.write(fr)
    finally:
        vw.release()
    return p


def write_truth_csv(path, clip: SyntheticClip, *, min_visible: float = 0.999) -> None:
    """Ground truth as a usdface 2D CSV (pixels; samples less than ``min_visible`` visible left empty)."""
    from ..model.capture import Capture
    from ..io.csv_format import write_csv

    pos = np.zeros(clip.truth.shape[:2] + (3,))
    pos[..., :2] = clip.truth
    pos[clip.visible < min_visible] = np.nan
    cap = Capture(names=clip.names, positions=pos, rate=clip.rate, units=None, source="synthetic",
                  history=({"step": "render", "dims": 2},))
    write_csv(path, cap, dims=2)


def score_tracks(positions: np.ndarray, truth: np.ndarray, visible: np.ndarray, *, full: float = 0.999,
                 hidden: float = 0.5) -> dict:
    """Compare tracked positions with the ground truth.

    Parameters
    ----------
    positions : ndarray (F, M, 2)
        Tracked positions (NaN where invalid), markers in the truth's order.
    truth : ndarray (F, M, 2)
    visible : ndarray (F, M)
        Visible fraction of each dot.
    full, hidden : float
        A dot is *visible* when at least ``full`` of it shows, *occluded* when less than ``hidden``.

    Returns
    -------
    dict
        ``mean_error``, ``p99_error``, ``max_error`` (pixels, over found visible dots),
        ``found`` (fraction of visible dots found), ``occluded_invalid`` (fraction of occluded dots
        marked invalid; 1.0 when none is occluded), ``identity_switches`` (samples nearer another
        marker's true position than their own), ``n_visible``, ``n_occluded``.
    """
    pos = np.asarray(positions, dtype=np.float64)
    ok = np.isfinite(pos).all(axis=2)
    vis = visible >= full
    occ = visible < hidden
    err = np.linalg.norm(pos - truth, axis=2)
    e = err[ok & vis]
    d_all = np.linalg.norm(pos[:, :, None, :] - truth[:, None, :, :], axis=3)  # (F, M, M)
    nearest = np.where(np.isfinite(d_all), d_all, np.inf).argmin(axis=2)
    switches = int((ok & (nearest != np.arange(pos.shape[1])[None, :])).sum())
    return {
        "mean_error": float(e.mean()) if e.size else float("nan"),
        "p99_error": float(np.percentile(e, 99)) if e.size else float("nan"),
        "max_error": float(e.max()) if e.size else float("nan"),
        "found": float((ok & vis).sum() / max(vis.sum(), 1)),
        "occluded_invalid": float((~ok & occ).sum() / occ.sum()) if occ.any() else 1.0,
        "identity_switches": switches,
        "n_visible": int(vis.sum()),
        "n_occluded": int(occ.sum()),
    }
