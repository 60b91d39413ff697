"""Aerial manipulator: kinematics, rotor model and its MJCF."""
