"""Cascade PID for the UAV and joint PIDs for the arm."""
