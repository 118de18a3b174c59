"""What the Python binding costs, measured: run with a release build of the package installed
(`pip install ./python`) from the repository root.

    python python/benches/bench.py [--files 200] [--occt]

(It lives outside python/knotwork's parent folder so that Python, which puts a script's
folder first on its path, imports the installed package, not its uncompiled sources.)

1. The teapot at 256x256 vertices per patch (2.1 M vertices) on the CPU, f64 and f32:
   `knotwork.tessellate` on a read Scene, median of 7, in M vertices/s. The Rust API's figure
   for the same job is `cargo bench --bench cpu -- cpu_scene` (printed next to it here
   when given with --rust-seconds).
2. A folder of small files (transformed teapot copies at the default 33x33): files/s for a
   Python loop, Python threads (the GIL is released), knotwork.ray on one node, and the
   CLI's own batch (`knotwork tessellate FOLDER -o OUT`, on PATH or target/release).
3. With --occt: STEP parts read and meshed by Open CASCADE (OCP's STEPControl_Reader +
   BRepMesh_IncrementalMesh, deflection T, parallel) next to knotwork.tessellate at the same
   tolerance T = 1e-3 of the part's diagonal, from Python, seconds and triangles.
"""

import argparse
import concurrent.futures
import os
import pathlib
import random
import shutil
import statistics
import subprocess
import sys
import tempfile
import time

import knotwork

try:
    import ray

    import knotwork.ray
except ImportError:
    ray = None

ROOT = pathlib.Path(__file__).resolve().parents[2]
DATA = ROOT / "data"


def median_seconds(job, runs=7):
    job()  # warm: the tessellator (and its thread pool) is made once per process
    times = []
    for _ in range(runs):
        start = time.perf_counter()
        job()
        times.append(time.perf_counter() - start)
    return statistics.median(times)


def teapot_256(rust_seconds):
    scene = knotwork.read(DATA / "teapot.bpt")
    vertices = 32 * 256 * 256
    print(f"teapot 256x256 per patch ({vertices / 1e6:.2f} M vertices), CPU:")
    for dtype in ("float64", "float32"):
        seconds = median_seconds(lambda: knotwork.tessellate(scene, grid=256, backend="cpu", dtype=dtype))
        line = f"  Python {dtype}: {seconds * 1e3:.1f} ms, {vertices / seconds / 1e6:.1f} M vertices/s"
        rust = rust_seconds.get(dtype)
        if rust:
            line += f"; Rust API {rust * 1e3:.1f} ms: binding overhead {100 * (seconds / rust - 1):+.1f} %"
        print(line)


def small_files(folder, count):
    sys.path.insert(0, str(ROOT / "python" / "tests"))
    from models import transformed_bpt  # the Ray test's generator of transformed copies

    rng = random.Random(3)
    teapot = (DATA / "teapot.bpt").read_text()
    for k in range(count):
        (folder / f"teapot_{k:04}.bpt").write_text(transformed_bpt(teapot, rng))
    return sorted(folder.iterdir())


def folder_throughput(count):
    work = pathlib.Path(tempfile.mkdtemp(prefix="knotwork-bench-"))
    try:
        inputs = work / "in"
        inputs.mkdir()
        files = small_files(inputs, count)
        print(f"folder of {count} teapot copies (32 patches, 33x33 each), CPU, .glb out:")

        def timed(name, job):
            out = work / name
            out.mkdir()
            # Every output is fsynced: flush what earlier stages wrote first, so no stage
            # pays for another's disk backlog.
            os.sync()
            start = time.perf_counter()
            job(out)
            seconds = time.perf_counter() - start
            assert len(list(out.glob("*.glb"))) == count, name
            shutil.rmtree(out)  # a gigabyte per stage at 1000 files: no stage runs in another's page cache
            print(f"  {name:<22} {count / seconds:7.1f} files/s ({seconds:.2f} s)")
            return seconds

        def one(path, out):
            mesh = knotwork.tessellate(path, backend="cpu", dtype="float32")  # glb is f32
            mesh.write(out / (path.stem + ".glb"))

        timed("python loop", lambda out: [one(p, out) for p in files])
        with concurrent.futures.ThreadPoolExecutor(os.cpu_count()) as pool:
            timed("python threads", lambda out: list(pool.map(lambda p: one(p, out), files)))
        built = ROOT / "target" / "release" / "knotwork"
        cli = str(built) if built.exists() else shutil.which("knotwork")

        def cli_batch(out):
            command = [cli, "tessellate", str(inputs), "-o", str(out), "--format", "glb", "--backend", "cpu"]
            subprocess.run(command, check=True, capture_output=True)

        if ray is None:
            timed("CLI batch", cli_batch)
            print("  (Ray not installed: pip install ray)")
            return
        ray.init(include_dashboard=False, log_to_driver=False)
        # Ray's workers start on their first tasks: a warm-up job with tasks for every CPU, as
        # on a cluster that is already running.
        cpus = int(ray.cluster_resources()["CPU"])
        warm = [str(p) for p in files[: 4 * cpus]]
        knotwork.ray.tessellate_files(warm, work / "warm", format="glb", files_per_task=1)
        # The CLI and Ray in turn, five rounds, each going first in every other round (what
        # ran just before, and the disk's work on its deleted files, slows a stage): on two
        # cores the spread between runs is as large as the difference.
        ratios = []
        for round in range(5):
            def ray_batch(out):
                knotwork.ray.tessellate_files(str(inputs), out, format="glb")

            stages = [("CLI batch", cli_batch), ("knotwork.ray", ray_batch)]
            if round % 2:
                stages.reverse()
            seconds = {name: timed(f"{name} [{round + 1}]", job) for name, job in stages}
            ratios.append(seconds["knotwork.ray"] / seconds["CLI batch"])
        print(f"  Ray / CLI time per round: {', '.join(f'{r:.2f}' for r in ratios)}; median {statistics.median(ratios):.2f}")
        ray.shutdown()
    finally:
        shutil.rmtree(work)


def occt_step():
    from OCP.BRep import BRep_Tool
    from OCP.BRepMesh import BRepMesh_IncrementalMesh
    from OCP.IFSelect import IFSelect_RetDone
    from OCP.STEPControl import STEPControl_Reader
    from OCP.TopAbs import TopAbs_FACE
    from OCP.TopExp import TopExp_Explorer
    from OCP.TopLoc import TopLoc_Location
    from OCP.TopoDS import TopoDS

    print("STEP parts, knotwork.tessellate vs Open CASCADE from Python (read + mesh, T = 1e-3 of the diagonal):")
    for path in [DATA / "abc-0000.step", DATA / "boxed_sphere.step", ROOT.parent / "shared" / "data" / "AMSurface.step"]:
        if not path.exists():
            continue
        mesh = knotwork.tessellate(path, tolerance_rel=1e-3, backend="cpu")
        positions = mesh.positions
        diagonal = float(((positions.max(axis=0) - positions.min(axis=0)) ** 2).sum() ** 0.5)
        tolerance = 1e-3 * diagonal

        def ours():
            return knotwork.tessellate(path, tolerance=tolerance, backend="cpu").triangle_count

        def theirs():
            reader = STEPControl_Reader()
            assert reader.ReadFile(str(path)) == IFSelect_RetDone
            reader.TransferRoots()
            shape = reader.OneShape()
            BRepMesh_IncrementalMesh(shape, tolerance, False, 0.5, True)
            triangles = 0
            explorer = TopExp_Explorer(shape, TopAbs_FACE)
            while explorer.More():
                triangulation = BRep_Tool.Triangulation_s(TopoDS.Face(explorer.Current()), TopLoc_Location())
                if triangulation is not None:
                    triangles += triangulation.NbTriangles()
                explorer.Next()
            return triangles

        k_seconds, o_seconds = median_seconds(ours, 5), median_seconds(theirs, 5)
        print(
            f"  {path.name:<20} knotwork {ours():>7} triangles in {k_seconds * 1e3:7.1f} ms;"
            f" OCCT {theirs():>7} in {o_seconds * 1e3:7.1f} ms"
        )


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--files", type=int, default=200, help="small files in the folder job")
    parser.add_argument("--occt", action="store_true", help="also time Open CASCADE (needs OCP)")
    parser.add_argument("--skip-teapot", action="store_true", help="leave out the teapot job")
    parser.add_argument(
        "--rust-seconds",
        nargs=2,
        type=float,
        metavar=("F64", "F32"),
        help="the Rust API's seconds for the teapot job (cargo bench --bench cpu -- cpu_scene: "
        "its f64 and its 'f32 split' cases, the f32 meshes the binding returns)",
    )
    args = parser.parse_args()
    rust = dict(zip(("float64", "float32"), args.rust_seconds or ()))
    if not args.skip_teapot:
        teapot_256(rust)
    folder_throughput(args.files)
    if args.occt:
        occt_step()


if __name__ == "__main__":
    main()
