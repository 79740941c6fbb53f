"""The MakeHuman ARKit rig, its marker binding and basis, loaded once per session."""
from __future__ import annotations

import pytest


@pytest.fixture(scope="session")
def makehuman(sample_assets):
    from usdface.blendshape.rig import load_npz_rig, marker_basis
    from usdface.io.meshes import read_mesh
    from usdface.mesh.layout import read_layout
    from usdface.mesh.topology import find_hole_regions
    from usdface.mesh.layout_binding import binding_from_layout

    mesh = read_mesh(sample_assets / "meshes" / "makehuman_hm08_face_cm.obj")
    rig = load_npz_rig(sample_assets / "meshes" / "makehuman_hm08_face_units_cm.npz", mesh)
    binding = binding_from_layout(mesh, read_layout(sample_assets / "layouts" / "makehuman_hm08_face.layout.json"))
    return {"mesh": mesh, "rig": rig, "binding": binding, "basis": marker_basis(rig, binding),
            "regions": find_hole_regions(mesh)}
