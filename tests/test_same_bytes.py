"""Where the work runs changes how fast files come, never what they hold: a run rendered on one worker, on two local
processes and on a local Ray cluster of two, and a dataset built on one worker and on two, are the same bytes.

Every file is compared, byte for byte. None of a render's or a dataset's files holds a wall-clock value (the one
that does, `timings.json` with each stage's seconds, is written by `renderloop run`, and so are the report's
seconds); the ownership ledger (`.renderloop-files`) lists the files in the order they were written, which is the
order the workers finished them in, so it is compared as the set of files it lists."""

from __future__ import annotations

import hashlib
import shutil
from pathlib import Path

import pytest

from renderloop.config import load_config
from renderloop.config.dataset import DatasetSpec
from renderloop.dataset.build import build_dataset
from renderloop.io.ownership import LEDGER, read_ledger
from renderloop.parallel import LOCAL, Executor, ray_session
from renderloop.planning.stage import run_plan
from renderloop.render.stage import run_render
from renderloop.rundir import files, names
from renderloop.scene.stage import run_scene
from renderloop.sim.stage import run_fly

EXECUTORS = {"one worker": LOCAL, "two processes": Executor(workers=2), "ray of two": Executor(kind="ray", workers=2)}


def _contents(directory: Path) -> dict[str, str]:
    """Every file below `directory` by its path and the sha1 of its bytes; the ledger by the files it lists."""
    found = {path.relative_to(directory).as_posix(): hashlib.sha1(path.read_bytes()).hexdigest()
             for path in sorted(directory.rglob("*")) if path.is_file() and path.name != LEDGER}
    return found | {LEDGER: ",".join(sorted(read_ledger(directory)))}


@pytest.fixture(scope="module")
def flown(tmp_path_factory) -> Path:
    """The demo greenhouse cut to two plants, flown and set to render a few raster frames."""
    config = load_config("demo").override({"greenhouse": {"plants_per_table": 2}, "renderer": {"backend": "raster"},
                                           "camera": {"rate_hz": 0.2}})
    run_dir = tmp_path_factory.mktemp("same") / "flown"
    for stage in (run_scene, run_plan, run_fly):
        stage(run_dir, config)
    return run_dir


def test_a_run_rendered_on_one_worker_two_processes_or_a_ray_cluster_is_the_same_bytes(flown: Path, tmp_path: Path):
    made = {}
    with ray_session(EXECUTORS["ray of two"]):  # started once, joined by the render
        for name, executor in EXECUTORS.items():
            run_dir = Path(shutil.copytree(flown, tmp_path / name.replace(" ", "_")))
            assert run_render(run_dir, files.read_config(run_dir), executor=executor)
            made[name] = _contents(run_dir)
    one = made["one worker"]
    assert len([name for name in one if name.startswith(f"{names.RGB}/")]) == len(files.read_poses(flown)[0]) > 4
    for name, contents in made.items():
        assert contents == one, f"{name}: {sorted(k for k in contents.keys() | one.keys() if contents.get(k) != one.get(k))}"


def test_a_dataset_built_on_one_worker_or_two_is_the_same_bytes(tmp_path: Path):
    spec = DatasetSpec(seed=3, width=64, height=48, views_per_scene=1, samples=(1,), val_every=2)  # a scene a worker
    for name, executor in (("one", LOCAL), ("two", Executor(workers=2))):
        assert build_dataset(tmp_path / name, 2, spec, executor) == 2
    one, two = _contents(tmp_path / "one"), _contents(tmp_path / "two")
    assert len([name for name in one if name.startswith("images/")]) == 2
    assert two == one, sorted(k for k in one.keys() | two.keys() if one.get(k) != two.get(k))
