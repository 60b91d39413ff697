"""The scan figure (waypoints, planned and flown paths over the greenhouse) and the tracking error."""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.collections import PatchCollection  # noqa: E402
from matplotlib.patches import Rectangle  # noqa: E402
from mpl_toolkits.mplot3d.art3d import Line3DCollection  # noqa: E402

from renderloop.io.atomic import atomic_path  # noqa: E402
from renderloop.planning.waypoints import Waypoint  # noqa: E402
from renderloop.scene.model import Scene  # noqa: E402
from renderloop.sim.flight import FlightLog  # noqa: E402

STRIDE = 10  # plot every 10th control tick


def _save(figure, path: Path) -> None:
    figure.tight_layout()
    with atomic_path(Path(path)) as tmp:
        figure.savefig(tmp, format="png")
    plt.close(figure)


def _box_edges(low, high) -> list[np.ndarray]:
    """The 12 edges of an axis-aligned box, as (2, 3) segments."""
    corners = np.array([[x, y, z] for z in (low[2], high[2]) for y in (low[1], high[1]) for x in (low[0], high[0])])
    pairs = [(a, b) for a in range(8) for b in range(a + 1, 8) if bin(a ^ b).count("1") == 1]
    return [corners[[a, b]] for a, b in pairs]


def draw_flight_paths(scene: Scene, waypoints: list[Waypoint], log: FlightLog, planned_camera: np.ndarray, path: Path) -> None:
    """3D view and top view, like the reference work's scan figure: red planned body path and
    waypoints, blue flown body path, orange camera path."""
    figure = plt.figure(figsize=(16, 8), dpi=90)
    view3d = figure.add_subplot(1, 2, 1, projection="3d")
    top = figure.add_subplot(1, 2, 2)
    scan = np.array([w.dofs[:3] for w in waypoints if w.kind == "scan"])
    other = np.array([w.dofs[:3] for w in waypoints if w.kind != "scan"])
    planned, flown, camera = log.reference[::STRIDE, :3], log.position[::STRIDE], log.camera_position[::STRIDE]
    # One collection per kind of box, not an artist per edge: hundreds of 3D lines took most of the figure's second.
    tables = [(np.array(row.table.center) - np.array(row.table.size) / 2, np.array(row.table.center) + np.array(row.table.size) / 2)
              for row in scene.rows]
    plants = [(np.asarray(plant.bounds.min), np.asarray(plant.bounds.max)) for plant in scene.plants]
    for boxes, style, patch in ((tables, {"color": "0.5", "lw": 0.6}, {"fc": "0.85", "ec": "0.5"}),
                                (plants, {"color": "#2a7a2a", "lw": 0.4}, {"fc": "none", "ec": "#2a7a2a", "lw": 0.6})):
        view3d.add_collection3d(Line3DCollection([edge for low, high in boxes for edge in _box_edges(low, high)], **style))
        top.add_collection(PatchCollection([Rectangle(low[:2], *(high - low)[:2]) for low, high in boxes], **patch))
    station = scene.workstation
    top.add_patch(Rectangle((station.center[0] - station.size[0] / 2, station.center[1] - station.size[1] / 2),
                            station.size[0], station.size[1], fc="#8090b0"))
    for axes, dims in ((view3d, slice(0, 3)), (top, slice(0, 2))):
        axes.plot(*planned[:, dims].T, color="red", lw=0.8, label="planned (body)")
        axes.plot(*flown[:, dims].T, color="tab:blue", lw=0.8, ls="--", label="flown (body)")
        axes.plot(*camera[:, dims].T, color="orange", lw=0.6, label="camera")
        axes.scatter(*scan[:, dims].T, s=6, color="red", label="scan waypoints")
        if len(other):
            axes.scatter(*other[:, dims].T, s=6, color="k", marker="x", label="transit waypoints")
    low = np.minimum(flown.min(axis=0), camera.min(axis=0)) - 0.3
    high = np.maximum(flown.max(axis=0), camera.max(axis=0)) + 0.3
    low[2] = 0.0
    view3d.set_xlim(low[0], high[0])
    view3d.set_ylim(low[1], high[1])
    view3d.set_zlim(low[2], high[2])
    view3d.set_box_aspect(tuple(high - low))
    length, width, _ = scene.room
    view3d.view_init(elev=35, azim=-60)
    view3d.set_title("scan path, 3D")
    top.set_aspect("equal")
    top.set_xlim(-length / 2, length / 2)
    top.set_ylim(-width / 2, width / 2)
    top.set_title("scan path, top view")
    top.legend(loc="upper right", fontsize=8)
    top.grid(alpha=0.3)
    _save(figure, path)


def draw_tracking_error(log: FlightLog, planned_camera: np.ndarray, path: Path) -> None:
    camera_error = np.linalg.norm(log.camera_position - planned_camera, axis=1) * 100
    body_error = np.linalg.norm(log.reference[:, :3] - log.position, axis=1) * 100
    joint_error = np.degrees(np.abs(log.reference[:, 4:7] - log.joints))
    figure, (positions, joints, rotors) = plt.subplots(3, 1, figsize=(14, 9), dpi=90, sharex=True)
    rms = float(np.sqrt(np.mean(camera_error**2)))
    positions.plot(log.t, camera_error, lw=0.6, label=f"camera (RMS {rms:.2f} cm, max {camera_error.max():.2f} cm)")
    positions.plot(log.t, body_error, lw=0.6, alpha=0.7, label=f"body (RMS {np.sqrt(np.mean(body_error**2)):.2f} cm)")
    contacts = log.t[log.contacts > 0]
    if len(contacts):
        positions.scatter(contacts, np.zeros_like(contacts), color="red", marker="|", label="contact")
    positions.set_ylabel("position error (cm)")
    positions.legend(loc="upper right")
    for k in range(3):
        joints.plot(log.t, joint_error[:, k], lw=0.6, label=f"q{k + 1}")
    joints.set_ylabel("|joint - planned| (deg)\n(q1 also cancels body pitch)")
    joints.legend(loc="upper right")
    rotors.plot(log.t, log.rotor_speeds, lw=0.4)
    rotors.set_ylabel("rotor speed (rad/s)")
    rotors.set_xlabel("time (s)")
    saturated = 100 * float(np.mean(log.saturated))
    rotors.set_title(f"rotor speeds (saturated {saturated:.2f} % of the time)", fontsize=9)
    for axes in (positions, joints, rotors):
        axes.grid(alpha=0.3)
    _save(figure, path)
