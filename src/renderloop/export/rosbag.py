"""`renderloop export DIR --rosbag OUT`: a run as a ROS 2 bag (MCAP storage, zstd chunks), stamped in sim time.

Topics and frames are those of a real UAV with a RealSense on its arm, so RViz,
Foxglove and ROS nodes (depth_image_proc, vision_msgs consumers) take the bag as is:
/tf carries world -> base_link -> arm_link1..3 at the flight log's rate, /tf_static
the fixed arm_link3 -> camera_optical_frame, so composing /tf at a frame's stamp
gives that frame's pose in groundtruth.txt. Messages are written in time order.
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Callable, Iterator
from pathlib import Path

import numpy as np
from rosbags.interfaces import (
    Qos,
    QosDurability,
    QosHistory,
    QosLiveliness,
    QosReliability,
    QosTime,
)
from rosbags.rosbag2 import Writer
from rosbags.rosbag2.enums import CompressionFormat, CompressionMode, StoragePlugin
from scipy.spatial.transform import Rotation

from renderloop.export.ros_messages import RosMessages
from renderloop.io import ownership
from renderloop.io.atomic import atomic_directory
from renderloop.perception.pointcloud import organised_cloud
from renderloop.render.frames import decode_depth, read_png
from renderloop.robot.kinematics import arm_frames, homogeneous
from renderloop.export.contents import RunContents

OPTICAL_FRAME = "camera_optical_frame"
LINKS = ("base_link", "arm_link1", "arm_link2", "arm_link3")
TOPICS = {
    "/tf": "tf2_msgs/msg/TFMessage",
    "/tf_static": "tf2_msgs/msg/TFMessage",
    "/uav/odometry": "nav_msgs/msg/Odometry",
    "/uav/reference": "trajectory_msgs/msg/JointTrajectoryPoint",
    "/camera/color/image_raw": "sensor_msgs/msg/Image",
    "/camera/color/camera_info": "sensor_msgs/msg/CameraInfo",
    "/camera/depth/image_rect_raw": "sensor_msgs/msg/Image",
    "/camera/depth/camera_info": "sensor_msgs/msg/CameraInfo",
    "/camera/depth/color/points": "sensor_msgs/msg/PointCloud2",
    "/detections": "vision_msgs/msg/Detection2DArray",
    "/peppers": "visualization_msgs/msg/MarkerArray",
}
LATCHED = Qos(QosHistory.KEEP_LAST, 1, QosReliability.RELIABLE, QosDurability.TRANSIENT_LOCAL, QosTime(0, 0),
              QosTime(0, 0), QosLiveliness.AUTOMATIC, QosTime(0, 0), False)

Message = tuple[str, object]  # topic, message
Event = tuple[int, int, Callable[[], list[Message]]]  # stamp in ns, order among equal stamps, builder


def _nanoseconds(seconds: float) -> int:
    return round(seconds * 1e9)


def _body_poses(flight: dict[str, np.ndarray]) -> np.ndarray:
    rotations = Rotation.from_quat(np.column_stack([flight[k] for k in ("qx", "qy", "qz", "qw")])).as_matrix()
    positions = np.column_stack([flight["x"], flight["y"], flight["z"]])
    return np.array([homogeneous(r, p) for r, p in zip(rotations, positions)])


def _body_twist(t: np.ndarray, poses: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Linear and angular velocity in the body frame, by differences of the logged poses (the log has no rates)."""
    if len(t) < 2:
        return np.zeros((len(t), 3)), np.zeros((len(t), 3))
    rotations = poses[:, :3, :3]
    world_velocity = np.gradient(poses[:, :3, 3], t, axis=0)
    linear = np.einsum("nji,nj->ni", rotations, world_velocity)
    step = Rotation.from_matrix(np.einsum("nji,njk->nik", rotations[:-1], rotations[1:])).as_rotvec()
    angular = step / np.diff(t)[:, None]
    return linear, np.vstack([angular, angular[-1:]])


class BagBuilder:
    """The time-ordered events of one run; each builds its messages only when written."""

    def __init__(self, contents: RunContents, every: int) -> None:
        self.run, self.every, self.ros = contents, every, RosMessages()
        self.arm = contents.config.robot.arm

    def events(self) -> Iterator[Event]:
        run = self.run
        static = arm_frames(self.arm, (0.0, 0.0, 0.0))
        link_to_optical = np.linalg.inv(static[2]) @ static[3]  # the same at every q: the camera rides the last link
        yield 0, 0, lambda: [("/tf_static", self.ros.tf([self.ros.transform(0.0, LINKS[-1], OPTICAL_FRAME, link_to_optical)]))]
        if run.counts is not None and run.scene is not None:
            yield 0, 1, lambda: [("/peppers", self._peppers())]
        if run.flight is not None:
            t = run.flight["t"]
            poses = _body_poses(run.flight)
            linear, angular = _body_twist(t, poses)
            for k in range(len(t)):
                yield _nanoseconds(t[k]), 2, lambda k=k: self._flight_row(k, poses[k], linear[k], angular[k])
        if run.trajectory is not None:
            for row in run.trajectory:
                yield _nanoseconds(row[0]), 3, lambda row=row: [("/uav/reference", self.ros.trajectory_point(row[0], row[1:8], row[8:15], row[15:22]))]
        for number, frame in enumerate(run.frames):
            if number % self.every == 0:
                yield _nanoseconds(frame.timestamp), 4, lambda frame=frame: self._camera(frame)
            if run.detections is not None:
                found = run.detections.get(frame.index, [])
                yield _nanoseconds(frame.timestamp), 5, lambda frame=frame, found=found: [
                    ("/detections", self.ros.detections(frame.timestamp, OPTICAL_FRAME, found, np.linalg.inv(frame.pose)))]

    def _flight_row(self, row: int, body: np.ndarray, linear: np.ndarray, angular: np.ndarray) -> list[Message]:
        flight = self.run.flight
        seconds = float(flight["t"][row])
        joints = arm_frames(self.arm, (flight["q1"][row], flight["q2"][row], flight["q3"][row]))[:3]
        chain = [body, joints[0], np.linalg.inv(joints[0]) @ joints[1], np.linalg.inv(joints[1]) @ joints[2]]
        parents = ("world", *LINKS[:-1])
        transforms = [self.ros.transform(seconds, parent, child, T) for parent, child, T in zip(parents, LINKS, chain)]
        return [("/tf", self.ros.tf(transforms)), ("/uav/odometry", self.ros.odometry(seconds, body, linear, angular))]

    def _camera(self, frame) -> list[Message]:
        ros, seconds, intrinsics = self.ros, frame.timestamp, self.run.intrinsics
        rgb = read_png(frame.rgb, np.uint8)[..., :3]
        depth = decode_depth(read_png(frame.depth, np.uint16))
        millimetres = np.round(depth * 1000.0).astype(np.uint16)  # 0 (no return) stays 0
        return [
            ("/camera/color/camera_info", ros.camera_info(seconds, OPTICAL_FRAME, intrinsics)),
            ("/camera/color/image_raw", ros.image(seconds, OPTICAL_FRAME, rgb, "rgb8")),
            ("/camera/depth/camera_info", ros.camera_info(seconds, OPTICAL_FRAME, intrinsics)),
            ("/camera/depth/image_rect_raw", ros.image(seconds, OPTICAL_FRAME, millimetres, "16UC1")),
            ("/camera/depth/color/points", ros.point_cloud(seconds, OPTICAL_FRAME, organised_cloud(depth, intrinsics), rgb)),
        ]

    def _peppers(self):
        """The counted fruit, one sphere per cluster in its plant's colour, and a label per plant: estimate (truth)."""
        scene = self.run.scene
        palette = _palette(len(scene.plants))
        markers = []
        for entry in self.run.counts.plants:
            colour = palette[entry.id % len(palette)]
            for centres, shape in ((entry.clusters, "SPHERE"), (entry.unripe_clusters, "CUBE")):
                for centre in centres:
                    markers.append(self.ros.marker(0.0, f"plant_{entry.id}", len(markers), shape, centre, 0.06, colour))
            box = scene.plant(entry.id).bounds
            top = [(box.min[0] + box.max[0]) / 2, (box.min[1] + box.max[1]) / 2, box.max[2] + 0.1]
            label = f"plant {entry.id}: {entry.estimate} ({entry.truth})"
            markers.append(self.ros.marker(0.0, "labels", len(markers), "TEXT_VIEW_FACING", top, 0.08, (1.0, 1.0, 1.0, 1.0), label))
        return self.ros.marker_array(markers)


def _palette(count: int) -> list[tuple[float, float, float, float]]:
    import matplotlib

    colours = matplotlib.colormaps["tab20"](np.arange(max(count, 1)) % 20)
    return [tuple(map(float, c)) for c in colours]


def write_rosbag(contents: RunContents, out: Path, every: int = 1) -> dict[str, int]:
    """Write the bag directory `out` (metadata.yaml + one .mcap); returns messages per topic. An existing `out` is
    replaced only if it is a bag renderloop wrote."""
    builder = BagBuilder(contents, every)
    counts: Counter[str] = Counter()
    with atomic_directory(Path(out), ownership.BAG) as tmp:
        writer = Writer(tmp, version=9, storage_plugin=StoragePlugin.MCAP)
        writer.set_compression(CompressionMode.STORAGE, CompressionFormat.ZSTD)
        with writer:
            connections = {}
            for stamp, _, build in sorted(builder.events(), key=lambda event: event[:2]):
                for topic, message in build():
                    if topic not in connections:  # only topics with messages: a run not yet rendered has no camera topics
                        connections[topic] = writer.add_connection(
                            topic, TOPICS[topic], typestore=builder.ros.store,
                            offered_qos_profiles=[LATCHED] if topic == "/tf_static" else ())
                    writer.write(connections[topic], stamp, builder.ros.serialize(message))
                    counts[topic] += 1
    return dict(counts)
