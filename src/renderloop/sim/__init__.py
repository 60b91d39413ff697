"""MuJoCo closed-loop flight and the camera pose log."""
