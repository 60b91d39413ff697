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
