"""renderloop: a render-in-the-loop aerial robotics simulator and its sweet-pepper yield estimation."""

import os

# MuJoCo picks its OpenGL platform at first import; headless EGL unless the user chose another.
os.environ.setdefault("MUJOCO_GL", "egl")

__version__ = "0.1.0"

__all__ = ["Simulation", "load_config"]


def __getattr__(name: str):
    """The public API, imported on first use so that `import renderloop` stays light (no MuJoCo, no Blender)."""
    if name == "Simulation":
        from renderloop.loop.simulation import Simulation

        return Simulation
    if name == "load_config":
        from renderloop.config import load_config

        return load_config
    raise AttributeError(f"module 'renderloop' has no attribute {name!r}")
