"""The corpus of implausible captures and meshes: corrupted copies of the real sample data.

Each builder writes one file the way a broken exporter or a careless edit would, starting from
the real AnimFace Jaw take (``sample_assets/capture/JawMoCap.ma``) or the real MakeHuman face; the
tests run `usdface` on it as a user would and check the exit code and the message (file, marker,
frame). Nothing here is synthetic except the corruption itself.
"""
from __future__ import annotations

import re
import sys
from pathlib import Path

import numpy as np
import pytest


#: frames of the Jaw take the CSV cases keep (0..599: neutral, small drop, wide open)
FRAMES = 600
CHIN_KEY = 412  # a key (= frame, keys fall on the 60 Hz grid) inside the wide-open hold


@pytest.fixture(scope="session")
def jaw(sample_assets):
    """The real Jaw take (41 markers, 1590 frames, cm)."""
    from usdface.io.maya_ascii import read_maya_ascii

    return read_maya_ascii(sample_assets / "capture" / "JawMoCap.ma")


@pytest.fixture(scope="session")
def corpus(tmp_path_factory, sample_assets, jaw):
    """{case: path} of every corrupted file (built once per session)."""
    return build_corpus(tmp_path_factory.mktemp("corpus"), sample_assets, jaw)


def build_corpus(d: Path, sample_assets: Path, jaw) -> dict:
    """Write every corrupted file into folder ``d``; returns {case: path} (and a few facts)."""
    from usdface.io.c3d import write_c3d
    from usdface.io.csv_format import write_csv

    d.mkdir(parents=True, exist_ok=True)
    out = {"dir": d}
    head = jaw.replace(positions=jaw.positions[:FRAMES].copy())
    chin = jaw.index("Chin")

    # Maya: one key of Chin.ty replaced by 9.9e30 (the file otherwise intact)
    text = (sample_assets / "capture" / "JawMoCap.ma").read_text()
    start = text.index('createNode animCurveTL -n "Chin_translateY";')
    head_text = 'setAttr ".ktv[250:499]"'  # the key block holding key CHIN_KEY
    offset = text.index(head_text, start) + len(head_text)
    tokens = list(re.finditer(r"\S+", text[offset:text.index(";", offset)]))
    value = tokens[2 * (CHIN_KEY - 250) + 1]  # the value of key CHIN_KEY (pairs: time value)
    text = text[:offset + value.start()] + "9.9e30" + text[offset + value.end():]
    out["maya_huge_key"] = d / "JawMoCap_hugekey.ma"
    out["maya_huge_key"].write_text(text)
    out["maya_huge_key_line"] = text.count("\n", 0, offset + value.start()) + 1

    # C3D: gaps written as exact zeros with a valid residual, as many exporters do
    pos = head.positions.copy()
    pos[100:160, chin] = 0.0
    pos[300:310, jaw.index("Mouth_Down")] = 0.0
    out["c3d_zeros"] = d / "jaw_zeros.c3d"
    write_c3d(out["c3d_zeros"], head.replace(positions=pos))
    out["c3d_clean"] = d / "jaw_clean.c3d"
    write_c3d(out["c3d_clean"], head)

    # CSV: every other marker in mm, the header says cm
    pos = head.positions.copy()
    mm = np.arange(jaw.n_markers) % 2 == 1
    pos[:, mm] *= 10.0
    out["csv_mixed_units"] = d / "jaw_mixed_units.csv"
    write_csv(out["csv_mixed_units"], head.replace(positions=pos))
    out["mixed_markers"] = [n for n, b in zip(jaw.names, mm) if b]

    # CSV: the Chin marker 50 cm in front of the face for the whole take
    pos = head.positions.copy()
    pos[:, chin, 2] += 50.0
    out["csv_far_marker"] = d / "jaw_chin_50cm.csv"
    write_csv(out["csv_far_marker"], head.replace(positions=pos))

    # CSV: metres written under a "# units=cm" header
    out["csv_metres_as_cm"] = d / "jaw_metres_as_cm.csv"
    write_csv(out["csv_metres_as_cm"], head.replace(positions=head.positions / 100.0))

    # CSV: one sample thrown 40 cm (a ghost marker picked up for one frame)
    pos = head.positions.copy()
    pos[CHIN_KEY, chin, 1] += 40.0
    out["csv_spike"] = d / "jaw_spike.csv"
    write_csv(out["csv_spike"], head.replace(positions=pos))

    # CSV: NoseTop jumps 3 cm for three frames (a glitch too small for the outlier test)
    pos = head.positions.copy()
    pos[500:503, jaw.index("NoseTop"), 0] += 3.0
    out["csv_glitch"] = d / "jaw_glitch.csv"
    write_csv(out["csv_glitch"], head.replace(positions=pos))

    out["csv_clean"] = d / "jaw_clean.csv"
    write_csv(out["csv_clean"], head)

    # OBJ: the MakeHuman face in metres (an OBJ has no units: read as cm)
    lines = []
    for line in (sample_assets / "meshes" / "makehuman_hm08_face_cm.obj").read_text().splitlines():
        if line.startswith("v "):
            x, y, z = (float(v) / 100.0 for v in line.split()[1:4])
            line = f"v {x:.8f} {y:.8f} {z:.8f}"
        lines.append(line)
    out["obj_metres"] = d / "face_metres.obj"
    out["obj_metres"].write_text("\n".join(lines) + "\n")

    # layout: the MakeHuman layout with the performer's left and right names swapped
    import json

    layout = json.loads((sample_assets / "layouts" / "makehuman_hm08_face.layout.json").read_text())
    layout["markers"] = {_mirror_name(k): v for k, v in layout["markers"].items()}
    out["layout_mirrored"] = d / "mirrored.layout.json"
    out["layout_mirrored"].write_text(json.dumps(layout))

    # 2D tracks: the video's exact tracks with one dot's track 250 px off (a wrong seed)
    from usdface.io.csv_format import read_csv

    tracks = read_csv(sample_assets / "video" / "animface_dots.truth.csv", units="cm")
    pos = tracks.positions.copy()
    pos[:, tracks.index("NoseHead"), 0] += 250.0
    out["tracks_off"] = d / "tracks_nosehead_off.csv"
    write_csv(out["tracks_off"], tracks.replace(positions=pos, units=None), dims=2)
    return out


def _mirror_name(name: str) -> str:
    """Swap the performer's left and right in an AnimFace marker name."""
    swaps = [(r"^L(eye|eyebrow|cheek)", r"R\1"), (r"^R(eye|eyebrow|cheek)", r"L\1"), (r"_L$", "_R"), (r"_R$", "_L"),
             (r"_L(\d)$", r"_R\1"), (r"_R(\d)$", r"_L\1"), (r"^Mouth_Lend$", "Mouth_Rend"),
             (r"^Mouth_Rend$", "Mouth_Lend"), (r"L1$", "R1"), (r"R1$", "L1"), (r"DownL$", "DownR"),
             (r"DownR$", "DownL")]
    for pattern, repl in swaps:
        new = re.sub(pattern, repl, name)
        if new != name:
            return new
    return name


@pytest.fixture()
def warnings_of(caplog):
    """The usdface warnings logged during a test (message text)."""
    import logging

    caplog.set_level(logging.WARNING, logger="usdface")

    def get() -> list[str]:
        return [r.getMessage() for r in caplog.records if r.levelno >= logging.WARNING and r.name == "usdface"]

    return get


if __name__ == "__main__":  # python tests/plausibility/conftest.py OUTDIR: write the corpus there
    from usdface.io.maya_ascii import read_maya_ascii

    assets = Path(__file__).resolve().parents[2] / "sample_assets"
    made = build_corpus(Path(sys.argv[1] if len(sys.argv) > 1 else "out/corpus"), assets,
                        read_maya_ascii(assets / "capture" / "JawMoCap.ma"))
    for case, path in made.items():
        if isinstance(path, Path) and path.is_file():
            print(f"{case:18s} {path}")
