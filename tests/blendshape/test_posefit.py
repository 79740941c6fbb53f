"""Pose refit: the solve corrects a wrong head stabilisation and a biased rest pose (issue 19, item 3)."""
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from usdface.blendshape.mirror import find_mirror_pairs
from usdface.blendshape.posefit import refit_pose, rigid_corrections
from usdface.blendshape.solver import CurveSolver
from usdface.blendshape.synthetic import layered_weight_curves, observable_shapes
from usdface.blendshape.take import DEFAULT_EXCLUDE, resolve_exclude


def _rigid(angles_deg, axis_seed=0):
    rng = np.random.default_rng(axis_seed)
    axes = rng.normal(size=(len(angles_deg), 3))
    axes /= np.linalg.norm(axes, axis=1, keepdims=True)
    return Rotation.from_rotvec(np.radians(angles_deg)[:, None] * axes).as_matrix()


def test_rigid_corrections_recover_a_rigid_motion_and_shrug_off_one_bad_marker():
    rng = np.random.default_rng(1)
    model = rng.normal(0, 4, (20, 30, 3))
    rot = _rigid(rng.uniform(0, 3, 20))
    t = rng.normal(0, 0.5, (20, 3))
    observed = np.einsum("fij,fmj->fmi", rot, model) + t[:, None]
    valid = np.ones((20, 30), dtype=bool)
    valid[3, :28] = False  # 2 markers: too few, identity
    r, tt = rigid_corrections(model, observed, valid)
    ok = np.arange(20) != 3
    assert np.abs(r[ok] - rot[ok]).max() < 1e-9 and np.abs(tt[ok] - t[ok]).max() < 1e-9
    assert np.array_equal(r[3], np.eye(3)) and np.array_equal(tt[3], np.zeros(3))
    noisy = observed + rng.normal(0, 0.03, observed.shape)
    noisy[:, 7] += 2.0  # one marker the model does not follow, 2 cm off in every frame
    r_plain, _ = rigid_corrections(model, noisy, np.ones((20, 30), dtype=bool))
    from usdface.capture.rigid import fit_rigid_batch, rotation_angle

    r_ls, _, _ = fit_rigid_batch(model, noisy)
    err = rotation_angle(np.einsum("fji,fjk->fik", rot, r_plain))
    err_ls = rotation_angle(np.einsum("fji,fjk->fik", rot, r_ls))
    assert np.median(err) < 0.25 * np.median(err_ls)


@pytest.fixture(scope="module")
def take(makehuman):
    """600 frames on the MakeHuman rig (the tuning rig): layered curves, 0.3 mm noise, 5 still frames."""
    rig, basis = makehuman["rig"], makehuman["basis"]
    w = layered_weight_curves(600, rig.n_shapes, shapes=observable_shapes(rig.names), seed=3)
    rng = np.random.default_rng(4)
    clean = np.einsum("fk,mkd->fmd", w, basis)
    noisy = clean + rng.normal(0, 0.03, clean.shape)
    noisy[rng.random(noisy.shape[:2]) < 0.05] = np.nan
    solver = CurveSolver(basis, names=rig.names, symmetric_pairs=find_mirror_pairs(rig).symmetric_pairs,
                         exclude=resolve_exclude(DEFAULT_EXCLUDE, rig.names))
    q = makehuman["binding"].surface_points(makehuman["mesh"].points)
    return {"w": w, "noisy": noisy, "solver": solver, "q": q, "basis": basis}


def test_a_wrong_stabilisation_is_corrected(take):
    """The markers turned by up to 1.5 degrees that the head never turned (a stabilisation that took
    expression for head motion): the refit finds the turn and the weights come back."""
    w, q, solver = take["w"], take["q"], take["solver"]
    f_n = w.shape[0]
    angles = 1.5 * np.abs(np.sin(np.arange(f_n) / 40.0))
    rot = _rigid(angles, axis_seed=5)
    centre = q.mean(axis=0)
    x = q[None] + take["noisy"]
    turned = np.einsum("fij,fmj->fmi", rot, x - centre) + centre
    d = turned - q[None]
    plain = solver.solve(d, rate=60.0)
    sol, corrected, refit = refit_pose(solver, d, q, rate=60.0, tolerance=2e-3, solve_options={}, head=True)
    err = lambda est: float(np.sqrt(((est - w) ** 2).mean()))  # noqa: E731
    assert refit.rounds >= 2 and refit.corrections.shape == (f_n, 4, 4)
    assert err(sol.weights) < 0.5 * err(plain.weights)
    # the corrections are the turn (up to the error the noise leaves)
    from usdface.capture.rigid import rotation_angle

    residual = rotation_angle(np.einsum("fji,fjk->fik", rot, refit.corrections[:, :3, :3]))
    assert np.median(residual) < 0.25 * np.median(angles)
    # the corrected displacements are the markers taken back by the corrections
    ok = np.isfinite(d).all(axis=2)
    back = np.einsum("fij,fmj->fmi", refit.corrections[:, :3, :3], q[None] + refit.rest_offset[None] + corrected)
    back += refit.corrections[:, None, :3, 3]
    assert np.abs(back[ok] - turned[ok]).max() < 1e-9


def test_a_rest_pose_biased_by_a_slow_start_is_corrected(take):
    """The rest pose averaged over the 5 still frames and the next 11, where an expression starts
    (up to 1 mm RMS): the refit re-averages it over the frames the solve calls neutral."""
    w, q, solver = take["w"], take["q"], take["solver"]
    noisy = take["noisy"]
    rest_bias = np.nanmean(noisy[:16], axis=0)  # the true rest is 0 here
    d = noisy - rest_bias[None]
    plain = solver.solve(d, rate=60.0)
    sol, _, refit = refit_pose(solver, d, q, rate=60.0, tolerance=2e-3, solve_options={}, head=False,
                               rest_frames=(0, 16))
    assert refit.corrections is None and refit.rounds >= 1
    assert set(refit.rest_frames) >= {0, 1, 2, 3, 4} and max(refit.rest_frames) < 10
    rest_error = lambda rest: np.sqrt((rest ** 2).sum(axis=1).mean())  # noqa: E731
    assert rest_error(rest_bias + refit.rest_offset) < 0.6 * rest_error(rest_bias)
    err = lambda est: float(np.sqrt(((est - w) ** 2).mean()))  # noqa: E731
    assert err(sol.weights) < 0.5 * err(plain.weights)
    # a one-frame neutral has nothing to refit; no rounds at all without head or stretch
    one = refit_pose(solver, d, q, rate=60.0, tolerance=2e-3, solve_options={}, head=False, rest_frames=(0, 1))[2]
    assert one.rounds == 0 and one.rest_frames == [] and not one.rest_offset.any()


def test_solve_take_refits_a_stabilised_take_and_its_head_motion(makehuman, sample_assets):
    """A take without head motion, stabilised as `usdface solve` does (the stabilisation takes
    expression for head motion): with the pose refit the weights are nearer the truth and the
    delivered head motion nearer the identity it really is."""
    from usdface.blendshape.parameters import TakeParameters
    from usdface.blendshape.take import solve_take
    from usdface.model.capture import Capture
    from usdface.capture.neutral import set_rest_pose
    from usdface.capture.rigid import rotation_angle
    from usdface.capture.stabilize import stabilize
    from usdface.mesh.binding import bind_layout
    from usdface.mesh.layout import read_layout

    rig, basis, binding = makehuman["rig"], makehuman["basis"], makehuman["binding"]
    w = layered_weight_curves(900, rig.n_shapes, shapes=observable_shapes(rig.names), seed=11)
    rng = np.random.default_rng(12)
    q = binding.surface_points(makehuman["mesh"].points)
    pos = q[None] + np.einsum("fk,mkd->fmd", w, basis) + rng.normal(0, 0.03, (900, binding.n_markers, 3))
    cap = Capture(binding.names, pos, 60.0, units="cm", source="synthetic")
    cap, _ = set_rest_pose(stabilize(cap)[0])
    bound = bind_layout(makehuman["mesh"], read_layout(sample_assets / "layouts" / "makehuman_hm08_face.layout.json"),
                        cap)
    before = solve_take(rig, cap, bound, TakeParameters(pose_refit=0))
    after = solve_take(rig, cap, bound)
    unstabilised, _ = set_rest_pose(Capture(binding.names, pos, 60.0, units="cm", source="synthetic"))
    oracle = solve_take(rig, unstabilised, bind_layout(makehuman["mesh"], read_layout(
        sample_assets / "layouts" / "makehuman_hm08_face.layout.json"), unstabilised))  # the head pose known
    err = lambda res: float(np.sqrt(((res.weights - w) ** 2).mean()))  # noqa: E731
    assert after.pose_refit["rounds"] >= 2 and "headAngleDegMedian" in after.pose_refit
    rest = after.pose_refit["restFrames"]
    assert len(rest) >= 2 and set(rest) <= {0, 1, 2, 3, 4}  # still frames, never the ramp's first (5, 6)
    assert before.pose_refit["rounds"] == 0
    assert err(before) > 1.05 * err(oracle) and err(after) < 1.05 * err(oracle)
    def turn(res):
        """Median turn of the delivered head about its mean pose (the true head never turns; the pose
        every frame shares is the neutral frame's, whose noise the stabilisation's reference keeps)."""
        from scipy.spatial.transform import Rotation

        rot = res.head_motion[:, :3, :3]
        mean = Rotation.from_matrix(rot).mean().as_matrix()
        return np.median(rotation_angle(np.matmul(mean.T[None], rot)))

    assert turn(after) < 0.35 * turn(before)
    # what the curves layer shows: the rig posed by the weights, moved by the head motion, lands on
    # the markers (mesh space) as well as the refit's model does
    ok = np.isfinite(after.displacements).all(axis=2)
    posed = q[None] + np.einsum("fk,mkd->fmd", after.weights, basis)
    world = np.einsum("fij,fmj->fmi", after.head_motion[:, :3, :3], posed) + after.head_motion[:, None, :3, 3]
    markers = np.einsum("ij,fmj->fmi", bound.capture_to_mesh[:3, :3], cap.world_positions()) \
        + bound.capture_to_mesh[:3, 3]
    rest_world = np.einsum("ij,mj->mi", bound.capture_to_mesh[:3, :3], cap.neutral) + bound.capture_to_mesh[:3, 3]
    # compare displacements (the binding's bound points and the capture's rest differ by the fit residual)
    miss_after = np.linalg.norm((world - q[None]) - (markers - rest_world[None]), axis=2)[ok]
    posed0 = q[None] + np.einsum("fk,mkd->fmd", before.weights, basis)
    world0 = np.einsum("fij,fmj->fmi", before.head_motion[:, :3, :3], posed0) + before.head_motion[:, None, :3, 3]
    miss_before = np.linalg.norm((world0 - q[None]) - (markers - rest_world[None]), axis=2)[ok]
    assert np.median(miss_after) < np.median(miss_before)
    from usdface.errors import OptionError

    for bad in (-1, 1.5, True):
        with pytest.raises(OptionError, match=r"^--pose-refit .*: expected a whole number >= 0$"):
            TakeParameters(pose_refit=bad)
