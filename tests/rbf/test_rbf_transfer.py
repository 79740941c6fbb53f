"""RBFTransfer: interpolation exactness, paper Eqs. 1-5, validity patterns, conditioning, streaming."""
from __future__ import annotations

import dataclasses
import warnings

import numpy as np
import pytest

from usdface.errors import ComputeError, InputError, OptionError
from usdface.rbf import KERNELS, RBFCentres, RBFSettings, RBFTransfer, transfer_motion

MESH = "meshes/makehuman_hm08_face_cm.obj"


_SETTINGS = {f.name for f in dataclasses.fields(RBFSettings)}


def _rbf(D_vc, D_cc, **options):
    """RBFTransfer from the keywords of RBFSettings and RBFCentres (the tests' shorthand)."""
    settings = RBFSettings(**{k: v for k, v in options.items() if k in _SETTINGS})
    centres = RBFCentres(**{k: v for k, v in options.items() if k not in _SETTINGS})
    return RBFTransfer(D_vc, D_cc, settings=settings, centres=centres)


# ---------------------------------------------------------------------------------------- data
def _read_obj_vertices(path):
    """Tiny OBJ reader: the 'v x y z' lines only."""
    with open(path) as fh:
        return np.array([[float(t) for t in line.split()[1:4]] for line in fh if line.startswith("v ")])


def _farthest_points(points, k, start=0):
    chosen = [start]
    d = np.linalg.norm(points - points[start], axis=1)
    for _ in range(k - 1):
        chosen.append(int(np.argmax(d)))
        d = np.minimum(d, np.linalg.norm(points - points[chosen[-1]], axis=1))
    return np.array(chosen)


def _sphere_patch(n, seed=0):
    """Points on a 10 cm sphere cap about 18 cm across (a face-sized patch), cm."""
    rng = np.random.default_rng(seed)
    v = rng.normal(size=(4 * n, 3))
    v /= np.linalg.norm(v, axis=1, keepdims=True)
    v = v[v[:, 2] > 0.45][:n]
    return 10.0 * v


def _euclid(a, b):
    return np.linalg.norm(a[:, None, :] - b[None, :, :], axis=2)


class Face:
    """Vertices (cm), 41 marker vertices by farthest-point sampling, constraint centres on the rim."""

    def __init__(self, vertices, n_markers=41, n_constraints=8):
        self.V = vertices
        self.markers = _farthest_points(vertices, n_markers)
        centre = vertices.mean(axis=0)
        r = np.linalg.norm((vertices - centre)[:, :2], axis=1)
        rim = np.flatnonzero(r >= np.quantile(r, 0.97))
        rim = rim[~np.isin(rim, self.markers)]
        self.constraints = rim[_farthest_points(vertices[rim], n_constraints)]
        self.centres = np.concatenate([self.markers, self.constraints])
        self.C = vertices[self.centres]
        self.D_vc = _euclid(vertices, self.C)
        self.D_cc = _euclid(self.C, self.C)
        self.M = n_markers
        self.names = [f"m{j:02d}" for j in range(n_markers)]


@pytest.fixture(scope="module")
def face(repo_root):
    path = repo_root.parent / "shared" / "data" / MESH
    vertices = _read_obj_vertices(path) if path.is_file() else _sphere_patch(2000)
    return Face(vertices)


def _motion(F, M, seed=1, amplitude=1.0):
    """Smooth per-marker displacement curves (cm), F frames."""
    rng = np.random.default_rng(seed)
    t = np.linspace(0, 1, F)[:, None, None]
    a, w, p = rng.normal(size=(3, 1, M, 3))
    return amplitude * a * np.sin(2 * np.pi * (1 + 2 * np.abs(w)) * t + p)


def _with_gaps(D, seed=2):
    """Some invalid samples: single markers, a pair, a repeated pattern; returns a copy."""
    D = D.copy()
    D[3, 5] = np.nan
    D[4, 5, 1] = np.nan  # one NaN component invalidates the marker
    D[7, [0, 17]] = np.nan
    D[10:14, 30] = np.nan
    D[15, [2, 3, 4]] = np.inf
    return D


def _rel_err(a, b):
    return np.max(np.abs(a - b)) / np.max(np.abs(b))


# ---------------------------------------------------------------------------------------- interpolate
@pytest.mark.parametrize("polynomial", [False, True])
@pytest.mark.parametrize("kernel", list(KERNELS))
def test_interpolate_reproduces_markers(face, kernel, polynomial):
    D = _with_gaps(_motion(20, face.M))
    keep = D.copy()
    rbf = _rbf(face.D_vc, face.D_cc, kernel=kernel, polynomial=polynomial, n_markers=face.M,
                      centre_points=face.C, vertex_points=face.V).fit()
    out64 = rbf.apply(D, dtype=np.float64)
    np.testing.assert_array_equal(D, keep)  # input untouched
    assert out64.shape == (20, len(face.V), 3) and out64.dtype == np.float64
    at_markers = out64[:, face.markers]
    valid = np.isfinite(D).all(axis=2)
    scale = np.nanmax(np.abs(np.where(np.isfinite(D), D, np.nan)))
    assert np.max(np.abs(at_markers[valid] - D[valid])) <= 1e-5 * scale
    assert np.max(np.abs(out64[:, face.constraints])) <= 1e-5 * scale  # constraint centres stay put
    assert np.isfinite(out64).all()  # invalid markers got interpolated values, never NaN
    out32 = rbf.apply(D)
    assert out32.dtype == np.float32
    assert _rel_err(out32, out64) < 1e-4


@pytest.mark.parametrize("polynomial", [False, True])
def test_invalid_pattern_equals_refactorised_solve(face, polynomial):
    """The cached pattern operator equals dropping the invalid centres and solving from scratch."""
    D = _with_gaps(_motion(20, face.M))
    w = np.linspace(3.0, 5.0, len(face.centres))  # per-centre widths
    rbf = _rbf(face.D_vc, face.D_cc, widths=w, polynomial=polynomial, n_markers=face.M,
                      centre_points=face.C, vertex_points=face.V, regularization=1e-9)
    out = rbf.apply(D, dtype=np.float64)
    M, C = face.M, len(face.centres)
    for f in [3, 7, 12, 15]:
        valid = np.isfinite(D[f]).all(axis=1)
        keep = np.concatenate([np.flatnonzero(valid), np.arange(M, C)])
        A = np.exp(-((face.D_cc[np.ix_(keep, keep)] / w[keep]) ** 2)) + 1e-9 * np.eye(keep.size)
        Phi = np.exp(-((face.D_vc[:, keep] / w[keep]) ** 2))
        rhs = np.zeros((keep.size, 3))
        rhs[: valid.sum()] = D[f][valid]
        if polynomial:
            P = np.hstack([np.ones((keep.size, 1)), face.C[keep]])
            A = np.block([[A, P], [P.T, np.zeros((4, 4))]])
            Phi = np.hstack([Phi, np.ones((len(face.V), 1)), face.V])
            rhs = np.vstack([rhs, np.zeros((4, 3))])
        expected = Phi @ np.linalg.solve(A, rhs)
        assert _rel_err(out[f], expected) < 1e-8, f


def test_matches_scipy_rbfinterpolator(face):
    scipy_interp = pytest.importorskip("scipy.interpolate")
    D = _motion(5, face.M)
    s = 3.0
    for polynomial, degree in [(False, -1), (True, 1)]:
        rbf = _rbf(face.D_vc[:, : face.M], face.D_cc[: face.M, : face.M], widths=s, polynomial=polynomial,
                          centre_points=face.C[: face.M], vertex_points=face.V)
        ours = rbf.apply(D, dtype=np.float64)
        values = D.transpose(1, 0, 2).reshape(face.M, -1)
        ref = scipy_interp.RBFInterpolator(face.C[: face.M], values, kernel="gaussian", epsilon=1 / s,
                                           degree=degree)(face.V)
        ref = ref.reshape(len(face.V), 5, 3).transpose(1, 0, 2)
        assert _rel_err(ours, ref) < 1e-8


def test_polynomial_reproduces_affine_motion(face):
    rng = np.random.default_rng(5)
    L, t = 0.05 * rng.normal(size=(3, 3)), rng.normal(size=3)
    markers = face.C[: face.M]
    D = (markers @ L.T + t)[None]
    for kernel in ["thin_plate_spline", "gaussian", "cubic"]:
        rbf = _rbf(face.D_vc[:, : face.M], face.D_cc[: face.M, : face.M], kernel=kernel, polynomial=True,
                          centre_points=markers, vertex_points=face.V)
        out = rbf.apply(D, dtype=np.float64)[0]
        np.testing.assert_allclose(out, face.V @ L.T + t, atol=1e-7)


def test_asymmetric_centre_distances_still_exact(face):
    """Row j of D_cc is measured from centre j; vertices with that row get exactly centre j's value."""
    rng = np.random.default_rng(3)
    D_cc = face.D_cc * (1 + 0.2 * rng.random(face.D_cc.shape))
    np.fill_diagonal(D_cc, 0.0)
    assert not np.allclose(D_cc, D_cc.T)
    D_vc = face.D_vc.copy()
    D_vc[face.centres] = D_cc
    D = _with_gaps(_motion(16, face.M))
    rbf = _rbf(D_vc, D_cc, n_markers=face.M, kernel="inverse_multiquadric")
    out = rbf.apply(D, dtype=np.float64)
    valid = np.isfinite(D).all(axis=2)
    assert np.max(np.abs(out[:, face.markers][valid] - D[valid])) < 1e-9


def test_transfer_matrix_is_skin_weights(face):
    rbf = _rbf(face.D_vc, face.D_cc, n_markers=face.M)
    B = rbf.transfer_matrix
    assert B.shape == (len(face.V), face.M) and not B.flags.writeable
    D = _motion(3, face.M)
    np.testing.assert_allclose(rbf.apply(D, dtype=np.float64)[1], B @ D[1], rtol=0, atol=1e-12)
    # single frame form
    np.testing.assert_allclose(rbf.apply(D[1], dtype=np.float64), B @ D[1], rtol=0, atol=1e-12)
    np.testing.assert_allclose(B[face.markers], np.eye(face.M), atol=1e-9)


# ---------------------------------------------------------------------------------------- paper mode
def _paper_reference(D_vc, D_cc, M, widths, D):
    """Eqs. 1-5 with explicit loops: W_j = D_j / sum_k phi_k(d_jk); Dv_i = sum_j W_j phi_j(d_ij)."""
    F, N = D.shape[0], D_vc.shape[0]
    out = np.zeros((F, N, 3))
    for f in range(F):
        valid = [j for j in range(M) if all(np.isfinite(D[f, j]))]
        W = {}
        for j in valid:
            total = 0.0
            for k in valid:
                total += np.exp(-(D_cc[j, k] ** 2) / widths[k] ** 2)
            W[j] = [D[f, j, c] / total for c in range(3)]
        for i in range(N):
            for j in valid:
                phi = np.exp(-(D_vc[i, j] ** 2) / widths[j] ** 2)
                for c in range(3):
                    out[f, i, c] += W[j][c] * phi
    return out


@pytest.mark.parametrize("widths", ["uniform", "per_marker"])
def test_paper_mode_equals_plain_loops(widths):
    rng = np.random.default_rng(11)
    V = _sphere_patch(40, seed=4)
    M, P = 7, 2
    centres = _farthest_points(V, M + P)
    D_vc, D_cc = _euclid(V, V[centres]), _euclid(V[centres], V[centres])
    D_cc = D_cc * (1 + 0.1 * rng.random(D_cc.shape))  # asymmetric, like the hybrid distance
    np.fill_diagonal(D_cc, 0.0)
    w = np.full(M + P, 2.0) if widths == "uniform" else rng.uniform(1.5, 4.0, M + P)
    D = rng.normal(size=(6, M, 3))
    D[2, 3] = np.nan
    D[4, [0, 5]] = np.nan
    rbf = _rbf(D_vc, D_cc, mode="paper", widths=w, n_markers=M)
    out = rbf.apply(D, dtype=np.float64)
    ref = _paper_reference(D_vc, D_cc, M, w, D)
    assert np.max(np.abs(out - ref)) <= 1e-6 * np.max(np.abs(ref))
    assert _rel_err(rbf.apply(D), ref) < 1e-5  # float32 path
    # constraint centres do nothing in paper mode
    alone = _rbf(D_vc[:, :M], D_cc[:M, :M], mode="paper", widths=w[:M]).apply(D, dtype=np.float64)
    np.testing.assert_allclose(out, alone, rtol=0, atol=1e-12)
    assert rbf.condition_number is None and rbf.advice is None


def test_paper_mode_does_not_interpolate(face):
    D = _motion(4, face.M)
    out = _rbf(face.D_vc, face.D_cc, mode="paper", widths=2.0, n_markers=face.M).apply(D, dtype=np.float64)
    assert _rel_err(out[:, face.markers], D) > 1e-3  # documented: the paper's weights are not solved


# ---------------------------------------------------------------------------------------- patterns and policies
def test_validity_pattern_cache_counts(face):
    D = _with_gaps(_motion(20, face.M))
    rbf = _rbf(face.D_vc, face.D_cc, n_markers=face.M).fit()
    assert rbf.cache_info() == {"hits": 0, "misses": 0, "patterns": 1}  # all-valid, from fit()
    rbf.apply(D)
    # partial frames: 3, 4 (same pattern), 7, 10-13 (same), 15 -> 4 patterns, 8 frames
    assert rbf.cache_info() == {"hits": 4, "misses": 4, "patterns": 5}
    list(rbf.iter_chunks(D, chunk_frames=3))
    assert rbf.cache_info() == {"hits": 12, "misses": 4, "patterns": 5}
    rbf.clear_cache()
    assert rbf.cache_info() == {"hits": 0, "misses": 0, "patterns": 1}


def test_all_invalid_policies(face):
    D = _motion(9, face.M)
    D[[0, 4, 5]] = np.nan
    rbf = _rbf(face.D_vc, face.D_cc, n_markers=face.M)
    with pytest.raises(ComputeError, match=r"3 frame\(s\) have no valid marker: frame index\(es\) 0, 4, 5 of 9") as info:
        rbf.iter_chunks(D)  # raised at the call, before any output
    assert info.value.frames == [0, 4, 5]
    zero = _rbf(face.D_vc, face.D_cc, n_markers=face.M, all_invalid="zero").apply(D)
    assert not zero[[0, 4, 5]].any()
    hold_rbf = _rbf(face.D_vc, face.D_cc, n_markers=face.M, all_invalid="hold")
    for chunk_frames in (None, 1, 4, 5):  # the held frame crosses chunk boundaries
        hold = hold_rbf.apply(D, chunk_frames=chunk_frames)
        assert not hold[0].any()  # nothing to hold yet
        tol = dict(rtol=0, atol=1e-6 * np.abs(hold).max())  # float32 GEMM rounding differs by row block
        np.testing.assert_allclose(hold[4], hold[3], **tol)
        np.testing.assert_allclose(hold[5], hold[3], **tol)
        np.testing.assert_allclose(hold[6], zero[6], **tol)


def test_streaming_chunks_equal_one_shot(face):
    D = _with_gaps(_motion(23, face.M))
    rbf = _rbf(face.D_vc, face.D_cc, n_markers=face.M)
    full = rbf.apply(D)
    seen = []
    for frames, chunk in rbf.iter_chunks(D, chunk_frames=7):
        assert chunk.dtype == np.float32 and chunk.flags.c_contiguous
        assert chunk.shape == (frames.stop - frames.start, len(face.V), 3)
        seen.append(chunk)
    assert [c.shape[0] for c in seen] == [7, 7, 7, 2]
    np.testing.assert_allclose(np.concatenate(seen), full, rtol=1e-6, atol=1e-6 * np.abs(full).max())
    reused = []
    for frames, chunk in rbf.iter_chunks(D, chunk_frames=7, reuse_buffer=True):
        reused.append((chunk.copy(), chunk.__array_interface__["data"][0]))
    assert len({ptr for _, ptr in reused}) == 1  # one buffer, overwritten chunk after chunk
    np.testing.assert_array_equal(np.concatenate([c for c, _ in reused]), np.concatenate(seen))
    threads = rbf.apply(D, blas_threads=1)
    np.testing.assert_allclose(threads, full, rtol=1e-6, atol=1e-6 * np.abs(full).max())
    assert transfer_motion(face.D_vc, face.D_cc, D, centres=RBFCentres(n_markers=face.M)).shape == full.shape


def test_offset_and_extents_inside_the_product(face):
    """offset= adds the rest points inside the GEMM and extents= gives each frame's bounding box:
    the same as adding and reducing afterwards (float32 rounding), in float64 too."""
    D = _with_gaps(_motion(19, face.M))
    rbf = _rbf(face.D_vc, face.D_cc, n_markers=face.M)
    rest = np.asarray(face.V, dtype=np.float64) + np.array([3.0, -80.0, 12.0])   # far from the origin
    for dtype, rtol in ((np.float32, 1e-6), (np.float64, 1e-12)):
        ref = rbf.apply(D, dtype=np.float64) + rest[None]
        got, boxes = [], []
        for frames, pts, box in rbf.iter_chunks(D, chunk_frames=5, offset=rest, extents=True, dtype=dtype):
            assert pts.dtype == dtype and box.dtype == dtype and box.shape == (pts.shape[0], 2, 3)
            got.append(pts)
            boxes.append(box)
        got, boxes = np.concatenate(got), np.concatenate(boxes)
        np.testing.assert_allclose(got, ref, rtol=0, atol=rtol * np.abs(ref).max())
        np.testing.assert_array_equal(boxes[:, 0], got.min(axis=1))    # the box of what was yielded
        np.testing.assert_array_equal(boxes[:, 1], got.max(axis=1))
    with pytest.raises(InputError, match="offset"):
        next(iter(rbf.iter_chunks(D, offset=rest[:-1])))
    # a ring of 3 buffers: the same values, three distinct buffers reused in turn
    ring = [(c.copy(), c.__array_interface__["data"][0])
            for _, c in rbf.iter_chunks(D, chunk_frames=5, offset=rest, buffers=3, dtype=np.float64)]
    np.testing.assert_array_equal(np.concatenate([c for c, _ in ring]), got)
    assert [p for _, p in ring] == [ring[i % 3][1] for i in range(len(ring))] and len({p for _, p in ring}) == 3
    with pytest.raises(OptionError, match="buffers"):
        rbf.iter_chunks(D, buffers=0)


def test_polynomial_needs_four_non_coplanar_valid_centres():
    V = _sphere_patch(50)
    C = V[:5]
    D = np.zeros((2, 5, 3))
    D[1, :2] = np.nan  # 3 valid centres left
    rbf = _rbf(_euclid(V, C), _euclid(C, C), polynomial=True, centre_points=C, vertex_points=V,
                      marker_names=list("abcde"))
    with pytest.raises(ComputeError, match=r"frame\(s\) 1 with invalid markers 'a', 'b'"):
        rbf.apply(D)


# ---------------------------------------------------------------------------------------- conditioning
def test_condition_number_and_advice_on_coincident_markers(face):
    M = face.M
    good = _rbf(face.D_vc, face.D_cc, n_markers=M, marker_names=face.names)
    assert 1 < good.condition_number < 1e10 and good.advice is None
    # marker 7 duplicated 1e-6 cm away from marker 3 (a binding mistake)
    C = face.C.copy()
    C[7] = C[3] + np.array([1e-6, 0, 0])
    D_cc, D_vc = _euclid(C, C), _euclid(face.V, C)
    bad = _rbf(D_vc, D_cc, n_markers=M, marker_names=face.names)
    with pytest.warns(RuntimeWarning, match="condition number"):
        bad.fit()
    assert bad.condition_number > 1e10
    advice = bad.advice
    assert "'m03' and 'm07'" in advice and "regularization" in advice and "smaller width" in advice
    assert bad.nearly_coincident()[0][:2] == ("'m03'", "'m07'")
    # regularisation is one of the cures
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert _rbf(D_vc, D_cc, n_markers=M, regularization=1e-6).condition_number < 1e10
    # exactly coincident: singular, refused with the same advice
    C[7] = C[3]
    with pytest.raises(ComputeError, match="singular.*'m03' and 'm07'"):
        _rbf(_euclid(face.V, C), _euclid(C, C), n_markers=M, marker_names=face.names).fit()


def test_regularization_residual_grows(face):
    D = _motion(10, face.M)
    residuals = []
    for lam in [0.0, 1e-6, 1e-4, 1e-2, 1e-1, 1.0]:
        rbf = _rbf(face.D_vc, face.D_cc, n_markers=face.M, regularization=lam)
        out = rbf.apply(D, dtype=np.float64)
        residuals.append(np.sqrt(np.mean((out[:, face.markers] - D) ** 2)))
    assert residuals[0] < 1e-10
    assert all(a < b for a, b in zip(residuals, residuals[1:])), residuals
    assert residuals[-1] < np.sqrt(np.mean(D**2))  # still an approximation, not garbage


# ---------------------------------------------------------------------------------------- bad inputs
def test_bad_inputs(face):
    D_vc, D_cc, M = face.D_vc, face.D_cc, face.M
    with pytest.raises(OptionError, match="widths.*m04=nan"):
        _rbf(D_vc, D_cc, n_markers=M, marker_names=face.names, widths={"m04": float("nan")})
    with pytest.raises(OptionError, match="unknown marker.*Chin.*m00, m01"):
        _rbf(D_vc, D_cc, n_markers=M, marker_names=face.names, widths={"Chin": 1.0})
    with pytest.raises(OptionError, match="regularization.*>= 0"):
        _rbf(D_vc, D_cc, n_markers=M, regularization=-1e-3)
    with pytest.raises(OptionError, match="regularization"):
        _rbf(D_vc, D_cc, n_markers=M, regularization=float("nan"))
    with pytest.raises(InputError, match=r"D_cc .* must have shape \(C, C\) = \(49, 49\)"):
        _rbf(D_vc, D_cc[:-1], n_markers=M)
    with pytest.raises(InputError, match="D_vc"):
        _rbf(D_vc[0], D_cc)
    bad = D_vc.copy()
    bad[10, 2] = np.nan
    with pytest.raises(InputError, match=r"D_vc: 1 distance\(s\) are NaN \(e.g. at \(10, 2\)\)"):
        _rbf(bad, D_cc, n_markers=M)
    with pytest.raises(InputError, match="negative"):
        _rbf(-D_vc, D_cc, n_markers=M)
    inf = D_vc.copy()
    inf[0, 0] = np.inf
    _rbf(inf, D_cc, n_markers=M).fit()  # gaussian: unreachable = no influence
    with pytest.raises(ComputeError, match="infinite.*multiquadric"):
        _rbf(inf, D_cc, n_markers=M, kernel="multiquadric")
    with pytest.raises(OptionError, match="n_markers"):
        _rbf(D_vc, D_cc, n_markers=0)
    with pytest.raises(OptionError, match="n_markers"):
        _rbf(D_vc, D_cc, n_markers=D_cc.shape[0] + 1)
    with pytest.raises(OptionError, match="mode"):
        _rbf(D_vc, D_cc, mode="hybrid")
    with pytest.raises(OptionError, match="all_invalid"):
        _rbf(D_vc, D_cc, all_invalid="skip")
    with pytest.raises(OptionError, match="needs centre_points and vertex_points"):
        _rbf(D_vc, D_cc, polynomial=True)
    with pytest.raises(InputError, match=r"vertex_points must have shape \(N, 3\)"):
        _rbf(D_vc, D_cc, polynomial=True, centre_points=face.C, vertex_points=face.V[:10])
    with pytest.raises(OptionError, match="mode='interpolate' only"):
        _rbf(D_vc, D_cc, mode="paper", polynomial=True, centre_points=face.C, vertex_points=face.V)
    with pytest.raises(OptionError, match="mode='interpolate' only"):
        _rbf(D_vc, D_cc, mode="paper", regularization=0.1)
    rbf = _rbf(D_vc, D_cc, n_markers=M)
    with pytest.raises(InputError, match=r"displacements must have shape \(F, M, 3\) = \(F, 41, 3\)"):
        rbf.apply(np.zeros((3, M + 1, 3)))
    with pytest.raises(OptionError, match="chunk_frames"):
        rbf.iter_chunks(np.zeros((3, M, 3)), chunk_frames=0)
    with pytest.raises(OptionError, match="dtype"):
        rbf.apply(np.zeros((3, M, 3)), dtype=np.float16)
    empty = rbf.apply(np.zeros((0, M, 3)))
    assert empty.shape == (0, len(face.V), 3)


# ---------------------------------------------------------------------------------------- the options objects
def test_settings_are_checked_and_normalised_when_made():
    """RBFSettings refuses a bad field before any distance is read, with the transfer's messages,
    and stores the kernel's canonical name, lambda as a float and the polynomial flag as a bool."""
    s = RBFSettings(kernel="inverse-multiquadric", regularization=np.float32(0.5), polynomial=1)
    assert (s.kernel, s.regularization, s.polynomial) == ("inverse_multiquadric", 0.5, True)
    assert type(s.regularization) is float and s.polynomial is True
    with pytest.raises(dataclasses.FrozenInstanceError):
        s.kernel = "gaussian"
    cases = [
        (dict(mode="hybrid"), "mode: expected one of interpolate, paper; got 'hybrid'"),
        (dict(all_invalid="skip"), "all_invalid: expected one of error, hold, zero; got 'skip'"),
        (dict(regularization="much"), "regularization: expected a number >= 0; got 'much'"),
        (dict(regularization=-1e-3), "regularization: expected a finite number >= 0; got -0.001"),
        (dict(mode="paper", polynomial=True),
         "polynomial=True applies to mode='interpolate' only (Eqs. 1-5 have no polynomial term)"),
        (dict(mode="paper", kernel="cubic"),
         "kernel 'cubic' does not decay with distance: paper mode (Eqs. 1-5, no solve) needs one of "
         "gaussian, inverse_multiquadric; use mode='interpolate'"),
        (dict(mode="paper", regularization=0.1),
         "regularization applies to mode='interpolate' only (paper mode solves no system)"),
    ]
    for fields, message in cases:
        with pytest.raises(OptionError) as err:
            RBFSettings(**fields)
        assert str(err.value) == message


def test_centres_are_checked_against_the_distances(face):
    """RBFCentres' sizes come from the distances: the transfer's set-up checks them, with the same
    messages, and keeps the names as a tuple of str."""
    D_vc, D_cc, M = face.D_vc, face.D_cc, face.M
    centres = RBFCentres(n_markers=M, marker_names=face.names)
    assert centres.marker_names == tuple(face.names)
    assert RBFTransfer(D_vc, D_cc, centres=centres).marker_names == tuple(face.names)
    cases = [
        (RBFCentres(n_markers=0), OptionError, "n_markers: expected an integer in 1..49 (the number of centres); got 0"),
        (RBFCentres(n_markers=M, marker_names=face.names[:-1]), OptionError, "marker_names: 40 names for 41 markers"),
        (RBFCentres(n_markers=M, marker_names=["m00"] * M), OptionError, "marker_names: duplicated names m00"),
        (RBFCentres(n_markers=M, collocation=(np.zeros((M, 3), int), np.ones((M, 3)) / 3)), None, None),
        (RBFCentres(n_markers=M, collocation=(np.full((M, 3), len(face.V)), np.ones((M, 3)) / 3)), InputError,
         f"collocation: triangle vertex indices outside 0..{len(face.V) - 1}"),
    ]
    for c, error, message in cases:
        if error is None:
            RBFTransfer(D_vc, D_cc, centres=c)
            continue
        with pytest.raises(error) as err:
            RBFTransfer(D_vc, D_cc, centres=c)
        assert str(err.value) == message
    with pytest.raises(OptionError, match=r"^collocation applies to mode='interpolate' only$"):
        RBFTransfer(D_vc, D_cc, settings=RBFSettings(mode="paper"), centres=cases[3][0])
    with pytest.raises(OptionError, match=r"^settings: expected RBFSettings; got dict$"):
        RBFTransfer(D_vc, D_cc, settings={"kernel": "gaussian"})


def test_a_refused_system_still_reports_its_condition_number(face):
    """fit() refuses a singular system; condition_number then gives what its SVD measured."""
    C = face.C.copy()
    C[7] = C[3]
    D_cc = _euclid(C, C)
    rbf = RBFTransfer(_euclid(face.V, C), D_cc, centres=RBFCentres(n_markers=face.M))
    measured = np.linalg.cond(KERNELS["gaussian"](D_cc, rbf.widths))
    assert rbf.condition_number == measured and 1e15 < measured < np.inf
    with pytest.raises(ComputeError, match="singular"):
        rbf.fit()
    assert rbf.cache_info() == {"hits": 0, "misses": 0, "patterns": 0}


def test_transfer_motion_is_the_fitted_transfer_applied(face):
    D = _with_gaps(_motion(20, face.M))
    settings, centres = RBFSettings(kernel="inverse_multiquadric"), RBFCentres(n_markers=face.M)
    one_call = transfer_motion(face.D_vc, face.D_cc, D, settings=settings, centres=centres, dtype=np.float64)
    solver = RBFTransfer(face.D_vc, face.D_cc, settings=settings, centres=centres).fit()
    assert np.array_equal(one_call, solver.apply(D, dtype=np.float64))


def test_public_names_are_where_they_were():
    import usdface.rbf as rbf
    from usdface.rbf.transfer import ADVICE_CONDITION, RBFTransfer as Direct, transfer_motion as direct_motion

    assert rbf.RBFTransfer is Direct and rbf.transfer_motion is direct_motion
    assert rbf.ADVICE_CONDITION == ADVICE_CONDITION == 1e10
    assert {"RBFSettings", "RBFCentres"} <= set(rbf.__all__) <= set(dir(rbf))
