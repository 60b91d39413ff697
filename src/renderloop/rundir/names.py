"""Every file of a run directory, named once.

`OUTPUTS` is the pipeline's contract: the files whose presence (newer than the stage's
inputs) says a stage is complete. Everything else a stage writes (plots, frames, its
record) is named here too, so no module spells a run's file name itself.
"""

from __future__ import annotations

CONFIG = "config.yaml"  # the resolved config the run was made with
SCENE = "scene.json"  # the greenhouse: the single source of truth
WORLD = "world.xml"  # MJCF of the scene and the robot
TOP_VIEW = "scene_topview.png"

WAYPOINTS = "waypoints.csv"
TRAJECTORY = "trajectory.csv"

FLIGHT = "flight.csv"
POSES = "groundtruth.txt"  # camera optical-frame poses at the camera's instants, TUM layout
FLIGHT_PATHS = "flight_paths.png"
TRACKING_ERROR = "tracking_error.png"

RGB = "rgb"
DEPTH = "depth"  # ideal planar depth
DEPTH_SENSOR = "depth_sensor"  # with the RealSense-like noise model, when the run renders it
MASKS = "masks"
RGB_SENSOR = "rgb_sensor"  # the colour a real camera delivers (render/sensor.py), when the run renders it
FRAME_DIRS = (RGB, DEPTH, DEPTH_SENSOR, MASKS, RGB_SENSOR)
CAMERA_INFO = "camera_info.yaml"
CONTACT_SHEET = "contact_sheet.png"
RENDER_RECORD = "render.json"  # what the frames were rendered from

DETECTIONS = "detections.json"
DETECTION_SCORES = "detection_scores.json"
DETECTION_SHEET = "detections.png"
DETECT_CACHE = ".detections.cache.jsonl"  # frames detected so far, for a resumed detect

MISSION = "mission.json"  # what the adaptive mission decided

COUNTS = "counts.json"
HARVEST = "harvest.json"
COUNT_PLOTS = "counts"

ROW_RUNS = "rows"  # a scan split by rows (mission.split: rows): each row's mission a run of its own in rows/row_<id>
FLEET = "fleet.json"  # which UAV flies which row's mission when

TIMINGS = "timings.json"
REPORT = "report.html"


def frame_name(index: int) -> str:
    return f"{index:06d}.png"


def frame_file(stream: str, index: int) -> str:
    """A frame's file relative to the run directory, e.g. rgb/000012.png."""
    return f"{stream}/{frame_name(index)}"


def frames_index(stream: str) -> str:
    """The TUM RGB-D list of a stream's images: rgb.txt, depth.txt, depth_sensor.txt."""
    return f"{stream}.txt"


def row_run(row_id: int) -> str:
    """A row's mission's run directory inside the compartment's, e.g. rows/row_1."""
    return f"{ROW_RUNS}/row_{row_id}"


def row_plot(row_id: int) -> str:
    return f"{COUNT_PLOTS}/row_{row_id}.png"


OUTPUTS: dict[str, tuple[str, ...]] = {
    "scene": (CONFIG, SCENE, WORLD, TOP_VIEW),
    "plan": (WAYPOINTS, TRAJECTORY),
    "fly": (FLIGHT, POSES, FLIGHT_PATHS, TRACKING_ERROR),
    "render": (frames_index(RGB), frames_index(DEPTH), CAMERA_INFO, CONTACT_SHEET),
    "detect": (DETECTIONS, DETECTION_SCORES, DETECTION_SHEET),
    "mission": (MISSION,),
    "count": (COUNTS, HARVEST),
}


def made_by(name: str) -> str:
    """The verb that writes a run's file: what to run when it is missing."""
    return next(stage for stage, outputs in OUTPUTS.items() if name in outputs)
