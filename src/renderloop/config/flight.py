"""The robot, its scan's planning and its control (`robot`, `planner`, `controller`)."""

from __future__ import annotations

from typing import Literal

from pydantic import Field, model_validator

from renderloop.config.fields import (
    MAX_TABLES,
    Angle,
    Coordinate,
    Count,
    Gain,
    Real,
    Strict,
    ordered_range,
)


class RotorConfig(Strict):
    """Rotor thrust F = kf w^2, drag moment M = km F (docs/design.md)."""

    kf: Real(1e-9, 1e-2) = Field(8.54858e-6, description="Thrust coefficient kf of F = kf w², N s²/rad².")
    km: Real(0.0, 1.0, low_open=True) = Field(0.016, description="Drag moment over thrust km of M = km F, m.")
    max_speed: Real(10.0, 20_000.0) = Field(1475.0, description="Largest rotor speed, rad/s.")
    time_constant: Real(0.0, 1.0) = Field(0.0, description="First-order motor lag, s; 0 means none.")
    layout: Literal["x", "+"] = Field("x", description="Quadrotor layout: 'x' (rotors between the axes) or '+' (on them).")


class ArmConfig(Strict):
    """3-DoF pitch chain below the body with the RGB-D camera on its tip."""

    mount: tuple[Real(-1.0, 1.0), Real(-1.0, 1.0), Real(-1.0, 1.0)] = Field(
        (0.0, 0.0, -0.08), description="Joint 1 position in the body frame, m.")
    link_lengths: tuple[Real(0.01, 2.0), Real(0.01, 2.0), Real(0.01, 2.0)] = Field(
        (0.12, 0.14, 0.3), description="Length of links 1, 2 and 3 (the last carries the camera), m.")
    link_masses: tuple[Real(0.001, 10.0), Real(0.001, 10.0), Real(0.001, 10.0)] = Field(
        (0.05, 0.05, 0.12), description="Mass of links 1, 2 and 3, kg.")
    joint_limits: tuple[Angle, Angle] = Field((-1.6, 1.6), description="Lower and upper limit of every joint, rad.")
    nominal_posture: tuple[Angle, Angle] = Field((0.0, 0.0), description="q1, q2 that inverse kinematics keeps, rad; q3 sets the pitch.")
    max_torque: Real(0.01, 1000.0) = Field(2.0, description="Joint motor torque limit, N m.")

    @model_validator(mode="after")
    def _limits(self) -> ArmConfig:
        ordered_range(self.joint_limits, "joint_limits")
        return self


class RobotConfig(Strict):
    mass: Real(0.05, 100.0) = Field(2.083, description="UAV body mass without the arm, kg.")
    inertia: tuple[Real(1e-6, 100.0), Real(1e-6, 100.0), Real(1e-6, 100.0)] = Field(
        (0.0827, 0.0827, 0.0104), description="Body principal moments of inertia (x, y, z), kg m².")
    arm_length: Real(0.02, 5.0) = Field(0.314, description="Body centre to rotor axis, m.")
    prop_radius: Real(0.01, 2.0) = Field(0.12, description="Propeller radius, m.")
    leg_length: Real(0.01, 2.0) = Field(0.2, description="Landing legs below the body centre, m.")
    rotor: RotorConfig = Field(RotorConfig(), description="The four rotors.")
    arm: ArmConfig = Field(ArmConfig(), description="The camera arm.")
    home: tuple[Coordinate, Coordinate, Real(0.0, 50.0)] = Field((0.0, -1.2, 0.0), description="Take-off point on the floor, m.")

    @model_validator(mode="after")
    def _physical_inertia(self) -> RobotConfig:
        # No rigid body has a principal moment larger than the other two together; MuJoCo refuses one.
        a, b, c = self.inertia
        if a > b + c or b > a + c or c > a + b:
            raise ValueError(f"inertia: no rigid body has principal moments {list(self.inertia)}: "
                             "each must be at most the sum of the other two")
        return self


class PlannerConfig(Strict):
    """Elliptical scan waypoints and TOPP-RA limits for q* = (x, y, z, yaw, q1, q2, q3)."""

    distance: Real(0.1, 10.0) = Field(1.0, description="Horizontal distance from a plant's axis to the UAV body on its scan ellipse, m.")
    semi_axes: tuple[Real(0.01, 5.0), Real(0.01, 5.0)] = Field(
        (0.125, 0.25), description="Half width (along the row) and half height of the camera's scan ellipse, m.")
    points_per_ellipse: Count(1, 360) = Field(10, description="Scan waypoints on each ellipse.")
    bands: Count(1, 20) = Field(
        1, description="Ellipses stacked up the canopy on each side of a plant, each aimed at the middle of its own "
        "band of the canopy's height: 1 where the camera sees the whole canopy, more for a tall crop.")
    row: Count(0, MAX_TABLES - 1) | None = Field(
        None, description="The one row the scan visits, by its index in greenhouse.tables (a mission a row in a long "
        "compartment); null means every row.")
    sides: Literal["both", "aisles"] = Field(
        "both", description="Sides of a row the scan flies. 'both': each row from both its sides, out along one and "
        "back along the other (free-standing tables). 'aisles': each row from the sides where the UAV fits its scan "
        "line (a line of a double row faces one path; the gap between the two lines is no aisle); a row with no such "
        "side is a planning error.")
    max_camera_pitch: Real(0.0, 1.5) = Field(0.6, description="Largest camera pitch, rad; 0.6 lets the camera aim at the centroid from the ellipse top.")
    # Lower limits keep a trajectory (its length over its speed, times sample_rate_hz samples) within memory.
    velocity_limits: tuple[Real(0.05, 20.0), ...] = Field(
        (1.5, 1.5, 0.5, 0.3, 1.0, 1.0, 1.0), min_length=7, max_length=7,
        description="Speed limit of x, y, z (m/s), yaw, q1, q2, q3 (rad/s).")
    acceleration_limits: tuple[Real(0.05, 50.0), ...] = Field(
        (0.6, 0.6, 0.4, 0.3, 1.2, 1.2, 1.2), min_length=7, max_length=7,
        description="Acceleration limit of x, y, z (m/s²), yaw, q1, q2, q3 (rad/s²).")
    limit_margin: Real(0.1, 1.0) = Field(0.98, description="Fraction of each limit given to TOPP-RA.")
    sample_rate_hz: Real(1.0, 1000.0) = Field(100.0, description="Rate at which the trajectory is sampled into trajectory.csv, Hz.")


class PID(Strict):
    p: Gain = Field(0.0, description="Proportional gain, in the units of its loop (ControllerConfig).")
    i: Gain = Field(0.0, description="Integral gain, 1/s times the proportional units.")
    d: Gain = Field(0.0, description="Derivative gain, s times the proportional units.")
    limit: Real(1e-3, 1e5) | None = Field(None, description="Clamp on the loop's output, in its units; null means none.")


class ControllerConfig(Strict):
    """Cascade PID gains in SI units, and the loop rates.

    Position loops give velocity (1/s), velocity loops acceleration (m/s² per m/s; the xy
    gains are in rad of tilt per m/s as in the reference work, times g), the attitude loop
    body rates (1/s) and the rate loop angular acceleration (1/s, times the inertia).
    The xy and attitude gains are the authors'; z, rate and joint gains are retuned for
    these units (their rate and z gains acted on rotor-speed units). Joint PIDs act on
    joint acceleration through the arm's mass matrix, with gravity compensation.
    """

    rate_hz: Real(50.0, 1000.0) = Field(100.0, description="Control loop rate, Hz; its period is a whole number of physics steps.")
    physics_dt: Real(1e-4, 0.002) = Field(0.002, description="MuJoCo physics time step, s.")
    position_xy: PID = Field(PID(p=2.0, limit=3.0), description="Horizontal position loop: m/s per m; limit in m/s.")
    velocity_xy: PID = Field(PID(p=0.5, i=0.1), description="Horizontal velocity loop: rad of tilt per m/s, times g.")
    max_tilt: Real(0.0, 1.57, low_open=True, high_open=True) = Field(0.6, description="Largest commanded roll or pitch, rad.")
    position_z: PID = Field(PID(p=4.0, limit=2.0), description="Vertical position loop: m/s per m; limit in m/s.")
    velocity_z: PID = Field(PID(p=8.0, i=3.0), description="Vertical velocity loop: m/s² per m/s.")
    attitude: PID = Field(PID(p=7.0), description="Roll and pitch loop: rad/s per rad.")
    rate: PID = Field(PID(p=25.0, i=3.0), description="Body rate loop: rad/s² per rad/s, times the inertia.")
    yaw: PID = Field(PID(p=5.0), description="Yaw loop: rad/s per rad.")
    yaw_rate: PID = Field(PID(p=12.0, i=1.0), description="Yaw rate loop: rad/s² per rad/s, times the inertia.")
    joints: PID = Field(PID(p=400.0, i=200.0, d=32.0), description="Arm joint loops: rad/s² per rad, through the mass matrix.")
    compensate_arm_pitch: bool = Field(True, description="Joint 1 cancels the body's pitch, so the camera holds its planned pitch.")
    position_noise_std: Real(0.0, 1.0) = Field(0.0, description="UWB-like noise on the position fed back, m.")

    @model_validator(mode="after")
    def _whole_physics_steps(self) -> ControllerConfig:
        period = 1.0 / self.rate_hz
        steps = round(period / self.physics_dt)
        if steps < 1 or abs(steps * self.physics_dt - period) > 1e-9:
            raise ValueError(f"rate_hz: the control period 1/{self.rate_hz:g} s must be a whole number of "
                             f"physics steps of {self.physics_dt:g} s")
        return self
