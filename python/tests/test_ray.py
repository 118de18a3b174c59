"""knotwork.ray on a local two-CPU Ray cluster: a few hundred generated files, good and
broken mixed, each good one tessellated and written exactly once, each broken one reported."""

import json
import os
import pathlib
import random
import sys

import pytest

ray = pytest.importorskip("ray")
import knotwork  # noqa: E402
import knotwork.ray  # noqa: E402
from models import transformed_bpt  # noqa: E402

DATA = pathlib.Path(__file__).resolve().parents[2] / "data"
GOOD, BROKEN = 240, 24


@pytest.fixture(scope="module")
def cluster():
    ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False)
    yield
    ray.shutdown()


def make_inputs(folder):
    rng = random.Random(7)
    teapot = (DATA / "teapot.bpt").read_text()
    ducky = (DATA / "ducky.obj").read_text()
    good, broken = [], []
    for k in range(GOOD):
        if k % 4 == 3:
            path = folder / f"ducky_{k:03}.obj"
            path.write_text(ducky)
        else:
            path = folder / f"teapot_{k:03}.bpt"
            path.write_text(transformed_bpt(teapot, rng))
        good.append(path)
    for k in range(BROKEN):
        kind = k % 4
        path = folder / f"broken_{k:03}.{['bpt', 'obj', 'bpt', 'step'][kind]}"
        if kind == 0:  # cut short in the middle of a patch
            path.write_text(teapot[: len(teapot) // 3])
        elif kind == 1:  # a surface naming a vertex that does not exist
            path.write_text(ducky.replace("1.5708 1 2 3 ", "1.5708 99999 2 3 ", 1))
        elif kind == 2:  # a coordinate that is not a number
            lines = teapot.splitlines()
            lines[3] = "1.0 oops 2.0"
            path.write_text("\n".join(lines))
        else:  # not STEP at all
            path.write_text("this is not an ISO 10303-21 file\n")
        broken.append(path)
    return good, broken


def test_a_folder_on_ray_every_good_file_once_every_broken_one_reported(tmp_path, cluster):
    inputs, out = tmp_path / "in", tmp_path / "out"
    inputs.mkdir()
    good, broken = make_inputs(inputs)
    records = knotwork.ray.tessellate_files(str(inputs / "*"), out, format="glb", grid=9)
    assert [r["input"] for r in records] == sorted(str(p) for p in good + broken)
    by_input = {r["input"]: r for r in records}
    for path in good:
        record = by_input[str(path)]
        assert record["error"] is None, record
        assert record["output"] == str(out / (path.stem + ".glb"))
        assert record["triangles"] > 0 and record["seconds"] > 0
    for path in broken:
        record = by_input[str(path)]
        assert record["output"] is None
        assert record["error"] and str(path) in record["error"], record
    # Exactly one output per good file, nothing else (no temporary files), and the records.
    written = sorted(p.name for p in out.iterdir())
    assert written == sorted([p.stem + ".glb" for p in good] + [knotwork.ray.RECORDS])
    lines = (out / knotwork.ray.RECORDS).read_text().splitlines()
    assert [json.loads(line) for line in lines] == records
    # Each output is the mesh knotwork gives for its file on its own.
    sample = good[0]
    alone = knotwork.tessellate(sample, grid=9, backend="cpu")
    assert by_input[str(sample)]["triangles"] == alone.triangle_count
    assert by_input[str(sample)]["vertices"] == alone.vertex_count


def test_inputs_that_would_collide_are_refused_before_anything_runs(tmp_path, cluster):
    (tmp_path / "a").mkdir()
    (tmp_path / "b").mkdir()
    for folder in ("a", "b"):
        (tmp_path / folder / "teapot.bpt").write_text((DATA / "teapot.bpt").read_text())
    with pytest.raises(ValueError, match="would both be written"):
        knotwork.ray.tessellate_files(str(tmp_path / "*" / "*.bpt"), tmp_path / "out")
    assert not (tmp_path / "out").exists() or not any((tmp_path / "out").iterdir())
    with pytest.raises(ValueError, match="no input files"):
        knotwork.ray.tessellate_files(str(tmp_path / "*.step"), tmp_path / "out")
    with pytest.raises(ValueError, match="format"):
        knotwork.ray.tessellate_files(str(tmp_path / "a"), tmp_path / "out", format="fbx")


class CrashOnUse:
    """A grid that kills the worker process reading it while `marker` exists — the worst a
    file can do to a worker (a crash past Python). With `once`, the first use also removes
    the marker, so only one task dies."""

    def __init__(self, marker, once):
        self.marker, self.once = str(marker), once

    def __index__(self):
        if os.path.exists(self.marker):
            if self.once:
                try:
                    os.unlink(self.marker)
                except FileNotFoundError:  # another worker took the crash
                    return 9
            os._exit(3)
        return 9


def test_a_task_whose_worker_dies_costs_only_its_own_file(tmp_path, cluster):
    ray.cloudpickle.register_pickle_by_value(sys.modules[__name__])  # workers need not import this test
    inputs = tmp_path / "in"
    inputs.mkdir()
    for k in range(4):
        (inputs / f"teapot_{k}.bpt").write_text((DATA / "teapot.bpt").read_text())
    marker = tmp_path / "crash"
    no_retry = {"max_retries": 0}
    # One crash: the chunk it killed is split into one task per file, and all are meshed.
    marker.touch()
    records = knotwork.ray.tessellate_files(
        inputs, tmp_path / "once", grid=CrashOnUse(marker, once=True), files_per_task=2, ray_remote_args=no_retry
    )
    assert not marker.exists(), "a worker died"
    assert all(r["error"] is None and r["triangles"] == 32 * 8 * 8 * 2 for r in records), records
    assert len(list((tmp_path / "once").glob("*.obj"))) == 4
    # Every task dies: every file is recorded as failed, by name, and the job still ends.
    marker.touch()
    records = knotwork.ray.tessellate_files(
        inputs, tmp_path / "always", grid=CrashOnUse(marker, once=False), files_per_task=2, ray_remote_args=no_retry
    )
    assert [r["input"] for r in records] == sorted(str(p) for p in inputs.iterdir())
    assert all(r["output"] is None and r["input"] in r["error"] and "failed" in r["error"] for r in records)
    assert sorted(p.name for p in (tmp_path / "always").iterdir()) == [knotwork.ray.RECORDS]
