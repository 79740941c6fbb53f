"""`usdface evaluate`: the command and its Python API function (:func:`usdface.api.evaluate`)."""
from __future__ import annotations

import json

import numpy as np
import pytest

from usdface import api
from usdface.blendshape.rig import read_shapes_npz
from usdface.errors import FormatError, InputError, OptionError
from usdface.options import EvaluateOptions


@pytest.fixture(scope="module")
def paths(sample_assets):
    return {"mesh": sample_assets / "meshes" / "makehuman_hm08_face_cm.obj",
            "shapes": sample_assets / "meshes" / "makehuman_hm08_face_units_cm.npz",
            "layout": sample_assets / "layouts" / "makehuman_hm08_face.layout.json"}


def test_evaluate_command_writes_the_table(paths, tmp_path, capsys):
    from usdface import cli

    out = tmp_path / "quality.md"
    options = EvaluateOptions(layout=str(paths["layout"]), only=("jawOpen", "eyeBlink*"),
                              methods=("euclidean", "hybrid"), pins=("upper",), widths=("default", "2"))
    result = api.evaluate(paths["mesh"], paths["shapes"], options, output=out)
    summary = result.summary
    assert summary["shapes"] == ["eyeBlinkLeft", "eyeBlinkRight", "jawOpen"]
    labels = [c["label"] for c in summary["configs"]]
    # 2 methods x (paper + interpolate/upper) x 2 widths
    # interpolate rows on the pipeline's fast marching, paper rows on the paper's edge paths
    assert len(labels) == 8 and "hybrid/fmm interpolate gauss 2 cm pin=upper" in labels
    assert "hybrid/graph paper gauss 2 cm pin=-" in labels
    text = out.read_text()
    assert "### The paper's claim" in text and "| hybrid/fmm | interpolate | gauss 2 cm | upper |" in text
    assert "jawOpen upperLip" in text
    assert result.files == {"output": str(out)} and result.layers == {}
    assert result.text[-1] == f"wrote {out}" and text == "\n".join(result.text[:-2]) + "\n"
    # the command prints the same report, or the summary as JSON
    argv = ["evaluate", "--mesh", str(paths["mesh"]), "--shapes", str(paths["shapes"]), "--layout",
            str(paths["layout"]), "--only", "jawOpen", "eyeBlink*", "--methods", "euclidean,hybrid", "--pins", "upper",
            "--widths", "default", "2", "-o", str(out)]
    assert cli.main(argv) == 0
    assert capsys.readouterr().out.splitlines() == result.text
    assert cli.main(argv + ["--json"]) == 0
    data = json.loads(capsys.readouterr().out)
    assert data["claim"][0]["label"] == labels[0] and data["output"] == str(out)


def test_evaluate_through_the_usdface_command(paths, capsys):
    from usdface import cli

    rc = cli.main(["evaluate", "--mesh", str(paths["mesh"]), "--shapes", str(paths["shapes"]), "--layout",
                   str(paths["layout"]), "--only", "jawOpen", "--methods", "euclidean", "--modes", "paper", "--json"])
    assert rc == 0
    data = json.loads(capsys.readouterr().out)
    assert data["shapes"] == ["jawOpen"] and len(data["configs"]) == 2
    rc = cli.main(["evaluate", "--mesh", str(paths["mesh"]), "--shapes", str(paths["shapes"]), "--layout",
                   str(paths["layout"]), "--only", "nope", "-q"])
    assert rc == 2 and "nope" in capsys.readouterr().err


def test_evaluate_reads_an_in_memory_mesh(paths, tmp_path):
    """The API takes the mesh as a layer (a DCC's scene): the numbers are those of the same layer
    saved to a file."""
    from pxr import Usd

    mesh_layer = api.import_mesh(str(paths["mesh"])).layer
    mesh_file = tmp_path / "face.usdc"
    assert mesh_layer.Export(str(mesh_file))
    options = EvaluateOptions(layout=str(paths["layout"]), only="jawOpen", methods="euclidean", modes="paper")
    from_memory = api.evaluate(mesh_layer, paths["shapes"], options).summary
    from_file = api.evaluate(mesh_file, paths["shapes"], options).summary
    assert from_memory["mesh"].startswith("in-memory layer") and from_file["mesh"] == str(mesh_file)

    def numbers(summary):
        def drop(v):
            if isinstance(v, dict):
                return {k: drop(x) for k, x in v.items() if k not in ("seconds", "distanceSeconds", "mesh")}
            return [drop(x) for x in v] if isinstance(v, list) else v
        return drop(summary)

    assert numbers(from_memory) == numbers(from_file) and len(from_file["configs"]) == 2
    stage = Usd.Stage.Open(mesh_layer)
    assert numbers(api.evaluate(stage, paths["shapes"], options).summary) == numbers(from_file)


def test_evaluate_errors(paths, tmp_path):
    with pytest.raises(OptionError, match="exactly one"):
        api.evaluate(paths["mesh"], paths["shapes"])
    bad = tmp_path / "bad.npz"
    np.savez(bad, names=np.array(["a"]), neutral=np.zeros((3, 3)))
    with pytest.raises(FormatError, match="deltas"):
        read_shapes_npz(bad)
    layout = {"layout": str(paths["layout"])}
    wrong = tmp_path / "wrong.npz"
    np.savez(wrong, names=np.array(["a"]), deltas=np.zeros((1, 10, 3)))
    with pytest.raises(InputError, match="10 vertices"):
        api.evaluate(paths["mesh"], wrong, layout)
    z = np.load(paths["shapes"])
    moved = tmp_path / "moved.npz"
    np.savez(moved, names=z["names"][:2], deltas=z["deltas"][:2], neutral=z["neutral"] + 1.0)
    with pytest.raises(InputError, match="neutral differs"):
        api.evaluate(paths["mesh"], moved, layout)
    with pytest.raises(OptionError, match="not found"):
        api.evaluate(paths["mesh"], paths["shapes"], {**layout, "only": ["nope"]})
    with pytest.raises(OptionError, match="--methods .*: expected names"):
        EvaluateOptions(methods=[object()])


def test_names_split_on_commas_and_spaces():
    o = EvaluateOptions(methods=["euclidean, hybrid", "geodesic"], widths=[2, "default"], only="jawOpen")
    assert o.methods == ("euclidean", "hybrid", "geodesic") and o.widths == ("2", "default") and o.only == ("jawOpen",)
    assert EvaluateOptions(methods=[" , "]).methods is None
    assert EvaluateOptions(methods=o.methods) == EvaluateOptions(methods=("euclidean", "hybrid", "geodesic"))
