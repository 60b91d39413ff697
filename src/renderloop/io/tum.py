"""TUM RGB-D trajectory files: `timestamp tx ty tz qx qy qz qw`, one pose per line, '#' comments.

Open3D, evo and the SLAM tools read them as they are.
"""

from __future__ import annotations

import io
import warnings
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from renderloop.errors import UserError
from renderloop.io.atomic import write_text


FORMAT = ["%.6f"] + ["%.9f"] * 7  # timestamp, then position and quaternion


def _rows(times: np.ndarray, positions: np.ndarray, rotations: np.ndarray) -> np.ndarray:
    quaternions = Rotation.from_matrix(rotations).as_quat()  # qx qy qz qw, as TUM and ROS store them
    return np.column_stack([times, positions, quaternions])


def write_tum(path: Path, times: np.ndarray, positions: np.ndarray, rotations: np.ndarray, comment: str) -> None:
    buffer = io.StringIO()
    buffer.write("".join(f"# {line}\n" for line in comment.splitlines()))
    buffer.write("# timestamp tx ty tz qx qy qz qw\n")
    np.savetxt(buffer, _rows(times, positions, rotations), fmt=FORMAT)
    write_text(path, buffer.getvalue())


def as_stored(position: np.ndarray, rotation: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """A pose as a TUM file gives it back: rounded as written, so a pose used now equals the one read later."""
    row = _rows(np.zeros(1), np.reshape(position, (1, 3)), np.reshape(rotation, (1, 3, 3)))[0]
    stored = np.array([float(fmt % value) for fmt, value in zip(FORMAT, row)])
    return stored[1:4], Rotation.from_quat(stored[4:8]).as_matrix()


def read_tum(path: Path) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Timestamps (N,), positions (N, 3) and rotation matrices (N, 3, 3)."""
    path = Path(path)
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", UserWarning)  # an empty file is reported below, in one line
            table = np.loadtxt(path, comments="#", ndmin=2)
    except FileNotFoundError:
        raise UserError(f"{path}: no such file") from None
    except ValueError as exc:
        raise UserError(f"{path}: not a TUM pose file ({str(exc).splitlines()[0]})") from None
    if table.size == 0:
        raise UserError(f"{path}: holds no poses")
    if table.shape[1] != 8:
        raise UserError(f"{path}: expected lines of 8 numbers: timestamp tx ty tz qx qy qz qw")
    bad = np.flatnonzero(~np.all(np.isfinite(table), axis=1) | (np.abs(np.linalg.norm(table[:, 4:8], axis=1) - 1.0) > 1e-3))
    if len(bad):
        raise UserError(f"{path}: pose {bad[0]} (t={table[bad[0], 0]}) has NaN or a quaternion that is not unit length")
    return table[:, 0], table[:, 1:4], Rotation.from_quat(table[:, 4:8]).as_matrix()
