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
from renderloop.io.bounded import FINITE, Bound, check_columns, check_increasing


FORMAT = ["%.6f"] + ["%.9f"] * 7  # timestamp, then position and quaternion
COLUMNS = ["timestamp", "tx", "ty", "tz", "qx", "qy", "qz", "qw"]
UNIT_TOLERANCE = 1e-3  # how far from length 1 a stored quaternion may be (9 decimals are written)


def _rows(times: np.ndarray, positions: np.ndarray, rotations: np.ndarray) -> np.ndarray:
    quaternions = Rotation.from_matrix(rotations).as_quat()  # qx qy qz qw, as TUM and ROS store them
    return np.column_stack([times, positions, quaternions])


def write_tum(path: Path, times: np.ndarray, positions: np.ndarray, rotations: np.ndarray, comment: str) -> None:
    buffer = io.StringIO()
    buffer.write("".join(f"# {line}\n" for line in comment.splitlines()))
    buffer.write(f"# {' '.join(COLUMNS)}\n")
    np.savetxt(buffer, _rows(times, positions, rotations), fmt=FORMAT)
    write_text(path, buffer.getvalue())


def as_stored(position: np.ndarray, rotation: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """A pose as a TUM file gives it back: rounded as written, so a pose used now equals the one read later."""
    row = _rows(np.zeros(1), np.reshape(position, (1, 3)), np.reshape(rotation, (1, 3, 3)))[0]
    stored = np.array([float(fmt % value) for fmt, value in zip(FORMAT, row)])
    return stored[1:4], Rotation.from_quat(stored[4:8]).as_matrix()


def read_tum(path: Path, time: Bound = FINITE, position: Bound = FINITE) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Timestamps (N,), positions (N, 3) and rotation matrices (N, 3, 3). Timestamps within `time` and not
    decreasing, positions within `position`, quaternions of unit length: else one line naming the pose."""
    path = Path(path)
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", UserWarning)  # an empty file is reported below, in one line
            table = np.loadtxt(path, comments="#", ndmin=2)
    except FileNotFoundError:
        raise UserError(f"{path}: no such file") from None
    except (ValueError, UnicodeDecodeError) as exc:
        raise UserError(f"{path}: not a TUM pose file ({str(exc).splitlines()[0] if str(exc) else exc.__class__.__name__})") from None
    if table.size == 0:
        raise UserError(f"{path}: holds no poses")
    if table.shape[1] != len(COLUMNS):
        raise UserError(f"{path}: expected lines of {len(COLUMNS)} numbers: {' '.join(COLUMNS)}")

    def pose(index: int) -> str:
        return f"pose {index} (t={table[index, 0]})"

    check_columns(str(path), table, COLUMNS, [time, position, position, position] + [FINITE] * 4, pose)
    check_increasing(str(path), table[:, 0], COLUMNS[0], pose, strictly=False)
    with np.errstate(over="ignore"):  # a huge component makes the norm inf: not unit length, said below
        bad = np.flatnonzero(np.abs(np.linalg.norm(table[:, 4:8], axis=1) - 1.0) > UNIT_TOLERANCE)
    if len(bad):
        raise UserError(f"{path}: {pose(int(bad[0]))} has a quaternion that is not unit length")
    return table[:, 0], table[:, 1:4], Rotation.from_quat(table[:, 4:8]).as_matrix()
