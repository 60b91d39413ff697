"""Rerun export: the .rrd reads back with Rerun's own reader and holds the run's poses, images and detections."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest
import rerun as rr
from conftest import fly_demo_raster
from rerun.error_utils import strict_mode

from renderloop.export.rerun_recording import write_rerun
from renderloop.io.tum import read_tum
from renderloop.render.stage import run_render
from renderloop.export.contents import read_run
from renderloop.rundir.files import read_config
from renderloop.scene.model import load_scene


@pytest.fixture(autouse=True)
def strict_rerun():
    """Rerun only warns about bad input by default; a test must fail on it instead."""
    previous = strict_mode()
    rr.set_strict_mode(True)
    yield
    rr.set_strict_mode(previous)


def _fake_detections(run_dir: Path) -> dict[int, int]:
    """A detections.json with 0, 1 or 2 boxes per frame (some without a position) and a counts.json; boxes per frame."""
    times, _, _ = read_tum(run_dir / "groundtruth.txt")
    peppers = load_scene(run_dir / "scene.json").peppers
    frames = []
    for index, timestamp in enumerate(times):
        found = [{"bbox": [10.0 + k, 20.0, 60.0 + k, 90.0], "score": 0.9 - 0.1 * k, "label": ("ripe", "unripe")[k],
                  "position": list(peppers[index % len(peppers)].center) if k == 0 else None} for k in range(index % 3)]
        frames.append({"index": index, "timestamp": float(timestamp), "image": f"rgb/{index:06d}.png", "detections": found})
    document = {"model": "fake", "score_threshold": 0.5, "depth": "depth", "frames": frames}
    (run_dir / "detections.json").write_text(json.dumps(document))
    plants = [{"id": 0, "row": 0, "estimate": 2, "truth": 2, "unripe_estimate": 1, "unripe_truth": 1,
               "clusters": [[1.0, 2.0, 1.0], [1.1, 2.0, 1.1]], "unripe_clusters": [[1.0, 2.1, 0.9]]},
              {"id": 1, "row": 0, "estimate": 1, "truth": 1, "unripe_estimate": 0, "unripe_truth": 0,
               "clusters": [[1.0, 3.0, 1.0]], "unripe_clusters": []}]
    total = {"estimate": 3, "truth": 3, "error_pct": 0.0, "unripe_estimate": 1, "unripe_truth": 1, "exact_plants": 1.0}
    tally = {"frames": len(frames), "ripe": 0, "unripe": 0, "no_position": 0, "removed": 0, "unripe_removed": 0}
    (run_dir / "counts.json").write_text(json.dumps({"plants": plants, "rows": [], "total": total, "detections": tally, "settings": {}}))
    return {frame["index"]: len(frame["detections"]) for frame in frames}


@pytest.fixture(scope="module")
def flown(tmp_path_factory) -> Path:
    return fly_demo_raster(tmp_path_factory.mktemp("rerun") / "flown", rate_hz=0.25)


@pytest.fixture(scope="module")
def rendered(flown: Path, tmp_path_factory) -> tuple[Path, dict[int, int]]:
    run_dir = tmp_path_factory.mktemp("rerun") / "rendered"
    shutil.copytree(flown, run_dir)
    run_render(run_dir, read_config(run_dir))
    return run_dir, _fake_detections(run_dir)


def _column(table, name: str) -> list:
    return table.column(name).to_pylist()


def _entities(recording) -> set[str]:
    return {column.entity_path for column in recording.schema().component_columns()}


def _rgb_times(recording) -> np.ndarray:
    table = recording.view(index="sim_time", contents="/world/camera/image/rgb").select().read_all()
    return table.column("sim_time").cast("int64").to_numpy()


def test_recording_reads_back_with_poses_images_and_detections(rendered, tmp_path: Path):
    run_dir, boxes_per_frame = rendered
    out = tmp_path / "run.rrd"
    logged = write_rerun(read_run(run_dir), out)
    assert [p.name for p in tmp_path.iterdir()] == ["run.rrd"]  # no temporary left beside it

    times, positions, rotations = read_tum(run_dir / "groundtruth.txt")
    assert len(times) >= 5
    assert logged["frames"] == logged["images"] == len(times)
    assert logged["detections"] == sum(boxes_per_frame.values()) and logged["clusters"] == 4 and logged["uav_poses"] > 0

    recording = rr.dataframe.load_recording(out)
    assert recording.application_id() == "renderloop"
    assert {"/world", "/world/greenhouse/tables", "/world/greenhouse/plants", "/world/greenhouse/workstation",
            "/world/greenhouse/peppers", "/world/plan/waypoints", "/world/plan/camera_path", "/world/flight/camera_path",
            "/world/flight/body_path", "/world/uav", "/world/camera", "/world/camera/image", "/world/camera/image/rgb",
            "/world/camera/image/depth", "/world/camera/image/detections", "/world/camera/points", "/world/detections/points",
            "/world/counts/ripe", "/world/counts/unripe"} <= _entities(recording)
    np.testing.assert_allclose(_rgb_times(recording), np.round(times * 1e9), atol=1)

    cameras = recording.view(index="sim_time", contents={"/world/camera": ["Translation3D", "TransformMat3x3"]}).select().read_all()
    assert len(cameras) == len(times)
    for translation, matrix, position, rotation in zip(_column(cameras, "/world/camera:Translation3D"),
                                                      _column(cameras, "/world/camera:TransformMat3x3"), positions, rotations):
        np.testing.assert_allclose(translation[0], position, atol=1e-6)
        np.testing.assert_allclose(np.reshape(matrix[0], (3, 3)).T, rotation, atol=1e-6)  # Rerun stores it column-major

    boxes = recording.view(index="sim_time", contents={"/world/camera/image/detections": ["HalfSize2D"]}).select().read_all()
    assert [len(sizes) for sizes in _column(boxes, "/world/camera/image/detections:HalfSize2D")] == [
        boxes_per_frame[i] for i in range(len(times))]
    points = recording.view(index="sim_time", contents={"/world/detections/points": ["Position3D"]}).select().read_all()
    assert sum(len(p) for p in _column(points, "/world/detections/points:Position3D")) == sum(n >= 1 for n in boxes_per_frame.values())


def test_every_second_frame_keeps_poses_and_halves_images(rendered, tmp_path: Path):
    run_dir, _ = rendered
    contents = read_run(run_dir)
    logged = write_rerun(contents, tmp_path / "half.rrd", every=2)
    recording = rr.dataframe.load_recording(tmp_path / "half.rrd")
    expected = [f.timestamp for f in contents.frames if f.index % 2 == 0]
    assert logged["images"] == len(expected) == (len(contents.frames) + 1) // 2
    np.testing.assert_allclose(_rgb_times(recording), np.round(np.array(expected) * 1e9), atol=1)
    cameras = recording.view(index="sim_time", contents="/world/camera").select().read_all()
    assert logged["frames"] == len(cameras) == len(contents.frames)


def test_a_run_only_flown_still_writes_a_recording(flown: Path, tmp_path: Path):
    contents = read_run(flown)
    assert contents.flight is not None and not contents.frames
    out = tmp_path / "flown.rrd"
    logged = write_rerun(contents, out)
    assert logged["frames"] == logged["images"] == logged["detections"] == 0 and logged["uav_poses"] > 0
    entities = _entities(rr.dataframe.load_recording(out))
    assert {"/world/greenhouse/tables", "/world/plan/camera_path", "/world/flight/camera_path", "/world/uav"} <= entities
    assert not any(path.startswith("/world/camera") for path in entities)
    assert [p.name for p in tmp_path.iterdir()] == ["flown.rrd"]
