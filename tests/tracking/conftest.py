"""A short rendered clip (real AnimFace capture over the astronaut photo), made once per session."""
from __future__ import annotations

import json

import numpy as np
import pytest


@pytest.fixture(scope="session")
def clip(sample_assets, shared_data):
    from usdface.tracking.synthetic import animface_clip

    # 72 frames at 30 fps, 512x640, 30 px/cm, dots r = 6 px: a head jerk (frames ~32-35 and back at
    # ~50-53), lighting dims 25%, a hand passes over the lower right face (frames ~43-61)
    return animface_clip(sample_assets, shared_data, n_frames=72, start=900, step=2)


@pytest.fixture(scope="session")
def clip_files(clip, tmp_path_factory):
    from usdface.tracking.synthetic import write_clip

    d = tmp_path_factory.mktemp("clip")
    video = write_clip(d / "face.mp4", clip)
    seeds = d / "seeds.json"
    seeds.write_text(json.dumps(clip.seeds(0, jitter=1.5, seed=3)))
    return {"dir": d, "video": video, "seeds": seeds}


@pytest.fixture(scope="session")
def tracked(clip, clip_files):
    from usdface.io.video import open_video
    from usdface.tracking.tracker import initialise_from_seeds, track_frames

    reader = open_video(clip_files["video"])
    seeds = json.loads(clip_files["seeds"].read_text())
    det, names, xy, area = initialise_from_seeds(reader.read(0), seeds, radius=(4, 9))
    return track_frames(reader, det, names, xy, initial_area=area, rate=reader.rate, size=reader.size)


@pytest.fixture
def cli():
    """`usdface ARGS...` in-process; returns the exit code."""
    import usdface.cli as cli_module

    return lambda *args: cli_module.main([str(a) for a in args])


def plain_frame(w=160, h=120, colour=(120, 150, 200)):
    return np.tile(np.array(colour, np.uint8), (h, w, 1))
