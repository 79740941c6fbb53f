"""usdface.tissue.expressions: presets, timelines and their JSON."""
from __future__ import annotations

import json

import numpy as np
import pytest

from usdface.errors import FormatError, InputError, OptionError
from usdface.tissue.expressions import (JAW_KEY, PRESET_NAMES, Timeline, expression_timeline, preset_contractions,
                                        read_timeline, write_timeline)

NAMES = ["zygomaticMajor_L", "zygomaticMajor_R", "frontalisInner_L", "frontalisInner_R", "orbicularisOris"]


def test_presets_are_the_papers_and_more():
    assert set(PRESET_NAMES) == {"neutral", "sadness", "anger", "joy", "fear", "disgust", "surprise", "pursed_lips"}
    a, jaw = preset_contractions("joy", NAMES)
    assert a.tolist() == [1.0, 1.0, 0.0, 0.0, 0.0] and 0 < jaw < 0.2
    a, jaw = preset_contractions("surprise", NAMES, intensity=0.5)
    assert a.tolist() == [0, 0, 0.5, 0.5, 0] and jaw == pytest.approx(0.2)
    assert not preset_contractions("neutral", NAMES)[0].any()
    with pytest.raises(OptionError, match="unknown expression 'smirk'"):
        preset_contractions("smirk", NAMES)


def test_expression_timeline_ramps_zero_to_one():
    tl = expression_timeline("pursed_lips", NAMES, ramp_frames=10, hold_frames=5, start_frame=1)
    frames, a, jaw = tl.sample(NAMES)
    assert frames[0] == 1 and frames[-1] == 16
    k = NAMES.index("orbicularisOris")
    assert a[0, k] == 0 and a[10, k] == 1.0 and a[5, k] == pytest.approx(0.5) and a[-1, k] == 1.0
    assert np.all(np.diff(a[:11, k]) > 0)
    assert not a[:, :4].any() and not jaw.any()


def test_timeline_json_round_trip(tmp_path):
    data = {"rate": 30, "keys": {"zygomaticMajor_L": [[0, 0.0], [10, 1.0], [20, 0.25]], JAW_KEY: [[5, 0.0], [15, 0.5]]}}
    p = tmp_path / "t.json"
    p.write_text(json.dumps(data))
    tl = read_timeline(p)
    assert tl.rate == 30 and tl.first_frame == 0 and tl.last_frame == 20
    a, jaw = tl.evaluate(15, NAMES)
    assert a[0] == pytest.approx(0.625) and jaw == pytest.approx(0.5)
    a, jaw = tl.evaluate(0, NAMES)      # before the jaw's first key: held
    assert jaw == 0.0
    tl.check_names(NAMES)
    q = write_timeline(tmp_path / "u.json", tl)
    assert read_timeline(q).to_dict() == tl.to_dict()


@pytest.mark.parametrize("keys, error, match", [
    ({"zygomaticMajor_L": [[0, 0.0], [5, 1.4]]}, OptionError, r"must be in \[0, 1\].*frame 5: 1\.4"),
    ({"zygomaticMajor_L": [[5, 0.0], [0, 1.0]]}, FormatError, "must increase"),
    ({"zygomaticMajor_L": [[0, "x"]]}, FormatError, "zygomaticMajor_L"),
    ({"zygomaticMajor_L": []}, FormatError, "non-empty"),
    ({JAW_KEY: [[0, -0.5]]}, OptionError, "jaw opening"),
])
def test_bad_timelines_are_refused(keys, error, match):
    with pytest.raises(error, match=match):
        Timeline(rate=24, keys=keys)


def test_timeline_files_are_checked(tmp_path):
    with pytest.raises(InputError, match="no such file"):
        read_timeline(tmp_path / "missing.json")
    p = tmp_path / "bad.json"
    p.write_text("{not json")
    with pytest.raises(FormatError, match="not valid JSON"):
        read_timeline(p)
    p.write_text(json.dumps({"rate": 24, "keyz": {}}))
    with pytest.raises(FormatError, match="unknown field"):
        read_timeline(p)
    p.write_text(json.dumps({"rate": -1, "keys": {"a": [[0, 0]]}}))
    with pytest.raises(FormatError, match="rate"):
        read_timeline(p)
    tl = Timeline(rate=24, keys={"buccinator_L": [[0, 0.5]]})
    with pytest.raises(InputError, match="not in the rig: buccinator_L"):
        tl.check_names(NAMES)
