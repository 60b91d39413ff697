"""`world.xml`: the MJCF physics view of a scene, with the robot in it.

Physics needs only simple shapes: floor, walls, tables, pots, one box per plant
canopy (the plant's bounding volume above its pot: touching it counts as a
collision with the plant), the workstation and the robot. The greenhouse's shapes
come from `scene/objects.py` (`collision_objects`, the static ones shared with the
renderers), their colours from the material table `scene/materials.py`. Environment
geoms and robot geoms sit in different collision groups, so the robot collides with
the greenhouse but not with itself and the greenhouse is never tested against itself.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET

import numpy as np

from renderloop.config import Config
from renderloop.robot.mjcf import ROBOT_CLASS, fmt, robot_actuators, robot_body
from renderloop.scene.materials import display_rgba
from renderloop.scene.model import Scene
from renderloop.scene.objects import Box, Shape, collision_objects

ROBOT_MATERIALS = ("uav_body", "uav_prop", "uav_arm", "uav_camera")  # the materials robot/mjcf.py's geoms name
ROOM_SHELL = ("floor", "walls")  # the objects of scene/objects.py that span the room


def shape_geom(parent: ET.Element, shape: Shape, **look: str) -> ET.Element:
    """One primitive shape as a MuJoCo geom (both MJCF views, physics and raster, make geoms here);
    `look` is its material or rgba."""
    if isinstance(shape, Box):
        return ET.SubElement(parent, "geom", name=shape.name, type="box", pos=fmt(*shape.center), size=fmt(*shape.half), **look)
    # By centre, half length and axis, not `fromto`: MuJoCo turns a vertical fromto into a half-turn
    # quaternion (the same solid, but not the exact identity frame the pots always had).
    start, end = np.asarray(shape.start, dtype=float), np.asarray(shape.end, dtype=float)
    return ET.SubElement(parent, "geom", name=shape.name, type="cylinder", pos=fmt(*(start + end) / 2),
                         size=fmt(shape.radius, np.linalg.norm(end - start) / 2), zaxis=fmt(*(end - start)), **look)


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

    objects = collision_objects(scene)
    asset = ET.SubElement(root, "asset")
    for name in dict.fromkeys([obj.material for obj in objects] + list(ROBOT_MATERIALS)):
        ET.SubElement(asset, "material", name=name, rgba=fmt(*display_rgba(name)))

    world = ET.SubElement(root, "worldbody")
    height = scene.room[2]
    ET.SubElement(world, "light", name="sun", directional="true", pos=fmt(0, 0, height), dir="0.2 0.3 -1", diffuse="0.7 0.7 0.7")
    # The floor is a slab, not a plane: a plane is tested against every robot geom at every step (a third of the physics time).
    # The floor and each wall span the room, so in the world body their boxes would cover all of the tree that MuJoCo's
    # midphase walks for the robot at every step: each stands in a static body of its own. More static bodies cost
    # more in the broadphase than they save (docs/stages/fly.md, "Measured").
    for obj in objects:
        for shape in obj.shapes:
            parent = ET.SubElement(world, "body", name=shape.name) if obj.name in ROOM_SHELL else world
            shape_geom(parent, shape, material=obj.material)

    world.append(robot_body(config.robot, config.camera))
    actuator = ET.SubElement(root, "actuator")
    actuator.extend(robot_actuators(config.robot))
    ET.indent(root)
    return ET.tostring(root, encoding="unicode") + "\n"
