"""Tracking on rendered videos of the real AnimFace capture: accuracy, identities, occlusion, merges."""
from __future__ import annotations

import json

import numpy as np
import pytest

from usdface.errors import MarkerError
from usdface.tracking.synthetic import _disc_coverage, score_tracks
from usdface.tracking.tracker import initialise_auto, initialise_from_seeds, name_by_layout, track_frames


def test_must_show_accuracy_identities_occlusion(clip, tracked):
    order = [tracked.names.index(n) for n in clip.names]
    s = score_tracks(tracked.positions[:, order], clip.truth, clip.visible)
    print(s)
    assert s["mean_error"] <= 0.3
    assert s["p99_error"] <= 1.0
    assert s["identity_switches"] == 0
    assert s["found"] >= 0.99
    assert s["n_occluded"] > 20 and s["occluded_invalid"] == 1.0   # the hand hides dots: never invented
    assert tracked.stats["globalShiftMax"] > 5                      # the jerk happened and was followed
    conf = tracked.confidence
    assert ((conf > 0) == tracked.valid).all() and conf.max() <= 1.0


def test_auto_init_named_by_layout(clip, clip_files):
    from usdface.io.video import open_video

    frame = open_video(clip_files["video"]).read(0)
    # a front-view "layout": the first frame's true positions, scaled, shifted and in y-up units
    lay = clip.truth[0] * np.array([0.033, -0.033]) + [3.0, 80.0]
    det, names, xy, _ = initialise_auto(frame, len(clip.names), radius=(4, 9),
                                        layout=(list(clip.names), lay * [1, -1]))
    for n, p in zip(names, xy):
        assert np.hypot(*(p - clip.truth[0, clip.names.index(n)])) < 0.6, n
    det, names, xy, _ = initialise_auto(frame, len(clip.names), radius=(4, 9))
    assert names[0] == "m00" and len(set(names)) == len(clip.names)


def test_name_by_layout_rotated():
    rng = np.random.default_rng(0)
    lay = rng.uniform(0, 10, (12, 2))
    a = np.deg2rad(8)
    rot = np.array([[np.cos(a), -np.sin(a)], [np.sin(a), np.cos(a)]])
    xy = (25 * lay @ rot.T + [100, 50])[rng.permutation(12)]
    names, resid = name_by_layout(xy, [f"k{i}" for i in range(12)], lay)
    back = {n: p for n, p in zip(names, xy)}
    assert resid < 1e-6
    for i in range(12):
        assert np.allclose(back[f"k{i}"], 25 * rot @ lay[i] + [100, 50])


def test_marker_never_found_is_named(clip, clip_files):
    from usdface.io.video import open_video

    frame = open_video(clip_files["video"]).read(0)
    seeds = json.loads(clip_files["seeds"].read_text())
    seeds["Ghost"] = [5.0, 320.0]  # plain skin, no dot
    with pytest.raises(MarkerError, match="Ghost"):
        initialise_from_seeds(frame, seeds, radius=(4, 9))


def _two_dots_video(n=40, w=220, h=120, radius=6.0):
    """Two dots that approach until they touch (merge into one blob), then part."""
    skin = np.array([120, 150, 200], np.float32)
    blue = np.array([215, 70, 20], np.float32)
    rng = np.random.default_rng(0)
    t = np.arange(n)
    gap = 11.0 + 32.0 * np.abs(t - n / 2) / (n / 2)  # centre distance: 43 px -> 11 px (overlapping) -> 43 px
    a = np.stack([110 - gap / 2, 60 + 0.2 * t], axis=1)
    b = np.stack([110 + gap / 2, 60 - 0.2 * t], axis=1)
    frames = []
    for f in range(n):
        img = np.tile(skin, (h, w, 1))
        for c in (a[f], b[f]):
            cov = _disc_coverage(c[None], radius, 0, 0, w, h, ss=4)[..., None].astype(np.float32)
            img = img * (1 - cov) + blue * cov
        img += rng.normal(0, 1.5, img.shape)
        frames.append(np.clip(img + 0.5, 0, 255).astype(np.uint8))
    return frames, a, b


def test_merged_blob_is_split_keeping_identities():
    frames, a, b = _two_dots_video()
    det, names, xy, area = initialise_from_seeds(frames[0], {"A": a[0], "B": b[0]}, radius=(4, 9))
    res = track_frames(frames, det, names, xy, initial_area=area, rate=30, size=(220, 120), gate=12)
    assert res.stats["splits"] > 0
    pa, pb = res.positions[:, 0], res.positions[:, 1]
    ok = res.valid.all(axis=1)
    assert ok.mean() > 0.9
    # identities never swap; split centres are close to the truth
    assert (np.linalg.norm(pa[ok] - a[ok], axis=1) < 1.5).all()
    assert (np.linalg.norm(pb[ok] - b[ok], axis=1) < 1.5).all()
