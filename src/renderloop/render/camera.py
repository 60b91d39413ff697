"""The pinhole camera: intrinsics, projection, `camera_info.yaml`, and the one frame conversion.

Pixel (u, v) integers sit at pixel centres, so a centred principal point is
cx = (W-1)/2, cy = (H-1)/2. Poses are of the optical frame (x right, y down,
z forward); Blender and MuJoCo cameras look down their -z with y up, the same frame
turned half a turn about x: `to_gl_camera` is the only place that conversion lives.
Depth is planar, along the optical z axis (REP-118).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import yaml

from renderloop.config import CameraConfig

OPTICAL_TO_GL = np.diag([1.0, -1.0, -1.0])
CAMERA_NAME = "renderloop_rgbd"


@dataclass(frozen=True)
class Intrinsics:
    width: int
    height: int
    fx: float
    fy: float
    cx: float
    cy: float

    @classmethod
    def from_config(cls, camera: CameraConfig) -> Intrinsics:
        return cls(camera.width, camera.height, camera.fx, camera.fx, (camera.width - 1) / 2, (camera.height - 1) / 2)

    @property
    def matrix(self) -> np.ndarray:
        return np.array([[self.fx, 0.0, self.cx], [0.0, self.fy, self.cy], [0.0, 0.0, 1.0]])

    @property
    def fovy_deg(self) -> float:
        """Vertical field of view, what MuJoCo's camera takes (square pixels, centred principal point)."""
        return float(np.degrees(2 * np.arctan(self.height / 2 / self.fy)))

    def corner_range(self, depth: float) -> float:
        """How far from the camera an image corner's ray runs before it reaches planar `depth`: the farthest point
        of the clip plane at that depth."""
        return float(depth * np.hypot(np.hypot(1.0, self.width / 2 / self.fx), self.height / 2 / self.fy))

    def project(self, points: np.ndarray) -> np.ndarray:
        """Optical-frame points (N, 3) to pixel coordinates (N, 2)."""
        points = np.atleast_2d(points)
        return np.column_stack([self.fx * points[:, 0] / points[:, 2] + self.cx, self.fy * points[:, 1] / points[:, 2] + self.cy])

    def back_project(self, pixels: np.ndarray, depth: np.ndarray) -> np.ndarray:
        """Pixels (N, 2) with planar depths (N,) to optical-frame points (N, 3)."""
        pixels = np.atleast_2d(pixels)
        z = np.asarray(depth, dtype=float)
        return np.column_stack([(pixels[:, 0] - self.cx) * z / self.fx, (pixels[:, 1] - self.cy) * z / self.fy, z])


def to_gl_camera(pose: np.ndarray) -> np.ndarray:
    """T_world_optical -> T_world_camera for a camera that looks down -z with y up (Blender, MuJoCo)."""
    converted = np.array(pose, dtype=float)
    converted[:3, :3] = pose[:3, :3] @ OPTICAL_TO_GL
    return converted


def camera_info_yaml(intrinsics: Intrinsics) -> str:
    """ROS camera_calibration YAML of an ideal (undistorted, rectified) camera."""
    k = intrinsics.matrix
    projection = np.hstack([k, np.zeros((3, 1))])
    data = {
        "image_width": intrinsics.width,
        "image_height": intrinsics.height,
        "camera_name": CAMERA_NAME,
        "camera_matrix": {"rows": 3, "cols": 3, "data": [float(v) for v in k.ravel()]},
        "distortion_model": "plumb_bob",
        "distortion_coefficients": {"rows": 1, "cols": 5, "data": [0.0] * 5},
        "rectification_matrix": {"rows": 3, "cols": 3, "data": [float(v) for v in np.eye(3).ravel()]},
        "projection_matrix": {"rows": 3, "cols": 4, "data": [float(v) for v in projection.ravel()]},
    }
    return yaml.safe_dump(data, sort_keys=False)


def parse_camera_info(text: str) -> Intrinsics:
    """The intrinsics of a ROS camera_info YAML; ValueError says what is wrong with it."""
    try:
        data = yaml.safe_load(text)
        k = np.array(data["camera_matrix"]["data"], dtype=float).reshape(3, 3)
        intrinsics = Intrinsics(int(data["image_width"]), int(data["image_height"]), k[0, 0], k[1, 1], k[0, 2], k[1, 2])
    except (yaml.YAMLError, KeyError, TypeError, ValueError):
        raise ValueError("not a ROS camera_info YAML") from None
    if not (0 < intrinsics.width <= 65535 and 0 < intrinsics.height <= 65535):
        raise ValueError(f"image size {intrinsics.width}x{intrinsics.height} is not a camera's")
    if not (np.isfinite([intrinsics.fx, intrinsics.fy, intrinsics.cx, intrinsics.cy]).all() and intrinsics.fx > 0 and intrinsics.fy > 0):
        raise ValueError("camera_matrix: focal lengths must be positive and finite")
    return intrinsics
