"""The scan figure (waypoints, planned and flown paths over the greenhouse) and the tracking error.

Both are drawn for a page: 1280 px wide with 13 pt text (18 px), which stays readable
where report.html scales them to its content width (about 1150 px).
"""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.collections import PatchCollection  # noqa: E402
from matplotlib.patches import Patch, Rectangle  # noqa: E402
from matplotlib.ticker import MaxNLocator  # noqa: E402
from mpl_toolkits.mplot3d.art3d import Line3DCollection  # noqa: E402

from renderloop.io.atomic import atomic_path  # noqa: E402
from renderloop.planning.waypoints import Waypoint  # noqa: E402
from renderloop.scene.model import Scene  # noqa: E402
from renderloop.sim.flight import FlightLog  # noqa: E402

STRIDE = 10  # plot every 10th control tick
WIDTH_IN, DPI = 12.8, 100  # 1280 px
STYLE = {"font.size": 13, "axes.titlesize": 14, "axes.labelsize": 13, "xtick.labelsize": 12, "ytick.labelsize": 12,
         "legend.fontsize": 12, "figure.titlesize": 15}


def _save(figure, path: Path, tight: bool = True) -> None:
    if tight:
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
    waypoints, blue flown body path, orange camera path; one legend for both, below them."""
    with plt.rc_context(STYLE):
        _draw_flight_paths(scene, waypoints, log, path)


def _draw_flight_paths(scene: Scene, waypoints: list[Waypoint], log: FlightLog, path: Path) -> None:
    figure = plt.figure(figsize=(WIDTH_IN, 6.8), dpi=DPI)
    grid = figure.add_gridspec(1, 2, width_ratios=(1.45, 1))
    view3d = figure.add_subplot(grid[0], projection="3d")
    top = figure.add_subplot(grid[1])
    scan = np.array([w.dofs[:3] for w in waypoints if w.kind == "scan"])
    other = np.array([w.dofs[:3] for w in waypoints if w.kind != "scan"])
    planned, flown, camera = log.reference[::STRIDE, :3], log.position[::STRIDE], log.camera_position[::STRIDE]
    # One collection per kind of box, not an artist per edge: hundreds of 3D lines took most of the figure's second.
    tables = [(np.array(row.table.center) - np.array(row.table.size) / 2, np.array(row.table.center) + np.array(row.table.size) / 2)
              for row in scene.rows]
    plants = [(np.asarray(plant.bounds.min), np.asarray(plant.bounds.max)) for plant in scene.plants]
    for boxes, style, patch in ((tables, {"color": "0.5", "lw": 0.8}, {"fc": "0.85", "ec": "0.5"}),
                                (plants, {"color": "#2a7a2a", "lw": 0.6}, {"fc": "none", "ec": "#2a7a2a", "lw": 0.9})):
        view3d.add_collection3d(Line3DCollection([edge for low, high in boxes for edge in _box_edges(low, high)], **style))
        top.add_collection(PatchCollection([Rectangle(low[:2], *(high - low)[:2]) for low, high in boxes], **patch))
    station = scene.workstation
    station_low = np.array(station.center[:2]) - np.array(station.size[:2]) / 2
    top.add_patch(Rectangle(tuple(station_low), station.size[0], station.size[1], fc="#8090b0"))
    for axes, dims in ((view3d, slice(0, 3)), (top, slice(0, 2))):
        axes.plot(*planned[:, dims].T, color="red", lw=1.2, label="planned path (body)")
        axes.plot(*flown[:, dims].T, color="tab:blue", lw=1.2, ls="--", label="flown path (body)")
        axes.plot(*camera[:, dims].T, color="orange", lw=1.0, label="camera path")
        axes.scatter(*scan[:, dims].T, s=12, color="red", label="scan waypoints")
        if len(other):
            axes.scatter(*other[:, dims].T, s=14, color="k", marker="x", label="transit waypoints")
    low = np.minimum(flown.min(axis=0), camera.min(axis=0)) - 0.3
    high = np.maximum(flown.max(axis=0), camera.max(axis=0)) + 0.3
    low[2] = 0.0
    view3d.set_xlim(low[0], high[0])
    view3d.set_ylim(low[1], high[1])
    view3d.set_zlim(low[2], high[2])
    view3d.set_box_aspect(tuple(high - low), zoom=1.1)
    view3d.view_init(elev=35, azim=-60)
    view3d.set_xlabel("x (m)")
    view3d.set_ylabel("y (m)")
    view3d.set_zlabel("z (m)")
    view3d.zaxis.set_major_locator(MaxNLocator(4))
    view3d.set_title("scan path, 3D")
    # The top view spans what was flown and the tables and workstation, not the whole room: the path stays large.
    corners = np.vstack([low[:2], high[:2], station_low, station_low + np.array(station.size[:2]),
                         *[corner[:2] for box in tables for corner in box]])
    length, width, _ = scene.room
    span_low = np.maximum(corners.min(axis=0) - 0.2, [-length / 2, -width / 2])
    span_high = np.minimum(corners.max(axis=0) + 0.2, [length / 2, width / 2])
    top.set_aspect("equal")
    top.set_xlim(span_low[0], span_high[0])
    top.set_ylim(span_low[1], span_high[1])
    top.set_xlabel("x (m)")
    top.set_ylabel("y (m)")
    top.set_title("scan path, top view")
    top.grid(alpha=0.3)
    handles, labels = top.get_legend_handles_labels()
    handles += [Patch(fc="0.85", ec="0.5"), Patch(fc="none", ec="#2a7a2a"), Patch(fc="#8090b0")]
    labels += ["tables", "plant volumes", "workstation"]
    figure.legend(handles, labels, loc="lower center", ncol=4, frameon=False, markerscale=1.5)
    figure.tight_layout(rect=(0, 0.1, 1, 1))
    _save(figure, path, tight=False)


def draw_tracking_error(log: FlightLog, planned_camera: np.ndarray, path: Path) -> None:
    """Position, joint and rotor figures over time, each legend above its panel, clear of the lines."""
    with plt.rc_context(STYLE):
        _draw_tracking_error(log, planned_camera, path)


def _draw_tracking_error(log: FlightLog, planned_camera: np.ndarray, path: Path) -> None:
    camera_error = np.linalg.norm(log.camera_position - planned_camera, axis=1) * 100
    body_error = np.linalg.norm(log.reference[:, :3] - log.position, axis=1) * 100
    joint_error = np.degrees(np.abs(log.reference[:, 4:7] - log.joints))
    figure, (positions, joints, rotors) = plt.subplots(3, 1, figsize=(WIDTH_IN, 10.0), dpi=DPI, sharex=True)
    rms = float(np.sqrt(np.mean(camera_error**2)))
    positions.plot(log.t, camera_error, lw=0.8, label=f"camera (RMS {rms:.2f} cm, max {camera_error.max():.2f} cm)")
    positions.plot(log.t, body_error, lw=0.8, alpha=0.75,
                   label=f"body (RMS {np.sqrt(np.mean(body_error**2)):.2f} cm, max {body_error.max():.2f} cm)")
    contacts = log.t[log.contacts > 0]
    if len(contacts):
        positions.scatter(contacts, np.zeros_like(contacts), color="red", marker="|", s=120, label="contact")
    positions.set_ylabel("position error (cm)")
    for k in range(3):
        joints.plot(log.t, joint_error[:, k], lw=0.8, label=f"q{k + 1}" + (" (also cancels body pitch)" if k == 0 else ""))
    joints.set_ylabel("|joint - planned| (deg)")
    for k in range(log.rotor_speeds.shape[1]):
        rotors.plot(log.t, log.rotor_speeds[:, k], lw=0.6, label=f"rotor {k + 1}")
    rotors.set_ylabel("rotor speed (rad/s)")
    rotors.set_xlabel("time (s)")
    saturated = 100 * float(np.mean(log.saturated))
    rotors.set_title(f"saturated {saturated:.2f} % of the time", loc="right", fontsize=12)
    for axes in (positions, joints, rotors):
        axes.grid(alpha=0.3)
        axes.legend(loc="lower left", bbox_to_anchor=(0, 1), ncol=4, frameon=False, borderaxespad=0.1,
                    handlelength=1.5, columnspacing=1.2)
        axes.margins(x=0.01)
    _save(figure, path)
