"""renderloop: a render-in-the-loop aerial robotics simulator and its sweet-pepper yield estimation."""

import os

# MuJoCo picks its OpenGL platform at first import; headless EGL unless the user chose another.
os.environ.setdefault("MUJOCO_GL", "egl")

__version__ = "0.1.0"
