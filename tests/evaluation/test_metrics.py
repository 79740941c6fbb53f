"""Issue 19's figures, the committed hold-out split, and what the pipeline's defaults give on it."""
from __future__ import annotations

import fnmatch
import json

import numpy as np
import pytest

from usdface.errors import InputError, OptionError
from usdface.evaluation import TransferConfig as T
from usdface.evaluation import TransferSetup, evaluate, jaw_drop_mouth_error, mesh_error, read_split
from usdface.evaluation.configs import REGION_NAMES
from usdface.io.meshes import read_mesh
from usdface.mesh.layout import read_layout
from usdface.mesh.topology import find_hole_regions
from usdface.mesh.layout_binding import binding_from_layout
from usdface.rbf.soundness import SOUND_KERNELS


@pytest.fixture(scope="module")
def split(repo_root):
    return read_split(repo_root / "benchmarks" / "heldout_split.json")


@pytest.fixture(scope="module")
def face(sample_assets, split):
    mesh = read_mesh(sample_assets / "meshes" / "makehuman_hm08_face_cm.obj")
    regions = find_hole_regions(mesh)
    binding = binding_from_layout(mesh, read_layout(sample_assets / "layouts" / "makehuman_hm08_face.layout.json"))
    z = np.load(sample_assets / "meshes" / "makehuman_hm08_face_units_cm.npz")
    names = [str(n) for n in z["names"]]
    keep = list(split.tuning) + list(split.heldout)
    deltas = z["deltas"].astype(np.float64)[[names.index(n) for n in keep]]
    return {"mesh": mesh, "regions": regions, "binding": binding, "names": keep, "deltas": deltas,
            "setup": TransferSetup(mesh, regions, binding), "all_names": names}


def test_committed_split(split, face, repo_root):
    raw = json.loads((repo_root / "benchmarks" / "heldout_split.json").read_text())
    split.check(face["all_names"])
    used = set(split.tuning) | set(split.heldout)
    for n in face["all_names"]:  # every shape is in exactly one place, by the committed patterns
        excluded = any(fnmatch.fnmatchcase(n, p) for p in raw["exclude_patterns"])
        tuned = any(fnmatch.fnmatchcase(n, p) for p in raw["tuning_patterns"])
        held = any(fnmatch.fnmatchcase(n, p) for p in raw["heldout_patterns"])
        assert (n in split.tuning) == (tuned and not excluded)
        assert (n in split.heldout) == (held and not excluded)
        assert (n in used) != excluded
    assert split.reverse().tuning == split.heldout


def test_split_errors(tmp_path):
    p = tmp_path / "s.json"
    p.write_text(json.dumps({"tuning": ["a", "b"], "heldout": ["b"]}))
    with pytest.raises(InputError, match="shapes both tuned on and held out: b"):
        read_split(p)
    p.write_text(json.dumps({"tuning": ["a"]}))
    with pytest.raises(InputError, match="expected lists 'tuning' and 'heldout'"):
        read_split(p)
    p.write_text(json.dumps({"tuning": ["a"], "heldout": ["eyeLookUpLeft"], "exclude_patterns": ["eyeLook*"]}))
    with pytest.raises(InputError, match="excluded shapes eyeLookUpLeft are in a set"):
        read_split(p).check(["a", "eyeLookUpLeft"])
    with pytest.raises(InputError, match="shapes eyeLookUpLeft are not in the shapes file"):
        read_split(p).check(["a"])


def test_mesh_error_and_jaw_drop_against_plain_sums(face, split):
    cfg = T("hybrid", pin="upper")
    rep = evaluate(face["mesh"], face["regions"], face["binding"], face["names"], face["deltas"], configs=[cfg],
                   setup=face["setup"], keep_predictions=True)
    res = rep.results[0]
    err = np.linalg.norm(res.predictions - face["deltas"], axis=2).mean(axis=1)   # cm: the face is in cm
    true = np.linalg.norm(face["deltas"], axis=2).mean(axis=1)
    held = [face["names"].index(n) for n in split.heldout]
    moving = [i for i in held if true[i] > 0.05]
    assert 0 < len(moving) < len(held)
    assert mesh_error(rep, res, shapes=split.heldout) == pytest.approx(100 * err[moving].sum() / true[moving].sum())
    assert mesh_error(rep, res, shapes=split.heldout, min_mean_cm=0) == pytest.approx(
        100 * err[held].sum() / true[held].sum())
    j = face["names"].index("jawOpen")
    mouth = face["setup"].regions["mouth"]
    assert jaw_drop_mouth_error(rep, res) == pytest.approx(
        np.linalg.norm(res.predictions[j] - face["deltas"][j], axis=1)[mouth].mean())
    assert np.isnan(jaw_drop_mouth_error(rep, res, shape="nope"))
    assert np.isnan(mesh_error(rep, res, shapes=["browInnerUp"]))   # moves less than 0.5 mm on average
    assert mesh_error(rep, res, shapes=["jawOpen"], region="mouth") == pytest.approx(
        100 * res.mean_error[j, REGION_NAMES.index("mouth")] / true[j])
    with pytest.raises(OptionError, match="shapes nope were not evaluated"):
        mesh_error(rep, res, shapes=["nope"])


def test_every_accepted_kernel_stays_within_1_25x_of_the_euclidean_gaussian(face, split):
    """Issue 19: on the held-out shapes, with the pipeline's defaults (edge-path geodesics)."""
    configs = [T(m, kernel=k, pin="upper") for m, kernels in SOUND_KERNELS.items() for k in kernels]
    rep = evaluate(face["mesh"], face["regions"], face["binding"], face["names"], face["deltas"], configs=configs,
                   setup=face["setup"])
    base = mesh_error(rep, rep.result(T("euclidean", pin="upper")), shapes=split.heldout)
    for res in rep.results:
        assert mesh_error(rep, res, shapes=split.heldout) <= 1.25 * base, res.config.label
    refused = T("geodesic", kernel="thin_plate_spline", pin="upper")
    with pytest.raises(OptionError, match="--kernel thin_plate_spline with --method geodesic: no well-posed variant"):
        face["setup"].transfer(refused)
    face["setup"].transfer(T("geodesic", kernel="thin_plate_spline", pin="upper", check=False))  # measurable


def test_thin_plate_rows_only_where_the_pipeline_runs_them(sample_assets):
    from usdface.evaluation import parse_configs
    from usdface import api
    from usdface.options import EvaluateOptions

    rows = [c for c in parse_configs(thin_plate=True) if c.kernel == "thin_plate_spline"]
    assert [(c.method, c.uses_polynomial) for c in rows] == [("euclidean", True)]
    options = EvaluateOptions(layout=str(sample_assets / "layouts" / "makehuman_hm08_face.layout.json"),
                              only=("jawOpen",), modes=("interpolate",), pins=("upper",), widths=("default",),
                              thin_plate=True)
    out = api.evaluate(str(sample_assets / "meshes" / "makehuman_hm08_face_cm.obj"),
                       str(sample_assets / "meshes" / "makehuman_hm08_face_units_cm.npz"), options).summary
    assert [c["kernel"] for c in out["configs"]] == ["gaussian"] * 3 + ["thin_plate_spline"]
