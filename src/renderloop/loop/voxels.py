"""An occupancy voxel map built only from depth frames: what the robot itself knows about the space round a plant.

The map is an axis-aligned box of the world frame (m) cut into cubes of `voxel` m, each
unknown, free or occupied. It is filled from planar depth frames (REP-118, along the
optical z axis) and camera poses (T_world_optical), never from the scene's truth.

The rule is "occupied wins": a voxel where any ray returned is occupied, one that a ray
only passed through is free, and the rest stay unknown. The map is then the same
whatever order its frames come in (the online loop's workers may deliver them in any
order), and a grazing ray that passes a corner of a leaf's voxel on its way to the
background cannot erase the leaf, which counting hits and misses (log-odds) can at a
2 cm grid. Its cost, a noise spike that stays occupied, is small here: the depth noise
(a few mm at the ranges a plant is scanned from) is well under a voxel.

No return (depth 0 or NaN) marks nothing. A sensor's no-return is ambiguous: too near
(under the near clip), too far, or a surface it cannot see (dark, glossy, grazing); marking
the ray free would erase what stands there. Returns beyond `max_range` (along the ray)
mark the ray free up to `max_range` and nothing at the return: the depth noise grows
with the square of the range. Unknown voxels never block a ray in the queries
(`visible`, `gain`): what has not been seen may be free.

The rays are walked voxel by voxel (Amanatides and Woo's 3D DDA), compiled with numba;
every compiled function lives in this module, as numba's on-disk cache notices edits to
the file that defines a function, not to the files of the functions it calls.
Everything is deterministic.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from numba import njit

from renderloop.errors import UserError
from renderloop.render.camera import Intrinsics

UNKNOWN, FREE, OCCUPIED = 0, 1, 2  # voxel states (int8)
MAX_RANGE = 2.0  # m along a ray: beyond it the depth noise (growing with z²) is no longer well under a 2 cm voxel
MAX_VOXELS = 2**27  # a map larger than this (128 MiB of states) is a mistaken voxel size or box
EDGE = 1e-9  # voxels: a bound this close to a voxel edge sits on that edge (float rounding of (x - lower) / voxel)

_compiled = njit(cache=True)


# ------------------------------------------------------------------------------------------------ the ray walk


@_compiled
def _clip_to_box(origin, direction, lower, upper):
    """(t0, t1): the part of origin + t·direction inside the box (t0 > t1: none)."""
    t0, t1 = -np.inf, np.inf
    for a in range(3):
        if direction[a] != 0.0:
            ta = (lower[a] - origin[a]) / direction[a]
            tb = (upper[a] - origin[a]) / direction[a]
            t0 = max(t0, min(ta, tb))
            t1 = min(t1, max(ta, tb))
        elif origin[a] < lower[a] or origin[a] > upper[a]:
            return 1.0, 0.0
    return t0, t1


@_compiled
def _axis(origin, direction, lower, voxel, count, t):
    """One axis of the walk's start at parameter t: the voxel, the step, the t of the next boundary, the t between
    boundaries."""
    i = min(max(int(math.floor((origin + t * direction - lower) / voxel)), 0), count - 1)  # on a face: the inside one
    if direction > 0.0:
        return i, 1, (lower + (i + 1) * voxel - origin) / direction, voxel / direction
    if direction < 0.0:
        return i, -1, (lower + i * voxel - origin) / direction, -voxel / direction
    return i, 0, np.inf, np.inf


@_compiled
def _walk(origin, direction, lower, upper, voxel, shape, stop, cells):
    """Amanatides and Woo: the flat indices of the voxels that origin + t·direction passes for t in [0, stop] inside
    the map, in order, into `cells`; their count. On a tie the first axis steps first."""
    t0, t1 = _clip_to_box(origin, direction, lower, upper)
    t0 = max(t0, 0.0)
    stop = min(stop, t1)
    if t0 > stop:
        return 0
    nx, ny, nz = shape
    i, si, bx, dx = _axis(origin[0], direction[0], lower[0], voxel, nx, t0)
    j, sj, by, dy = _axis(origin[1], direction[1], lower[1], voxel, ny, t0)
    k, sk, bz, dz = _axis(origin[2], direction[2], lower[2], voxel, nz, t0)
    count = 0
    while True:
        cells[count] = (i * ny + j) * nz + k
        count += 1
        if bx <= by and bx <= bz:
            if bx >= stop:
                break
            i += si
            bx += dx
            if i < 0 or i >= nx:
                break
        elif by <= bz:
            if by >= stop:
                break
            j += sj
            by += dy
            if j < 0 or j >= ny:
                break
        else:
            if bz >= stop:
                break
            k += sk
            bz += dz
            if k < 0 or k >= nz:
                break
    return count


@_compiled
def _integrate(state, lower, upper, voxel, origin, ends, hits):
    """Walk origin -> ends[r]: the voxels before the end free (where unknown), the end's voxel occupied when hits[r]
    and the end lies in the map."""
    flat = state.reshape(-1)
    nx, ny, nz = state.shape
    cells = np.empty(nx + ny + nz, np.int64)
    direction = np.empty(3)
    for r in range(ends.shape[0]):
        for a in range(3):
            direction[a] = ends[r, a] - origin[a]
        count = _walk(origin, direction, lower, upper, voxel, state.shape, 1.0, cells)
        end = -1
        if hits[r]:
            i = int(math.floor((ends[r, 0] - lower[0]) / voxel))
            j = int(math.floor((ends[r, 1] - lower[1]) / voxel))
            k = int(math.floor((ends[r, 2] - lower[2]) / voxel))
            if 0 <= i < nx and 0 <= j < ny and 0 <= k < nz:
                end = (i * ny + j) * nz + k
        for n in range(count):
            cell = cells[n]
            if cell == end:
                break
            if flat[cell] == UNKNOWN:
                flat[cell] = FREE
        if end >= 0:
            flat[end] = OCCUPIED


@_compiled
def _seen_unknown(state, lower, upper, voxel, origin, directions, max_range, low, high):
    """Flat indices of the distinct unknown voxels inside index box [low, high) that the rays (unit directions) pass
    before their first occupied voxel or max_range, in the order first met."""
    flat = state.reshape(-1)
    nx, ny, nz = state.shape
    cells = np.empty(nx + ny + nz, np.int64)
    seen = np.zeros(flat.size, np.bool_)
    found = np.empty((high[0] - low[0]) * (high[1] - low[1]) * (high[2] - low[2]), np.int64)
    total = 0
    for r in range(directions.shape[0]):
        count = _walk(origin, directions[r], lower, upper, voxel, state.shape, max_range, cells)
        for n in range(count):
            cell = cells[n]
            value = flat[cell]
            if value == OCCUPIED:
                break
            if value == UNKNOWN and not seen[cell]:
                i, rest = divmod(cell, ny * nz)
                j, k = divmod(rest, nz)
                if low[0] <= i < high[0] and low[1] <= j < high[1] and low[2] <= k < high[2]:
                    seen[cell] = True
                    found[total] = cell
                    total += 1
    return found[:total]


@_compiled
def _line_of_sight(state, lower, upper, voxel, origin, points):
    """Per point: no occupied voxel between the origin and it, its own voxel and their neighbours excepted."""
    flat = state.reshape(-1)
    nx, ny, nz = state.shape
    cells = np.empty(nx + ny + nz, np.int64)
    clear = np.ones(points.shape[0], np.bool_)
    direction = np.empty(3)
    for p in range(points.shape[0]):
        for a in range(3):
            direction[a] = points[p, a] - origin[a]
        own_i = math.floor((points[p, 0] - lower[0]) / voxel)
        own_j = math.floor((points[p, 1] - lower[1]) / voxel)
        own_k = math.floor((points[p, 2] - lower[2]) / voxel)
        count = _walk(origin, direction, lower, upper, voxel, state.shape, 1.0, cells)
        for n in range(count):
            cell = cells[n]
            if flat[cell] == OCCUPIED:
                i, rest = divmod(cell, ny * nz)
                j, k = divmod(rest, nz)
                if max(abs(i - own_i), abs(j - own_j), abs(k - own_k)) > 1:
                    clear[p] = False
                    break
    return clear


# ------------------------------------------------------------------------------------------------ the map


def pixel_grid(intrinsics: Intrinsics, stride: int) -> tuple[np.ndarray, np.ndarray]:
    """Rows and columns of the pixels sampled every `stride` pixels, from stride // 2 on."""
    if not (isinstance(stride, (int, np.integer)) and stride >= 1):
        raise UserError(f"stride: {stride!r} is not a whole number of pixels of at least 1")
    return np.arange(stride // 2, intrinsics.height, stride), np.arange(stride // 2, intrinsics.width, stride)


def _optical_rays(intrinsics: Intrinsics, rows: np.ndarray, columns: np.ndarray) -> np.ndarray:
    """(len(rows) · len(columns), 3) optical-frame rays of planar depth 1, row-major."""
    v, u = np.meshgrid(rows, columns, indexing="ij")
    return np.column_stack([((u - intrinsics.cx) / intrinsics.fx).ravel(), ((v - intrinsics.cy) / intrinsics.fy).ravel(),
                            np.ones(u.size)])


def _pose(pose: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    pose = np.asarray(pose, dtype=np.float64)
    if pose.shape != (4, 4) or not np.isfinite(pose).all():
        raise UserError(f"pose: a camera pose is a finite 4x4 T_world_optical, not an array of shape {pose.shape}")
    return pose[:3, :3], np.ascontiguousarray(pose[:3, 3])


def _max_range(max_range: float) -> float:
    if not (math.isfinite(max_range) and max_range > 0):
        raise UserError(f"max_range: {max_range!r} m is not a positive distance")
    return float(max_range)


def _box(lower: Sequence[float], upper: Sequence[float], name: str) -> tuple[np.ndarray, np.ndarray]:
    lower, upper = np.asarray(lower, dtype=np.float64), np.asarray(upper, dtype=np.float64)
    if lower.shape != (3,) or upper.shape != (3,) or not (np.isfinite(lower).all() and np.isfinite(upper).all()):
        raise UserError(f"{name}: its corners must be two finite (x, y, z) points")
    if not (upper > lower).all():
        raise UserError(f"{name}: empty box, from {lower.tolist()} to {upper.tolist()}")
    return lower, upper


class VoxelMap:
    """Unknown / free / occupied voxels of an axis-aligned world box, filled from depth frames (module docstring).

    The box is `lower` to `lower + shape · voxel`: `upper` rounded up to whole voxels. `state` holds the int8
    states (UNKNOWN, FREE, OCCUPIED), indexed [i, j, k] along x, y, z."""

    def __init__(self, lower: Sequence[float], upper: Sequence[float], voxel: float = 0.02) -> None:
        if not (isinstance(voxel, (int, float, np.floating, np.integer)) and math.isfinite(voxel) and voxel > 0):
            raise UserError(f"voxel: {voxel!r} m is not a positive size")
        lower, upper = _box(lower, upper, "voxel map")
        shape = np.maximum(np.ceil((upper - lower) / voxel - EDGE), 1).astype(np.int64)
        if float(np.prod(shape.astype(np.float64))) > MAX_VOXELS:
            raise UserError(f"voxel map: {' x '.join(map(str, shape))} voxels of {voxel} m is more than {MAX_VOXELS}")
        self.voxel = float(voxel)
        self.lower = lower
        self.upper = lower + shape * self.voxel
        self.state = np.zeros(tuple(int(n) for n in shape), np.int8)

    @property
    def shape(self) -> tuple[int, int, int]:
        return self.state.shape

    def copy(self) -> VoxelMap:
        other = object.__new__(VoxelMap)
        other.voxel, other.lower, other.upper, other.state = self.voxel, self.lower.copy(), self.upper.copy(), self.state.copy()
        return other

    def integrate(self, depth: np.ndarray, pose: np.ndarray, intrinsics: Intrinsics, stride: int = 4,
                  max_range: float = MAX_RANGE) -> None:
        """Add one depth frame (H, W) of planar depth in m (0 or NaN: no return) seen from `pose` (T_world_optical):
        a ray every `stride` pixels."""
        depth = np.asarray(depth)
        if depth.shape != (intrinsics.height, intrinsics.width):
            raise UserError(f"depth: shape {depth.shape} is not the camera's {(intrinsics.height, intrinsics.width)}")
        rotation, origin = _pose(pose)
        max_range = _max_range(max_range)
        rows, columns = pixel_grid(intrinsics, stride)
        z = depth[np.ix_(rows, columns)].astype(np.float64).ravel()
        returned = np.isfinite(z) & (z > 0)
        rays = _optical_rays(intrinsics, rows, columns)[returned] * z[returned, None]
        lengths = np.linalg.norm(rays, axis=1)
        hits = lengths <= max_range
        rays[~hits] *= (max_range / lengths[~hits])[:, None]
        ends = np.ascontiguousarray(rays @ rotation.T + origin)
        _integrate(self.state, self.lower, self.upper, self.voxel, origin, ends, hits)

    def cells(self, lower: Sequence[float], upper: Sequence[float]) -> tuple[np.ndarray, np.ndarray]:
        """The index box [low, high) of the voxels that overlap the world box `lower`-`upper` (clipped to the map)."""
        lower, upper = _box(lower, upper, "sub-box")
        low = np.clip(np.floor((lower - self.lower) / self.voxel + EDGE), 0, self.shape).astype(np.int64)
        high = np.clip(np.ceil((upper - self.lower) / self.voxel - EDGE), 0, self.shape).astype(np.int64)
        if not (high > low).all():
            raise UserError(f"sub-box: {lower.tolist()} to {upper.tolist()} lies outside the voxel map "
                            f"({self.lower.tolist()} to {self.upper.tolist()})")
        return low, high

    def unknown_fraction(self, lower: Sequence[float], upper: Sequence[float]) -> float:
        """The share of the voxels overlapping the sub-box (inside the map) that are still unknown."""
        low, high = self.cells(lower, upper)
        block = self.state[low[0]:high[0], low[1]:high[1], low[2]:high[2]]
        return float(np.count_nonzero(block == UNKNOWN) / block.size)

    def state_at(self, points: np.ndarray) -> np.ndarray:
        """The state of the voxel holding each world point (N, 3); UNKNOWN outside the map."""
        points = np.atleast_2d(np.asarray(points, dtype=np.float64))
        index = np.floor((points - self.lower) / self.voxel).astype(np.int64)
        inside = ((index >= 0) & (index < self.shape)).all(axis=1)
        states = np.full(len(points), UNKNOWN, np.int8)
        states[inside] = self.state[tuple(index[inside].T)]
        return states

    def visible(self, pose: np.ndarray, intrinsics: Intrinsics, points: np.ndarray, max_range: float = MAX_RANGE) -> np.ndarray:
        """Per world point (N, 3): inside the camera's image and within `max_range` of it (along the ray), and no
        occupied voxel on the line of sight but the point's own voxel and its neighbours (it lies on a surface)."""
        rotation, origin = _pose(pose)
        max_range = _max_range(max_range)
        points = np.asarray(points, dtype=np.float64).reshape(-1, 3)
        optical = (points - origin) @ rotation
        seen = (optical[:, 2] > 0) & (np.linalg.norm(optical, axis=1) <= max_range)
        with np.errstate(divide="ignore", invalid="ignore"):
            pixels = intrinsics.project(np.where(seen[:, None], optical, [0.0, 0.0, 1.0]))
        seen &= ((pixels[:, 0] >= -0.5) & (pixels[:, 0] <= intrinsics.width - 0.5) & (pixels[:, 1] >= -0.5)
                 & (pixels[:, 1] <= intrinsics.height - 0.5))
        if seen.any():
            seen[seen] = _line_of_sight(self.state, self.lower, self.upper, self.voxel, origin,
                                        np.ascontiguousarray(points[seen]))
        return seen

    def seen_unknown(self, pose: np.ndarray, intrinsics: Intrinsics, lower: Sequence[float], upper: Sequence[float],
                     stride: int = 4, max_range: float = MAX_RANGE) -> np.ndarray:
        """Flat indices (into `state`) of the distinct unknown voxels overlapping the sub-box that the camera at
        `pose` would see: rays every `stride` pixels through the map, each up to its first occupied voxel or
        `max_range`."""
        rotation, origin = _pose(pose)
        max_range = _max_range(max_range)
        low, high = self.cells(lower, upper)
        rays = _optical_rays(intrinsics, *pixel_grid(intrinsics, stride)) @ rotation.T
        directions = np.ascontiguousarray(rays / np.linalg.norm(rays, axis=1, keepdims=True))
        return _seen_unknown(self.state, self.lower, self.upper, self.voxel, origin, directions, max_range, low, high)

    def gain(self, pose: np.ndarray, intrinsics: Intrinsics, lower: Sequence[float], upper: Sequence[float],
             stride: int = 4, max_range: float = MAX_RANGE) -> int:
        """How many distinct unknown voxels of the sub-box the camera at `pose` would see (`seen_unknown`)."""
        return len(self.seen_unknown(pose, intrinsics, lower, upper, stride, max_range))
