"""Issue 19 through the commands: every kernel sound or refused (one line, exit 2), the polynomial a
kernel needs added by default, the per-marker metric-aware width rule, the amplification warning.
Real data: the MakeHuman face and the first two seconds of the Jaw take."""
from __future__ import annotations

import json

import numpy as np
import pytest

LAYOUT = "makehuman_hm08_face.layout.json"
MESH = "makehuman_hm08_face_cm.obj"


@pytest.fixture(scope="module")
def layers(tmp_path_factory, sample_assets, cli):
    d = tmp_path_factory.mktemp("transfer_defaults")
    f = {"dir": d, "mesh": d / "mesh.usdc", "capture": d / "capture.usdc", "binding": d / "binding.usda"}
    assert cli("import-mesh", sample_assets / "meshes" / MESH, "-o", f["mesh"], "-q") == 0
    assert cli("import-capture", sample_assets / "capture" / "JawMoCap.ma", "--trim", "0", "120", "--stabilize",
               "-o", f["capture"], "-q") == 0
    assert cli("bind", "--mesh", f["mesh"], "--capture", f["capture"], "--layout", sample_assets / "layouts" / LAYOUT,
               "-o", f["binding"], "-q") == 0
    for method in ("euclidean", "geodesic", "hybrid"):
        f[method] = d / f"analysis_{method}.usdc"
        assert cli("distances", "--mesh", f["mesh"], "--binding", f["binding"], "--method", method, "-o", f[method],
                   "-q") == 0
    return f


def _transfer(cli, layers, method, out, *extra):
    return cli("transfer", "--mesh", layers["mesh"], "--capture", layers["capture"], "--binding", layers["binding"],
               "--analysis", layers[method], "-o", out, *extra)


def _transfer_api(anim):
    from pxr import Usd

    stage = Usd.Stage.Open(str(anim))
    prim = stage.GetPrimAtPath("/Face/Geom")
    get = lambda name: prim.GetAttribute(f"usdface:transfer:{name}").Get()  # noqa: E731
    return {"widths": np.asarray(get("widths")), "polynomial": get("polynomial"), "kernel": get("kernel"),
            "parameters": json.loads(get("parameters"))}


def test_a_kernel_without_a_sound_variant_on_the_layers_distances_is_refused(layers, tmp_path, cli, capsys):
    """The transfer reads its method from the analysis layer and names it."""
    out = tmp_path / "anim.usdc"
    assert _transfer(cli, layers, "hybrid", out, "--kernel", "thin_plate_spline") == 2
    where = f"--method hybrid (the distances of {layers['hybrid']})"
    assert capsys.readouterr().err.splitlines() == [
        f"usdface transfer: error: --kernel thin_plate_spline with {where}: no well-posed variant (its guarantees hold "
        "for Euclidean distances only; on hybrid distances it amplifies marker motion 17x or more, 3-65x the error of "
        f"a Gaussian); kernels that work with {where}: gaussian, inverse_multiquadric"]
    assert not out.exists()


@pytest.mark.parametrize("argv, line", [
    (["--kernel", "cubic"], "--kernel cubic with --method hybrid: no usable variant with any --method (on hybrid "
                            "distances it amplifies marker motion 17x or more, 3-65x the error of a Gaussian; on "
                            "Euclidean ones, scale-free with its polynomial, about 9x at any width); kernels that work "
                            "with --method hybrid: gaussian, inverse_multiquadric"),
    (["--method", "euclidean", "--kernel", "cubic"],
     "--kernel cubic with --method euclidean: no usable variant with any --method (scale-free with its polynomial, it "
     "amplifies marker motion about 9x at any width, 1.5x the error of a Gaussian); kernels that work with --method "
     "euclidean: gaussian, inverse_multiquadric, multiquadric, thin_plate_spline"),
    (["--method", "euclidean", "--kernel", "thin_plate_spline", "--no-polynomial"],
     "--kernel thin_plate_spline with --method euclidean and --no-polynomial: thin_plate_spline is conditionally "
     "positive definite of order 2 and needs its linear polynomial term (drop --no-polynomial); kernels that work "
     "with --method euclidean without it: gaussian, inverse_multiquadric, multiquadric"),
    (["--method", "geodesic", "--kernel", "multiquadric"],
     "--kernel multiquadric with --method geodesic: no well-posed variant (its guarantees hold for Euclidean "
     "distances only; on geodesic distances it amplifies marker motion 17x or more, 3-65x the error of a Gaussian); "
     "kernels that work with --method geodesic: gaussian, inverse_multiquadric"),
])
def test_run_refuses_an_unsound_pair_in_one_line_before_any_work(argv, line, sample_assets, tmp_path, cli, capsys):
    out = tmp_path / "run"
    assert cli("run", "--mesh", sample_assets / "meshes" / MESH, "--capture", sample_assets / "capture" / "JawMoCap.ma",
               "--layout", sample_assets / "layouts" / LAYOUT, "-o", out, *argv) == 2
    assert capsys.readouterr().err.splitlines() == [f"usdface run: error: {line}"]
    assert not out.exists()


def test_thin_plate_gets_its_polynomial_by_default(layers, tmp_path, cli, capsys):
    from usdface.usd.layers import layer_provenance

    out = tmp_path / "tps.usdc"
    assert _transfer(cli, layers, "euclidean", out, "--kernel", "thin_plate_spline", "--json") == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary["polynomial"] is True and summary["widthRule"] == "uniform"
    assert _transfer_api(out)["polynomial"] is True
    assert json.loads(layer_provenance(out)["options"])["polynomial"] is True
    # the Gaussian does not need it: not added unless asked
    assert _transfer(cli, layers, "euclidean", tmp_path / "g.usdc", "--json") == 0
    assert json.loads(capsys.readouterr().out)["polynomial"] is False
    assert _transfer(cli, layers, "euclidean", tmp_path / "gp.usdc", "--polynomial", "--json") == 0
    assert json.loads(capsys.readouterr().out)["polynomial"] is True


@pytest.mark.parametrize("method", ["euclidean", "geodesic", "hybrid"])
def test_default_widths_are_per_marker_in_the_layers_metric(layers, method, tmp_path, cli):
    """0.7 x each marker's mean distance to its 3 nearest markers, in the analysis layer's own
    distances (a pair's distance: the smaller of its two entries), by plain loops."""
    from usdface.usd.analysis_layer import read_distance_matrix

    out = tmp_path / "anim.usdc"
    assert _transfer(cli, layers, method, out, "-q") == 0
    dm = read_distance_matrix(layers[method], method=method)
    m = len(_transfer_api(out)["widths"])
    d = dm.centre_to_centre
    want = []
    for j in range(m):
        near = sorted(min(d[j, k], d[k, j]) for k in range(m) if k != j)[:3]
        want.append(0.7 * sum(near) / 3)
    api = _transfer_api(out)
    np.testing.assert_allclose(api["widths"], want, rtol=1e-12)
    assert api["parameters"]["widthRule"] == "local"


def test_paper_mode_keeps_the_papers_width(layers, tmp_path, cli, sample_assets):
    """--rbf paper: 1.1 x the median Euclidean nearest-marker distance for every marker."""
    from usdface.model.mesh import FaceMesh  # noqa: F401
    from usdface.usd.layers import open_stage
    from usdface.usd.mesh_layer import read_binding, read_mesh_layer

    out = tmp_path / "paper.usdc"
    assert _transfer(cli, layers, "hybrid", out, "--rbf", "paper", "-q") == 0
    mesh, _ = read_mesh_layer(layers["mesh"])
    q = read_binding(open_stage(layers["binding"])).surface_points(mesh.points)
    nearest = [min(np.linalg.norm(q[j] - q[k]) for k in range(len(q)) if k != j) for j in range(len(q))]
    np.testing.assert_allclose(_transfer_api(out)["widths"], 1.1 * np.median(nearest), rtol=1e-12)


def test_an_amplification_that_slips_through_is_a_warning_naming_it(layers, tmp_path, cli, capsys, caplog):
    out = tmp_path / "wide.usdc"
    assert _transfer(cli, layers, "geodesic", out, "--stiffness", "3", "--regularization", "0", "--json") == 0
    amp = json.loads(capsys.readouterr().out)["amplification"]
    assert amp > 6
    warnings = [r.getMessage() for r in caplog.records if r.levelname == "WARNING"]
    assert warnings == [f"the gaussian transfer on geodesic distances amplifies marker motion {amp:.1f}x at some "
                        "vertices (a sound transfer stays under 6x): expect errors well above the markers' motion "
                        "there; try a smaller --stiffness or --method euclidean"]


def test_fast_marching_is_the_default_geodesic_and_paper_mode_keeps_edge_paths(layers, sample_assets, tmp_path,
                                                                            cli):
    """Held out, fmm at the default width transfers at least as well as edge paths (README), so it is
    the default; --rbf paper keeps the paper's edge paths unless --backend says otherwise."""
    from usdface.options import DistanceOptions, RunOptions
    from usdface.usd.analysis_layer import read_distance_matrix

    assert read_distance_matrix(layers["hybrid"], method="hybrid").backend == "fmm"
    assert DistanceOptions().backend == "fmm"
    assert (RunOptions().backend, RunOptions(rbf="paper").backend, RunOptions(rbf="paper", backend="fmm").backend,
            RunOptions(backend="graph").backend) == ("fmm", "graph", "fmm", "graph")
    out = tmp_path / "paper"
    assert cli("run", "--mesh", sample_assets / "meshes" / MESH, "--capture", sample_assets / "capture" / "JawMoCap.ma",
               "--layout", sample_assets / "layouts" / LAYOUT, "--trim", "0", "30", "--rbf", "paper", "-o", out,
               "-q") == 0
    assert json.loads((out / "summary.json").read_text())["backend"] == "graph"
    assert read_distance_matrix(out / "analysis.usdc").backend == "graph"
