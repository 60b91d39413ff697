"""Random greenhouse scenes for the training set.

Each dataset scene is a small greenhouse (two rows of four plants, every plant
bearing) whose plant shape, fruit size, colour mix, lighting and render quality are
drawn from the dataset seed and the scene's index, so that a view can be rebuilt
from two integers and the dataset grows without changing the images it has.
The ranges are wider than the presets' on purpose: the detector has to see more
variety than any one run will show it. A spec may also draw each scene's plant style
(the 'simple' plants or the dense 'pepper' ones) and its surroundings (plain walls or
the film greenhouse with sky and sun), so that one set holds both presets' looks; a
spec that draws nothing new makes the scenes it always made.
"""

from __future__ import annotations

import numpy as np

from renderloop.config import Config, SensorConfig, deep_merge, preset_overrides, validate
from renderloop.config.dataset import DatasetSpec
from renderloop.errors import UserError
from renderloop.scene.generate import generate_scene
from renderloop.scene.model import Scene

SCENE_STREAM = 0xDA7A
# 2: the neighbouring rows' plants bear their fruit, labelled (1 drew them without); 3: 'pepper' and 'highwire'
# leaves tinted per plant (DATASET_LEAF_TINT), the sensor's white balance misjudged (DATASET_SENSOR), close
# views clear of cutting a fruit with the near clip; 4: the colour sensor's noise measured on real frames, and averaged
# down in frames narrower than the stream it is stated for; 5: the lens's defocus from the camera's optics, stated for
# that stream too. A set is resumed only by the format it was made with.
FORMAT_VERSION = 5
MAX_TRIES = 20
HIGHWIRE_HEIGHT = (1.3, 1.9)  # m: the canopy of a 'highwire' scene's plants, under the room's 3.5 m
DATASET_LEAF_TINT = (0.0, 1.0)  # pepper_style.leaf_tint: dark green crops to light yellow-green ones
# The colour sensor of training views: the run's camera with its white balance misjudged twice as far either way,
# so the detector meets warm and cool casts wider than a camera's nominal ones (docs/stages/perception.md)
DATASET_SENSOR = SensorConfig(enabled=True, white_balance_warmth=(-0.5, 0.5))
CLOSE_NEAR_CLIP = 0.05  # m: the camera's near clip when views come as close as a hand's breadth
PICKED_VIEWS = 0.5  # share of a scene's close views that look at one of its picked fruit, where it has any


def manifest(spec: DatasetSpec) -> dict:
    """`dataset.json`: the renderer's format and the spec, which a dataset grows only with."""
    return {"format_version": FORMAT_VERSION, **spec.model_dump(mode="json")}


def _choice(rng: np.random.Generator, options: tuple[str, ...]) -> str:
    """One of the options, equally likely; a single option draws nothing, so a spec that draws nothing new makes the
    scenes it always made."""
    return options[int(rng.integers(len(options)))] if len(options) > 1 else options[0]


def _scene_overrides(rng: np.random.Generator, spec: DatasetSpec) -> dict:
    leaves_low = int(rng.integers(18, 40))
    leaf_low = float(rng.uniform(0.06, 0.09))
    length_low = float(rng.uniform(0.055, 0.08))
    colors = {"red": rng.uniform(0.1, 1.0), "yellow": rng.uniform(0.0, 1.0),
              "orange": rng.uniform(0.0, 1.0), "green": rng.uniform(0.1, 0.8)}
    style, environment = _choice(rng, spec.styles), _choice(rng, spec.environments)
    camera = {"width": spec.width, "height": spec.height}
    if spec.close > 0:
        camera["clip"] = (CLOSE_NEAR_CLIP, 5.0)
    overrides = {
        "greenhouse": {"size": (7.0, 6.0, 3.5), "tables": [(-1.0, 0.0), (1.0, 0.0)], "plants_per_table": 4,
                       "workstation_center": (0.0, -2.3), "environment": {"kind": environment}},
        "plants": {
            "style": style,
            "bearing": None,
            "leaves": (leaves_low, leaves_low + int(rng.integers(8, 30))),
            "leaf_length": (leaf_low, leaf_low + float(rng.uniform(0.03, 0.07))),
            "flowers": (0, int(rng.integers(1, 7))),
            "pepper_style": {"leaf_tint": DATASET_LEAF_TINT},
            "peppers": {
                "per_side": (1, int(rng.integers(2, 6))),
                "length": (length_low, length_low + float(rng.uniform(0.01, 0.035))),
                "colors": {name: float(weight) for name, weight in colors.items()},
            },
        },
        "camera": camera,
        "renderer": {"backend": "cycles", "samples": int(rng.choice(spec.samples)), "denoise": True},
    }
    if style == "highwire":  # a high-wire crop on low gutters, taller and with more fruit; drawn last, so a set
        # without this style keeps its scenes
        overrides = deep_merge(overrides, {
            "greenhouse": {"table_size": (0.3, 2.0, 0.1)},
            "plants": {"volume": (0.5, 0.5, float(rng.uniform(*HIGHWIRE_HEIGHT))),
                       "pepper_style": {"leaves": (int(rng.integers(250, 400)), 550)},
                       "peppers": {"per_side": (2, int(rng.integers(4, 8)))}},
        })
    return overrides


def dataset_scene(spec: DatasetSpec, scene_index: int) -> tuple[Config, Scene]:
    """The config and scene of dataset scene `scene_index`; a draw whose fruit do not fit is redrawn."""
    rng = np.random.default_rng(np.random.SeedSequence([spec.seed, SCENE_STREAM, scene_index]))
    base = preset_overrides("paper")
    for _ in range(MAX_TRIES):
        data = deep_merge(base, {**_scene_overrides(rng, spec), "seed": int(rng.integers(2**62))})
        config = validate(data, f"dataset scene {scene_index}")
        try:
            return config, generate_scene(config)
        except UserError:
            continue
    raise UserError(f"dataset scene {scene_index}: no fruit layout fits after {MAX_TRIES} draws")
