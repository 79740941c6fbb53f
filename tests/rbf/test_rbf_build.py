"""build_transfer: the pipeline's defaults and checks, on the real MakeHuman face and its layout."""
from __future__ import annotations

import warnings

import numpy as np
import pytest
from scipy.spatial.distance import cdist

from usdface.errors import OptionError
from usdface.io.meshes import read_mesh
from usdface.mesh.layout import read_layout
from usdface.mesh.layout_binding import binding_from_layout
from usdface.rbf import AmplificationWarning, TransferGeometry, TransferSettings, build_transfer
from usdface.rbf.stiffness import median_marker_spacing_from_points


@pytest.fixture(scope="module")
def face(sample_assets):
    mesh = read_mesh(sample_assets / "meshes" / "makehuman_hm08_face_cm.obj")
    b = binding_from_layout(mesh, read_layout(sample_assets / "layouts" / "makehuman_hm08_face.layout.json"))
    mp = b.surface_points(mesh.points)
    geometry = TransferGeometry(marker_points=mp, centre_points=mp, vertex_points=mesh.points,
                                marker_names=tuple(b.names), collocation=(b.triangle_vertices, b.barycentrics))
    return {"mesh": mesh, "mp": mp, "D_vc": cdist(mesh.points, mp), "D_cc": cdist(mp, mp), "geometry": geometry}


def build(face, scale=1.0, method="euclidean", **settings):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", AmplificationWarning)
        return build_transfer(scale * face["D_vc"], scale * face["D_cc"], method, settings=TransferSettings(**settings),
                              geometry=face["geometry"])


def test_default_width_follows_the_distance_metric(face):
    """Distances uniformly 15% longer (edge paths run long) change nothing: the widths scale with them."""
    a, info = build(face)
    b, _ = build(face, scale=1.15)
    np.testing.assert_allclose(b.widths, 1.15 * a.widths, rtol=1e-12)
    np.testing.assert_allclose(b.transfer_matrix, a.transfer_matrix, atol=1e-9)
    assert info["widthRule"] == "local" and info["polynomial"] is False and info["regularization"] == 0.0
    # the paper rule stays on the Euclidean spacing of the bound points, whatever the distances
    p, info = build(face, scale=1.15, mode="paper")
    np.testing.assert_allclose(p.widths, 1.1 * median_marker_spacing_from_points(face["mp"]), rtol=1e-12)
    assert info["widthRule"] == "paper"


def test_thin_plate_gets_its_polynomial_and_reproduces_affine_motion(face):
    rng = np.random.default_rng(5)
    A = 0.02 * rng.normal(size=(3, 3))
    t = np.array([0.1, -0.2, 0.05])
    field = face["mesh"].points @ A.T + t                      # an affine displacement field (cm)
    disp = face["mp"] @ A.T + t
    solver, info = build(face, kernel="thin_plate_spline")
    assert info["polynomial"] is True and info["widthRule"] == "uniform"
    np.testing.assert_allclose(solver.apply(disp, dtype=np.float64), field, atol=1e-9)
    with pytest.raises(OptionError, match="needs its linear polynomial term"):
        build(face, kernel="thin_plate_spline", polynomial=False)
    plain, _ = build(face, kernel="thin_plate_spline", polynomial=False, check=False)
    assert np.abs(plain.apply(disp, dtype=np.float64) - field).max() > 1e-3  # without it: not reproduced


def test_refused_pairs_name_the_analysis_layer(face):
    with pytest.raises(OptionError) as err:
        build_transfer(face["D_vc"], face["D_cc"], "hybrid", settings=TransferSettings(kernel="cubic"),
                       geometry=face["geometry"], method_source="shot/analysis.usdc")
    assert str(err.value).startswith("--kernel cubic with --method hybrid (the distances of shot/analysis.usdc): ")
    assert err.value.exit_code == 2


def test_amplification_that_slips_through_is_reported(face):
    with warnings.catch_warnings():
        warnings.simplefilter("error", AmplificationWarning)
        _, info = build_transfer(face["D_vc"], face["D_cc"], "euclidean", settings=TransferSettings(),
                                 geometry=face["geometry"])
    assert info["amplificationWarning"] is None and info["amplification"] < 3
    with pytest.warns(AmplificationWarning) as rec:
        _, info = build_transfer(face["D_vc"], face["D_cc"], "euclidean", settings=TransferSettings(stiffness=4.0),
                                 geometry=face["geometry"])
    amp = info["amplification"]
    assert amp > 6 and info["regularization"] == 0.0   # within the auto bound (25x): nothing regularised it
    assert str(rec[0].message) == info["amplificationWarning"] == (
        f"the gaussian transfer on euclidean distances amplifies marker motion {amp:.1f}x at some vertices (a sound "
        "transfer stays under 6x): expect errors well above the markers' motion there; try a smaller --stiffness")


def test_settings_are_checked():
    with pytest.raises(OptionError, match="apply to --rbf interpolate only"):
        TransferSettings(mode="paper", polynomial=True)
    with pytest.raises(OptionError, match="regularization: expected 'auto' or a number >= 0"):
        TransferSettings(regularization=-1.0)
    with pytest.raises(OptionError, match="warn_amplification: expected a positive number"):
        TransferSettings(warn_amplification=0)


def test_amplification_message_suggests_what_applies():
    from usdface.rbf.stability import amplification_warning

    assert amplification_warning(5.9, kernel="gaussian", method="hybrid") is None
    assert amplification_warning(17.04, kernel="inverse_multiquadric", method="geodesic", regularization=0.03) == (
        "the inverse_multiquadric transfer on geodesic distances amplifies marker motion 17.0x at some vertices even "
        "with regularization 0.03 (a sound transfer stays under 6x): expect errors well above the markers' motion "
        "there; try a smaller --stiffness or --method euclidean or --kernel gaussian")
