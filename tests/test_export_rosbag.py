"""The ROS 2 bag of a run: every message reads back, and it says what the run directory says."""

from __future__ import annotations

import json
from collections import Counter, defaultdict
from pathlib import Path

import numpy as np
import pytest
from conftest import cli, fly_demo_raster
from rosbags.highlevel import AnyReader
from scipy.spatial.transform import Rotation

from renderloop.export.command import export_run
from renderloop.export.rosbag import LINKS, OPTICAL_FRAME
from renderloop.perception.pointcloud import organised_cloud
from renderloop.render.camera import read_camera_info
from renderloop.render.frames import decode_depth, read_png
from renderloop.rundir.files import read_poses


@pytest.fixture(scope="module")
def run_dir(complete_run: Path) -> Path:
    return complete_run


@pytest.fixture(scope="module")
def bag(run_dir: Path, tmp_path_factory) -> dict:
    """The exported bag, read back with rosbags' own reader from the definitions stored in it."""
    path = tmp_path_factory.mktemp("bag") / "run_bag"
    assert export_run(run_dir, path, None, every=1, force=False, echo=print) == []
    messages = defaultdict(list)
    with AnyReader([path]) as reader:
        for connection, stamp, raw in reader.messages():
            messages[connection.topic].append((stamp, reader.deserialize(raw, connection.msgtype)))
    return {"path": path, "messages": messages}


def _matrix(transform) -> np.ndarray:
    matrix = np.eye(4)
    q, p = transform.rotation, transform.translation
    matrix[:3, :3] = Rotation.from_quat([q.x, q.y, q.z, q.w]).as_matrix()
    matrix[:3, 3] = [p.x, p.y, p.z]
    return matrix


def test_message_counts_match_frames_and_flight_log(bag: dict, run_dir: Path):
    counts = Counter({topic: len(entries) for topic, entries in bag["messages"].items()})
    frames = len(read_poses(run_dir)[0])
    flight_rows = len((run_dir / "flight.csv").read_text().splitlines()) - 1
    trajectory_rows = len((run_dir / "trajectory.csv").read_text().splitlines()) - 1
    for topic in ("/camera/color/image_raw", "/camera/color/camera_info", "/camera/depth/image_rect_raw",
                  "/camera/depth/camera_info", "/camera/depth/color/points", "/detections"):
        assert counts[topic] == frames, topic
    assert counts["/tf"] == counts["/uav/odometry"] == flight_rows
    assert counts["/uav/reference"] == trajectory_rows
    assert counts["/tf_static"] == counts["/peppers"] == 1
    stamps = [stamp for entries in bag["messages"].values() for stamp, _ in entries]
    assert min(stamps) == 0  # simulation time, from the start of the trajectory


def test_clouds_are_the_perception_stage_cloud_and_images_the_frames(bag: dict, run_dir: Path):
    intrinsics = read_camera_info(run_dir)
    depth_dir = "depth_sensor" if (run_dir / "depth_sensor").is_dir() else "depth"
    clouds = bag["messages"]["/camera/depth/color/points"]
    depths = bag["messages"]["/camera/depth/image_rect_raw"]
    colours = bag["messages"]["/camera/color/image_raw"]
    for index in (0, len(clouds) // 2, len(clouds) - 1):
        cloud_msg, depth_msg, colour_msg = clouds[index][1], depths[index][1], colours[index][1]
        assert (cloud_msg.width, cloud_msg.height) == (intrinsics.width, intrinsics.height)
        assert cloud_msg.header.frame_id == depth_msg.header.frame_id == OPTICAL_FRAME
        points = np.frombuffer(cloud_msg.data.tobytes(), dtype=np.float32).reshape(cloud_msg.height, cloud_msg.width, 4)
        depth = decode_depth(read_png(run_dir / depth_dir / f"{index:06d}.png", np.uint16))
        expected = organised_cloud(depth, intrinsics)
        np.testing.assert_array_equal(points[..., :3], expected)  # NaN where the perception cloud has no return
        rgb = read_png(run_dir / "rgb" / f"{index:06d}.png", np.uint8)
        packed = points[..., 3].view(np.uint32)
        np.testing.assert_array_equal(np.stack([packed >> 16, (packed >> 8) & 255, packed & 255], axis=-1), rgb)
        assert colour_msg.encoding == "rgb8" and colour_msg.data.tobytes() == rgb.tobytes()
        assert depth_msg.encoding == "16UC1"
        millimetres = np.frombuffer(depth_msg.data.tobytes(), dtype=np.uint16).reshape(depth.shape)
        assert np.all((millimetres == 0) == (depth == 0))
        assert np.abs(millimetres / 1000.0 - depth).max() <= 0.0005


def test_camera_info_is_the_run_camera(bag: dict, run_dir: Path):
    intrinsics = read_camera_info(run_dir)
    for topic in ("/camera/color/camera_info", "/camera/depth/camera_info"):
        info = bag["messages"][topic][0][1]
        assert (info.width, info.height) == (intrinsics.width, intrinsics.height)
        np.testing.assert_array_equal(info.k.reshape(3, 3), intrinsics.matrix)
        np.testing.assert_array_equal(info.p.reshape(3, 4)[:, :3], intrinsics.matrix)
        assert info.distortion_model == "plumb_bob" and not info.d.any()


def test_tf_at_frame_stamps_composes_to_the_ground_truth_pose(bag: dict, run_dir: Path):
    (static,) = bag["messages"]["/tf_static"]
    (link_to_camera,) = static[1].transforms
    assert (link_to_camera.header.frame_id, link_to_camera.child_frame_id) == (LINKS[-1], OPTICAL_FRAME)
    tf_at = {stamp: message.transforms for stamp, message in bag["messages"]["/tf"]}
    times, poses = read_poses(run_dir)
    for stamp, pose in zip(times, poses):
        chain = tf_at[round(stamp * 1e9)]
        assert [(t.header.frame_id, t.child_frame_id) for t in chain] == list(zip(("world", *LINKS[:-1]), LINKS))
        composed = np.linalg.multi_dot([_matrix(t.transform) for t in chain] + [_matrix(link_to_camera.transform)])
        assert np.linalg.norm(composed[:3, 3] - pose[:3, 3]) < 1e-3
        assert np.degrees(Rotation.from_matrix(composed[:3, :3].T @ pose[:3, :3]).magnitude()) < 0.1


def test_detections_and_counted_peppers(bag: dict, run_dir: Path):
    frames = json.loads((run_dir / "detections.json").read_text())["frames"]
    arrays = bag["messages"]["/detections"]
    assert [len(message.detections) for _, message in arrays] == [len(frame["detections"]) for frame in frames]
    for (_, message), frame in zip(arrays, frames):
        for detection, truth in zip(message.detections, frame["detections"]):
            x0, _y0, x1, _y1 = truth["bbox"]
            assert (detection.bbox.center.position.x, detection.bbox.size_x) == pytest.approx(((x0 + x1) / 2, x1 - x0))
            assert detection.results[0].hypothesis.class_id == truth["label"]
    counts = json.loads((run_dir / "counts.json").read_text())
    spheres = [m for m in bag["messages"]["/peppers"][0][1].markers if m.type == m.SPHERE]
    assert len(spheres) == sum(len(plant["clusters"]) for plant in counts["plants"])


def test_existing_output_is_refused_and_a_run_without_frames_exports_what_it_has(bag: dict, run_dir: Path, tmp_path: Path,
                                                                                monkeypatch, capsys):
    code, _, err = cli(monkeypatch, capsys, "export", str(run_dir), "--rosbag", str(bag["path"]))
    assert code == 2 and "exists" in err and len(err.strip().splitlines()) == 1
    flown = fly_demo_raster(tmp_path / "flown", rate_hz=0.2)
    code, _out, err = cli(monkeypatch, capsys, "export", str(flown), "--rosbag", str(tmp_path / "flown_bag"))
    assert code == 2 and "frames (0 of" in err and len(err.strip().splitlines()) == 1
    with AnyReader([tmp_path / "flown_bag"]) as reader:
        topics = set(reader.topics)
    assert "/tf" in topics and "/camera/color/image_raw" not in topics
    assert not list(tmp_path.glob(".*partial*"))
