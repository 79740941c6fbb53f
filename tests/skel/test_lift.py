"""`usdface lift`: 2D tracks (the real Jaw capture projected by a camera) back to 3D on the mesh."""
from __future__ import annotations

import numpy as np
import pytest

from usdface.capture.lift import fit_weak_perspective
from usdface.io.csv_format import write_csv

PX_PER_CM = 40.0


def _truth(jaw):
    """Marker positions the transfer sees (bound point + retargeted displacement), mesh space."""
    from usdface.capture.retarget import marker_displacements
    from usdface.usd.capture_layer import read_capture_layer
    from usdface.usd.layers import open_stage
    from usdface.usd.mesh_layer import read_binding, read_mesh_layer

    # the lift measures from the tracks' neutral frame: the truth is the capture with that frame as
    # its rest pose (the real capture's rest pose is averaged over its still stretch)
    cap = read_capture_layer(jaw["capture"]).replace(neutral_window=None)
    mesh, _ = read_mesh_layer(jaw["mesh"])
    b = read_binding(open_stage(jaw["binding"]))
    disp = marker_displacements(cap, b.names, b.displacement_transform())
    return cap, b.surface_points(mesh.points), disp


def _tracks(cap, q, *, pinhole_cm=None):
    """Front camera looking down -z at the face, pixels with y down: orthographic, or a pinhole
    ``pinhole_cm`` in front of the face."""
    x, y, z = q[..., 0], q[..., 1], q[..., 2]
    s = PX_PER_CM if pinhole_cm is None else PX_PER_CM * pinhole_cm / (pinhole_cm + 12.0 - z)
    u = np.stack([s * x + 640, -s * (y - 70) + 360, np.zeros_like(x)], axis=-1)
    return cap.replace(positions=u, units="cm", head_motion=None, history=({"step": "read", "dims": 2},))


@pytest.fixture(scope="module")
def lifted(jaw, ucli, tmp_path_factory):
    d = tmp_path_factory.mktemp("lift")
    cap, bound, disp = _truth(jaw)
    write_csv(d / "tracks.csv", _tracks(cap, bound[None] + disp), dims=2)
    out = {"dir": d, "tracks": d / "tracks.csv", "bound": bound, "disp": disp}
    for depth in ("zero", "tangent"):
        out[depth] = d / f"lift_{depth}.usdc"
        assert ucli("lift", d / "tracks.csv", "--mesh", jaw["mesh"], "--layout", jaw["layout"], "--depth", depth,
                    "-o", out[depth], "-q") == 0
    return out


def test_lift_recovers_in_plane_motion(lifted, jaw, ucli):
    from usdface.usd.capture_layer import read_capture_layer

    disp = lifted["disp"]
    for depth in ("zero", "tangent"):
        cap = read_capture_layer(lifted[depth])
        assert cap.units == "cm" and cap.n_frames == 1590 and cap.rate == 60
        got = cap.positions - cap.positions[cap.neutral_frame]
        e = got - disp
        inplane = np.linalg.norm(e[..., :2], axis=2)
        e3 = np.linalg.norm(e, axis=2)
        print(f"lift ({depth}): in-plane error max {inplane.max():.3g} cm; 3D error rms "
              f"{np.sqrt((e3 ** 2).mean()):.3f} cm, max {e3.max():.2f} cm (true depth motion rms "
              f"{np.sqrt((disp[..., 2] ** 2).mean()):.3f} cm, total rms {np.sqrt((disp ** 2).sum(2).mean()):.3f} cm)")
        assert inplane.max() < 1e-4
        assert np.allclose(cap.positions[cap.neutral_frame], lifted["bound"], atol=1e-4)
    assert ucli("check", lifted["zero"], "-q") == 0


def test_transfer_from_lifted_capture_is_close_to_the_true_transfer(lifted, jaw, ucli, points_of):
    from usdface.usd.capture_layer import write_capture_layer

    d = lifted["dir"]
    # the true capture measured from the neutral frame, as the lift measures its tracks
    cap, _, _ = _truth(jaw)
    write_capture_layer(d / "true_one_frame_rest.usdc", cap, prov={"processor": "test"})
    assert ucli("transfer", "--mesh", jaw["mesh"], "--capture", d / "true_one_frame_rest.usdc", "--binding",
                jaw["binding"], "--analysis", jaw["analysis"], "-o", d / "anim_true.usdc", "-q") == 0
    true = points_of(d / "anim_true.usdc")
    rest = points_of(jaw["mesh"])[0]
    moved = np.linalg.norm(true - rest, axis=2)
    for depth in ("zero", "tangent"):
        b, a = d / f"bind_{depth}.usda", d / f"anim_{depth}.usdc"
        assert ucli("bind", "--mesh", jaw["mesh"], "--capture", lifted[depth], "--layout", jaw["layout"], "-o", b,
                    "-q") == 0
        assert ucli("transfer", "--mesh", jaw["mesh"], "--capture", lifted[depth], "--binding", b, "--analysis",
                    jaw["analysis"], "-o", a, "-q") == 0
        got = points_of(a)
        e = np.linalg.norm(got - true, axis=2)
        inplane = np.linalg.norm((got - true)[..., :2], axis=2)
        print(f"transfer of lifted ({depth}) vs transfer of the true capture: vertex error mean {e.mean():.3f} cm "
              f"({100 * e.mean() / moved.mean():.0f}% of the mean displacement {moved.mean():.3f} cm), max "
              f"{e.max():.2f} cm; in-plane max {inplane.max():.2g} cm")
        assert inplane.max() < 1e-3            # the in-plane motion transfers exactly
        assert e.mean() < 0.75 * moved.mean()  # the depth the image cannot see is the whole error


def test_pinhole_tracks_lift_with_perspective_error_only(lifted, jaw, ucli):
    from usdface.usd.capture_layer import read_capture_layer

    cap, bound, disp = _truth(jaw)
    d = lifted["dir"]
    write_csv(d / "pinhole.csv", _tracks(cap, bound[None] + disp, pinhole_cm=60.0), dims=2)
    out = d / "lift_pinhole.usdc"
    assert ucli("lift", d / "pinhole.csv", "--mesh", jaw["mesh"], "--layout", jaw["layout"], "-o", out, "-q") == 0
    got = read_capture_layer(out)
    e = np.linalg.norm((got.positions - got.positions[0] - disp)[..., :2], axis=2)
    print(f"pinhole camera 60 cm away, weak-perspective lift: in-plane error max {e.max():.3g} cm, "
          f"rms {np.sqrt((e ** 2).mean()):.3g} cm")
    assert np.sqrt((e ** 2).mean()) < 0.05


def test_camera_fit_recovers_a_weak_perspective_camera():
    from scipy.spatial.transform import Rotation

    rng = np.random.default_rng(1)
    x = rng.normal(scale=5.0, size=(30, 3))
    r = Rotation.random(random_state=2).as_matrix()[:2]
    u = 37.0 * x @ r.T + [300.0, 200.0]
    cam = fit_weak_perspective(u, x)
    assert np.allclose(cam.rows, r, atol=1e-9) and abs(cam.scale - 37.0) < 1e-9 and cam.residual_max < 1e-9


def test_track_layer_input(lifted, jaw, ucli, tmp_path):
    """A track layer (usdface.usd.track_layer) and a 2D capture layer read like the CSV."""
    from usdface.io.csv_format import read_csv
    from usdface.usd.capture_layer import read_capture_layer, write_capture_layer

    tracks = read_csv(lifted["tracks"])
    ref = read_capture_layer(lifted["zero"]).positions
    layers = [tmp_path / "capture2d.usdc"]
    write_capture_layer(layers[0], tracks, prov={"processor": "test"})
    try:
        from usdface.usd.track_layer import write_track_layer
    except ImportError:
        pass
    else:
        layers.append(tmp_path / "tracks.usdc")
        write_track_layer(layers[1], tracks.replace(units=None), image_size=(1280, 720), prov={"processor": "test"})
    for layer in layers:
        out = tmp_path / f"lifted_{layer.stem}.usdc"
        assert ucli("lift", layer, "--mesh", jaw["mesh"], "--layout", jaw["layout"], "-o", out, "-q") == 0, layer
        assert np.allclose(read_capture_layer(out).positions, ref, atol=1e-4)


def test_marker_sets_that_differ_fail_cleanly(lifted, jaw, ucli, tmp_path, capsys):
    from usdface.io.csv_format import read_csv

    tracks = read_csv(lifted["tracks"])
    keep = [n for n in tracks.names if n != "Chin"]
    idx = [tracks.index(n) for n in keep]
    renamed = tracks.replace(names=keep[:-1] + ["Jaw_Tip"], positions=tracks.positions[:, idx])
    write_csv(tmp_path / "bad.csv", renamed, dims=2)
    out = tmp_path / "never.usdc"
    code = ucli("lift", tmp_path / "bad.csv", "--mesh", jaw["mesh"], "--layout", jaw["layout"], "-o", out)
    err = capsys.readouterr().err
    assert code == 2 and "marker sets differ" in err and "Chin" in err and "Jaw_Tip" in err and "Chin_L2" in err
    assert not out.exists() and list(tmp_path.glob(".never*")) == []


def test_3d_tracks_are_refused(jaw, ucli, tmp_path, capsys):
    from usdface.usd.capture_layer import read_capture_layer

    write_csv(tmp_path / "3d.csv", read_capture_layer(jaw["capture"]), dims=3)
    code = ucli("lift", tmp_path / "3d.csv", "--mesh", jaw["mesh"], "--layout", jaw["layout"], "-o",
                tmp_path / "x.usdc")
    assert code == 2 and "3D" in capsys.readouterr().err and not (tmp_path / "x.usdc").exists()
