"""MJCF of the aerial manipulator: a free-flying body, 4 rotor actuators, a 3-joint arm, the camera.

The rotor actuators take the squared rotor speed w² as their control, with gear
(0, 0, kf, 0, 0, d·km·kf): MuJoCo then applies exactly u = K · w² of the rotor model,
and ctrlrange clamps at the maximum rotor speed. Geometry numbers are written with
repr() so that MuJoCo parses the same doubles that our kinematics uses.
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET

import numpy as np
from scipy.spatial.transform import Rotation

from renderloop.config import CameraConfig, RobotConfig
from renderloop.robot.kinematics import OPTICAL_IN_LINK
from renderloop.robot.rotors import rotor_geometry

ROBOT_CLASS = "robot"
ROBOT_BODY = "uav"  # the free body at the root of the robot's tree
ROTOR_HEIGHT = 0.05  # propeller plane above the body centre, m
CAMERA_SITE = "camera_optical"
CAMERA_NAME = "rgbd"
JOINT_NAMES = ("q1", "q2", "q3")
ROOT_JOINT = "uav_root"


def fmt(*values: float) -> str:
    return " ".join(repr(float(v)) for v in values)


def quat_wxyz(rotation: np.ndarray) -> str:
    x, y, z, w = Rotation.from_matrix(rotation).as_quat()
    return fmt(w, x, y, z)


def _rod_inertia(mass: float, length: float, radius: float = 0.01) -> str:
    axial = mass * radius**2 / 2
    transverse = mass * (3 * radius**2 + length**2) / 12
    return fmt(axial, transverse, transverse)


def robot_body(robot: RobotConfig, camera: CameraConfig) -> ET.Element:
    """The `uav` body subtree, resting on its legs at the configured home point."""
    home = robot.home
    uav = ET.Element("body", name=ROBOT_BODY, pos=fmt(home[0], home[1], home[2] + robot.leg_length + 0.008), childclass=ROBOT_CLASS)
    ET.SubElement(uav, "freejoint", name=ROOT_JOINT)
    ET.SubElement(uav, "inertial", pos="0 0 0", mass=repr(robot.mass), diaginertia=fmt(*robot.inertia))
    ET.SubElement(uav, "geom", name="uav_frame", type="box", size=fmt(0.09, 0.09, 0.035), material="uav_body")
    ET.SubElement(uav, "site", name="imu", pos="0 0 0", size="0.01")
    geometry = rotor_geometry(robot.arm_length, robot.rotor.layout)
    for index, (x, y) in enumerate(geometry.positions):
        ET.SubElement(uav, "geom", name=f"uav_boom{index}", type="capsule", size="0.012", fromto=fmt(0, 0, 0, x, y, ROTOR_HEIGHT), material="uav_body")
        ET.SubElement(uav, "geom", name=f"uav_prop{index}", type="cylinder", size=fmt(robot.prop_radius, 0.004),
                      pos=fmt(x, y, ROTOR_HEIGHT), material="uav_prop")
        ET.SubElement(uav, "site", name=f"rotor{index}", pos=fmt(x, y, ROTOR_HEIGHT), size="0.01")
        leg_x, leg_y = 0.4 * x, 0.4 * y
        ET.SubElement(uav, "geom", name=f"uav_leg{index}", type="capsule", size="0.008",
                      fromto=fmt(leg_x, leg_y, -0.03, 1.15 * leg_x, 1.15 * leg_y, -robot.leg_length), material="uav_body")

    arm = robot.arm
    parent, offset = uav, arm.mount
    for index, (name, length, mass) in enumerate(zip(JOINT_NAMES, arm.link_lengths, arm.link_masses), start=1):
        link = ET.SubElement(parent, "body", name=f"arm_link{index}", pos=fmt(*offset))
        ET.SubElement(link, "joint", name=name, type="hinge", axis="0 1 0", range=fmt(*arm.joint_limits), damping="0.02", armature="0.0005")
        ET.SubElement(link, "inertial", pos=fmt(length / 2, 0, 0), mass=repr(mass), diaginertia=_rod_inertia(mass, length))
        ET.SubElement(link, "geom", name=f"arm_link{index}", type="capsule", size="0.01", fromto=fmt(0, 0, 0, length, 0, 0), material="uav_arm")
        parent, offset = link, (length, 0.0, 0.0)

    tip = arm.link_lengths[2]
    ET.SubElement(parent, "geom", name="camera_body", type="box", size=fmt(0.0125, 0.045, 0.0125), pos=fmt(tip - 0.0125, 0, 0), material="uav_camera")
    ET.SubElement(parent, "site", name=CAMERA_SITE, pos=fmt(tip, 0, 0), quat=quat_wxyz(OPTICAL_IN_LINK), size="0.005")
    # MuJoCo cameras look down their -z with y up: the optical frame turned half a turn about x.
    fovy = math.degrees(2 * math.atan(camera.height / 2 / camera.fx))
    ET.SubElement(parent, "camera", name=CAMERA_NAME, pos=fmt(tip, 0, 0), quat=quat_wxyz(OPTICAL_IN_LINK @ np.diag([1.0, -1.0, -1.0])), fovy=repr(fovy))
    return uav


def robot_actuators(robot: RobotConfig) -> list[ET.Element]:
    rotor = robot.rotor
    geometry = rotor_geometry(robot.arm_length, rotor.layout)
    actuators = []
    for index, drag_sign in enumerate(geometry.drag_signs):
        actuators.append(ET.Element(
            "general", name=f"rotor{index}", site=f"rotor{index}", ctrlrange=fmt(0.0, rotor.max_speed**2),
            gear=fmt(0, 0, rotor.kf, 0, 0, drag_sign * rotor.km * rotor.kf),
        ))
    torque = robot.arm.max_torque
    for name in JOINT_NAMES:
        actuators.append(ET.Element("motor", name=f"{name}_motor", joint=name, ctrlrange=fmt(-torque, torque)))
    return actuators
