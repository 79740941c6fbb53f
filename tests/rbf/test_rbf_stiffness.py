"""Kernel widths: the default rule and per-marker overrides."""
from __future__ import annotations

import numpy as np
import pytest

from usdface.errors import ComputeError, OptionError
from usdface.rbf import stiffness as S


def _line(spacings):
    x = np.concatenate([[0.0], np.cumsum(spacings)])
    return np.abs(x[:, None] - x[None, :]), x


def test_median_spacing_and_default_rule():
    D, x = _line([1.0, 2.0, 4.0, 8.0])  # nearest distances 1, 1, 2, 4, 8 -> median 2
    assert S.median_marker_spacing(D) == 2.0
    pts = np.stack([x, np.zeros_like(x), np.zeros_like(x)], axis=1)
    assert S.median_marker_spacing_from_points(pts) == pytest.approx(2.0)
    assert S.DEFAULT_WIDTH_FACTOR == 1.1
    assert S.default_width(D, 5) == pytest.approx(2.2)
    # only the marker block counts: a constraint centre very close to marker 0 changes nothing
    Dc = np.zeros((6, 6))
    Dc[:5, :5] = D
    Dc[5, :5] = Dc[:5, 5] = D[0] + 0.01
    assert S.default_width(Dc, 5) == pytest.approx(2.2)


def test_spacing_uses_row_minimum_for_asymmetric_distances():
    D = np.array([[0.0, 1.0, 5.0], [3.0, 0.0, 2.0], [5.0, 2.5, 0.0]])
    assert S.median_marker_spacing(D) == 2.0  # row minima 1, 2, 2.5


def test_resolve_widths_forms():
    D, _ = _line([1.0, 2.0, 4.0, 8.0])
    C, M = 5, 4  # last centre is a constraint centre
    names = ["a", "b", "c", "d"]
    np.testing.assert_allclose(S.resolve_widths(None, D, M), 1.1 * np.median([1, 1, 2, 4]))
    np.testing.assert_allclose(S.resolve_widths(2.0, D, M), np.full(C, 2.0))
    w = S.resolve_widths([1, 2, 3, 4], D, M)
    np.testing.assert_allclose(w[:4], [1, 2, 3, 4])
    assert w[4] == pytest.approx(S.default_width(D, M))
    np.testing.assert_allclose(S.resolve_widths([1, 2, 3, 4, 5], D, M), [1, 2, 3, 4, 5])
    w = S.resolve_widths({"b": 7.0}, D, M, marker_names=names)
    default = S.default_width(D, M)
    np.testing.assert_allclose(w, [default, 7.0, default, default, default])


def test_resolve_widths_errors():
    D, _ = _line([1.0, 2.0, 4.0])
    names = ["Chin", "Nose", "Brow", "Lip"]
    with pytest.raises(OptionError, match=r"unknown marker\(s\) Chinn; the 4 markers are: Chin, Nose, Brow, Lip"):
        S.resolve_widths({"Chinn": 1.0}, D, 4, marker_names=names)
    with pytest.raises(OptionError, match="needs marker_names"):
        S.resolve_widths({"Chin": 1.0}, D, 4)
    with pytest.raises(OptionError, match="Nose=nan"):
        S.resolve_widths([1.0, np.nan, 1.0, 1.0], D, 4, marker_names=names)
    with pytest.raises(OptionError, match="positive"):
        S.resolve_widths(-1.0, D, 4)
    with pytest.raises(OptionError, match="positive"):
        S.resolve_widths({"Lip": 0.0}, D, 4, marker_names=names)
    with pytest.raises(OptionError, match="4 \\(markers\\) or 4"):
        S.resolve_widths([1.0, 2.0], D, 4)
    with pytest.raises(OptionError, match="expected a number"):
        S.resolve_widths("wide", D, 4)
    with pytest.raises(ComputeError, match="coincide"):
        S.median_marker_spacing(np.zeros((3, 3)))


# ------------------------------------------------------------------------------- per-marker rule
def _plain_local(D, k):
    """Mean of the k smallest off-diagonal pair distances min(D[j, i], D[i, j]) per row, by loops."""
    M = D.shape[0]
    out = []
    for j in range(M):
        d = sorted(min(D[j, i], D[i, j]) for i in range(M) if i != j and np.isfinite(min(D[j, i], D[i, j])))
        out.append(sum(d[:k]) / len(d[:k]))
    return np.array(out)


def test_local_spacing_matches_plain_loops():
    rng = np.random.default_rng(3)
    p = rng.normal(size=(12, 3))
    D = np.linalg.norm(p[:, None] - p[None], axis=2)
    D_asym = D * (1.0 + 0.2 * rng.random(D.shape))  # hybrid-like: rows measured from their own marker
    D_asym[2, 7] = D_asym[7, 2] = np.inf            # an unreachable pair
    for k in (1, 3, 5, 11, 40):
        np.testing.assert_allclose(S.local_marker_spacing(D_asym, k), _plain_local(D_asym, k), rtol=1e-14)
    keep = D_asym.copy()
    S.local_marker_spacing(D_asym, 3)
    np.testing.assert_array_equal(D_asym, keep)
    # on a line the local spacing is exact: markers at 0, 1, 3, 7, 15
    D, _ = _line([1.0, 2.0, 4.0, 8.0])
    np.testing.assert_allclose(S.local_marker_spacing(D, 2), [2.0, 1.5, 2.5, 5.0, 10.0])


def test_local_spacing_errors():
    with pytest.raises(ComputeError, match="at least 2 markers"):
        S.local_marker_spacing(np.zeros((1, 1)), 3)
    with pytest.raises(ComputeError, match=r"1 marker\(s\) \(e\.g\. #2\) have no other marker"):
        D = np.ones((3, 3))
        D[2, :2] = D[:2, 2] = np.inf
        S.local_marker_spacing(D, 3)
    with pytest.raises(OptionError, match="neighbours: expected an integer >= 1"):
        S.local_marker_spacing(np.ones((3, 3)), 0)


def test_width_rules():
    D, _ = _line([1.0, 2.0, 4.0, 8.0])
    Dc = np.zeros((6, 6))   # 5 markers + 1 constraint centre next to marker 0
    Dc[:5, :5] = D
    Dc[5, :5] = Dc[:5, 5] = D[0] + 0.01
    local = np.array([2.0, 1.5, 2.5, 5.0, 10.0])
    np.testing.assert_allclose(S.WidthRule(0.7, 2, per_marker=True).widths(Dc, 5),
                               np.concatenate([0.7 * local, [0.7 * 2.5]]))
    np.testing.assert_allclose(S.WidthRule(1.1).widths(Dc, 5), np.full(6, 2.2))  # the median rule
    assert S.LOCAL_WIDTH_RULE == S.WidthRule(0.7, 3, per_marker=True, name="local")
    assert S.PAPER_WIDTH_RULE.factor == 1.1 and not S.PAPER_WIDTH_RULE.per_marker
    with pytest.raises(OptionError, match="width factor must be a positive number"):
        S.WidthRule(0.0)


def test_transfer_widths_follow_the_metric_and_the_kernel():
    rng = np.random.default_rng(4)
    p = rng.normal(size=(9, 3)) * 2.0
    D = np.linalg.norm(p[:, None] - p[None], axis=2)
    local = _plain_local(D[:8, :8], 3)                     # 8 markers, centre 8 a constraint centre
    w = S.transfer_widths(None, D, 8)
    np.testing.assert_allclose(w, np.concatenate([0.7 * local, [0.7 * np.median(local)]]))
    # metric-aware: distances 15% longer (edge paths) give widths 15% wider
    np.testing.assert_allclose(S.transfer_widths(None, 1.15 * D, 8), 1.15 * w)
    # growing kernels: one width, 0.1 (multiquadric) or 1 (thin-plate, cubic) x the median spacing
    h = S.median_marker_spacing(D[:8, :8])
    np.testing.assert_allclose(S.transfer_widths(None, D, 8, kernel="mq"), np.full(9, 0.1 * h))
    np.testing.assert_allclose(S.transfer_widths(None, D, 8, kernel="thin_plate_spline"), np.full(9, h))
    # paper mode: 1.1 x the Euclidean median spacing of the bound points, whatever D_cc is
    hp = S.median_marker_spacing_from_points(p[:8])
    np.testing.assert_allclose(S.transfer_widths(None, 3.0 * D, 8, mode="paper", marker_points=p[:8]),
                               np.full(9, 1.1 * hp))
    # a partial dict keeps the per-marker default for the other centres
    names = [f"m{j}" for j in range(8)]
    w2 = S.transfer_widths({"m3": 9.0}, D, 8, marker_names=names)
    np.testing.assert_allclose(np.delete(w2, 3), np.delete(w, 3))
    assert w2[3] == 9.0
    np.testing.assert_allclose(S.transfer_widths(2.0, D, 8), np.full(9, 2.0))
    with pytest.raises(OptionError, match="mode: expected interpolate or paper"):
        S.transfer_widths(None, D, 8, mode="exact")
