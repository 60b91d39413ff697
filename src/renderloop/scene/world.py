"""`world.xml`: the MJCF physics view of a scene, with the robot in it.

Physics needs only simple shapes: floor, walls, tables, pots, one box per plant
canopy (the plant's bounding volume above its pot: touching it counts as a
collision with the plant), the workstation and the robot. Environment geoms and
robot geoms sit in different collision groups, so the robot collides with the
greenhouse but not with itself and the greenhouse is never tested against itself.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET

from renderloop.config import Config
from renderloop.robot.mjcf import ROBOT_CLASS, fmt, robot_actuators, robot_body
from renderloop.scene.model import Scene

TABLE_TOP_THICKNESS = 0.04
TABLE_LEG = 0.04
WALL_THICKNESS = 0.05
WORKSTATION_COLUMN = (0.6, 0.05)  # height above the workstation table and radius of its manipulator, m

MATERIALS = {
    "floor": "0.45 0.42 0.38 1",
    "wall": "0.85 0.88 0.9 1",
    "table": "0.55 0.56 0.58 1",
    "pot": "0.12 0.12 0.12 1",
    "canopy": "0.2 0.55 0.2 0.35",
    "workstation": "0.35 0.38 0.45 1",
    "uav_body": "0.15 0.15 0.17 1",
    "uav_prop": "0.8 0.8 0.8 0.6",
    "uav_arm": "0.7 0.45 0.1 1",
    "uav_camera": "0.1 0.1 0.1 1",
}


def _box(parent: ET.Element, name: str, center, half_size, material: str) -> None:
    ET.SubElement(parent, "geom", name=name, type="box", pos=fmt(*center), size=fmt(*half_size), material=material)


def wall_boxes(room) -> list[tuple[str, tuple, tuple]]:
    """(name, centre, half size) of the four walls just outside the room."""
    length, width, height = room
    t = WALL_THICKNESS / 2
    return [
        ("wall_east", (length / 2 + t, 0, height / 2), (t, width / 2, height / 2)),
        ("wall_west", (-length / 2 - t, 0, height / 2), (t, width / 2, height / 2)),
        ("wall_north", (0, width / 2 + t, height / 2), (length / 2, t, height / 2)),
        ("wall_south", (0, -width / 2 - t, height / 2), (length / 2, t, height / 2)),
    ]


def table_boxes(name: str, center, size) -> list[tuple[str, tuple, tuple]]:
    """(name, centre, half size) of a table's slab and four legs; `center` is the centre of the
    table's whole box, floor to top. The physics world and both renderers build tables from this."""
    x, y, _ = center
    sx, sy, height = size
    leg_height = height - TABLE_TOP_THICKNESS
    boxes = [(name, (x, y, height - TABLE_TOP_THICKNESS / 2), (sx / 2, sy / 2, TABLE_TOP_THICKNESS / 2))]
    for index, (dx, dy) in enumerate(((-1, -1), (-1, 1), (1, -1), (1, 1))):
        leg_center = (x + dx * (sx / 2 - TABLE_LEG), y + dy * (sy / 2 - TABLE_LEG), leg_height / 2)
        boxes.append((f"{name}_leg{index}", leg_center, (TABLE_LEG / 2, TABLE_LEG / 2, leg_height / 2)))
    return boxes


def world_xml(scene: Scene, config: Config) -> str:
    root = ET.Element("mujoco", model="renderloop_greenhouse")
    ET.SubElement(root, "compiler", angle="radian", autolimits="true")
    ET.SubElement(root, "option", timestep=repr(config.controller.physics_dt), gravity="0 0 -9.81", integrator="implicitfast")
    visual = ET.SubElement(root, "visual")
    ET.SubElement(visual, "global", offwidth=str(max(640, config.camera.width)), offheight=str(max(480, config.camera.height)))
    ET.SubElement(visual, "headlight", ambient="0.35 0.35 0.35", diffuse="0.5 0.5 0.5")

    default = ET.SubElement(root, "default")
    ET.SubElement(default, "geom", contype="1", conaffinity="2", condim="3", friction="0.8 0.01 0.001")
    robot_default = ET.SubElement(default, "default", attrib={"class": ROBOT_CLASS})
    ET.SubElement(robot_default, "geom", contype="2", conaffinity="1")

    asset = ET.SubElement(root, "asset")
    for name, rgba in MATERIALS.items():
        ET.SubElement(asset, "material", name=name, rgba=rgba)

    world = ET.SubElement(root, "worldbody")
    length, width, height = scene.room
    ET.SubElement(world, "light", name="sun", directional="true", pos=fmt(0, 0, height), dir="0.2 0.3 -1", diffuse="0.7 0.7 0.7")
    # A slab, not a plane: a plane is tested against every robot geom at every step (a third of the physics time).
    _box(world, "floor", (0, 0, -0.05), (length / 2, width / 2, 0.05), "floor")
    for name, center, half in wall_boxes(scene.room):
        _box(world, name, center, half, "wall")

    station = scene.workstation
    tables = [(f"table_{row.id}", row.table, "table") for row in scene.rows] + [("workstation", station, "workstation")]
    for name, table, material in tables:
        for box_name, center, half in table_boxes(name, table.center, table.size):
            _box(world, box_name, center, half, material)
    height, radius = WORKSTATION_COLUMN
    top = station.size[2]
    ET.SubElement(world, "geom", name="workstation_arm", type="capsule", size=repr(radius),
                  fromto=fmt(station.center[0], station.center[1], top, station.center[0], station.center[1], top + height), material="workstation")

    for plant in scene.plants:
        x, y, z = plant.position
        pot = plant.pot
        ET.SubElement(world, "geom", name=f"pot_{plant.id}", type="cylinder", pos=fmt(x, y, z + pot.height / 2),
                      size=fmt(pot.radius_top, pot.height / 2), material="pot")
        low, high = plant.bounds.min, plant.bounds.max
        canopy_low = z + pot.height
        _box(world, f"plant_{plant.id}", ((low[0] + high[0]) / 2, (low[1] + high[1]) / 2, (canopy_low + high[2]) / 2),
             ((high[0] - low[0]) / 2, (high[1] - low[1]) / 2, (high[2] - canopy_low) / 2), "canopy")

    world.append(robot_body(config.robot, config.camera))
    actuator = ET.SubElement(root, "actuator")
    actuator.extend(robot_actuators(config.robot))
    ET.indent(root)
    return ET.tostring(root, encoding="unicode") + "\n"
