"""Mesh conversions to other libraries' types (imported only when asked for)."""

import numpy as np


def to_trimesh(mesh):
    """A trimesh.Trimesh with its own copy of the mesh's arrays (vertices not merged)."""
    import trimesh

    return trimesh.Trimesh(
        vertices=np.array(mesh.positions, dtype=np.float64),
        faces=np.array(mesh.indices, dtype=np.int64),
        vertex_normals=np.array(mesh.normals, dtype=np.float64),
        visual=trimesh.visual.TextureVisuals(uv=np.array(mesh.uvs)),
        process=False,
    )


def to_pyvista(mesh):
    """A pyvista.PolyData with its own copy of the points and triangles, and point data
    "Normals" and "uv"."""
    import pyvista

    triangles = np.asarray(mesh.indices)
    faces = np.empty((len(triangles), 4), dtype=np.int64)
    faces[:, 0] = 3
    faces[:, 1:] = triangles
    poly = pyvista.PolyData(np.array(mesh.positions), faces.ravel())
    poly.point_data["Normals"] = np.array(mesh.normals)
    poly.point_data["uv"] = np.array(mesh.uvs)
    return poly
