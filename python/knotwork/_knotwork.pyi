"""Type stubs of knotwork's native module (re-exported by the package `knotwork`)."""

import os
from typing import List, Literal, Optional, Tuple, TypedDict, Union

import numpy as np
import numpy.typing as npt

__version__: str

class Error(Exception):
    """An error knotwork reported; where it was found, as far as it says."""

    file: Optional[str]
    line: Optional[int]
    entity: Optional[str]
    item: Optional[int]

class Item:
    index: int
    kind: Literal["surface", "coons", "curve", "trimmed", "shell"]
    name: Optional[str]

class Node:
    index: int
    name: str
    parent: Optional[int]
    transform: List[List[float]]
    placement: List[List[float]]
    items: Tuple[int, int]
    copy_of: Optional[int]
    shape: Optional[str]

class Scene:
    @property
    def items(self) -> list[Item]: ...
    @property
    def nodes(self) -> list[Node]: ...
    @property
    def path(self) -> Optional[str]: ...
    @property
    def notes(self) -> list[str]: ...
    @property
    def dropped(self) -> list[Tuple[str, str]]: ...
    def __len__(self) -> int: ...

class MeshMemory:
    """The memory behind one array of a Mesh (the array's `base`)."""

    @property
    def mesh(self) -> Mesh: ...
    @property
    def __array_interface__(self) -> dict: ...

class Mesh:
    @property
    def positions(self) -> npt.NDArray[np.floating]: ...
    @property
    def normals(self) -> npt.NDArray[np.floating]: ...
    @property
    def uvs(self) -> npt.NDArray[np.floating]: ...
    @property
    def indices(self) -> npt.NDArray[np.uint32]: ...
    @property
    def parts(self) -> np.ndarray: ...
    @property
    def polylines(self) -> list[Tuple[int, npt.NDArray[np.float64], npt.NDArray[np.float64]]]: ...
    @property
    def groups(self) -> list[Tuple[str, int, int]]: ...
    @property
    def left_out(self) -> list[str]: ...
    @property
    def backend(self) -> str: ...
    @property
    def dtype(self) -> Literal["float32", "float64"]: ...
    @property
    def vertex_count(self) -> int: ...
    @property
    def triangle_count(self) -> int: ...
    def write(
        self,
        path: Union[str, os.PathLike[str]],
        format: Optional[Literal["obj", "ply", "stl", "glb"]] = None,
    ) -> None: ...
    def to_trimesh(self): ...
    def to_pyvista(self): ...

def read(
    path: Union[str, os.PathLike[str]],
    format: Optional[Literal["obj", "bpt", "json", "iges", "igs", "step", "stp"]] = None,
) -> Scene: ...
def tessellate(
    source: Union[Scene, str, os.PathLike[str]],
    *,
    grid: Union[None, int, Tuple[int, int]] = None,
    tolerance: Optional[float] = None,
    tolerance_rel: Optional[float] = None,
    max_edge: Optional[float] = None,
    max_angle: Optional[float] = None,
    max_triangles: Optional[int] = None,
    samples: int = 65,
    backend: Literal["auto", "cpu", "gpu"] = "auto",
    dtype: Union[None, str, type, np.dtype] = None,
    max_memory: Optional[int] = None,
) -> Mesh: ...

class _Written(TypedDict):
    vertices: int
    triangles: int
    left_out: List[str]

def tessellate_file(
    source: Union[str, os.PathLike[str]],
    output: Union[str, os.PathLike[str]],
    *,
    format: Optional[Literal["obj", "ply", "stl", "glb"]] = None,
    grid: Union[None, int, Tuple[int, int]] = None,
    tolerance: Optional[float] = None,
    tolerance_rel: Optional[float] = None,
    max_edge: Optional[float] = None,
    max_angle: Optional[float] = None,
    max_triangles: Optional[int] = None,
    samples: int = 65,
    backend: Literal["auto", "cpu", "gpu"] = "auto",
    max_memory: Optional[int] = None,
) -> _Written: ...

class _Case(TypedDict, total=False):
    name: str
    kind: Literal["surface", "curve"]
    passes: bool
    worst_position: float
    worst_normal: float
    worst_degenerate_normal: float
    worst_uv: float
    worst_tangent: float

class _Conformance(TypedDict):
    adapter: str
    passes: bool
    cases: list[_Case]

class _Info(TypedDict):
    version: str
    reads: list[str]
    writes: list[str]
    adapters: str

def conformance() -> _Conformance: ...
def info() -> _Info: ...
def output_targets(
    files: list[Union[str, os.PathLike]], out_dir: Union[str, os.PathLike], format: str
) -> list[str]: ...
def is_surface_file(path: Union[str, os.PathLike]) -> bool: ...
