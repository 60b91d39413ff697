"""The physics world a planned flight can reach: world.xml less the greenhouse's geoms far from the planned path.

A MuJoCo step recomputes the pose of every geom, static ones too, and tests the robot against the greenhouse's: in
a five-row compartment of 1000 plants (4790 geoms) a step costs 2.5 times what it costs in one row of 200 (968
geoms; `mj_kinematics` alone 28 µs against 6), although one row's flight comes near a fifth of them. So the fly
stage flies in the corridor: the static geoms whose box comes within the robot's reach of the planned path of its
body, where the reach is the robot's extent from its body's centre (whatever its joints do) plus
`MARGIN` for the tracking error. A geom the robot could touch is never dropped and the kept ones keep their order,
so the flight is the whole world's to the bit; the flown path is checked against the plan afterwards, and a flight
that strayed farther than `MARGIN` is flown again in the whole world.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from pathlib import Path

import mujoco
import numpy as np
from scipy.spatial import cKDTree

from renderloop.config import Config
from renderloop.robot.mjcf import ROBOT_BODY
from renderloop.sim.flight import FlightLog, Reference, fly

MARGIN = 0.5  # m beyond the robot's extent: tracking errors are centimetres (docs/stages/fly.md), a strayed flight is redone
SPACING = 0.05  # m between the path's points that stand for it


def robot_extent(model: mujoco.MjModel, root: int) -> float:
    """A bound on how far any geom of the robot (the body `root` and its subtree) reaches from the root body's centre,
    in any pose of its joints: each body's offset from its parent, added along the chain, plus the geom's offset and
    bounding sphere."""
    reach = np.zeros(model.nbody)
    extent = 0.0
    for body in range(root + 1, model.nbody):  # MuJoCo numbers a body after its parent
        if model.body_rootid[body] == model.body_rootid[root]:
            reach[body] = reach[model.body_parentid[body]] + np.linalg.norm(model.body_pos[body])
    for geom in range(model.ngeom):
        body = model.geom_bodyid[geom]
        if body and model.body_rootid[body] == model.body_rootid[root]:
            extent = max(extent, reach[body] + np.linalg.norm(model.geom_pos[geom]) + model.geom_rbound[geom])
    return float(extent)


def path_points(positions: np.ndarray) -> np.ndarray:
    """Points along the polyline `positions` (N, 3) no farther than SPACING apart, ends included."""
    steps = np.linalg.norm(np.diff(positions, axis=0), axis=1)
    along = np.concatenate([[0.0], np.cumsum(steps)])
    marks = np.arange(0.0, along[-1], SPACING)
    return np.vstack([np.column_stack([np.interp(marks, along, positions[:, k]) for k in range(3)]), positions[-1:]])


def corridor_xml(world: Path, body_path: np.ndarray) -> tuple[str | None, int, int]:
    """world.xml without the static geoms beyond the robot's reach of `body_path` (N, 3): the MJCF text (None when
    every geom is within reach), and how many geoms it keeps and drops."""
    text = world.read_text(encoding="utf-8")
    model = mujoco.MjModel.from_xml_string(text)
    reach = robot_extent(model, model.body(ROBOT_BODY).id) + MARGIN + SPACING / 2
    static = np.flatnonzero(model.body_rootid[model.geom_bodyid] == 0)
    data = mujoco.MjData(model)
    mujoco.mj_kinematics(model, data)
    points = path_points(body_path)
    tree = cKDTree(points)
    far = []
    for geom in static:  # its box in the world's axes; a tall canopy's bounding sphere would reach into the next aisle
        rotation = data.geom_xmat[geom].reshape(3, 3)
        centre = data.geom_xpos[geom] + rotation @ model.geom_aabb[geom, :3]
        half = np.abs(rotation) @ model.geom_aabb[geom, 3:]
        near = tree.query_ball_point(centre, reach + float(np.linalg.norm(half)))
        if not near or np.linalg.norm(np.maximum(np.abs(points[near] - centre) - half, 0.0), axis=1).min() > reach:
            far.append(geom)
    far = np.array(far, dtype=int)
    if not len(far):
        return None, model.ngeom, 0
    names = {model.geom(int(geom)).name for geom in far}
    root = ET.fromstring(text)
    for parent in root.iter():
        for child in [c for c in parent if c.tag == "geom" and c.get("name") in names]:
            parent.remove(child)
    return ET.tostring(root, encoding="unicode"), model.ngeom - len(far), len(far)


def fly_in_corridor(world: Path, config: Config, reference: Reference) -> FlightLog:
    """The planned flight flown in the corridor of world.xml that its body's path can reach, or in the whole world
    when it strays past the margin."""
    text, _, _ = corridor_xml(world, reference.q[:, :3])
    if text is not None:
        log = fly(mujoco.MjModel.from_xml_string(text), config, reference)
        if np.max(np.linalg.norm(log.position - log.reference[:, :3], axis=1)) <= MARGIN:
            return log
    return fly(mujoco.MjModel.from_xml_path(str(world)), config, reference)
