"""`usdface skel`: UsdSkel joints and weights from the transfer, checked against the point cache."""
from __future__ import annotations

import json

import numpy as np
import pytest
from pxr import Sdf, Usd, UsdGeom, UsdSkel

from usdface.skel import full_weights, joint_names, prune_weights, skinning_error
from usdface.skel.joints import rotation_to_quaternion, sanitize_identifier
from usdface.skel.weights import motion_gram
from usdface.usd.skel_layer import read_skel_report, skinned_points


CM_TOL = 1e-4  # cm: UsdSkel skinning (float32) against the point cache


def _skel(ucli, jaw, out, *extra, capture=None):
    code = ucli("skel", "--mesh", jaw["mesh"], "--capture", capture or jaw["capture"], "--binding",
                jaw["binding"], "--analysis", jaw["analysis"], "-o", out, "-q", *extra)
    assert code == 0
    return read_skel_report(out)


@pytest.fixture(scope="module")
def skel_all(ucli, jaw):
    out = jaw["dir"] / "skel_all_still.usdc"
    return out, _skel(ucli, jaw, out, "--max-influences", "all", "--no-head-motion", "--no-verify")


@pytest.fixture(scope="module")
def skel_default(ucli, jaw):
    out = jaw["dir"] / "skel_default.usdc"
    return out, _skel(ucli, jaw, out)


def test_all_weights_reproduce_the_point_cache_with_usdskel(skel_all, jaw, points_of):
    out, report = skel_all
    times, skinned = skinned_points(out)  # UsdSkel.SkeletonQuery + SkinningQuery.ComputeSkinnedPoints
    cache = points_of(jaw["anim"])
    assert skinned.shape == cache.shape == (1590, 2020, 3)
    err = np.linalg.norm(skinned - cache, axis=2)
    print(f"UsdSkel skinning, all {report['maxInfluences']} weights, vs anim.usdc: max {err.max():.3g} cm, "
          f"mean {err.mean():.3g} cm")
    assert err.max() < CM_TOL
    assert report["pointCacheError"]["all"]["max"] < 1e-9  # the float64 algebra is exact


def test_head_motion_moves_the_point_cache_rigidly(ucli, jaw, points_of):
    from usdface.usd.capture_layer import read_capture_layer
    from usdface.usd.layers import open_stage
    from usdface.usd.mesh_layer import read_binding
    from usdface.skel import head_motion_in_mesh_space

    out = jaw["dir"] / "skel_all_head.usdc"
    report = _skel(ucli, jaw, out, "--max-influences", "all", "--no-verify")
    assert report["headMotion"]
    cap = read_capture_layer(jaw["capture"])
    b = read_binding(open_stage(jaw["binding"]))
    rel = np.einsum("ij,fjk->fik", np.linalg.inv(cap.head_motion[cap.neutral_frame]), cap.head_motion)
    h = head_motion_in_mesh_space(rel, b.capture_to_mesh)
    frames = np.arange(0, 1590, 53)
    _, skinned = skinned_points(out, times=frames.tolist())
    cache = points_of(jaw["anim"])[frames]
    moved = np.einsum("fij,fnj->fni", h[frames, :3, :3], cache) + h[frames, None, :3, 3]
    err = np.linalg.norm(skinned - moved, axis=2).max()
    print(f"UsdSkel skinning with head motion vs head-moved point cache: max {err:.3g} cm")
    assert err < CM_TOL
    # the head really moves (the test would be vacuous otherwise), and rests on the neutral frame
    assert np.abs(h[:, :3, 3]).max() > 0.1
    assert np.allclose(h[cap.neutral_frame], np.eye(4), atol=1e-9)


def test_pruned_weights_report_their_error(skel_default, jaw):
    out, report = skel_default
    errs = report["pointCacheError"]
    print("point-cache error by influences (cm):", json.dumps({k: round(v["max"], 4) for k, v in errs.items()}),
          "rms:", json.dumps({k: round(v["rms"], 5) for k, v in errs.items()}))
    assert set(errs) >= {"all", "4", "8"}
    assert errs["all"]["max"] < 1e-9 < errs["8"]["max"] < errs["4"]["max"]
    assert errs["8"]["max"] < 0.2 and errs["8"]["rms"] < 0.02  # cm, on a take moving vertices up to 5 cm
    stage = Usd.Stage.Open(str(out))
    binding = UsdSkel.BindingAPI(stage.GetPrimAtPath("/Face/Geom"))
    assert binding.GetJointIndicesPrimvar().GetElementSize() == 8
    assert binding.GetJointWeightsPrimvar().GetElementSize() == 8
    w = np.asarray(binding.GetJointWeightsPrimvar().Get()).reshape(-1, 8)
    assert np.allclose(w.sum(axis=1), 1.0, atol=1e-6)
    assert report["headMotion"]


def test_lsq_refit_beats_plain_renormalising(jaw, ucli):
    out = jaw["dir"] / "skel_renorm.usdc"
    renorm = _skel(ucli, jaw, out, "--weight-fit", "renormalize", "--no-verify")
    lsq = read_skel_report(jaw["dir"] / "skel_default.usdc") if (jaw["dir"] / "skel_default.usdc").exists() else None
    if lsq is None:
        pytest.skip("default layer not written")
    for k in ("4", "8"):
        print(f"K={k}: renormalize max {renorm['pointCacheError'][k]['max']:.3g} cm, "
              f"lsq max {lsq['pointCacheError'][k]['max']:.3g} cm")
        assert lsq["pointCacheError"][k]["rms"] < renorm["pointCacheError"][k]["rms"]


def test_layer_passes_usdface_check_and_usdskel_validation(skel_default, ucli):
    from usdface.usd.validation import check_layer
    from pxr import UsdValidation

    out, _ = skel_default
    assert ucli("check", out, "-q") == 0
    findings = check_layer(out)
    assert not [f for f in findings if f.severity == "error"], findings
    names = [v.GetMetadata().name for v in UsdValidation.ValidationRegistry().GetOrLoadAllValidators()]
    assert any(n.startswith("usdSkelValidators:") for n in names)  # they ran as part of the check
    stage = Usd.Stage.Open(str(out))
    roots = [p for p in stage.Traverse() if p.IsA(UsdSkel.Root)]
    assert [str(p.GetPath()) for p in roots] == ["/Face"]
    assert stage.GetTimeCodesPerSecond() == 60 and stage.GetFramesPerSecond() == 60
    assert stage.GetRootLayer().HasTimeCodesPerSecond() and stage.GetRootLayer().HasFramesPerSecond()
    skel = UsdSkel.Skeleton(stage.GetPrimAtPath("/Face/Skeleton"))
    joints = list(skel.GetJointsAttr().Get())
    assert joints[0] == "Head" and all(j.startswith("Head/") for j in joints[1:]) and len(joints) == 42
    assert all(Sdf.Path.IsValidIdentifier(j.split("/")[-1]) for j in joints)
    anim = UsdSkel.Animation(stage.GetPrimAtPath("/Face/Skeleton/Anim"))
    for attr in (anim.GetTranslationsAttr(), anim.GetRotationsAttr(), anim.GetScalesAttr()):
        assert len(attr.GetTimeSamples()) == 1590
    cache = UsdSkel.Cache()
    cache.Populate(UsdSkel.Root(roots[0]), Usd.TraverseInstanceProxies())
    q = cache.GetSkelQuery(skel)
    assert q and q.HasBindPose() and q.HasRestPose() and q.GetAnimQuery()


def test_missing_markers_follow_the_resolved_transfer(ucli, jaw, points_of):
    out = jaw["dir"] / "skel_gaps.usdc"
    report = _skel(ucli, jaw, out, "--max-influences", "all", "--no-head-motion", "--no-verify",
                   capture=jaw["gaps"])
    assert report["framesResolved"] == 65
    frames = [0, 400, 415, 445, 459, 460, 902, 1200]
    _, skinned = skinned_points(out, times=frames)
    cache = points_of(jaw["anim_gaps"])[frames]
    err = np.linalg.norm(skinned - cache, axis=2).max()
    print(f"frames with missing markers: UsdSkel vs re-solved point cache max {err:.3g} cm")
    assert err < CM_TOL
    # and those frames really differ from the full-capture transfer (the markers were missing)
    assert np.linalg.norm(cache[2] - points_of(jaw["anim"])[415], axis=1).max() > 1e-3


def test_bad_options_fail_cleanly_and_write_nothing(ucli, jaw, capsys):
    out = jaw["dir"] / "never.usdc"
    code = ucli("skel", "--mesh", jaw["mesh"], "--capture", jaw["capture"], "--binding", jaw["binding"],
                "--analysis", jaw["analysis"], "--max-influences", "0", "-o", out)
    assert code == 2 and "--max-influences" in capsys.readouterr().err
    assert not out.exists() and not list(jaw["dir"].glob(".never*"))


# -- pure functions ---------------------------------------------------------------------------------

def test_joint_names_are_valid_identifiers_with_a_mapping():
    names, mapping = joint_names(["Lip.Upper-1", "3D", "a.b", "a_b", "Head", "Chin"])
    assert names == ["Lip_Upper_1", "_3D", "a_b", "a_b_2", "Head_2", "Chin"]
    assert all(Sdf.Path.IsValidIdentifier(n) for n in names)
    assert mapping == {"Lip_Upper_1": "Lip.Upper-1", "_3D": "3D", "a_b": "a.b", "a_b_2": "a_b", "Head_2": "Head"}
    assert sanitize_identifier("") == "_"


def test_weights_algebra_on_random_transfer():
    rng = np.random.default_rng(7)
    n, m, f = 300, 12, 80
    b = rng.normal(scale=0.3, size=(n, m))
    d = rng.normal(size=(f, m, 3))
    rest = rng.normal(scale=50, size=(n, 3))
    full = full_weights(b)
    assert np.allclose(full.sum(axis=1), 1.0)
    exact = prune_weights(full, None)
    assert skinning_error(exact, b, d, rest)["max"] < 1e-10
    gram = motion_gram(d)
    lsq = prune_weights(full, 4, gram=gram)
    ren = prune_weights(full, 4, fit="renormalize")
    assert np.allclose(lsq.weights.sum(axis=1), 1.0) and np.allclose(ren.weights.sum(axis=1), 1.0)
    assert skinning_error(lsq, b, d, rest)["rms"] < skinning_error(ren, b, d, rest)["rms"]
    clamped = prune_weights(full, 4, gram=gram, negative="clamp")
    assert (clamped.weights >= 0).all() and np.allclose(clamped.weights.sum(axis=1), 1.0)
    # numpy LBS with the dense weights equals the error formula
    dense = lsq.dense(m + 1)
    skinned = rest[None] + np.einsum("nj,fjc->fnc", dense[:, 1:], d)
    cache = rest[None] + np.einsum("nm,fmc->fnc", b, d)
    assert abs(np.linalg.norm(skinned - cache, axis=2).max() - skinning_error(lsq, b, d, rest)["max"]) < 1e-9


def test_quaternions_match_scipy():
    from scipy.spatial.transform import Rotation

    r = Rotation.random(50, random_state=3)
    q = rotation_to_quaternion(r.as_matrix())
    ref = r.as_quat()[:, [3, 0, 1, 2]]
    ref[ref[:, 0] < 0] *= -1
    assert np.allclose(q, ref, atol=1e-12)
