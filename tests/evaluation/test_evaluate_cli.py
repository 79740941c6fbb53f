"""`usdface evaluate`: the command registered through register_cli, run in-process."""
from __future__ import annotations

import argparse
import json

import numpy as np
import pytest

from usdface.errors import FormatError, InputError, OptionError
from usdface.processors.evaluate import evaluate_shapes, load_shapes, register_cli


def parse(argv):
    parser = argparse.ArgumentParser(prog="usdface")
    sub = parser.add_subparsers(dest="command", required=True)
    register_cli(sub)
    return parser.parse_args([str(a) for a in argv])


@pytest.fixture(scope="module")
def paths(sample_assets):
    return {"mesh": sample_assets / "meshes" / "makehuman_hm08_face_cm.obj",
            "shapes": sample_assets / "meshes" / "makehuman_hm08_face_units_cm.npz",
            "layout": sample_assets / "layouts" / "makehuman_hm08_face.layout.json"}


def test_evaluate_command_writes_the_table(paths, tmp_path, capsys):
    from usdface.cli import _print_summary

    out = tmp_path / "quality.md"
    args = parse(["evaluate", "--mesh", paths["mesh"], "--shapes", paths["shapes"], "--layout", paths["layout"],
                  "--only", "jawOpen", "eyeBlink*", "--methods", "euclidean", "hybrid", "--pins", "upper",
                  "--widths", "default", "2", "-o", out])
    summary = args.func(args)
    assert summary["shapes"] == ["eyeBlinkLeft", "eyeBlinkRight", "jawOpen"]
    labels = [c["label"] for c in summary["configs"]]
    # 2 methods x (paper + interpolate/upper) x 2 widths
    assert len(labels) == 8 and "hybrid/graph interpolate gauss 2 cm pin=upper" in labels
    text = out.read_text()
    assert "### The paper's claim" in text and "| hybrid/graph | interpolate | gauss 2 cm | upper |" in text
    assert "jawOpen upperLip" in text
    _print_summary(summary, False, False)
    assert "wrote" in capsys.readouterr().out
    _print_summary(summary, True, False)
    data = json.loads(capsys.readouterr().out)
    assert data["claim"][0]["label"] == labels[0]


def test_evaluate_through_the_usdface_command(paths, tmp_path, monkeypatch, capsys):
    """`usdface evaluate` via usdface.cli.main."""
    from usdface import cli

    rc = cli.main(["evaluate", "--mesh", str(paths["mesh"]), "--shapes", str(paths["shapes"]), "--layout",
                   str(paths["layout"]), "--only", "jawOpen", "--methods", "euclidean", "--modes", "paper", "--json"])
    assert rc == 0
    data = json.loads(capsys.readouterr().out)
    assert data["shapes"] == ["jawOpen"] and len(data["configs"]) == 2
    rc = cli.main(["evaluate", "--mesh", str(paths["mesh"]), "--shapes", str(paths["shapes"]), "--layout",
                   str(paths["layout"]), "--only", "nope", "-q"])
    assert rc == 2 and "nope" in capsys.readouterr().err


def test_evaluate_errors(paths, tmp_path):
    with pytest.raises(OptionError, match="exactly one"):
        evaluate_shapes(paths["mesh"], paths["shapes"])
    bad = tmp_path / "bad.npz"
    np.savez(bad, names=np.array(["a"]), neutral=np.zeros((3, 3)))
    with pytest.raises(FormatError, match="deltas"):
        load_shapes(bad)
    wrong = tmp_path / "wrong.npz"
    np.savez(wrong, names=np.array(["a"]), deltas=np.zeros((1, 10, 3)))
    with pytest.raises(InputError, match="10 vertices"):
        evaluate_shapes(paths["mesh"], wrong, layout=paths["layout"])
    z = np.load(paths["shapes"])
    moved = tmp_path / "moved.npz"
    np.savez(moved, names=z["names"][:2], deltas=z["deltas"][:2], neutral=z["neutral"] + 1.0)
    with pytest.raises(InputError, match="neutral differs"):
        evaluate_shapes(paths["mesh"], moved, layout=paths["layout"])
    with pytest.raises(OptionError, match="not found"):
        evaluate_shapes(paths["mesh"], paths["shapes"], layout=paths["layout"], only=["nope"])
