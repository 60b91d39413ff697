"""renderloop: a render-in-the-loop aerial robotics simulator and its sweet-pepper yield estimation."""

import os

# MuJoCo picks its OpenGL platform at first import; headless EGL unless the user chose another.
os.environ.setdefault("MUJOCO_GL", "egl")

__version__ = "0.1.0"


def _register_environments() -> None:
    """`gymnasium.make("renderloop/PepperScan-v0")` once renderloop is imported; the environment's module (MuJoCo, the
    detector) is imported only when one is made."""
    try:
        import gymnasium
    except ImportError:  # a dependency, but the simulator itself runs without it
        return
    if "renderloop/PepperScan-v0" not in gymnasium.registry:
        gymnasium.register(id="renderloop/PepperScan-v0", entry_point="renderloop.loop.gym_env:PepperScanEnv")


_register_environments()
