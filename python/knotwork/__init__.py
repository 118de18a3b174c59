"""knotwork: Bezier, B-spline and NURBS surfaces — OBJ free-form, .bpt, JSON, IGES and STEP
files — tessellated into triangle meshes whose arrays are numpy views, on the GPU (wgpu
compute shaders, f32) or on knotwork's f64 CPU reference path.

    import knotwork
    mesh = knotwork.tessellate("teapot.bpt", tolerance_rel=1e-3)
    mesh.positions, mesh.indices    # (n, 3) float64 and (m, 3) uint32 numpy arrays, no copy
    mesh.write("teapot.glb")

`read` gives a Scene (items with kinds and names) to tessellate several ways;
`knotwork.ray.tessellate_files` tessellates a folder of files on a Ray cluster.
"""

import os as _os
import tempfile as _tempfile


def _quiet_driver_runtime_dir():
    """Mesa's drivers print "XDG_RUNTIME_DIR is invalid or not set" when opening a GPU
    device where that variable is unset (containers, CI, Ray workers), which reads as an
    error of knotwork's: give the process a private runtime folder (0700, this user's)."""
    if _os.name != "posix" or "XDG_RUNTIME_DIR" in _os.environ:
        return
    folder = _os.path.join(_tempfile.gettempdir(), f"knotwork-runtime-{_os.getuid()}")
    try:
        _os.makedirs(folder, mode=0o700, exist_ok=True)
        status = _os.stat(folder)
    except OSError:
        return
    if status.st_uid == _os.getuid():
        _os.environ["XDG_RUNTIME_DIR"] = folder


_quiet_driver_runtime_dir()

from ._knotwork import (
    Error,
    Item,
    Mesh,
    MeshMemory,
    Node,
    Scene,
    __version__,
    conformance,
    info,
    read,
    tessellate,
    tessellate_file,
)


class IncompleteMeshWarning(UserWarning):
    """Part of a file is not in its mesh (an entity that could not be read, a face that could
    not be meshed) or a job moved from the GPU to the CPU: the message says which and why."""


__all__ = [
    "Error",
    "IncompleteMeshWarning",
    "Item",
    "Mesh",
    "MeshMemory",
    "Node",
    "Scene",
    "conformance",
    "info",
    "read",
    "tessellate",
    "tessellate_file",
]
