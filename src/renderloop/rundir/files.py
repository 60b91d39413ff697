"""A typed reader and writer for every file of a run directory, and the bounds of its tables.

Stages, the report, the evaluation and the exporters read each other's files only
through here, so a format lives in one place; the three files that hold a domain's own
type are read and written beside that type, with the names and bounds here
(`scene.json`: `renderloop.scene.model`, `waypoints.csv`: `renderloop.planning.waypoints`,
`camera_info.yaml`: `renderloop.render.camera`), since rundir lies below the domain
(docs/design.md, Layers). Every reader turns a missing, damaged
or hand-edited file into one UserError line naming the file (and the field, for JSON;
the row and column, for tables); every number is checked finite and within its bound
(the tables' below, the JSON files' in `renderloop.rundir.models` and
`renderloop.scene.model`), and no document is parsed that nests deeper than
`renderloop.io.bounded.MAX_DEPTH`. Every writer writes atomically
(`renderloop.io.atomic`) into a directory renderloop owns (`renderloop.io.ownership`).
"""

from __future__ import annotations

import io
import math
from pathlib import Path, PurePosixPath
from typing import TypeVar

import numpy as np
from pydantic import BaseModel, ValidationError

from renderloop.config import Config, PlannerConfig, RotorConfig, describe_changes, load_resolved
from renderloop.config.fields import WORLD_BOUND
from renderloop.errors import UserError, problem
from renderloop.io.atomic import dumps_json, write_text
from renderloop.io.bounded import Bound, check_increasing, check_json_depth, field_bounds, number_text
from renderloop.io.csvtable import read_csv, row_name, write_csv
from renderloop.io.tum import read_tum, write_tum
from renderloop.rundir import names
from renderloop.rundir.models import (
    MAX_COUNT,
    MAX_DISTANCE,
    MAX_TIME,
    Counts,
    Detections,
    DetectionScores,
    Harvest,
    Mission,
    RenderRecord,
    Timings,
)

Model = TypeVar("Model", bound=BaseModel)

FLIGHT_HEADER = [
    "t", "x", "y", "z", "qx", "qy", "qz", "qw", "q1", "q2", "q3", "w1", "w2", "w3", "w4",
    "ref_x", "ref_y", "ref_z", "ref_yaw", "ref_q1", "ref_q2", "ref_q3",
    "err_x", "err_y", "err_z", "err_yaw", "cam_x", "cam_y", "cam_z", "cam_err", "contacts", "saturated",
]
FLIGHT_FORMAT = ["%.6f"] * 30 + ["%d", "%d"]
POSES_COMMENT = (
    "renderloop ground truth: pose of the camera optical frame (x right, y down, z forward)\n"
    "in the world frame (ENU, z up), from the simulated arm; time in simulation seconds"
)

# The bounds of the tables' numbers: physical limits wide enough for every run the config allows, so that only a
# damaged or hand-edited file is refused. Positions share scene.json's WORLD_BOUND, times and distances the JSON
# files' (renderloop.rundir.models).
TIME = Bound(0.0, MAX_TIME, "s")
POSITION = Bound(-WORLD_BOUND, WORLD_BOUND, "m")
OFFSET = Bound(-2 * WORLD_BOUND, 2 * WORLD_BOUND, "m")  # one position less another
DISTANCE = Bound(0.0, MAX_DISTANCE, "m")
# Yaw is unwrapped along a trajectory, so turns add up: a million radians is more than any scan turns (at most
# half a turn from one waypoint to the next), and a float64 still holds such an angle to 1e-10 rad.
HEADING = Bound(-1e6, 1e6, "rad")
# A turn either way: every joint limit lies within [-π, π] (robot.arm.joint_limits), MuJoCo's soft limits let a
# flown joint overshoot a little, and a wrapped angle written to 6 decimals may pass π by rounding.
TURN = Bound(-2 * math.pi, 2 * math.pi, "rad")
QUATERNION = Bound(-1.0, 1.0)
# Five times the planner's largest limits: TOPP-RA keeps a trajectory within planner.velocity_limits and
# planner.acceleration_limits, whose ceilings these follow.
_FASTEST, _HARDEST = (5 * field_bounds(PlannerConfig, name)[1] for name in ("velocity_limits", "acceleration_limits"))
RATE = Bound(-_FASTEST, _FASTEST, "m/s or rad/s")
ACCELERATION = Bound(-_HARDEST, _HARDEST, "m/s² or rad/s²")
# No rotor spins faster than the largest robot.rotor.max_speed the config allows.
ROTOR_SPEED = Bound(0.0, field_bounds(RotorConfig, "max_speed")[1], "rad/s")
COUNT = Bound(0, MAX_COUNT, integer=True)
FLAG = Bound(0, 1, integer=True)

DOF_BOUNDS = {"x": POSITION, "y": POSITION, "z": POSITION, "yaw": HEADING, "q1": TURN, "q2": TURN, "q3": TURN}  # q*
TRAJECTORY_HEADER = ["t", *DOF_BOUNDS, *(f"d{name}" for name in DOF_BOUNDS), *(f"dd{name}" for name in DOF_BOUNDS)]


def column_bounds(header: list[str], bound_of: dict[str, Bound]) -> list[Bound]:
    """One bound per column of `header`, from the column's name."""
    assert set(bound_of) == set(header), set(bound_of) ^ set(header)
    return [bound_of[name] for name in header]


TRAJECTORY_BOUNDS = column_bounds(TRAJECTORY_HEADER, {
    "t": TIME, **DOF_BOUNDS, **{f"d{name}": RATE for name in DOF_BOUNDS}, **{f"dd{name}": ACCELERATION for name in DOF_BOUNDS}})
FLIGHT_BOUNDS = column_bounds(FLIGHT_HEADER, {
    "t": TIME, "x": POSITION, "y": POSITION, "z": POSITION, **dict.fromkeys(("qx", "qy", "qz", "qw"), QUATERNION),
    "q1": TURN, "q2": TURN, "q3": TURN, **dict.fromkeys(("w1", "w2", "w3", "w4"), ROTOR_SPEED),
    **{f"ref_{name}": bound for name, bound in DOF_BOUNDS.items()},
    "err_x": OFFSET, "err_y": OFFSET, "err_z": OFFSET, "err_yaw": TURN,
    "cam_x": POSITION, "cam_y": POSITION, "cam_z": POSITION, "cam_err": DISTANCE, "contacts": COUNT, "saturated": FLAG})
# The planner samples at planner.sample_rate_hz: rows this far off their one step apart are not its (6 decimals
# are written, so two roundings at most).
SAMPLE_TOLERANCE = 2.5e-6  # s


def _missing(run_dir: Path, name: str) -> UserError:
    return UserError(f"{run_dir}: missing {name} (run `renderloop {names.made_by(name)}` first)")


def require(run_dir: Path, needed: tuple[str, ...]) -> None:
    """Refuse to go on while files an earlier stage writes are missing, naming the stage to run."""
    missing = [name for name in needed if not (Path(run_dir) / name).is_file()]
    if missing:
        stage = names.made_by(missing[0])  # the earliest stage not run: what it writes, not what later ones would
        listed = ", ".join(name for name in missing if names.made_by(name) == stage)
        raise UserError(f"{run_dir}: missing {listed} (run `renderloop {stage}` first)")


# JSON files ---------------------------------------------------------------------------------------------------------

def read_model(path: Path, model: type[Model]) -> Model:
    """A JSON file as its model; missing, unreadable or invalid is one line naming the file and the field."""
    path = Path(path)
    try:
        data = path.read_bytes()
    except FileNotFoundError:
        raise UserError(f"{path}: no such file") from None
    except IsADirectoryError:
        raise UserError(f"{path}: a folder, not a JSON file") from None
    check_json_depth(data, str(path))
    try:
        return model.model_validate_json(data)
    except ValidationError as exc:
        raise UserError(f"{path}: {problem(exc)}") from None


def write_model(path: Path, document: BaseModel) -> None:
    write_text(path, dumps_json(document.model_dump(mode="json")))


def _is_file(path: Path) -> bool:
    """Whether `path` is a file; a name the file system cannot hold (too long, say) is not a file of the run."""
    try:
        return path.is_file()
    except OSError:
        return False


def read_detections(run_dir: Path, frame_count: int) -> Detections:
    """`detections.json`, checked against the run: every frame a frame of groundtruth.txt, once, and its image a
    file of the run, so counts are never made from another run's detections."""
    run_dir = Path(run_dir)
    path = run_dir / names.DETECTIONS
    if not path.is_file():
        raise _missing(run_dir, names.DETECTIONS)
    data = read_model(path, Detections)
    seen: set[int] = set()
    for number, frame in enumerate(data.frames):
        where = f"{path}: frames.{number}"
        if frame.index >= frame_count:
            raise UserError(f"{where}: index {frame.index} but {names.POSES} has {frame_count} frames")
        if frame.index in seen:
            raise UserError(f"{where}: frame index {frame.index} appears twice")
        seen.add(frame.index)
        image = PurePosixPath(frame.image)
        if image.is_absolute() or ".." in image.parts or not _is_file(run_dir / image):
            raise UserError(f"{where}: image {frame.image!r} is not a file of {run_dir}")
    return data


def read_counts(run_dir: Path) -> Counts:
    path = Path(run_dir) / names.COUNTS
    if not path.is_file():
        raise _missing(run_dir, names.COUNTS)
    return read_model(path, Counts)


def read_mission(run_dir: Path) -> Mission:
    path = Path(run_dir) / names.MISSION
    if not path.is_file():
        raise UserError(f"{run_dir}: missing {names.MISSION} (an adaptive mission writes it: `renderloop run --mission adaptive`)")
    return read_model(path, Mission)


def read_harvest(run_dir: Path) -> Harvest:
    path = Path(run_dir) / names.HARVEST
    if not path.is_file():
        raise _missing(run_dir, names.HARVEST)
    return read_model(path, Harvest)


def read_detection_scores(run_dir: Path) -> DetectionScores:
    path = Path(run_dir) / names.DETECTION_SCORES
    if not path.is_file():
        raise _missing(run_dir, names.DETECTION_SCORES)
    return read_model(path, DetectionScores)


def read_timings(run_dir: Path) -> dict[str, float]:
    path = Path(run_dir) / names.TIMINGS
    return read_model(path, Timings).root if path.is_file() else {}


def record_timing(run_dir: Path, stage: str, seconds: float) -> None:
    """Keep the seconds of the last run of each stage; a skipped stage (0 s) keeps its earlier time."""
    try:
        timings = read_timings(run_dir)
    except UserError:
        timings = {}  # a damaged record of times is not worth stopping a run for: it is written anew
    if seconds > 0 or stage not in timings:
        updated = {**timings, stage: round(seconds, 2)}
        if updated != timings:
            write_model(Path(run_dir) / names.TIMINGS, Timings(updated))


def read_render_record(run_dir: Path) -> RenderRecord | None:
    """What the frames in the directory were rendered from; None when there is no usable record (then they are redone)."""
    try:
        return read_model(Path(run_dir) / names.RENDER_RECORD, RenderRecord)
    except UserError:
        return None


# The config -----------------------------------------------------------------------------------------------

def read_config(run_dir: Path) -> Config:
    path = Path(run_dir) / names.CONFIG
    if not path.is_file():
        raise UserError(f"{run_dir}: not a run directory (no {names.CONFIG}; run `renderloop scene` first)")
    return load_resolved(path)


def write_config(run_dir: Path, config: Config) -> None:
    write_text(Path(run_dir) / names.CONFIG, config.to_yaml())


def _what_it_computes(config: Config) -> Config:
    """The config less what decides how fast files come, not what they hold: the renderer's thread count and device,
    and whether the scan is flown online (the online loop writes the batch stages' files)."""
    return config.override({"renderer": {"threads": 0, "device": "cpu"}, "mission": {"online": False}})


def check_config(run_dir: Path, config: Config, remade: dict | None = None) -> None:
    """Refuse to add files of one config to a run directory made with another: mixing two seeds' files in one
    directory would make every later figure a lie. `remade`: fields (an override, set on both sides before they are
    compared) that decide only files the caller writes again at every call."""
    path = Path(run_dir) / names.CONFIG
    if not path.is_file():
        return
    made, given = _what_it_computes(load_resolved(path)), _what_it_computes(config)
    if remade:
        made, given = made.override(remade), given.override(remade)
    if made != given:
        raise UserError(f"{path}: this run directory was made with another config ({describe_changes(made, given)}); "
                        "use --force to start it again, or another --out")


# Tables: trajectory, flight, poses, frame lists ----------------------------------------------------------

def write_trajectory(run_dir: Path, table: np.ndarray) -> None:
    write_csv(Path(run_dir) / names.TRAJECTORY, TRAJECTORY_HEADER, table)


def read_trajectory(run_dir: Path) -> np.ndarray:
    """Rows of t, q*, q̇*, q̈* (7 DoF each) at the planner's sample rate: t increasing in equal steps."""
    require(run_dir, (names.TRAJECTORY,))
    path = Path(run_dir) / names.TRAJECTORY
    table = read_csv(path, TRAJECTORY_HEADER, TRAJECTORY_BOUNDS)
    check_increasing(str(path), table[:, 0], "t", row_name, strictly=True)
    steps = np.diff(table[:, 0])
    uneven = np.flatnonzero(np.abs(steps - steps[0]) > SAMPLE_TOLERANCE) if len(steps) else []
    if len(uneven):
        index = int(uneven[0]) + 1  # the row after the uneven step
        raise UserError(f"{path}: {row_name(index)} has {number_text(table[index, 0])} in column t, not one "
                        f"sample step ({number_text(steps[0])} s) after {row_name(index - 1)}")
    return table


def as_stored_trajectory(table: np.ndarray) -> np.ndarray:
    """A trajectory table as trajectory.csv gives it back (six decimals, as written and parsed): a plan flown from
    memory is then the plan `renderloop fly` flies from the file, to the bit."""
    buffer = io.StringIO()
    np.savetxt(buffer, np.asarray(table) + 0.0, delimiter=",", fmt="%.6f")  # write_csv's format
    return np.loadtxt(io.StringIO(buffer.getvalue()), delimiter=",", ndmin=2, comments=None)


def as_stored_times(times: np.ndarray) -> np.ndarray:
    """Waypoint times as waypoints.csv gives them back (six decimals)."""
    return np.array([float(f"{t:.6f}") for t in times])


def write_flight(run_dir: Path, table: np.ndarray) -> None:
    write_csv(Path(run_dir) / names.FLIGHT, FLIGHT_HEADER, table, fmt=FLIGHT_FORMAT)


def read_flight(run_dir: Path) -> dict[str, np.ndarray]:
    """flight.csv's columns by name."""
    require(run_dir, (names.FLIGHT,))
    path = Path(run_dir) / names.FLIGHT
    table = read_csv(path, FLIGHT_HEADER, FLIGHT_BOUNDS)
    check_increasing(str(path), table[:, 0], "t", row_name, strictly=True)  # one row per control tick
    return {name: table[:, column] for column, name in enumerate(FLIGHT_HEADER)}


def write_poses(run_dir: Path, times: np.ndarray, positions: np.ndarray, rotations: np.ndarray) -> None:
    write_tum(Path(run_dir) / names.POSES, times, positions, rotations, POSES_COMMENT)


def read_poses(run_dir: Path) -> tuple[np.ndarray, np.ndarray]:
    """The camera's timestamps (N,) and optical-frame poses in the world, T_world_optical (N, 4, 4)."""
    require(run_dir, (names.POSES,))
    times, positions, rotations = read_tum(Path(run_dir) / names.POSES, TIME, POSITION)
    poses = np.tile(np.eye(4), (len(times), 1, 1))
    poses[:, :3, :3], poses[:, :3, 3] = rotations, positions
    return times, poses


def write_frames_index(run_dir: Path, stream: str, times: np.ndarray) -> None:
    """rgb.txt, depth.txt, depth_sensor.txt: `timestamp path` per frame, as TUM RGB-D lists them."""
    lines = [f"# {stream} images of renderloop, TUM RGB-D layout", "# timestamp filename"]
    lines += [f"{t:.6f} {names.frame_file(stream, i)}" for i, t in enumerate(times)]
    write_text(Path(run_dir) / names.frames_index(stream), "\n".join(lines) + "\n")
