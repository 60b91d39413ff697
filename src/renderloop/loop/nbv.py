"""Next-best views of one plant: where to look again, from what the robot's depth frames and its count know.

Candidates are a fixed grid of views about the plant (`renderloop.loop.viewpoints`): every
AZIMUTH_STEP of azimuth from world +x, at the `heights` about the canopy's middle (three for a
short canopy, more up a tall one) and the DISTANCES from its axis (fractions of the views'
height and distance ranges in viewpoints). A
candidate is kept when the arm's inverse kinematics reaches it and the robot posed there
is clear of the greenhouse in MuJoCo (`Projector.dofs`, `Projector.clear`); in a row, the
views along the row run into the neighbours and drop out.

The score of a candidate is the unknown voxels of the plant's canopy box it would see
(`VoxelMap.seen_unknown`: rays through the map up to the first occupied voxel) plus a
weight times the uncertain fruit it would see (`VoxelMap.visible` of the points the caller
gives, the centres of the clusters the count is unsure of). The weight defaults to the
canopy box's voxel count: one uncertain fruit outweighs any amount of unknown space, and
unknown space decides among views that see the same fruit. Views are chosen greedily:
what a chosen view sees no longer counts for the next (the map itself is not changed: an
unknown voxel seen is still unknown, it may be free, so it blocks no ray). The choice
stops at `max_views`, when the best score falls under `min_gain` (or to 0), or when no
remaining view fits in the flight-time budget; a view that would overrun the budget is
passed over, and a cheaper one may still fit.

Flight time is estimated from view to view round the plant as `Projector.path` flies (the
azimuth the shorter way, height and distance linearly): the slowest of the camera's
horizontal path (the arc at the mean distance, with the change of distance) at the
slower of the x and y speed limits, the height change at the z limit, and the turn
(the body yaws with the azimuth to keep looking at the plant) at the yaw limit, from
`planner.velocity_limits`. With the default limits the yaw rate governs. The estimate
ignores acceleration, so it is a lower bound.
The chosen views are flown in nearest-neighbour order (by that time) from the robot's
camera position; each gets the voxels and fruit it newly sees in that order and the
estimated flight time up to it.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from renderloop.config import PlannerConfig
from renderloop.errors import UserError
from renderloop.loop.viewpoints import DISTANCE_RANGE, HEIGHT_RANGE, Projector, View, height_range, view_at, wrap
from renderloop.loop.voxels import MAX_RANGE, VoxelMap
from renderloop.render.camera import Intrinsics
from renderloop.robot.kinematics import dofs_to_camera_pose
from renderloop.scene.model import Plant

AZIMUTH_STEP = math.radians(20.0)  # 18 azimuths round the plant
HEIGHT_STEP = 2 / 3 * HEIGHT_RANGE  # m: the most between two candidate heights; a short canopy has three
DISTANCES = tuple(round(DISTANCE_RANGE[0] + f * (DISTANCE_RANGE[1] - DISTANCE_RANGE[0]), 9) for f in (0.25, 0.75))  # m


@dataclass(frozen=True)
class Candidate:
    """A view the robot can be at: the view, its q* (x, y, z, yaw, q1, q2, q3) and its camera pose (T_world_optical)."""

    view: View
    dofs: np.ndarray
    pose: np.ndarray


@dataclass(frozen=True)
class ChosenView:
    """A chosen view, in flight order: what it newly sees (the views before it seen) and the flight time up to it."""

    view: View
    dofs: np.ndarray  # q* (x, y, z, yaw, q1, q2, q3)
    pose: np.ndarray  # T_world_optical
    gain_cells: int  # unknown voxels of the canopy box it newly sees
    gain_fruit: int  # uncertain fruit it newly sees
    flight_s: float  # estimated flight time from the robot's position through the views before it to it, s


def canopy_box(plant: Plant) -> tuple[np.ndarray, np.ndarray]:
    """The plant's box above its pot: where its fruit can be."""
    lower = np.array(plant.bounds.min, dtype=float)
    lower[2] = plant.position[2] + plant.pot.height
    return lower, np.array(plant.bounds.max, dtype=float)


def _frozen(array: np.ndarray) -> np.ndarray:
    array = np.array(array, dtype=float)
    array.flags.writeable = False
    return array


def heights(plant: Plant) -> tuple[float, ...]:
    """The candidate views' heights about the canopy's middle, m: from -2/3 to 2/3 of the views' reach
    (viewpoints.height_range), at most HEIGHT_STEP apart."""
    reach = 2 / 3 * height_range(plant)
    count = max(3, math.ceil(2 * reach / HEIGHT_STEP - 1e-9) + 1)
    return tuple(round(float(h), 9) for h in np.linspace(-reach, reach, count))


def candidate_views(projector: Projector) -> list[Candidate]:
    """The grid of views about the projector's plant (module docstring) that the robot can reach and be at, clear."""
    candidates = []
    for k in range(round(2 * math.pi / AZIMUTH_STEP)):
        for height in heights(projector.plant):
            for distance in DISTANCES:
                view = View(wrap(k * AZIMUTH_STEP), height, distance)
                dofs = projector.dofs(view)
                if dofs is not None and projector.clear(dofs[None]):
                    candidates.append(Candidate(view, _frozen(dofs), _frozen(dofs_to_camera_pose(dofs, projector.arm))))
    return candidates


def flight_time(a: View, b: View, velocity_limits: Sequence[float]) -> float:
    """Estimated seconds from view a to view b round the plant (module docstring)."""
    vx, vy, vz, vyaw = velocity_limits[:4]
    turn = abs(wrap(b.azimuth - a.azimuth))
    horizontal = math.hypot((a.distance + b.distance) / 2 * turn, b.distance - a.distance)
    return max(horizontal / min(vx, vy), abs(b.height - a.height) / vz, turn / vyaw)


def _flight_order(start: View | None, views: list[View], velocity_limits: Sequence[float]) -> tuple[list[int], list[float]]:
    """Nearest-neighbour order of `views` from `start` (none: from the first view) and the flight time up to each."""
    left = list(range(len(views)))
    order, times, here, elapsed = [], [], start, 0.0
    while left:
        if here is None:
            best, step = left[0], 0.0
        else:
            step, best = min((flight_time(here, views[i], velocity_limits), i) for i in left)
        elapsed += step
        order.append(best)
        times.append(elapsed)
        left.remove(best)
        here = views[best]
    return order, times


def _check(weak: np.ndarray, budget_s: float, max_views: int, min_gain: float, fruit_weight: float | None) -> np.ndarray:
    """The arguments a caller can simply get wrong, one UserError line each; the uncertain fruit as (N, 3)."""
    if not (isinstance(max_views, (int, np.integer)) and max_views >= 1):
        raise UserError(f"max_views: {max_views!r} is not a whole number of at least 1")
    if not (math.isfinite(min_gain) and min_gain >= 0):
        raise UserError(f"min_gain: {min_gain!r} is not a number of voxels of at least 0")
    if math.isnan(budget_s):
        raise UserError("budget_s: NaN is not a flight time")
    if fruit_weight is not None and not (math.isfinite(fruit_weight) and fruit_weight >= 0):
        raise UserError(f"fruit_weight: {fruit_weight!r} is not a number of voxels of at least 0")
    weak = np.asarray(weak, dtype=float)
    if weak.size % 3 or not np.isfinite(weak).all():
        raise UserError(f"weak: the uncertain fruit are finite (N, 3) points, not an array of shape {weak.shape}")
    return weak.reshape(-1, 3)


def select(candidates: Sequence[Candidate], voxel_map: VoxelMap, intrinsics: Intrinsics, box: tuple[np.ndarray, np.ndarray],
           weak: np.ndarray, *, start: View | None, velocity_limits: Sequence[float], budget_s: float, max_views: int,
           min_gain: float, fruit_weight: float | None = None, stride: int = 4,
           max_range: float = MAX_RANGE) -> tuple[list[ChosenView], str]:
    """The greedy choice among `candidates` (module docstring), in flight order, and why it stopped.

    `box` is the canopy box (world lower and upper corners), `weak` the uncertain fruit (N, 3), `start` the robot's
    view now (None: the flight starts at the first view chosen). No budget or no candidate: an empty list and why."""
    weak = _check(weak, budget_s, max_views, min_gain, fruit_weight)
    if budget_s <= 0:
        return [], "no flight time budget left"
    if not candidates:
        return [], "no candidate view is reachable and clear of the greenhouse"
    low, high = voxel_map.cells(*box)
    weight = float(np.prod(high - low)) if fruit_weight is None else float(fruit_weight)
    cells = [voxel_map.seen_unknown(c.pose, intrinsics, *box, stride=stride, max_range=max_range) for c in candidates]
    fruit = [voxel_map.visible(c.pose, intrinsics, weak, max_range) for c in candidates]

    covered = np.zeros(voxel_map.state.size, np.bool_)
    seen = np.zeros(len(weak), np.bool_)
    chosen: list[int] = []
    passed_over: set[int] = set()
    while True:
        if len(chosen) == max_views:
            reason = f"max_views: {max_views} views chosen"
            break
        options = [i for i in range(len(candidates)) if i not in chosen and i not in passed_over]
        if not options:
            reason = (f"no further view fits in the flight time budget of {budget_s:g} s" if passed_over
                      else "every candidate view was chosen")
            break
        gains = {i: (int(np.count_nonzero(~covered[cells[i]])), int(np.count_nonzero(fruit[i] & ~seen))) for i in options}
        best = max(options, key=lambda i: (gains[i][0] + weight * gains[i][1], -i))  # ties: the first in grid order
        score = gains[best][0] + weight * gains[best][1]
        if score <= 0 or score < min_gain:
            reason = (f"the best remaining view would newly see {gains[best][0]} unknown voxels and "
                      f"{gains[best][1]} uncertain fruit: too little to fly to (min_gain {min_gain:g})")
            break
        _, times = _flight_order(start, [candidates[i].view for i in [*chosen, best]], velocity_limits)
        if times[-1] > budget_s:
            passed_over.add(best)
            continue
        chosen.append(best)
        covered[cells[best]] = True
        seen |= fruit[best]
    if not chosen:
        return [], reason

    order, times = _flight_order(start, [candidates[i].view for i in chosen], velocity_limits)
    covered[:] = False
    seen[:] = False
    views = []
    for position, elapsed in zip(order, times):
        i = chosen[position]
        new_cells = int(np.count_nonzero(~covered[cells[i]]))
        new_fruit = int(np.count_nonzero(fruit[i] & ~seen))
        covered[cells[i]] = True
        seen |= fruit[i]
        views.append(ChosenView(candidates[i].view, candidates[i].dofs, candidates[i].pose, new_cells, new_fruit, elapsed))
    return views, reason


def choose_views(projector: Projector, voxel_map: VoxelMap, intrinsics: Intrinsics, plant: Plant, *, weak: np.ndarray,
                 budget_s: float, max_views: int, min_gain: float, start: np.ndarray | None, planner: PlannerConfig,
                 fruit_weight: float | None = None, stride: int = 4,
                 max_range: float = MAX_RANGE) -> tuple[list[ChosenView], str]:
    """Next-best views of `plant` (the projector's) from what `voxel_map` knows and the uncertain fruit `weak` (N, 3),
    flown from the camera position `start` (world; None: from the first view), within `budget_s` seconds of flight:
    the views in flight order and why the choice stopped (the reason to log when the list is empty)."""
    if plant.id != projector.plant.id:
        raise UserError(f"plant {plant.id}: the projector was made for plant {projector.plant.id}")
    here = None if start is None else view_at(plant, np.asarray(start, dtype=float).reshape(3))
    _check(weak, budget_s, max_views, min_gain, fruit_weight)
    if budget_s <= 0:  # before the candidates: they cost MuJoCo checks
        return [], "no flight time budget left"
    return select(candidate_views(projector), voxel_map, intrinsics, canopy_box(plant), weak, start=here,
                  velocity_limits=planner.velocity_limits, budget_s=budget_s, max_views=max_views, min_gain=min_gain,
                  fruit_weight=fruit_weight, stride=stride, max_range=max_range)
