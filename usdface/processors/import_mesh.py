"""`usdface import-mesh`: a mesh file (OBJ/PLY/STL/OFF or USD) -> mesh layer with hole regions."""
from __future__ import annotations

import logging

import numpy as np

from ..options import ImportMeshOptions
from ..registry import Result
from ..usd.identity import identity, mesh_record
from ..usd.inputs import load_mesh
from ..usd.layers import check_output_path, provenance

log = logging.getLogger("usdface")


def import_mesh(source, *, options: ImportMeshOptions, output) -> Result:
    """Import a mesh (a file, or a USD mesh layer / stage), find its holes (outer border, mouth,
    eyes) as regions, write the mesh layer."""
    from ..mesh.topology import subset_faces, border_surface, boundary_loops, find_hole_regions, mesh_topology
    from ..usd.mesh_layer import write_mesh_layer

    input, units, up_axis = source, options.units, options.up_axis
    out = check_output_path(output, inputs={"input": input})
    mesh, regions = load_mesh(input, units=units)
    mesh.check_degenerate()
    if up_axis.upper() == "Z":  # Z-up source: (x, y, z) -> (x, z, -y)
        p = mesh.points
        mesh = mesh.with_points(np.stack([p[:, 0], p[:, 2], -p[:, 1]], axis=1))
    topo = mesh_topology(mesh)
    surface = border_surface(mesh)
    if not surface.clean:
        # the run goes on: the border and holes come from the rest of the surface
        log.warning("%s", surface.message(str(input)))
    if not regions:
        regions = find_hole_regions(mesh, loops=boundary_loops(subset_faces(mesh, surface.faces)))
    prov = provenance("import-mesh", options={"units": units, "up_axis": up_axis}, inputs={"mesh": input},
                      identity=identity(mesh=mesh_record(mesh)))  # the mesh as written: Y-up, float32
    write_mesh_layer(out, mesh, regions, prov=prov)
    sizes = {int(k): int(v) for k, v in zip(*np.unique(mesh.face_vertex_counts, return_counts=True))}
    summary = {
        "output": str(out), "source": str(input), "points": mesh.n_points, "faces": mesh.n_faces,
        "faceSizes": sizes, "units": mesh.units, "uvs": mesh.uvs is not None,
        "boundaryLoops": topo["boundary_loops"], "components": topo["components"],
        "nonManifoldEdges": topo["non_manifold_edges"], "borderSurface": surface.summary(),
        "regions": {r.name: {"role": r.role, "vertices": int(r.indices.size)} for r in regions},
    }
    text = [
        f"wrote {out}: {mesh.n_points} points, {mesh.n_faces} faces "
        f"({', '.join(f'{v} with {k} sides' for k, v in sizes.items())}), units {mesh.units}, "
        f"uvs {'yes' if mesh.uvs is not None else 'no'}",
        f"  topology: {topo['boundary_loops']} boundary loops, {topo['components']} component(s), "
        f"{topo['non_manifold_edges']} non-manifold edges",
    ] + [f"  region {r.name}: role {r.role}, {r.indices.size} vertices" for r in regions]
    return Result(layers={"output": out}, summary=summary, text=text)
