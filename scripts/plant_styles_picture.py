"""The docs' picture of the two plant styles: one plant of the demo scene in Cycles, 'simple' beside 'pepper'.

    python scripts/plant_styles_picture.py --out docs/images/plant_styles.jpg [--samples 32] [--seed 0] [--plant 1]

Same seed, plant and camera for both: the fruit are the same (the styles share them), the rest of
the plant is each style's own. The camera looks at the plant from its left side (-x), where the scan flies.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
from PIL import Image, ImageDraw

from renderloop.config import Config, load_config
from renderloop.render.camera import Intrinsics
from renderloop.render.cycles import CyclesRenderer
from renderloop.robot.kinematics import look_at
from renderloop.scene.generate import generate_scene

WIDTH, HEIGHT = 480, 560


def render(style: str, seed: int, plant_index: int, samples: int) -> np.ndarray:
    data = load_config("demo", seed=seed).model_dump(mode="json")
    data["plants"]["style"] = style
    data["camera"].update(width=WIDTH, height=HEIGHT)
    data["renderer"].update(samples=samples)
    config = Config.model_validate(data)
    scene = generate_scene(config)
    plant = scene.plants[plant_index]
    target = np.array([plant.position[0], plant.position[1], plant.position[2] + plant.pot.height + 0.22])
    pose = look_at(target + np.array([-0.62, -0.06, 0.1]), target)
    with CyclesRenderer(scene, config, Intrinsics.from_config(config.camera)) as renderer:
        return renderer.render(pose).rgb


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, required=True)
    parser.add_argument("--samples", type=int, default=32)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--plant", type=int, default=1)
    args = parser.parse_args()
    gap = 8
    canvas = Image.new("RGB", (2 * WIDTH + gap, HEIGHT), "white")
    for column, style in enumerate(("simple", "pepper")):
        panel = Image.fromarray(render(style, args.seed, args.plant, args.samples))
        ImageDraw.Draw(panel).text((10, 8), f"plants.style: {style}", fill="black")
        canvas.paste(panel, (column * (WIDTH + gap), 0))
    args.out.parent.mkdir(parents=True, exist_ok=True)
    canvas.save(args.out, quality=90)


if __name__ == "__main__":
    main()
