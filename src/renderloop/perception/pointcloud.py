"""The organised point cloud of a depth image: ROS depth_image_proc's and Open3D's math, vectorised.

For pixel (u, v) with planar depth z: x = (u - cx) z / fx, y = (v - cy) z / fy, in the
camera optical frame. The cloud keeps the image's H x W layout (so a 2D box selects
its 3D points by slicing) with NaN where the depth has no return.
"""

from __future__ import annotations

import numpy as np

from renderloop.render.camera import Intrinsics


def organised_cloud(depth: np.ndarray, intrinsics: Intrinsics) -> np.ndarray:
    """(H, W, 3) float32 points in the optical frame; NaN where depth is 0 (no return)."""
    height, width = depth.shape
    if (width, height) != (intrinsics.width, intrinsics.height):
        raise ValueError(f"depth is {width}x{height} but the camera is {intrinsics.width}x{intrinsics.height}")
    z = np.where(depth > 0, depth, np.nan).astype(np.float32)
    u = (np.arange(width, dtype=np.float32) - intrinsics.cx) / intrinsics.fx
    v = (np.arange(height, dtype=np.float32) - intrinsics.cy) / intrinsics.fy
    return np.stack([u[None, :] * z, v[:, None] * z, z], axis=-1)


def to_world(points: np.ndarray, pose: np.ndarray) -> np.ndarray:
    """Optical-frame points (..., 3) into the world with T_world_optical; NaN stays NaN."""
    return points @ pose[:3, :3].T.astype(points.dtype) + pose[:3, 3].astype(points.dtype)
