"""Maya ASCII capture reader: the real AnimFace takes, small scenes written here, bad input."""
from __future__ import annotations

import math
import re

import numpy as np
import pytest

from usdface.errors import FormatError, InputError, MarkerError, OptionError, PlausibilityError
from usdface.io.maya_ascii import read_maya_ascii

TAKES = {"Jaw": 1590, "Nose": 962, "Eyebrows": 902}

# The marker names documented in shared/data/README.md, in the files' order.
DOCUMENTED_NAMES = (
    [f"ForeHead_{s}" for s in "MLR"]
    + [f"Leyebrow_{s}" for s in ("M", "Inside", "Outside")] + ["Eyebrow_Center"]
    + [f"Reyebrow_{s}" for s in ("M", "Inside", "Outside")]
    + ["NoseTop", "NoseHead", "NoseHead_L", "NoseHead_R"]
    + [f"{side}eye_{s}" for side in "LR" for s in ("Up", "Down", "Inside", "Outside")]
    + [f"{side}cheek_{s}" for side in "LR" for s in ("Up", "Down", "Outside")]
    + [f"Mouth_{s}" for s in ("Up", "Down", "UpL1", "Lend", "UpR1", "Rend", "DownL", "DownR")]
    + ["Chin"] + [f"Chin_{s}" for s in ("R1", "R2", "L1", "L2")]
)


def take_path(shared_data, take):
    return shared_data / "animface" / f"{take}MoCap.ma"


@pytest.fixture(scope="module")
def takes(shared_data):
    return {take: read_maya_ascii(take_path(shared_data, take)) for take in TAKES}


def keys_in_text(text: str, curve: str) -> tuple[list[float], list[float]]:
    """Key times and values of one curve, read from the file text by plain string handling
    (independent of the reader: finds the curve by name, not through connections)."""
    start = text.index(f'createNode animCurveTL -n "{curve}";')
    end = text.index("createNode", start + 10)
    numbers = []
    for _, _, block in re.findall(r'"\.ktv\[(\d+):(\d+)\]"([^;]*);', text[start:end]):
        numbers += [float(v) for v in block.split()]
    return numbers[0::2], numbers[1::2]


# -- real data ----------------------------------------------------------------------------------

@pytest.mark.parametrize("take", TAKES)
def test_animface_shape_rate_units_names(takes, take):
    capture = takes[take]
    assert capture.n_markers == 41
    assert capture.n_frames == TAKES[take]
    assert capture.rate == 60.0
    assert capture.units == "cm"
    assert capture.start_frame == 0
    assert list(capture.names) == DOCUMENTED_NAMES
    assert capture.valid.all()
    step = capture.history[0]
    assert step["step"] == "read" and step["format"] == "maya_ascii"
    assert step["interpolated_samples"] == 0 and step["key_rate"] == 60.0
    assert capture.source.endswith(f"{take}MoCap.ma")


@pytest.mark.parametrize("marker, curve_prefix", [
    ("ForeHead_M", "ForeHead_M"), ("Rcheek_Up", "Rcheek_up"), ("Chin_L2", "Chin_L2"), ("Mouth_UpR1", "Mouth_UpR1"),
])
def test_jaw_positions_equal_file_keys(takes, shared_data, marker, curve_prefix):
    text = take_path(shared_data, "Jaw").read_text(encoding="latin-1")
    capture = takes["Jaw"]
    m = capture.index(marker)
    for axis, letter in enumerate("XYZ"):
        times, values = keys_in_text(text, f"{curve_prefix}_translate{letter}")
        assert len(values) == 1590
        # keys every 0.4 film frame = one 60 Hz frame
        assert times[1] == pytest.approx(0.4) and times[-1] == pytest.approx(1589 * 0.4)
        for frame in (0, 1, 250, 777, 1589):
            assert capture.positions[frame, m, axis] == values[frame]


def test_nose_group_offset_applied(takes, shared_data):
    text = take_path(shared_data, "Nose").read_text(encoding="latin-1")
    group = re.search(r'createNode transform -n "MoCapData";\s*rename[^;]*;\s*setAttr "\.t" -type "double3" '
                      r'(\S+) (\S+) (\S+)', text)
    offset = np.array([float(v) for v in group.groups()])
    np.testing.assert_allclose(offset, [8.556293, -60.848667, 0.0], atol=1e-6)
    capture = takes["Nose"]
    for marker, prefix in (("Rcheek_Up", "Rcheek_up"), ("NoseTop", "NoseTop"), ("Leye_Outside", "Leye_Outside")):
        m = capture.index(marker)
        for axis, letter in enumerate("XYZ"):
            _, values = keys_in_text(text, f"{prefix}_translate{letter}")
            for frame in (0, 480, 961):
                assert capture.positions[frame, m, axis] == values[frame] + offset[axis]


def test_takes_other_than_nose_have_no_offset(takes):
    # raw translates of all takes coincide; in world space the Nose take sits 60.8 cm lower
    drop = takes["Jaw"].positions[0, :, 1].mean() - takes["Nose"].positions[0, :, 1].mean()
    assert drop == pytest.approx(60.85, abs=0.5)


# -- small scenes ---------------------------------------------------------------------------------

def maya_scene(markers, *, unit_line="currentUnit -l centimeter -a degree -t film;", group_lines=(),
               footer=True, pairs_per_line=5, block=250, extra_lines=()):
    """Text of a .ma scene: a group "Grp" holding one transform per marker.

    markers: {name: {"t": (x, y, z) static translate (optional),
                     "X"/"Y"/"Z": (times, values) keys of an animCurveTL driving that channel,
                     "curve": name prefix of its curves (default: the marker name)}}
    """
    out = ["//Maya ASCII 2017 scene", "//Name: test.ma", 'requires maya "2017";']
    if unit_line:
        out.append(unit_line)
    out.append('createNode transform -n "Grp";')
    out += ["\t" + line for line in group_lines]
    for name, spec in markers.items():
        out.append(f'createNode transform -n "{name}" -p "Grp";')
        out.append('\trename -uid "0000";')
        if "t" in spec:
            out.append('\tsetAttr ".t" -type "double3" %r %r %r ;' % tuple(spec["t"]))
        out.append(f'createNode mesh -n "{name}Shape" -p "{name}";')
        out.append('\tsetAttr -k off ".v";')
    connections = []
    for name, spec in markers.items():
        for letter in "XYZ":
            if letter not in spec:
                continue
            times, values = spec[letter]
            curve = f"{spec.get('curve', name)}_translate{letter}"
            out.append(f'createNode animCurveTL -n "{curve}";')
            out.append('\tsetAttr ".tan" 18;')
            out.append(f'\tsetAttr -s {len(times)} ".ktv";')
            for first in range(0, len(times), block):
                last = min(first + block, len(times)) - 1
                pairs = [f"{t!r} {v!r}" for t, v in zip(times[first:last + 1], values[first:last + 1])]
                lines = [" ".join(pairs[i:i + pairs_per_line]) for i in range(0, len(pairs), pairs_per_line)]
                out.append(f'\tsetAttr ".ktv[{first}:{last}]" ' + "\n\t\t ".join(lines) + ";")
            connections.append(f'connectAttr "{curve}.o" "{name}.t{letter.lower()}";')
    out += list(extra_lines)
    out += connections
    out.append('connectAttr "polySphere1.out" "AShape.i";')
    if footer:
        out.append("// End of test.ma")
    return "\n".join(out) + "\n"


def keys(n, step=0.4, start=0.0, scale=1.0, offset=0.0):
    times = [round(start + step * i, 6) for i in range(n)]
    values = [offset + scale * math.sin(0.1 * i) for i in range(n)]
    return times, values


def write(tmp_path, text, name="scene.ma"):
    path = tmp_path / name
    path.write_text(text)
    return path


def test_small_scene_static_channels_and_curve_names(tmp_path):
    text = maya_scene({
        "A": {"X": keys(10), "Y": keys(10, offset=5), "Z": keys(10, offset=-1), "curve": "a_lower"},
        "B": {"t": (1.5, 2.5, 3.5), "Y": keys(10, scale=2)},
    })
    capture = read_maya_ascii(write(tmp_path, text))
    assert capture.names == ("A", "B")
    assert capture.n_frames == 10 and capture.rate == 60.0 and capture.units == "cm"
    np.testing.assert_array_equal(capture.positions[:, 0, 0], keys(10)[1])
    np.testing.assert_array_equal(capture.positions[:, 1, 0], 1.5)   # static setAttr value
    np.testing.assert_array_equal(capture.positions[:, 1, 1], keys(10, scale=2)[1])
    np.testing.assert_array_equal(capture.positions[:, 1, 2], 3.5)


@pytest.mark.parametrize("unit_line, step, rate, units", [
    ("currentUnit -l millimeter -a degree -t ntsc;", 0.5, 60.0, "mm"),    # 30 fps unit, keys every half frame
    ("currentUnit -l meter -t 120fps;", 2.0, 60.0, "m"),
    ("currentUnit -l inch -t pal;", 1.0, 25.0, "in"),
    ("currentUnit -l foot -t game;", 0.125, 120.0, "ft"),
    ("currentUnit -l centimeter -t sec;", 0.01, 100.0, "cm"),
    ("currentUnit -l centimeter -t millisec;", 1000 / 60, 60.0, "cm"),
    ("currentUnit -l centimeter -t ntscf;", 2.002, 29.97002997002997, "cm"),  # NTSC rate from a 60 fps unit
    (None, 0.8, 30.0, "cm"),                                                  # Maya defaults: cm, film
])
def test_time_and_linear_units(tmp_path, unit_line, step, rate, units):
    text = maya_scene({"A": {"X": keys(20, step=step), "Y": keys(20, step=step), "Z": keys(20, step=step)}},
                      unit_line=unit_line)
    capture = read_maya_ascii(write(tmp_path, text))
    assert capture.rate == pytest.approx(rate, rel=1e-12)
    assert capture.units == units
    assert capture.n_frames == 20
    np.testing.assert_array_equal(capture.positions[:, 0, 0], keys(20)[1])


def test_parent_rotation_and_scale(tmp_path):
    text = maya_scene({"A": {"X": keys(5), "t": (0.0, 0.0, 0.0)}},
                      group_lines=['setAttr ".t" -type "double3" 10 0 0 ;', 'setAttr ".r" -type "double3" 0 90 0 ;',
                                   'setAttr ".s" -type "double3" 2 2 2 ;'])
    capture = read_maya_ascii(write(tmp_path, text))
    x = np.array(keys(5)[1])
    # rotate +90 degrees about Y: (x, 0, 0) -> (0, 0, -x); scale 2; then translate
    np.testing.assert_allclose(capture.positions[:, 0], np.stack([10 + 0 * x, 0 * x, -2 * x], 1), atol=1e-12)


def test_curves_with_different_key_times_are_resampled(tmp_path):
    sparse_times = [0.0, 0.8, 1.6, 2.4, 3.2]       # every other 60 Hz frame
    sparse_values = [0.0, 2.0, 4.0, 6.0, 8.0]
    late_times = [1.2, 1.6, 2.0]                     # frames 3..5 only
    text = maya_scene({
        "A": {"X": keys(9), "Y": (sparse_times, sparse_values), "Z": (late_times, [7.0, 8.0, 9.0])},
    })
    capture = read_maya_ascii(write(tmp_path, text))
    assert capture.n_frames == 9 and capture.rate == 60.0
    valid = capture.valid[:, 0]
    np.testing.assert_array_equal(valid, [False, False, False, True, True, True, False, False, False])
    np.testing.assert_array_equal(capture.positions[3:6, 0, 1], [3.0, 4.0, 5.0])   # 3, 5 interpolated
    np.testing.assert_array_equal(capture.positions[3:6, 0, 2], [7.0, 8.0, 9.0])
    assert capture.history[0]["interpolated_samples"] == 4   # Y at frames 1, 3, 5, 7


def test_rate_option_sets_the_grid(tmp_path):
    text = maya_scene({"A": {"X": keys(9), "Y": keys(9), "Z": keys(9)}})
    capture = read_maya_ascii(write(tmp_path, text), rate=30)
    assert capture.rate == 30.0 and capture.n_frames == 5
    np.testing.assert_array_equal(capture.positions[:, 0, 0], keys(9)[1][0::2])   # keys on the grid, exact


def test_first_key_between_frames_records_offset(tmp_path):
    # Maya's default start is frame 1 (film) = 2.5 frames at 60 Hz
    text = maya_scene({"A": {"X": keys(6, start=1.0), "Y": keys(6, start=1.0), "Z": keys(6, start=1.0)}})
    capture = read_maya_ascii(write(tmp_path, text))
    assert capture.start_frame == 2
    assert capture.history[0]["time_offset_seconds"] == pytest.approx(0.5 / 60)
    np.testing.assert_array_equal(capture.positions[:, 0, 0], keys(6)[1])


def test_crlf_line_endings(tmp_path):
    text = maya_scene({"A": {"X": keys(12), "Y": keys(12), "Z": keys(12)}}).replace("\n", "\r\n")
    path = tmp_path / "crlf.ma"
    path.write_bytes(text.encode())
    assert read_maya_ascii(path).n_frames == 12


# -- bad input ------------------------------------------------------------------------------------

def test_truncated_inside_key_block(tmp_path, shared_data):
    text = take_path(shared_data, "Jaw").read_text(encoding="latin-1")
    block = text.index('setAttr ".ktv[500:749]"', len(text) // 2)
    cut = text.index("\n", block + 2000)              # a few lines into the block
    path = write(tmp_path, text[:cut], "JawCut.ma")
    line = text.count("\n", 0, block) + 1
    with pytest.raises(FormatError, match=rf"JawCut\.ma, line {line}: .*ktv\[500:749\].*not terminated by ';'.*truncated"):
        read_maya_ascii(path)


def test_truncated_between_statements(tmp_path):
    text = maya_scene({"A": {"X": keys(5)}}, footer=False)
    with pytest.raises(FormatError, match=r"scene\.ma.*End of.*truncated"):
        read_maya_ascii(write(tmp_path, text))


def test_fewer_keys_than_declared(tmp_path):
    text = maya_scene({"A": {"X": keys(30), "curve": "cA"}}, block=10)
    text = re.sub(r'\tsetAttr "\.ktv\[20:29\]"[^;]*;\n', "", text)
    line = text[:text.index('createNode animCurveTL -n "cA_translateX"')].count("\n") + 1
    with pytest.raises(FormatError, match=rf"line {line}: curve 'cA_translateX' declares 30 keys .* hold 20"):
        read_maya_ascii(write(tmp_path, text))


def test_key_block_with_wrong_count(tmp_path):
    text = maya_scene({"A": {"X": keys(10)}}).replace(" 0.4 ", " 0.4 1e-3 ", 1)
    line = text[:text.index('setAttr ".ktv[0:9]"')].count("\n") + 1
    with pytest.raises(FormatError, match=rf"line {line}: curve 'A_translateX': key block \.ktv\[0:9\] must hold 10 "
                                          r"time/value pairs \(20 numbers\) but it holds 21"):
        read_maya_ascii(write(tmp_path, text))


def test_key_block_with_garbage(tmp_path):
    text = maya_scene({"A": {"X": keys(10)}}).replace(" 0.4 ", " 0.4x ", 1)
    line = text[:text.index('setAttr ".ktv[0:9]"')].count("\n") + 1
    with pytest.raises(FormatError, match=rf"line {line}: .*'0\.4x' is not a number"):
        read_maya_ascii(write(tmp_path, text))


def test_key_times_must_increase(tmp_path):
    times, values = keys(6)
    times[3], times[4] = times[4], times[3]
    with pytest.raises(FormatError, match=r"curve 'A_translateX': key times must increase"):
        read_maya_ascii(write(tmp_path, maya_scene({"A": {"X": (times, values)}})))


def test_not_maya_ascii(tmp_path):
    with pytest.raises(FormatError, match=r"notmaya\.ma, line 1: not a Maya ASCII file"):
        read_maya_ascii(write(tmp_path, "hello\nworld;\n", "notmaya.ma"))


def test_missing_file(tmp_path):
    with pytest.raises(InputError, match=r"nothere\.ma: no such file"):
        read_maya_ascii(tmp_path / "nothere.ma")


def test_no_animated_transform(tmp_path):
    text = maya_scene({"A": {"t": (1, 2, 3)}})
    with pytest.raises(MarkerError, match=r"scene\.ma: no marker found.*animCurveTL"):
        read_maya_ascii(write(tmp_path, text))


def test_duplicate_marker_names(tmp_path):
    text = maya_scene({"A": {"X": keys(4)}}, extra_lines=[
        'createNode transform -n "Other";', 'createNode transform -n "A" -p "Other";',
        'createNode animCurveTL -n "dupX";', '\tsetAttr -s 4 ".ktv[0:3]"  0 1 0.4 1 0.8 1 1.2 1;',
        'connectAttr "dupX.o" "|Other|A.tx";',
    ]).replace('"A.tx"', '"|Grp|A.tx"')
    with pytest.raises(MarkerError, match=r"scene\.ma has duplicate marker names: A"):
        read_maya_ascii(write(tmp_path, text))


def test_translate_driven_by_something_else(tmp_path):
    text = maya_scene({"A": {"X": keys(4)}}, extra_lines=['createNode pointConstraint -n "pc1";',
                                                         'connectAttr "pc1.ctz" "A.tz";'])
    with pytest.raises(FormatError, match=r"line \d+: A\.tz is driven by 'pc1\.ctz' \(a pointConstraint node\)"):
        read_maya_ascii(write(tmp_path, text))


def test_unsupported_group_pivot(tmp_path):
    text = maya_scene({"A": {"X": keys(4)}}, group_lines=['setAttr ".rp" -type "double3" 0 1 0 ;'])
    with pytest.raises(FormatError, match=r"group 'Grp' above markers sets \.rp"):
        read_maya_ascii(write(tmp_path, text))


def test_unsupported_units(tmp_path):
    text = maya_scene({"A": {"X": keys(4)}}, unit_line="currentUnit -l yard -t film;")
    with pytest.raises(FormatError, match=r"linear unit 'yard'"):
        read_maya_ascii(write(tmp_path, text))
    text = maya_scene({"A": {"X": keys(4)}}, unit_line="currentUnit -l cm -t weird;")
    with pytest.raises(FormatError, match=r"time unit 'weird'"):
        read_maya_ascii(write(tmp_path, text))


def test_options_checked(tmp_path):
    path = write(tmp_path, maya_scene({"A": {"X": keys(4)}}))
    with pytest.raises(OptionError, match=r"declares units 'cm' but --units 'mm'"):
        read_maya_ascii(path, units="mm")
    assert read_maya_ascii(path, units="cm").units == "cm"
    with pytest.raises(OptionError, match=r"--rate: expected a positive number of Hz; got -5"):
        read_maya_ascii(path, rate=-5)
    with pytest.raises(OptionError, match=r"--units: unknown unit 'parsec'"):
        read_maya_ascii(path, units="parsec")
    with pytest.raises(PlausibilityError, match=r"scene\.ma: a capture rate of 6e\+06 Hz \(given with --rate\) is "
                                                r"outside the plausible 1-10000 Hz"):
        read_maya_ascii(path, rate=6e6)
    # accepted, the rate still makes far more frames than the curves have keys
    with pytest.raises(PlausibilityError, match=r"scene\.ma: its frame numbers span 300,001 frames but it holds 4 "
                                                r"keys on its longest curve: a typo'd frame number\? \(--allow frame-count"):
        read_maya_ascii(path, rate=6e6, allow={"rate"})
