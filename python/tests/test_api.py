"""The Python API against knotwork's own guarantees: exact positions on closed forms, the
mesh layout, zero-copy arrays, errors that name where, threads that overlap."""

import math
import os
import pathlib
import subprocess
import threading
import time

import numpy as np
import pytest

import knotwork

HERE = pathlib.Path(__file__).resolve().parent
DATA = HERE.parents[1] / "data"
TEAPOT = DATA / "teapot.bpt"
# Relative tolerance of f64 positions against closed forms (the CPU path holds ~1e-15).
F64_REL = 1e-12
# The GPU bound: 1e-5 of the diagonal (plus f32 rounding of the position).
GPU_REL = 1e-5 + 2.0**-23


def sphere_json(path, radius=2.0, centre=(1.0, -3.0, 0.5)):
    """A JSON scene of one exact sphere (knotwork's `sphere` form)."""
    path.write_text(
        '{"surfaces": [{"kind": "sphere", "centre": [%r, %r, %r], "radius": %r, "name": "ball"}]}'
        % (*centre, radius)
    )
    return path


def test_read_gives_items_with_kinds_and_names():
    scene = knotwork.read(TEAPOT)
    assert len(scene) == 32
    assert [item.kind for item in scene.items] == ["surface"] * 32
    assert [item.index for item in scene.items] == list(range(32))
    assert scene.path == str(TEAPOT)
    assert scene.dropped == []
    step = knotwork.read(DATA / "abc-0000.step")
    assert {item.kind for item in step.items} == {"shell"}


def test_a_step_assembly_reads_with_its_tree():
    # data/fixture_assembly.step (Open CASCADE's writer): a plate and a pair of bolts placed
    # twice, the second pair turned 90° about z at (70, 45, 10), its right bolt 20 along x.
    scene = knotwork.read(DATA / "fixture_assembly.step")
    names = [node.name for node in scene.nodes]
    assert names == ["fixture", "base plate", "front pair", "bolt left", "bolt right",
                     "back pair", "bolt left", "bolt right"]
    assert [node.parent for node in scene.nodes] == [None, 0, 0, 2, 2, 0, 5, 5]
    back_right = scene.nodes[7]
    assert back_right.copy_of == 3 and back_right.shape == "bolt"
    assert scene.items[back_right.items[0]].name == "fixture/back pair/bolt right"
    # Its placement takes the bolt's axis origin to (70, 45, 10) + R_90°·(20, 0, 0).
    placement = np.array(back_right.placement)
    assert np.allclose(placement @ [0.0, 0.0, 0.0, 1.0], [70.0, 65.0, 10.0, 1.0], atol=1e-9)
    assert np.allclose(placement[:3, :3] @ [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], atol=1e-12)
    # The transforms compose to the placements, parent first.
    for node in scene.nodes:
        parent = np.eye(4) if node.parent is None else np.array(scene.nodes[node.parent].placement)
        assert np.allclose(parent @ np.array(node.transform), node.placement, atol=1e-9)
    assert knotwork.read(TEAPOT).nodes == []


def test_grid_mesh_layout_matches_the_conventions():
    mesh = knotwork.tessellate(TEAPOT, grid=(5, 7), backend="cpu")
    assert mesh.vertex_count == 32 * 5 * 7
    assert mesh.triangle_count == 32 * 4 * 6 * 2
    assert mesh.positions.shape == (32 * 35, 3) and mesh.positions.dtype == np.float64
    assert mesh.normals.shape == (32 * 35, 3)
    assert mesh.uvs.shape == (32 * 35, 2)
    assert mesh.indices.shape == (32 * 48, 3) and mesh.indices.dtype == np.uint32
    parts = mesh.parts
    assert list(parts["item"]) == list(range(32))
    assert list(parts["first_vertex"]) == [35 * k for k in range(32)]
    assert set(parts["grid_u"]) == {5} and set(parts["grid_v"]) == {7}
    assert list(parts["index_count"]) == [48 * 3] * 32
    # u fastest: vertex (i, j) of part 0 at j*5 + i; uv spans [0, 1]^2.
    uv = mesh.uvs[:35].reshape(7, 5, 2)
    assert np.allclose(uv[0, :, 0], np.linspace(0, 1, 5)) and np.allclose(uv[:, 0, 1], np.linspace(0, 1, 7))
    assert np.allclose(np.linalg.norm(mesh.normals, axis=1), 1.0)
    assert mesh.indices.max() < mesh.vertex_count


def test_sphere_positions_and_normals_are_exact(tmp_path):
    centre, radius = np.array([1.0, -3.0, 0.5]), 2.0
    mesh = knotwork.tessellate(sphere_json(tmp_path / "s.json"), grid=17, backend="cpu")
    offsets = mesh.positions - centre
    distance = np.linalg.norm(offsets, axis=1)
    assert np.max(np.abs(distance - radius)) <= F64_REL * 2 * radius
    # Outward unit normals, the poles included (their limit normal).
    assert np.max(np.abs(np.einsum("ij,ij->i", mesh.normals, offsets / radius) - 1.0)) <= 1e-9


def test_float32_and_gpu_stay_within_the_gpu_bound(tmp_path):
    reference = knotwork.tessellate(TEAPOT, grid=9, backend="cpu")
    gpu = knotwork.tessellate(TEAPOT, grid=9, backend="gpu", dtype="float32")
    assert gpu.dtype == "float32" and gpu.positions.dtype == np.float32
    assert gpu.positions.flags["C_CONTIGUOUS"] and gpu.normals.flags["C_CONTIGUOUS"]
    assert np.array_equal(gpu.indices, reference.indices)
    diagonal = np.linalg.norm(np.ptp(reference.positions, axis=0))
    error = np.max(np.linalg.norm(gpu.positions - reference.positions, axis=1))
    assert error <= GPU_REL * diagonal
    cpu32 = knotwork.tessellate(TEAPOT, grid=9, backend="cpu", dtype=np.float32)
    assert np.array_equal(cpu32.positions, reference.positions.astype(np.float32))


def test_tolerance_is_met_and_fewer_triangles_than_the_grid(tmp_path):
    centre, radius = np.array([1.0, -3.0, 0.5]), 2.0
    tolerance = 1e-3
    mesh = knotwork.tessellate(sphere_json(tmp_path / "s.json"), tolerance=tolerance, backend="cpu")
    # Deviation at triangle centroids from the true sphere (the surface is convex, so the
    # chord's distance to it is radius - |centroid - centre|).
    centroids = mesh.positions[mesh.indices].mean(axis=1)
    deviation = radius - np.linalg.norm(centroids - centre, axis=1)
    assert deviation.max() <= tolerance
    assert deviation.max() > tolerance / 20  # not wastefully fine
    finer = knotwork.tessellate(sphere_json(tmp_path / "s.json"), tolerance=tolerance / 100, backend="cpu")
    assert finer.triangle_count > 10 * mesh.triangle_count


def test_arrays_are_views_of_the_mesh_memory():
    mesh = knotwork.tessellate(TEAPOT, grid=9, backend="cpu")
    for name in ("positions", "normals", "uvs", "indices", "parts"):
        first, second = getattr(mesh, name), getattr(mesh, name)
        assert isinstance(first.base, knotwork.MeshMemory) and first.base.mesh is mesh
        assert first.ctypes.data == second.ctypes.data  # the same memory, not a copy
        assert first.flags["C_CONTIGUOUS"] and not first.flags["WRITEABLE"]
        with pytest.raises(ValueError):
            first[0] = 0
    positions = mesh.positions
    del mesh  # the array keeps the memory alive
    assert np.isfinite(positions).all() and positions.shape == (32 * 81, 3)


def test_options_that_do_not_go_together_are_refused():
    with pytest.raises(ValueError, match="grid"):
        knotwork.tessellate(TEAPOT, grid=9, tolerance=0.1)
    with pytest.raises(ValueError, match="not both"):
        knotwork.tessellate(TEAPOT, tolerance=0.1, tolerance_rel=1e-3)
    with pytest.raises(ValueError, match="backend"):
        knotwork.tessellate(TEAPOT, backend="tpu")
    with pytest.raises(ValueError, match="float16"):
        knotwork.tessellate(TEAPOT, dtype="float16")
    with pytest.raises(TypeError, match="Scene or a path"):
        knotwork.tessellate(42)
    with pytest.raises(ValueError, match="grid is -5"):
        knotwork.tessellate(TEAPOT, grid=-5)
    with pytest.raises(ValueError, match="is a folder"):
        knotwork.tessellate(DATA)
    with pytest.raises(knotwork.Error, match="at least 2"):
        knotwork.tessellate(TEAPOT, grid=(1, 9))
    with pytest.raises(knotwork.Error, match="tolerance"):
        knotwork.tessellate(TEAPOT, tolerance=-1.0)


def test_errors_carry_file_line_and_entity(tmp_path):
    with pytest.raises(knotwork.Error) as missing:
        knotwork.read(tmp_path / "nope.bpt")
    assert missing.value.file == str(tmp_path / "nope.bpt") and missing.value.line is None
    broken = tmp_path / "broken.obj"
    broken.write_text("v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\ncstype bspline\ndeg 1 1\nsurf 0 1 0 1 1 2 3 4\nparm u 0 1\nparm v 0 0 1\nend\n")
    with pytest.raises(knotwork.Error) as error:
        knotwork.tessellate(broken)
    assert error.value.file == str(broken)
    assert isinstance(error.value.line, int) and error.value.line >= 7
    assert str(broken) in str(error.value)
    with pytest.raises(knotwork.Error) as unknown:
        knotwork.read(tmp_path / "model.xyz")
    assert "xyz" in str(unknown.value) or "format" in str(unknown.value)
    cut = tmp_path / "cut.step"
    cut.write_text((DATA / "abc-0000.step").read_text()[:20000])
    with pytest.raises(knotwork.Error) as early:
        knotwork.tessellate(cut)
    assert early.value.file == str(cut) and early.value.line == 337
    assert "ended early" in str(early.value)
    wireframe = tmp_path / "points.step"
    wireframe.write_text(
        "ISO-10303-21;\nHEADER;\nENDSEC;\nDATA;\n#1=CARTESIAN_POINT('',(0.,0.,0.));\n"
        "#2=VERTEX_POINT('',#1);\nENDSEC;\nEND-ISO-10303-21;\n"
    )
    with pytest.raises(knotwork.Error, match="no B-rep"):
        knotwork.read(wireframe)
    face = tmp_path / "face.step"
    face.write_text(
        "ISO-10303-21;\nDATA;\n#1=MANIFOLD_SOLID_BREP('s',#2);\n#2=CLOSED_SHELL('',(#3));\n"
        "#3=ADVANCED_FACE('',(),#7,.T.);\n#7=DIRECTION('',(0.,0.,1.));\nENDSEC;\n"
    )
    scene = knotwork.read(face)  # the face is dropped by entity, and reported
    assert len(scene.dropped) == 1 and "#3" in scene.dropped[0][0] and "#7" in scene.dropped[0][1]


def test_every_format_is_written_atomically(tmp_path):
    mesh = knotwork.tessellate(TEAPOT, grid=5, backend="cpu")
    for format in ("obj", "ply", "stl", "glb"):
        path = tmp_path / f"teapot.{format}"
        mesh.write(path)
        assert path.stat().st_size > 1000
    mesh.write(tmp_path / "named.bin", format="stl")
    assert (tmp_path / "named.bin").read_bytes()[80:84] == np.uint32(mesh.triangle_count).tobytes()
    with pytest.raises(knotwork.Error):
        mesh.write(tmp_path / "conflict.ply", format="stl")
    with pytest.raises(knotwork.Error):
        mesh.write(tmp_path / "no-such-folder" / "t.obj")
    assert sorted(p.name for p in tmp_path.iterdir()) == [
        "named.bin",
        "teapot.glb",
        "teapot.obj",
        "teapot.ply",
        "teapot.stl",
    ]


def glb_chunks(data):
    """A glb's JSON (without its padding) and binary chunk."""
    length = int.from_bytes(data[12:16], "little")
    return data[20 : 20 + length].rstrip(b" "), data[20 + length + 8 :]


def test_tessellate_file_writes_what_the_mesh_would(tmp_path):
    # Streamed (a grid to PLY and glb) or made whole (OBJ from the f64 mesh, STL, a
    # tolerance), the file is the one Mesh.write makes of the same job's mesh (a streamed
    # glb reserves room for its JSON: only the padding differs).
    jobs = [("ply", {"grid": (7, 5)}), ("glb", {"grid": 6}), ("stl", {"grid": 6}), ("obj", {"grid": 4}),
            ("glb", {"tolerance_rel": 1e-2})]
    for k, (format, options) in enumerate(jobs):
        written = tmp_path / f"file{k}.{format}"
        record = knotwork.tessellate_file(TEAPOT, written, backend="cpu", **options)
        dtype = "float64" if format == "obj" else "float32"
        mesh = knotwork.tessellate(TEAPOT, backend="cpu", dtype=dtype, **options)
        mesh.write(tmp_path / f"mesh{k}.{format}")
        same = glb_chunks if format == "glb" else bytes
        assert same(written.read_bytes()) == same((tmp_path / f"mesh{k}.{format}").read_bytes()), (format, options)
        assert record == {"vertices": mesh.vertex_count, "triangles": mesh.triangle_count, "left_out": []}
    with pytest.warns(knotwork.IncompleteMeshWarning, match="crosses"):
        record = knotwork.tessellate_file(HERE / "data" / "crossing_loops.igs", tmp_path / "c.glb", backend="cpu", tolerance=1e-2)
    assert len(record["left_out"]) == 1 and record["triangles"] > 0
    with pytest.raises(knotwork.Error) as error:
        knotwork.tessellate_file(tmp_path / "missing.bpt", tmp_path / "missing.glb")
    assert error.value.file == str(tmp_path / "missing.bpt")
    with pytest.raises(ValueError, match="not a mesh format"):
        knotwork.tessellate_file(TEAPOT, tmp_path / "t.x", format="fbx")
    with pytest.raises(knotwork.Error, match="conflict|extension"):
        knotwork.tessellate_file(TEAPOT, tmp_path / "t.ply", format="stl")
    assert not any(p.name.startswith(("missing", "t.")) for p in tmp_path.iterdir())
    # A free-form OBJ written over itself would be lost: refused, the file as it was.
    model = tmp_path / "model.obj"
    model.write_bytes((HERE.parent.parent / "data" / "special_curves.obj").read_bytes())
    before = model.read_bytes()
    with pytest.raises(knotwork.Error, match="written over this input"):
        knotwork.tessellate_file(model, model, backend="cpu")
    assert model.read_bytes() == before


def test_written_obj_reads_back_as_the_same_mesh(tmp_path):
    mesh = knotwork.tessellate(TEAPOT, grid=4, backend="cpu", dtype="float32")
    mesh.write(tmp_path / "t.obj")
    vertices = [l.split()[1:] for l in (tmp_path / "t.obj").read_text().splitlines() if l.startswith("v ")]
    assert np.allclose(np.array(vertices, dtype=float), mesh.positions, rtol=0, atol=1e-6)


def test_faces_left_out_are_listed_and_warned():
    # An IGES trimmed face whose outer loop crosses its hole cannot be meshed; the free
    # plane beside it is (written by knotwork's IGES tests: tests/io.rs).
    with pytest.warns(knotwork.IncompleteMeshWarning, match="crosses"):
        mesh = knotwork.tessellate(HERE / "data" / "crossing_loops.igs", backend="cpu", tolerance=1e-2)
    assert len(mesh.left_out) == 1 and "face left out" in mesh.left_out[0]
    assert len(mesh.parts) == 1 and mesh.triangle_count > 0


def test_threads_overlap_because_the_gil_is_released():
    mesh_of = lambda: knotwork.tessellate(TEAPOT, grid=129, backend="cpu", dtype="float32")
    mesh_of()
    start = time.perf_counter()
    mesh_of()
    alone = time.perf_counter() - start
    ticks = []
    stop = threading.Event()

    def ticker():  # runs Python code only while the GIL is free
        while not stop.is_set():
            ticks.append(time.perf_counter())
            time.sleep(0.001)

    thread = threading.Thread(target=ticker)
    thread.start()
    for _ in range(3):
        mesh_of()
    stop.set()
    thread.join()
    # While the main thread was inside knotwork for 3 x `alone` seconds, the ticker kept
    # running: at least a third of the ticks it would get with the GIL free all along.
    assert len(ticks) >= max(3, 3 * alone / 0.0011 / 3)
    results = [None] * 4
    threads = [threading.Thread(target=lambda k=k: results.__setitem__(k, mesh_of())) for k in range(4)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert all(r.vertex_count == 32 * 129 * 129 for r in results)


def test_trimesh_conversion():
    trimesh = pytest.importorskip("trimesh")
    mesh = knotwork.tessellate(TEAPOT, grid=9, backend="cpu")
    converted = mesh.to_trimesh()
    assert isinstance(converted, trimesh.Trimesh)
    assert np.array_equal(converted.vertices, mesh.positions)
    assert np.array_equal(converted.faces, mesh.indices)
    assert np.allclose(converted.vertex_normals, mesh.normals)


def test_pyvista_conversion():
    pyvista = pytest.importorskip("pyvista")
    mesh = knotwork.tessellate(TEAPOT, grid=9, backend="cpu")
    poly = mesh.to_pyvista()
    assert isinstance(poly, pyvista.PolyData)
    assert poly.n_points == mesh.vertex_count and poly.n_cells == mesh.triangle_count
    assert np.array_equal(poly.points, mesh.positions)


def test_conformance_and_info():
    info = knotwork.info()
    assert info["version"] == knotwork.__version__
    assert "step" in info["reads"] and "glb" in info["writes"]
    report = knotwork.conformance()
    assert report["passes"], [c for c in report["cases"] if not c["passes"]]
    assert {c["kind"] for c in report["cases"]} == {"surface", "curve"}
    assert all(c["worst_position"] <= 1e-5 for c in report["cases"])


def test_help_reads_well():
    doc = knotwork.tessellate.__doc__
    for word in ("grid", "tolerance_rel", "backend", "dtype", "GIL", "knotwork.Error"):
        assert word in doc
    assert knotwork.tessellate.__text_signature__.startswith("(source, *, grid=None")
