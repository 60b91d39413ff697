"""Speed of the voxel map's ray walk (renderloop.loop.voxels) on one core: depth frames integrated and views scored per second.

Measured side by side in one run: a 320x240 depth frame (the demo camera, 57°) of a few
spheres in a 0.6 m box of 2 cm voxels, with a backdrop behind the box so that every ray
returns, integrated at a stride of 4 and of 2 pixels (4 800 and 19 200 rays) by the
compiled walk (numba), by the same walk run as plain Python (the functions' `py_func`,
the compiled helpers swapped for theirs), and by the same walk vectorised over the rays
in numpy (every ray one voxel further per numpy step, the states set at the end, which
the map's "occupied wins" rule allows); and `VoxelMap.gain` (a view's unknown voxels,
rays up to the first occupied voxel) from a second camera, compiled and in plain Python.
The three walks must leave the same map, and the two gains the same count: the script
fails otherwise. Compilation is not timed (a warm-up call first; the on-disk cache
serves it after the first run). Median over repeats, with min and max; the ratios are
the figures to read, the rates depend on the machine.

    .venv/bin/python benchmarks/voxels.py [--repeats 5] [--python-repeats 2] [--json out.json]
"""

from __future__ import annotations

import argparse
import contextlib
import json
import os
import time
from collections.abc import Iterator
from pathlib import Path

import numba
import numpy as np
from common import summary

import renderloop.loop.voxels as voxels
from renderloop.config import load_config
from renderloop.loop.voxels import FREE, OCCUPIED, UNKNOWN, VoxelMap
from renderloop.render.camera import Intrinsics
from renderloop.robot.kinematics import look_at

BOX = 0.6  # m, edge of the map
VOXEL = 0.02  # m
CENTRE = np.array([0.0, 0.0, 1.0])
SPHERES = [((0.08, 0.05, 0.06), 0.09), ((-0.1, -0.12, -0.05), 0.07), ((0.0, 0.14, -0.14), 0.06),
           ((-0.15, 0.1, 0.15), 0.05), ((0.12, -0.15, 0.12), 0.05)]  # (centre about CENTRE, radius), m
BACKDROP = -0.8  # m: the plane x = CENTRE x + BACKDROP behind the box returns the rays that miss the spheres
COMPILED = ("_clip_to_box", "_axis", "_walk", "_integrate", "_seen_unknown")


def depth_frame(pose: np.ndarray, intrinsics: Intrinsics) -> np.ndarray:
    """Planar depth of the spheres and the backdrop, cast analytically."""
    v, u = np.mgrid[0:intrinsics.height, 0:intrinsics.width]
    rays = np.stack([(u - intrinsics.cx) / intrinsics.fx, (v - intrinsics.cy) / intrinsics.fy, np.ones(u.shape)], -1)
    directions = rays.reshape(-1, 3) @ pose[:3, :3].T  # planar depth 1 along each
    origin = pose[:3, 3]
    depth = (CENTRE[0] + BACKDROP - origin[0]) / directions[:, 0]
    for centre, radius in SPHERES:
        offset = origin - (CENTRE + centre)
        a, b, c = (directions * directions).sum(1), directions @ offset, offset @ offset - radius**2
        disc = b * b - a * c
        t = (-b - np.sqrt(np.maximum(disc, 0.0))) / a
        depth = np.where((disc >= 0) & (t > 0) & (t < depth), t, depth)
    return depth.reshape(intrinsics.height, intrinsics.width).astype(np.float32)


@contextlib.contextmanager
def plain_python() -> Iterator[None]:
    """The module's compiled functions replaced by their Python source (`py_func`), helpers included."""
    saved = {name: getattr(voxels, name) for name in COMPILED}
    for name, function in saved.items():
        setattr(voxels, name, function.py_func)
    try:
        yield
    finally:
        for name, function in saved.items():
            setattr(voxels, name, function)


def numpy_walk(state, lower, upper, voxel, origin, ends, hits) -> None:
    """`voxels._integrate` vectorised over the rays: the same voxels in the same order (on a tie the first axis steps
    first), each ray one voxel further per numpy step; then free where unknown and the returns occupied, which the
    map's "occupied wins" rule allows."""
    shape = np.array(state.shape)
    direction = ends - origin
    with np.errstate(divide="ignore", invalid="ignore"):
        ta, tb = (lower - origin) / direction, (upper - origin) / direction
    inside = (origin >= lower) & (origin <= upper)
    t_low = np.where(direction != 0, np.minimum(ta, tb), np.where(inside, -np.inf, np.inf))
    t_high = np.where(direction != 0, np.maximum(ta, tb), np.where(inside, np.inf, -np.inf))
    t0, stop = np.maximum(t_low.max(axis=1), 0.0), np.minimum(t_high.min(axis=1), 1.0)
    end = np.floor((ends - lower) / voxel).astype(np.int64)
    returned = hits & ((end >= 0) & (end < shape)).all(axis=1)
    end_cell = np.full(len(ends), -1)
    end_cell[returned] = np.ravel_multi_index(end[returned].T, state.shape)
    index = np.clip(np.floor((origin + t0[:, None] * direction - lower) / voxel).astype(np.int64), 0, shape - 1)
    step = np.sign(direction).astype(np.int64)
    with np.errstate(divide="ignore", invalid="ignore"):
        boundary = np.where(direction > 0, (lower + (index + 1) * voxel - origin) / direction,
                            np.where(direction < 0, (lower + index * voxel - origin) / direction, np.inf))
        delta = np.where(direction != 0, voxel / np.abs(direction), np.inf)
    active = t0 <= stop
    free = []
    while active.any():
        rays = np.flatnonzero(active)
        cells = np.ravel_multi_index(index[rays].T, state.shape)
        reached = cells == end_cell[rays]
        free.append(cells[~reached])
        moving = rays[~reached & (boundary[rays].min(axis=1) < stop[rays])]
        axis = np.argmin(boundary[moving], axis=1)
        index[moving, axis] += step[moving, axis]
        boundary[moving, axis] += delta[moving, axis]
        active[rays] = False
        active[moving[(index[moving, axis] >= 0) & (index[moving, axis] < shape[axis])]] = True
    flat = state.reshape(-1)
    free = np.concatenate(free)
    flat[free[flat[free] == UNKNOWN]] = FREE
    flat[end_cell[returned]] = OCCUPIED


def integrate_numpy(grid: VoxelMap, depth: np.ndarray, pose: np.ndarray, intrinsics: Intrinsics, stride: int) -> None:
    """`VoxelMap.integrate` with its walk swapped for `numpy_walk`."""
    saved = voxels._integrate
    voxels._integrate = numpy_walk
    try:
        grid.integrate(depth, pose, intrinsics, stride=stride)
    finally:
        voxels._integrate = saved


def fresh_map() -> VoxelMap:
    return VoxelMap(CENTRE - BOX / 2, CENTRE + BOX / 2, VOXEL)


def frames_per_second(integrate, repeats: int, frames: int) -> list[float]:
    """Frames per second of `integrate(map)` into fresh maps, `frames` a repeat."""
    rates = []
    for _ in range(repeats):
        maps = [fresh_map() for _ in range(frames)]
        start = time.perf_counter()
        for grid in maps:
            integrate(grid)
        rates.append(frames / (time.perf_counter() - start))
    return rates


def views_per_second(grid: VoxelMap, pose: np.ndarray, intrinsics: Intrinsics, repeats: int, views: int) -> list[float]:
    rates = []
    for _ in range(repeats):
        start = time.perf_counter()
        for _ in range(views):
            grid.gain(pose, intrinsics, grid.lower, grid.upper, stride=4)
        rates.append(views / (time.perf_counter() - start))
    return rates


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--python-repeats", type=int, default=2, help="repeats of the plain-Python walk (one frame each)")
    parser.add_argument("--json", type=Path)
    args = parser.parse_args()
    os.sched_setaffinity(0, {sorted(os.sched_getaffinity(0))[0]})

    intrinsics = Intrinsics.from_config(load_config("demo").camera)
    pose = look_at(CENTRE + [0.6, 0.05, 0.1], CENTRE)  # about where the scan's camera stands from a plant
    other = look_at(CENTRE + [-0.3, -0.55, 0.2], CENTRE)  # a next view, from another side
    depth = depth_frame(pose, intrinsics)

    results: dict[str, object] = {"numba": numba.__version__, "numpy": np.__version__,
                                  "frame": [intrinsics.width, intrinsics.height], "map_voxels": list(fresh_map().shape)}
    rows = []
    for stride in (4, 2):
        def compiled(grid, stride=stride):
            grid.integrate(depth, pose, intrinsics, stride=stride)

        def vectorised(grid, stride=stride):
            integrate_numpy(grid, depth, pose, intrinsics, stride)

        maps = [fresh_map() for _ in range(3)]
        compiled(maps[0])  # compiles, or loads the cache
        vectorised(maps[1])
        with plain_python():
            compiled(maps[2])
        if not (np.array_equal(maps[0].state, maps[1].state) and np.array_equal(maps[0].state, maps[2].state)):
            raise SystemExit(f"stride {stride}: the compiled, numpy and Python walks left different maps")
        rays = int(np.count_nonzero(depth[np.ix_(*voxels.pixel_grid(intrinsics, stride))] > 0))
        fast = frames_per_second(compiled, args.repeats, 20)
        numpy_rates = frames_per_second(vectorised, args.repeats, 3)
        with plain_python():
            python = frames_per_second(compiled, args.python_repeats, 1)
        results[f"stride_{stride}"] = {"rays": rays, "numba_fps": summary(fast), "numpy_fps": summary(numpy_rates),
                                       "python_fps": summary(python),
                                       "numba_over_numpy": summary(fast)["median"] / summary(numpy_rates)["median"],
                                       "numba_over_python": summary(fast)["median"] / summary(python)["median"]}
        rows += [(f"integrate, stride {stride} ({rays} rays): numba fps", summary(fast)),
                 (f"integrate, stride {stride}: numpy (vectorised) fps", summary(numpy_rates)),
                 (f"integrate, stride {stride}: plain Python fps", summary(python))]

    grid = maps[0]  # the frame at stride 2
    count = grid.gain(other, intrinsics, grid.lower, grid.upper, stride=4)
    with plain_python():
        if grid.gain(other, intrinsics, grid.lower, grid.upper, stride=4) != count:
            raise SystemExit("gain: the compiled and Python walks counted differently")
        python_gain = views_per_second(grid, other, intrinsics, args.python_repeats, 1)
    fast_gain = views_per_second(grid, other, intrinsics, args.repeats, 50)
    results["gain_stride_4"] = {"unknown_voxels": count, "numba_views_per_s": summary(fast_gain),
                                "python_views_per_s": summary(python_gain),
                                "numba_over_python": summary(fast_gain)["median"] / summary(python_gain)["median"]}
    rows += [("gain, stride 4: numba views/s", summary(fast_gain)),
             ("gain, stride 4: plain Python views/s", summary(python_gain))]

    print(f"voxel map benchmark: {intrinsics.width}x{intrinsics.height} depth, {BOX} m box of {VOXEL * 100:g} cm voxels "
          f"({' x '.join(map(str, fresh_map().shape))}), one core, {args.repeats} repeats ({args.python_repeats} for Python)")
    print(f"{'figure':<52}{'median':>12}{'min':>12}{'max':>12}")
    for name, row in rows:
        print(f"{name:<52}{row['median']:>12.2f}{row['min']:>12.2f}{row['max']:>12.2f}")
    for stride in (4, 2):
        figures = results[f"stride_{stride}"]
        print(f"stride {stride}: numba {figures['numba_over_numpy']:.1f}x numpy, {figures['numba_over_python']:.0f}x Python")
    print(f"gain: numba {results['gain_stride_4']['numba_over_python']:.0f}x Python ({count} unknown voxels seen)")
    if args.json:
        args.json.write_text(json.dumps(results, indent=1) + "\n")


if __name__ == "__main__":
    main()
