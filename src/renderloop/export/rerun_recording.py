"""A run as a Rerun recording (.rrd): the scene, the plan, the flight and what the camera saw, on one timeline.

Scrubbing the "sim_time" timeline in the Rerun viewer shows the UAV, the camera frustum with
its image, depth and point cloud, and the detections at each instant against the static
greenhouse, plan and counts, which is where a wrong pose, a bad depth or a misplaced fruit
shows at a glance. A dedicated RecordingStream (not Rerun's global one) keeps several
exports in one process apart; its id is derived from the run directory, so exporting a run
twice gives the same id (the viewer merges files of one id into one recording).
"""

from __future__ import annotations

import uuid
from pathlib import Path

import numpy as np
import rerun as rr

from renderloop.errors import UserError
from renderloop.io.atomic import atomic_path
from renderloop.perception.pointcloud import organised_cloud
from renderloop.render.camera import Intrinsics
from renderloop.render.frames import DEPTH_SCALE, decode_depth, read_png
from renderloop.robot.kinematics import planned_camera_positions
from renderloop.export.contents import Frame, RunContents
from renderloop.rundir.models import Counts, Detection
from renderloop.scene.model import Scene

TIMELINE = "sim_time"
UAV_RATE_HZ = 10.0  # body poses: smooth to scrub, a fraction of the control rate's rows
CLOUD_STRIDE = 2  # every 2nd pixel each way: a quarter of the points, still dense on screen
FRUSTUM_DEPTH = 0.3  # m: a frustum that fits between the plants
CLASS_IDS = {"ripe": 1, "unripe": 2}
# Colours given per item: rr.AnnotationContext would say them once per class, but 0.23.1 fails to build one under numpy < 2.
CLASS_COLOURS = {"ripe": (220, 40, 40), "unripe": (60, 180, 60)}
PEPPER_COLOURS = {"red": (200, 30, 30), "yellow": (235, 200, 30), "orange": (240, 120, 20), "green": (50, 160, 50)}
PLANT_PALETTE = [(31, 119, 180), (255, 127, 14), (44, 160, 44), (214, 39, 40), (148, 103, 189),
                 (140, 86, 75), (227, 119, 194), (127, 127, 127), (188, 189, 34), (23, 190, 207)]


def _greenhouse(rec: rr.RecordingStream, scene: Scene) -> None:
    tables = [row.table for row in scene.rows]
    rec.log("world/greenhouse/tables", rr.Boxes3D(centers=[t.center for t in tables], sizes=[t.size for t in tables],
                                                  colors=(150, 120, 90), fill_mode="solid"), static=True)
    plants = scene.plants
    rec.log("world/greenhouse/plants", rr.Boxes3D(
        mins=[p.bounds.min for p in plants], sizes=[np.subtract(p.bounds.max, p.bounds.min) for p in plants],
        labels=[f"plant {p.id}" for p in plants], colors=(60, 140, 60)), static=True)
    station = scene.workstation
    rec.log("world/greenhouse/workstation", rr.Boxes3D(centers=[station.center], sizes=[station.size], labels=["workstation"],
                                                       colors=(110, 110, 130), fill_mode="solid"), static=True)
    peppers = scene.peppers
    if peppers:  # spheres of the fruit's width, so they read as fruit and not as markers
        rec.log("world/greenhouse/peppers", rr.Points3D(
            [p.center for p in peppers], radii=[p.width / 2 for p in peppers], colors=[PEPPER_COLOURS[p.color] for p in peppers],
            labels=[f"pepper {p.id} ({'ripe' if p.ripe else 'unripe'})" for p in peppers], show_labels=False), static=True)


def _plan(rec: rr.RecordingStream, contents: RunContents) -> None:
    arm = contents.config.robot.arm
    scans = [w for w in contents.waypoints or [] if w.kind == "scan"]
    if scans:
        rec.log("world/plan/waypoints", rr.Points3D(
            planned_camera_positions(np.array([w.dofs for w in scans]), arm), radii=0.02,
            labels=[f"plant {w.plant} {w.side}" for w in scans], show_labels=False), static=True)
    if contents.trajectory is not None:
        path = planned_camera_positions(contents.trajectory[:, 1:8], arm)
        rec.log("world/plan/camera_path", rr.LineStrips3D([path], colors=(120, 120, 255)), static=True)


def _stack(table: dict[str, np.ndarray], *names: str) -> np.ndarray:
    return np.column_stack([table[name] for name in names])


def _flight(rec: rr.RecordingStream, contents: RunContents) -> int:
    """Paths static; the body pose over time by columns, at UAV_RATE_HZ (the control rate would bloat the file)."""
    flight, robot = contents.flight, contents.config.robot
    rec.log("world/flight/camera_path", rr.LineStrips3D([_stack(flight, "cam_x", "cam_y", "cam_z")], colors=(255, 160, 0)), static=True)
    rec.log("world/flight/body_path", rr.LineStrips3D([_stack(flight, "x", "y", "z")], colors=(160, 160, 160)), static=True)
    span = 2 * (robot.arm_length + robot.prop_radius)
    rec.log("world/uav/body", rr.Boxes3D(sizes=[(span, span, 0.08)], labels=["uav"], colors=(80, 80, 80)), static=True)
    t = flight["t"]
    rows = np.unique(np.searchsorted(t, np.arange(t[0], t[-1] + 1e-9, 1 / UAV_RATE_HZ) - 1e-9))
    rec.send_columns("world/uav", indexes=[rr.TimeColumn(TIMELINE, duration=t[rows])], columns=rr.Transform3D.columns(
        translation=_stack(flight, "x", "y", "z")[rows], quaternion=_stack(flight, "qx", "qy", "qz", "qw")[rows]))
    return len(rows)


def _detections(rec: rr.RecordingStream, found: list[Detection]) -> int:
    """Logged on every frame, empty ones too: Rerun shows the latest value, so no-detections must overwrite the last boxes."""
    rec.log("world/camera/image/detections", rr.Boxes2D(
        array=np.array([d.bbox for d in found], dtype=np.float32).reshape(-1, 4), array_format=rr.Box2DFormat.XYXY,
        labels=[f"{d.label} {d.score:.2f}" for d in found], class_ids=[CLASS_IDS[d.label] for d in found],
        colors=[CLASS_COLOURS[d.label] for d in found]))
    placed = [d for d in found if d.position is not None]
    rec.log("world/detections/points", rr.Points3D(
        np.array([d.position for d in placed], dtype=np.float32).reshape(-1, 3), radii=0.015,
        class_ids=[CLASS_IDS[d.label] for d in placed], colors=[CLASS_COLOURS[d.label] for d in placed]))
    return len(found)


def _images(rec: rr.RecordingStream, frame: Frame, intrinsics: Intrinsics) -> None:
    """The RGB PNG goes in as is (lossless and smaller than raw pixels); depth as TUM units with meter=5000."""
    rec.log("world/camera/image/rgb", rr.EncodedImage(path=frame.rgb))
    units = read_png(frame.depth, np.uint16)
    rec.log("world/camera/image/depth", rr.DepthImage(units, meter=DEPTH_SCALE))
    cloud = organised_cloud(decode_depth(units), intrinsics)[::CLOUD_STRIDE, ::CLOUD_STRIDE]
    colours = read_png(frame.rgb, np.uint8)[::CLOUD_STRIDE, ::CLOUD_STRIDE]
    valid = ~np.isnan(cloud[..., 2])
    rec.log("world/camera/points", rr.Points3D(cloud[valid], colors=colours[valid]))


def _frames(rec: rr.RecordingStream, contents: RunContents, every: int) -> dict[str, int]:
    intrinsics = contents.intrinsics
    # Rerun puts pixel (0, 0)'s corner at the origin, the camera model its centre: hence the half pixel.
    rec.log("world/camera/image", rr.Pinhole(
        focal_length=[intrinsics.fx, intrinsics.fy], principal_point=[intrinsics.cx + 0.5, intrinsics.cy + 0.5],
        resolution=[intrinsics.width, intrinsics.height], camera_xyz=rr.ViewCoordinates.RDF,
        image_plane_distance=FRUSTUM_DEPTH), static=True)
    images = detections = 0
    for frame in contents.frames:
        rec.set_time(TIMELINE, duration=frame.timestamp)
        rec.log("world/camera", rr.Transform3D(translation=frame.pose[:3, 3], mat3x3=frame.pose[:3, :3]))
        if contents.detections is not None:
            detections += _detections(rec, contents.detections.get(frame.index, []))
        if frame.index % every == 0:
            _images(rec, frame, intrinsics)
            images += 1
        else:  # a stale cloud would ride along with the moving camera to where it was never seen
            rec.log("world/camera/points", rr.Clear(recursive=False))
    return {"frames": len(contents.frames), "images": images, "detections": detections}


def _counts(rec: rr.RecordingStream, counts: Counts) -> int:
    logged = 0
    for key, entity in (("clusters", "world/counts/ripe"), ("unripe_clusters", "world/counts/unripe")):
        centres = [(plant.id, centre) for plant in counts.plants for centre in getattr(plant, key)]
        if centres:
            rec.log(entity, rr.Points3D(
                [centre for _, centre in centres], radii=0.025, colors=[PLANT_PALETTE[i % len(PLANT_PALETTE)] for i, _ in centres],
                labels=[f"plant {i}" for i, _ in centres], show_labels=False), static=True)
        logged += len(centres)
    return logged


def write_rerun(contents: RunContents, out: Path, every: int = 1) -> dict[str, int]:
    """Write what the run holds to `out` atomically; `every` thins images, depth and clouds (not poses or
    detections) to every Nth frame so long runs stay small. Returns counts of what was logged."""
    if every < 1:
        raise UserError(f"every: {every} is not a positive frame step")
    run_id = uuid.uuid5(uuid.NAMESPACE_URL, contents.run_dir.resolve().as_uri())
    rec = rr.RecordingStream(application_id="renderloop", recording_id=run_id)
    if not rec.is_enabled():  # RERUN=off in the environment turns every stream into a no-op that writes nothing
        raise UserError("the Rerun SDK is disabled by the environment (RERUN=off): unset RERUN to export a recording")
    logged = {"frames": 0, "images": 0, "detections": 0, "uav_poses": 0, "clusters": 0}
    with atomic_path(Path(out)) as tmp:
        rec.save(tmp)
        try:
            rec.log("world", rr.ViewCoordinates.RIGHT_HAND_Z_UP, static=True)
            if contents.scene is not None:
                _greenhouse(rec, contents.scene)
            _plan(rec, contents)
            if contents.flight is not None:
                logged["uav_poses"] = _flight(rec, contents)
            if contents.frames and contents.intrinsics is not None:
                logged.update(_frames(rec, contents, every))
            if contents.counts is not None:
                logged["clusters"] = _counts(rec, contents.counts)
            rec.flush(blocking=True)
        finally:
            rec.disconnect()  # closes the file, so the rename below moves a complete recording
    return logged
