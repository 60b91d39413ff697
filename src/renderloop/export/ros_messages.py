"""ROS 2 messages of a run, built with rosbags' typestore (no ROS install needed).

The types are those of ROS 2 Jazzy; vision_msgs is not in rosbags' stores, so its
4.1 definitions (the version Humble and Jazzy ship) are registered from their .msg
text. Images follow the RealSense driver's conventions, which RViz, Foxglove and
depth_image_proc expect: rgb8 colour, 16UC1 depth in millimetres (REP-118), both in
the camera optical frame; the organised cloud is XYZRGB with NaN where depth has
no return, packed the way PCL packs colour (an RGB triple in a float32).
"""

from __future__ import annotations

import numpy as np
from rosbags.typesys import Stores, get_types_from_msg, get_typestore
from scipy.spatial.transform import Rotation

from renderloop.render.camera import Intrinsics
from renderloop.rundir.models import Detection

VISION_MSGS = {
    "vision_msgs/msg/Point2D": "float64 x\nfloat64 y\n",
    "vision_msgs/msg/Pose2D": "vision_msgs/Point2D position\nfloat64 theta\n",
    "vision_msgs/msg/BoundingBox2D": "vision_msgs/Pose2D center\nfloat64 size_x\nfloat64 size_y\n",
    "vision_msgs/msg/ObjectHypothesis": "string class_id\nfloat64 score\n",
    "vision_msgs/msg/ObjectHypothesisWithPose": "vision_msgs/ObjectHypothesis hypothesis\ngeometry_msgs/PoseWithCovariance pose\n",
    "vision_msgs/msg/Detection2D": "std_msgs/Header header\nvision_msgs/ObjectHypothesisWithPose[] results\n"
                                   "vision_msgs/BoundingBox2D bbox\nstring id\n",
    "vision_msgs/msg/Detection2DArray": "std_msgs/Header header\nvision_msgs/Detection2D[] detections\n",
}


def make_typestore():
    typestore = get_typestore(Stores.ROS2_JAZZY)
    for name, text in VISION_MSGS.items():
        typestore.register(get_types_from_msg(text, name))
    return typestore


class RosMessages:
    """Builders of the messages a run exports, over one typestore."""

    def __init__(self) -> None:
        self.store = make_typestore()
        self.t = self.store.types

    def serialize(self, message) -> bytes:
        return self.store.serialize_cdr(message, message.__msgtype__)

    def time(self, seconds: float, kind: str = "Time"):
        """builtin_interfaces Time (a stamp) or Duration (time from start): whole seconds and nanoseconds."""
        nanoseconds = round(seconds * 1e9)
        return self.t[f"builtin_interfaces/msg/{kind}"](sec=nanoseconds // 10**9, nanosec=nanoseconds % 10**9)

    def header(self, seconds: float, frame_id: str):
        return self.t["std_msgs/msg/Header"](stamp=self.time(seconds), frame_id=frame_id)

    def pose(self, transform: np.ndarray):
        x, y, z, w = Rotation.from_matrix(transform[:3, :3]).as_quat()
        return self.t["geometry_msgs/msg/Pose"](
            position=self.t["geometry_msgs/msg/Point"](*map(float, transform[:3, 3])),
            orientation=self.t["geometry_msgs/msg/Quaternion"](float(x), float(y), float(z), float(w)),
        )

    def transform(self, seconds: float, parent: str, child: str, transform: np.ndarray):
        pose = self.pose(transform)
        p, q = pose.position, pose.orientation
        return self.t["geometry_msgs/msg/TransformStamped"](
            header=self.header(seconds, parent), child_frame_id=child,
            transform=self.t["geometry_msgs/msg/Transform"](
                translation=self.t["geometry_msgs/msg/Vector3"](p.x, p.y, p.z), rotation=q),
        )

    def tf(self, transforms: list):
        return self.t["tf2_msgs/msg/TFMessage"](transforms=transforms)

    def image(self, seconds: float, frame_id: str, pixels: np.ndarray, encoding: str):
        height, width = pixels.shape[:2]
        data = np.ascontiguousarray(pixels).view(np.uint8).reshape(-1)
        return self.t["sensor_msgs/msg/Image"](
            header=self.header(seconds, frame_id), height=height, width=width, encoding=encoding,
            is_bigendian=0, step=data.size // height, data=data)

    def camera_info(self, seconds: float, frame_id: str, intrinsics: Intrinsics):
        k = intrinsics.matrix
        roi = self.t["sensor_msgs/msg/RegionOfInterest"](x_offset=0, y_offset=0, height=0, width=0, do_rectify=False)
        return self.t["sensor_msgs/msg/CameraInfo"](
            header=self.header(seconds, frame_id), height=intrinsics.height, width=intrinsics.width,
            distortion_model="plumb_bob", d=np.zeros(5), k=k.ravel(), r=np.eye(3).ravel(),
            p=np.hstack([k, np.zeros((3, 1))]).ravel(), binning_x=0, binning_y=0, roi=roi)

    def point_cloud(self, seconds: float, frame_id: str, cloud: np.ndarray, rgb: np.ndarray):
        """Organised XYZRGB: x y z float32 and the colour as 0x00RRGGBB in a float32 slot."""
        height, width = cloud.shape[:2]
        packed = (rgb[..., 0].astype(np.uint32) << 16) | (rgb[..., 1].astype(np.uint32) << 8) | rgb[..., 2].astype(np.uint32)
        points = np.empty((height, width, 4), dtype=np.float32)
        points[..., :3] = cloud
        points[..., 3] = packed.view(np.float32)
        field = self.t["sensor_msgs/msg/PointField"]
        fields = [field(name=name, offset=4 * i, datatype=field.FLOAT32, count=1) for i, name in enumerate(("x", "y", "z", "rgb"))]
        return self.t["sensor_msgs/msg/PointCloud2"](
            header=self.header(seconds, frame_id), height=height, width=width, fields=fields, is_bigendian=False,
            point_step=16, row_step=16 * width, data=points.view(np.uint8).reshape(-1), is_dense=False)

    def odometry(self, seconds: float, body: np.ndarray, linear: np.ndarray, angular: np.ndarray):
        """Pose in the world, twist in the body frame (nav_msgs' convention for child_frame_id)."""
        covariance = np.zeros(36)
        vector = self.t["geometry_msgs/msg/Vector3"]
        return self.t["nav_msgs/msg/Odometry"](
            header=self.header(seconds, "world"), child_frame_id="base_link",
            pose=self.t["geometry_msgs/msg/PoseWithCovariance"](pose=self.pose(body), covariance=covariance),
            twist=self.t["geometry_msgs/msg/TwistWithCovariance"](
                twist=self.t["geometry_msgs/msg/Twist"](linear=vector(*map(float, linear)), angular=vector(*map(float, angular))),
                covariance=covariance))

    def trajectory_point(self, seconds: float, positions: np.ndarray, velocities: np.ndarray, accelerations: np.ndarray):
        return self.t["trajectory_msgs/msg/JointTrajectoryPoint"](
            positions=positions, velocities=velocities, accelerations=accelerations, effort=np.zeros(0),
            time_from_start=self.time(seconds, "Duration"))

    def detections(self, seconds: float, frame_id: str, found: list[Detection], world_to_camera: np.ndarray):
        """Detection2DArray; each hypothesis' pose is the fruit point in the camera frame (zero when it had none)."""
        items = []
        for number, detection in enumerate(found):
            x0, y0, x1, y1 = detection.bbox
            point = np.zeros(3) if detection.position is None else world_to_camera[:3, :3] @ detection.position + world_to_camera[:3, 3]
            hypothesis = self.t["vision_msgs/msg/ObjectHypothesisWithPose"](
                hypothesis=self.t["vision_msgs/msg/ObjectHypothesis"](class_id=detection.label, score=float(detection.score)),
                pose=self.t["geometry_msgs/msg/PoseWithCovariance"](pose=self.pose(_translation(point)), covariance=np.zeros(36)))
            box = self.t["vision_msgs/msg/BoundingBox2D"](
                center=self.t["vision_msgs/msg/Pose2D"](position=self.t["vision_msgs/msg/Point2D"](x=(x0 + x1) / 2, y=(y0 + y1) / 2), theta=0.0),
                size_x=float(x1 - x0), size_y=float(y1 - y0))
            items.append(self.t["vision_msgs/msg/Detection2D"](header=self.header(seconds, frame_id), results=[hypothesis], bbox=box, id=str(number)))
        return self.t["vision_msgs/msg/Detection2DArray"](header=self.header(seconds, frame_id), detections=items)

    def marker(self, seconds: float, namespace: str, number: int, kind: str, position, scale: float,
               rgba: tuple[float, float, float, float], text: str = ""):
        marker = self.t["visualization_msgs/msg/Marker"]
        return marker(
            header=self.header(seconds, "world"), ns=namespace, id=number, type=getattr(marker, kind), action=marker.ADD,
            pose=self.pose(_translation(position)), scale=self.t["geometry_msgs/msg/Vector3"](scale, scale, scale),
            color=self.t["std_msgs/msg/ColorRGBA"](*map(float, rgba)),
            lifetime=self.time(0.0, "Duration"), frame_locked=False, points=[], colors=[],
            texture_resource="", texture=self.t["sensor_msgs/msg/CompressedImage"](header=self.header(seconds, ""), format="", data=np.zeros(0, np.uint8)),
            uv_coordinates=[], text=text, mesh_resource="",
            mesh_file=self.t["visualization_msgs/msg/MeshFile"](filename="", data=np.zeros(0, np.uint8)), mesh_use_embedded_materials=False)

    def marker_array(self, markers: list):
        return self.t["visualization_msgs/msg/MarkerArray"](markers=markers)


def _translation(point) -> np.ndarray:
    transform = np.eye(4)
    transform[:3, 3] = point
    return transform
