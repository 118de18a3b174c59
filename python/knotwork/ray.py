"""Batch tessellation on Ray: the same job on a laptop (`ray.init()`) and on a cluster.

    import knotwork.ray
    records = knotwork.ray.tessellate_files("models/**/*.step", "meshes/", tolerance_rel=1e-3)

Every input becomes ``out_dir/NAME.FORMAT`` (NAME: the input's file name without its
extension, as the CLI's batch names them), written atomically: a file is either complete or
absent, also when Ray re-runs a task whose worker died. A file that fails is recorded with
its error and never stops the job; a task whose worker dies (a crash, memory) past Ray's
retries is split into one task per file, so only the file at fault is recorded as failed. One record per input, in input order, is returned and
written to ``out_dir/knotwork-records.jsonl`` (also atomically).

On a cluster ``out_dir`` and the inputs must be on storage every node sees (NFS, a mounted
bucket); start the head with ``ray start --head``, workers with ``ray start --address
HEAD:6379``, and run the script on the head (or with ``ray.init(address="auto")``).
"""

import glob
import json
import math
import os
import tempfile
import time

import ray

import knotwork
from knotwork import _knotwork

RECORDS = "knotwork-records.jsonl"

# Tasks per CPU by default. Ray hands out whole tasks, so at the end of a job some CPUs sit
# idle while others finish their last task; the CLI's threads take one file at a time. On
# 1000 small files on two CPUs, Ray took 1.04-1.09x the CLI's time with 4 tasks per CPU and
# 0.99-1.06x with 16 (python/benches/bench.py); Ray's cost per task (milliseconds) stays
# small beside tasks of a few dozen files.
TASKS_PER_CPU = 16


def expand_inputs(paths_or_glob):
    """The files of a glob pattern (``**`` recursive), a folder (its surface files), a path
    or a list of any of these; sorted, each once."""
    if isinstance(paths_or_glob, (str, os.PathLike)):
        paths_or_glob = [paths_or_glob]
    files = set()
    for entry in paths_or_glob:
        entry = os.fspath(entry)
        if os.path.isdir(entry):
            for name in os.listdir(entry):
                path = os.path.join(entry, name)
                if os.path.isfile(path) and _knotwork.is_surface_file(path):
                    files.add(path)
        elif glob.has_magic(entry):
            files.update(p for p in glob.glob(entry, recursive=True) if os.path.isfile(p))
        else:
            files.add(entry)
    return sorted(files)


def _tessellate_one(path, target, format, options):
    """Tessellates one file into ``target``; its record (never raises)."""
    start = time.perf_counter()
    record = {"input": path, "output": None, "vertices": 0, "triangles": 0, "left_out": [], "error": None}
    try:
        written = knotwork.tessellate_file(path, target, format=format, **options)
        record.update(output=target, **written)
    except knotwork.Error as error:
        record["error"] = str(error)
    except (ValueError, TypeError, OSError) as error:
        record["error"] = f"{type(error).__name__}: {error}"
    except BaseException as error:  # a Rust panic surfaces as pyo3's PanicException
        if isinstance(error, (KeyboardInterrupt, SystemExit)):
            raise
        record["error"] = f"{type(error).__name__}: {error}"
    record["seconds"] = time.perf_counter() - start
    return record


def _tessellate_chunk(jobs, format, options):
    import warnings

    with warnings.catch_warnings():
        # Left-out faces are in each record; no warning per file on the workers' logs.
        warnings.simplefilter("ignore", knotwork.IncompleteMeshWarning)
        return [_tessellate_one(path, target, format, options) for path, target in jobs]


def tessellate_files(
    paths_or_glob,
    out_dir,
    *,
    format="obj",
    files_per_task=None,
    ray_remote_args=None,
    **options,
):
    """Tessellates every file of ``paths_or_glob`` (see `expand_inputs`) into ``out_dir``
    on Ray, each by knotwork.tessellate_file (as the CLI does: streamed to the disk where it
    can be) with its ``options`` (grid, tolerance, tolerance_rel, ...,
    backend: "cpu" unless given, as Ray schedules CPUs; pass ``backend="gpu"`` with
    ``ray_remote_args={"num_gpus": 1}`` on GPU nodes).

    format: "obj", "ply", "stl" or "glb". files_per_task: files one Ray task tessellates
    (default: about sixteen tasks per CPU of the cluster, so that the last tasks to finish
    leave the other CPUs idle for little of the job). ray_remote_args: resources of each
    task (default ``{"num_cpus": 1}``; knotwork then runs single-threaded in it).

    Starts a local Ray (``ray.init()``) unless one is running. Returns one record per input,
    in input order: {"input", "output" (None on error), "vertices", "triangles", "seconds",
    "error" (None or the message, naming file and line), "left_out" (what the mesh lacks)};
    the same records are written to ``out_dir/knotwork-records.jsonl``.
    """
    if format not in ("obj", "ply", "stl", "glb"):
        raise ValueError(f"format {format!r} is not a mesh format (obj, ply, stl, glb)")
    files = expand_inputs(paths_or_glob)
    if not files:
        raise ValueError(f"no input files in {paths_or_glob!r}")
    os.makedirs(out_dir, exist_ok=True)
    targets = [os.fspath(t) for t in _knotwork.output_targets(files, out_dir, format)]
    options.setdefault("backend", "cpu")
    # The format decides the precision: OBJ is written from the f64 mesh, PLY, STL and glTF
    # (which carry f32) from the f32 one, as the CLI's batch does.
    if "dtype" in options:
        raise TypeError("dtype is not an option of tessellate_files: the format decides it")
    if not ray.is_initialized():
        ray.init()
    remote_args = {"num_cpus": 1}
    remote_args.update(ray_remote_args or {})
    if remote_args.get("num_cpus") == 1:
        # One core per task: knotwork's own thread pool to match.
        env = remote_args.setdefault("runtime_env", {}).setdefault("env_vars", {})
        env.setdefault("RAYON_NUM_THREADS", "1")
    if files_per_task is None:
        cpus = max(1, int(ray.cluster_resources().get("CPU", 1)))
        files_per_task = max(1, math.ceil(len(files) / (TASKS_PER_CPU * cpus)))
    chunk = ray.remote(_tessellate_chunk).options(**remote_args)
    jobs = list(zip(files, targets))
    pending = {}  # task -> the jobs it tessellates
    for k in range(0, len(jobs), files_per_task):
        part = jobs[k : k + files_per_task]
        pending[chunk.remote(part, format, options)] = part
    by_input = {}
    while pending:
        done, _ = ray.wait(list(pending), num_returns=1)
        part = pending.pop(done[0])
        try:
            for record in ray.get(done[0]):
                by_input[record["input"]] = record
        except (ray.exceptions.RayError, OSError) as error:
            # The task failed past Ray's retries (its worker died: a crash, memory): its files
            # again one per task, so only the file at fault is recorded as failed.
            if len(part) > 1:
                for job in part:
                    pending[chunk.remote([job], format, options)] = [job]
            else:
                path, _ = part[0]
                by_input[path] = {
                    "input": path,
                    "output": None,
                    "vertices": 0,
                    "triangles": 0,
                    "left_out": [],
                    "error": f"{path}: the Ray task tessellating it failed: {type(error).__name__}: {error}",
                    "seconds": 0.0,
                }
    records = [by_input[path] for path in files]
    _write_records(os.path.join(out_dir, RECORDS), records)
    return records


def _write_records(path, records):
    """Writes the records as JSON lines through a temporary file renamed into place."""
    folder = os.path.dirname(path) or "."
    handle, temporary = tempfile.mkstemp(prefix=".knotwork-records-", dir=folder)
    try:
        with os.fdopen(handle, "w") as out:
            for record in records:
                out.write(json.dumps(record) + "\n")
        os.replace(temporary, path)
    except BaseException:
        os.unlink(temporary)
        raise
