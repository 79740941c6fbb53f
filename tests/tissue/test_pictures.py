"""Every preset's held pose on a face, and the picture of them."""
from __future__ import annotations

import numpy as np

from usdface.tissue.pictures import preset_contact_sheet, preset_poses


def test_preset_poses_are_the_presets_held(face):
    poses = preset_poses(face.mesh, face.regions, ("neutral", "joy"))
    assert list(poses) == ["neutral", "joy"]
    assert np.abs(poses["neutral"] - face.mesh.points).max() < 1e-6
    # joy lifts both mouth corners (the rig's landmarks, on the nearest vertices)
    d = poses["joy"] - face.mesh.points
    for side in ("L", "R"):
        v = int(np.argmin(np.linalg.norm(face.mesh.points - face.rig.landmarks[f"mouthCorner_{side}"], axis=1)))
        assert d[v, 1] > 0.3


def test_preset_contact_sheet_one_cell_per_face_and_preset(face):
    sheet = preset_contact_sheet([("realistic", face.mesh, face.regions)], presets=("neutral",), size=(120, 140))
    assert sheet.dtype == np.uint8 and sheet.ndim == 3 and sheet.shape[2] == 3
    assert sheet.shape[0] > 140 and 120 < sheet.shape[1] < 2 * 120  # one cell, with its caption and the title
    assert len(np.unique(sheet.reshape(-1, 3), axis=0)) > 20       # a shaded face, not a blank
