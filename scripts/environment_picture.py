"""The docs' picture of the greenhouse environment: one scan camera view in Cycles, 'plain' beside 'film'.

    python scripts/environment_picture.py --out docs/images/environment.jpg [--samples 16] [--seed 0] [--plant 2]
    python scripts/environment_picture.py --out /tmp/side_by_side.jpg --real ../shared/real/greenhouse-unlabelled

`--real FOLDER` adds a third panel, a photo of that folder (the first in name order, centre-cropped to 4:3, at
the same size), to compare renders with reality: such a picture stays outside the repository, as the photos do.

The greenhouse preset ('highwire' plants) with `greenhouse.environment.kind` plain and film: the same scanned
plants and fruit, seen from the same pose, a waypoint of the planned scan (the first of the plant's middle band
on its left side, -x).
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
from PIL import Image, ImageDraw

from renderloop.config import Config, load_config
from renderloop.planning.waypoints import plan_waypoints
from renderloop.render.camera import Intrinsics
from renderloop.render.cycles import CyclesRenderer
from renderloop.robot.kinematics import dofs_to_camera_pose
from renderloop.scene.generate import generate_scene

WIDTH, HEIGHT = 320, 240


def render(kind: str, seed: int, plant: int, samples: int) -> np.ndarray:
    data = load_config("greenhouse", seed=seed).model_dump(mode="json")
    data["greenhouse"]["environment"]["kind"] = kind
    data["camera"].update(width=WIDTH, height=HEIGHT)
    data["renderer"].update(samples=samples)
    config = Config.model_validate(data)
    scene = generate_scene(config)
    scan = [w for w in plan_waypoints(scene, config) if w.kind == "scan" and w.plant == plant and w.side == "left"]
    waypoint = scan[config.planner.bands // 2 * config.planner.points_per_ellipse]
    pose = dofs_to_camera_pose(waypoint.dofs, config.robot.arm)
    with CyclesRenderer(scene, config, Intrinsics.from_config(config.camera)) as renderer:
        return renderer.render(pose).rgb


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, required=True)
    parser.add_argument("--samples", type=int, default=16)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--plant", type=int, default=2)
    parser.add_argument("--real", type=Path, help="a folder of real photos: one beside the renders")
    args = parser.parse_args()
    gap = 6
    panels = [(Image.fromarray(render(kind, args.seed, args.plant, args.samples)), f"environment: {kind}")
              for kind in ("plain", "film")]
    if args.real:
        photo = Image.open(sorted(p for p in args.real.iterdir() if p.suffix.lower() in (".png", ".jpg", ".jpeg"))[0])
        side = min(photo.width, photo.height * 4 // 3)
        crop = photo.convert("RGB").crop(((photo.width - side) // 2, 0, (photo.width + side) // 2, side * 3 // 4))
        panels.append((crop.resize((WIDTH, HEIGHT), Image.Resampling.LANCZOS), "real photo"))
    canvas = Image.new("RGB", (len(panels) * (WIDTH + gap) - gap, HEIGHT), "white")
    for column, (panel, label) in enumerate(panels):
        draw = ImageDraw.Draw(panel)
        draw.rectangle(draw.textbbox((8, 6), label), fill="white")
        draw.text((8, 6), label, fill="black")
        canvas.paste(panel, (column * (WIDTH + gap), 0))
    args.out.parent.mkdir(parents=True, exist_ok=True)
    canvas.save(args.out, quality=90)


if __name__ == "__main__":
    main()
