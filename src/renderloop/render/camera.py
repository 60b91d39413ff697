"""The pinhole camera: intrinsics, projection, `camera_info.yaml`, and the one frame conversion.

Pixel (u, v) integers sit at pixel centres, so a centred principal point is
cx = (W-1)/2, cy = (H-1)/2. Poses are of the optical frame (x right, y down,
z forward); Blender and MuJoCo cameras look down their -z with y up, the same frame
turned half a turn about x: `to_gl_camera` is the only place that conversion lives.
Depth is planar, along the optical z axis (REP-118).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from renderloop.config import CameraConfig
from renderloop.config.fields import MAX_PIXELS
from renderloop.errors import UserError
from renderloop.io.atomic import write_text
from renderloop.io.bounded import field_bounds, load_yaml, number_text
from renderloop.rundir import files, names

OPTICAL_TO_GL = np.diag([1.0, -1.0, -1.0])
CAMERA_NAME = "renderloop_rgbd"
# camera_info.yaml's image is a camera the config allows: its width and height within camera.width's and
# camera.height's ranges, and at most MAX_PIXELS in all.
IMAGE_SIDES = {"image_width": field_bounds(CameraConfig, "width"), "image_height": field_bounds(CameraConfig, "height")}
# A focal length of 100 image widths is a 0.6° field of view, narrower than camera.hfov_deg allows (1°).
MAX_FOCAL_WIDTHS = 100
# The matrices of a ROS camera_info and their shape (rows, cols); None: as many as the file says (distortion).
MATRICES: dict[str, tuple[int, int | None]] = {
    "camera_matrix": (3, 3), "distortion_coefficients": (1, None), "rectification_matrix": (3, 3), "projection_matrix": (3, 4)}


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


def _shown(value: Any) -> str:
    """A value of the file as a message shows it: a number's digits, else its type (a string may be any length)."""
    if isinstance(value, (int, float)) and not isinstance(value, bool):
        return number_text(float(value)) if isinstance(value, float) or abs(value) < 10**15 else "a huge integer"
    return "nothing" if value is None else f"a {type(value).__name__}"


def _matrix(data: dict[str, Any], name: str, source: str) -> np.ndarray | None:
    """One of MATRICES, its entries finite and as many as its rows x cols; None when the file leaves it out."""
    if name not in data:
        return None
    rows, cols = MATRICES[name]
    entry = data[name]
    values = entry.get("data") if isinstance(entry, dict) else None
    if not isinstance(values, list):
        raise UserError(f"{source}: {name}: not a ROS camera_info matrix (rows, cols, data)")
    for index, value in enumerate(values):
        if not isinstance(value, (int, float)) or isinstance(value, bool) or not math.isfinite(value):
            raise UserError(f"{source}: {name}.data.{index}: {_shown(value)} is not a finite number")
    expected = rows * (cols if cols is not None else len(values))
    if len(values) != expected or (cols is None and not values):
        raise UserError(f"{source}: {name}: {len(values)} numbers, not {rows} x {cols or 'n'}")
    return np.array(values, dtype=float).reshape(rows, -1)


def parse_camera_info(text: str, source: str = "camera_info.yaml") -> Intrinsics:
    """The intrinsics of a ROS camera_info YAML (`source` names it in messages): its image size one the camera
    config allows, every matrix entry finite, focal lengths positive and the principal point in the image.
    Anything else is one UserError line."""
    data = load_yaml(text, source)
    if not isinstance(data, dict) or "camera_matrix" not in data:
        raise UserError(f"{source}: not a ROS camera_info YAML (no camera_matrix)")
    size = []
    for key, (low, high) in IMAGE_SIDES.items():
        value = data.get(key)
        if not isinstance(value, int) or isinstance(value, bool):
            raise UserError(f"{source}: {key}: {_shown(value)} is not a whole number of pixels")
        if not low <= value <= high:
            raise UserError(f"{source}: {key}: {value} is out of range [{low}, {high}] px")
        size.append(value)
    width, height = size
    if width * height > MAX_PIXELS:
        raise UserError(f"{source}: image_width: a {width} x {height} px image is more than {MAX_PIXELS} px")
    matrices = {name: _matrix(data, name, source) for name in MATRICES}
    k = matrices["camera_matrix"]
    intrinsics = Intrinsics(width, height, float(k[0, 0]), float(k[1, 1]), float(k[0, 2]), float(k[1, 2]))
    for name, value, high in (("fx", intrinsics.fx, MAX_FOCAL_WIDTHS * width), ("fy", intrinsics.fy, MAX_FOCAL_WIDTHS * width)):
        if not 0 < value <= high:
            raise UserError(f"{source}: camera_matrix: {name} {number_text(value)} is out of range (0, {high}] px")
    for name, value, high in (("cx", intrinsics.cx, width), ("cy", intrinsics.cy, height)):
        if not 0 <= value <= high:
            raise UserError(f"{source}: camera_matrix: {name} {number_text(value)} is out of range [0, {high}] px, "
                            "outside the image")
    return intrinsics


def write_camera_info(run_dir: Path, intrinsics: Intrinsics) -> None:
    write_text(Path(run_dir) / names.CAMERA_INFO, camera_info_yaml(intrinsics))


def read_camera_info(run_dir: Path) -> Intrinsics:
    files.require(run_dir, (names.CAMERA_INFO,))
    path = Path(run_dir) / names.CAMERA_INFO
    try:
        text = path.read_text(encoding="utf-8")
    except UnicodeDecodeError:
        raise UserError(f"{path}: not a ROS camera_info YAML") from None
    return parse_camera_info(text, str(path))
