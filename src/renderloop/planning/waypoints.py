"""Scan waypoints q* = (x, y, z, yaw, q1, q2, q3) for every plant of every row (or of the row `planner.row` names),
and the transits between them.

Per plant, the camera visits an ellipse in the vertical plane facing the plant
(semi-axes from the config) so that the UAV body flies its ellipse `distance`
from the plant's axis, as in the reference planner. At each point the camera looks
at the plant's centroid: the yaw exactly, the pitch up to `max_camera_pitch`, and
the arm's inverse kinematics turns that camera pose into q*. Rows are visited in a
boustrophedon over bands of rows; each row is scanned on both sides (out along
one, back along the other), or with `planner.sides: aisles` from each side that is
an aisle the UAV fits (a line of a double row faces one path), and the transits between scan lines are routed on the
occupancy grid so that they never cross a table, a plant or the workstation.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from itertools import groupby
from pathlib import Path

import numpy as np

from renderloop.config import Config
from renderloop.config.fields import MAX_PLANTS
from renderloop.errors import UserError
from renderloop.io.atomic import write_text
from renderloop.io.bounded import check_columns, check_increasing
from renderloop.io.csvtable import row_name
from renderloop.planning.transit import TransitPlanner
from renderloop.robot.kinematics import UnreachablePose, body_to_camera, camera_pose_to_dofs, camera_rotation, homogeneous
from renderloop.rundir import files, names
from renderloop.scene.model import Plant, Row, Scene

WAYPOINT_HEADER = ["index", "kind", "plant", "side", "t", "x", "y", "z", "yaw", "q1", "q2", "q3"]
WAYPOINT_KINDS = ("start", "scan", "transit", "end")
MAX_TRANSIT_SPACING = 0.4  # m between transit waypoints, so the spline keeps to the checked straight lines
FOOTPRINT_MARGIN = 0.05  # m added to the robot's radius when routing


@dataclass(frozen=True)
class Waypoint:
    kind: str  # "start", "scan", "transit" or "end"
    dofs: np.ndarray  # (7,) x, y, z, yaw, q1, q2, q3
    plant: int = -1
    side: str = ""
    time: float = float("nan")  # when the trajectory passes it, once parameterised


def scan_target(plant: Plant, band: int = 0, bands: int = 1) -> np.ndarray:
    """The point the camera aims at: the plant's axis, halfway up its canopy, or up band `band` of `bands`
    (counted from the bottom) of its height."""
    canopy_bottom, top = plant.position[2] + plant.pot.height, plant.bounds.max[2]
    up = 2 * band + 1  # written so that one band is exactly (bottom + top) / 2, as before bands existed
    return np.array([plant.position[0], plant.position[1], (canopy_bottom * (2 * bands - up) + top * up) / (2 * bands)])


def footprint_radius(config: Config) -> float:
    """Horizontal radius that holds the rotors and the arm at any yaw."""
    robot = config.robot
    arm_reach = float(np.linalg.norm(body_to_camera(robot.arm, (*robot.arm.nominal_posture, 0.0))[:2, 3])) + 0.03
    return max(robot.arm_length + robot.prop_radius, arm_reach) + FOOTPRINT_MARGIN


def _camera_distance(config: Config) -> float:
    """Horizontal camera-to-plant distance that puts the body `planner.distance` from the plant."""
    arm = config.robot.arm
    q1, q2 = arm.nominal_posture
    reach = body_to_camera(arm, (q1, q2, -q1 - q2))[0, 3]
    distance = config.planner.distance - reach
    if distance <= 0.05:
        raise UserError(f"planner.distance: {config.planner.distance} m leaves the camera inside the plant (arm reach {reach:.2f} m)")
    return distance


def plant_ellipse(plant: Plant, side: int, walk: int, config: Config, upward: bool = True) -> list[Waypoint]:
    """The ellipse of one plant seen from `side` (-1: from -x, +1: from +x), starting behind the walking direction;
    with `planner.bands` above 1, one ellipse per band, from the bottom up (`upward`) or from the top down."""
    planner = config.planner
    order = range(planner.bands) if upward else reversed(range(planner.bands))
    return [waypoint for band in order for waypoint in _ellipse(plant, scan_target(plant, band, planner.bands), side,
                                                                 walk, config)]


def _ellipse(plant: Plant, target: np.ndarray, side: int, walk: int, config: Config) -> list[Waypoint]:
    planner, arm = config.planner, config.robot.arm
    offset = side * _camera_distance(config)
    half_width, half_height = planner.semi_axes
    waypoints = []
    for k in range(planner.points_per_ellipse):
        angle = 2 * math.pi * k / planner.points_per_ellipse  # k = 0 is the point behind the walking direction
        camera = target + np.array([offset, -walk * half_width * math.cos(angle), half_height * math.sin(angle)])
        look = target - camera
        yaw = math.atan2(look[1], look[0])
        pitch = float(np.clip(math.atan2(-look[2], math.hypot(look[0], look[1])), -planner.max_camera_pitch, planner.max_camera_pitch))
        try:
            dofs = camera_pose_to_dofs(homogeneous(camera_rotation(yaw, pitch), camera), arm)
        except UnreachablePose as reason:
            raise UserError(f"planner: the arm cannot aim the camera at plant {plant.id}: {reason}") from None
        waypoints.append(Waypoint("scan", dofs, plant.id, "left" if side < 0 else "right"))
    return waypoints


def scan_line(row: Row, scene: Scene, side: int, walk: int, config: Config) -> list[Waypoint]:
    """Every plant of a row seen from one side, walking along +y (walk=1) or -y (walk=-1)."""
    plants = sorted((scene.plant(plant_id) for plant_id in row.plants), key=lambda p: walk * p.position[1])
    return [waypoint for index, plant in enumerate(plants)  # bands up one plant and down the next
            for waypoint in plant_ellipse(plant, side, walk, config, upward=index % 2 == 0)]


def _rows_in_order(scene: Scene) -> list[Row]:
    """Bands of rows with the same y, south to north; alternate bands run west-east and east-west."""
    ordered = []
    bands = groupby(sorted(scene.rows, key=lambda r: (round(r.table.center[1], 3), r.table.center[0])), key=lambda r: round(r.table.center[1], 3))
    for index, (_, band) in enumerate(bands):
        rows = list(band)
        ordered.extend(rows if index % 2 == 0 else rows[::-1])
    return ordered


def _turn(start_yaw: float, end_yaw: float, midpoint: np.ndarray) -> float:
    """Signed yaw change; a near half turn goes the way that faces the room's centre halfway,
    so that going round a row end the camera keeps facing the row, not the wall."""
    turn = math.remainder(end_yaw - start_yaw, 2 * math.pi)
    if abs(turn) < 0.75 * math.pi:
        return turn
    inward = -np.asarray(midpoint, dtype=float)
    candidates = (turn, turn - math.copysign(2 * math.pi, turn))
    return max(candidates, key=lambda c: math.cos(start_yaw + c / 2) * inward[0] + math.sin(start_yaw + c / 2) * inward[1])


def transit(planner: TransitPlanner, a: Waypoint, b: Waypoint) -> list[Waypoint]:
    """Transit waypoints strictly between a and b: routed corners, densified, q* interpolated by distance."""
    corners = [a.dofs[:2], *planner.route(a.dofs, b.dofs), b.dofs[:2]]
    points = [corners[0]]
    for start, end in zip(corners[:-1], corners[1:]):
        pieces = max(1, math.ceil(np.linalg.norm(end - start) / MAX_TRANSIT_SPACING))
        points.extend(start + (end - start) * t for t in np.linspace(0, 1, pieces + 1)[1:])
    lengths = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(points, axis=0), axis=1))])
    if lengths[-1] < 1e-9:
        return []
    turn = _turn(a.dofs[3], b.dofs[3], points[len(points) // 2])
    transit = []
    for point, travelled in zip(points[1:-1], lengths[1:-1]):
        f = travelled / lengths[-1]
        dofs = a.dofs + f * (b.dofs - a.dofs)
        dofs[:2] = point
        dofs[3] = a.dofs[3] + f * turn
        transit.append(Waypoint("transit", dofs))
    return transit


def _entry(row: Row, scene: Scene, here: np.ndarray, distance: float, sides: tuple[int, ...] = (-1, 1)) -> tuple[int, int]:
    """(side, walking direction) of `sides` whose first scan line starts nearest to where the UAV is now."""
    ys = [scene.plant(plant_id).position[1] for plant_id in row.plants]

    def start(side: int, walk: int) -> tuple[float, float]:
        return row.table.center[0] + side * distance, min(ys) if walk > 0 else max(ys)

    return min(((side, walk) for side in sides for walk in (-1, 1)), key=lambda option: math.dist(here, start(*option)))


def _scanned_rows(scene: Scene, config: Config) -> list[Row]:
    """The row `planner.row` names (every row when null), in the order the scan visits them."""
    chosen = config.planner.row
    if chosen is None:
        return _rows_in_order(scene)
    if chosen not in {row.id for row in scene.rows}:
        raise UserError(f"planner.row: the scene has no row {chosen} (its rows are 0 to {len(scene.rows) - 1})")
    return [row for row in scene.rows if row.id == chosen]


def _blocked(line: list[Waypoint], router: TransitPlanner) -> Waypoint | None:
    """The first waypoint of a scan line where the UAV would come within the router's radius of a table or wall."""
    return next((waypoint for waypoint in line if not router.grid.is_free(waypoint.dofs)), None)


def _too_close(waypoint: Waypoint, router: TransitPlanner) -> UserError:
    return UserError(f"planner.distance: scan waypoints of plant {waypoint.plant} come within "
                     f"{router.radius:.2f} m of a table or wall")


def _aisle_sides(row: Row, scene: Scene, config: Config, router: TransitPlanner) -> tuple[int, ...]:
    """The sides of a row whose scan line the UAV fits (an aisle), -1 before +1; a row with none is refused."""
    lines = {side: scan_line(row, scene, side, 1, config) for side in (-1, 1)}
    free = tuple(side for side, line in lines.items() if _blocked(line, router) is None)
    if not free:
        raise _too_close(_blocked(lines[-1], router), router)
    return free


def plan_waypoints(scene: Scene, config: Config) -> list[Waypoint]:
    if not scene.plants:
        raise UserError("scene.json: the scene has no plants to scan")
    arm = config.robot.arm
    q1, q2 = arm.nominal_posture
    rows = _scanned_rows(scene, config)
    scanned = [scene.plant(plant_id) for row in rows for plant_id in row.plants]
    if not scanned:
        raise UserError(f"planner.row: row {config.planner.row} holds no plants to scan")
    targets = np.array([scan_target(plant) for plant in (scene.plants if config.planner.row is None else scanned)])
    home = np.array([*config.robot.home[:2], targets[:, 2].mean(), 0.0, q1, q2, -q1 - q2])
    router = TransitPlanner(scene, footprint_radius(config))

    path = [Waypoint("start", home)]
    for row in rows:
        if config.planner.sides == "aisles":
            sides = _aisle_sides(row, scene, config, router)
            first_side, walk = _entry(row, scene, path[-1].dofs[:2], config.planner.distance, sides)
            passes = [(side, walk if side == first_side else -walk) for side in sorted(sides, key=lambda s: s != first_side)]
        else:
            first_side, walk = _entry(row, scene, path[-1].dofs[:2], config.planner.distance)
            passes = [(first_side, walk), (-first_side, -walk)]
        for side, direction in passes:
            line = scan_line(row, scene, side, direction, config)
            blocked = _blocked(line, router)
            if blocked is not None:
                raise _too_close(blocked, router)
            path.extend(transit(router, path[-1], line[0]))
            path.extend(line)
    end = replace(path[0], kind="end")
    path.extend(transit(router, path[-1], end))
    path.append(end)
    return path


# waypoints.csv ----------------------------------------------------------------------------------------------------

WAYPOINT_BOUNDS = files.column_bounds(WAYPOINT_HEADER[4:], {"t": files.TIME, **files.DOF_BOUNDS})  # the numeric columns, from t on


def write_waypoints(run_dir: Path, waypoints: list[Waypoint], times: np.ndarray) -> None:
    """One row per waypoint: what it is for (kind, plant, side), when it is passed, and q* (yaw unwrapped)."""
    dofs = np.array([w.dofs for w in waypoints])
    dofs[:, 3] = np.unwrap(dofs[:, 3])
    lines = [",".join(WAYPOINT_HEADER)]
    for index, (waypoint, time, q) in enumerate(zip(waypoints, times, dofs)):
        numbers = ",".join(f"{value:.6f}" for value in (time, *q))
        lines.append(f"{index},{waypoint.kind},{waypoint.plant},{waypoint.side},{numbers}")
    write_text(Path(run_dir) / names.WAYPOINTS, "\n".join(lines) + "\n")


def read_waypoints(run_dir: Path) -> list[Waypoint]:
    """The waypoints of `waypoints.csv`, each with the time it is passed as `time`."""
    files.require(run_dir, (names.WAYPOINTS,))
    path = Path(run_dir) / names.WAYPOINTS
    try:
        rows = path.read_text(encoding="utf-8").splitlines()
    except (OSError, UnicodeDecodeError):
        raise UserError(f"{path}: not a readable text file") from None
    if not rows or rows[0] != ",".join(WAYPOINT_HEADER):
        raise UserError(f"{path}: header is not {','.join(WAYPOINT_HEADER)}")
    if len(rows) < 2:
        raise UserError(f"{path}: holds no waypoints")
    parsed: list[tuple[str, int, str]] = []
    numbers = []
    for index, row in enumerate(rows[1:]):
        fields = row.split(",")
        where = f"{path}: {row_name(index)}"
        if len(fields) != len(WAYPOINT_HEADER):
            raise UserError(f"{where} has {len(fields)} fields, not {len(WAYPOINT_HEADER)}")
        if fields[0] != str(index):
            raise UserError(f"{where} has {fields[0]!r} in column index, not {index}")
        if fields[1] not in WAYPOINT_KINDS:
            raise UserError(f"{where} has {fields[1]!r} in column kind, not one of {', '.join(WAYPOINT_KINDS)}")
        if fields[3] not in ("", "left", "right"):
            raise UserError(f"{where} has {fields[3]!r} in column side, not left, right or nothing")
        try:
            plant = int(fields[2])
            numbers.append([float(v) for v in fields[4:]])
        except ValueError:
            raise UserError(f"{where} is not a waypoint row (a number that is not one)") from None
        if not -1 <= plant < MAX_PLANTS:
            raise UserError(f"{where} has {plant} in column plant, out of range [-1, {MAX_PLANTS - 1}]")
        parsed.append((fields[1], plant, fields[3]))
    table = np.array(numbers)
    check_columns(str(path), table, WAYPOINT_HEADER[4:], WAYPOINT_BOUNDS, row_name)
    check_increasing(str(path), table[:, 0], "t", row_name, strictly=False)
    return [Waypoint(kind, values[1:], plant, side, float(values[0])) for (kind, plant, side), values in zip(parsed, table)]
