"""What the 'pepper' plant style costs next to the 'simple' one: scene, file, Blender scene, frames.

Demo preset (seed 0, 4 plants, 320x240, the config's default quality: 1 sample, fast denoise), per
style: the time `generate_scene` takes, the size of `scene.json`, the time the Cycles renderer
takes to build its Blender scene, the first frame (which also syncs the scene into Cycles), and
then frames from scan-like poses; the raster backend's build and frames beside them. Medians with
min and max of wall seconds and of the process's CPU seconds (all its threads), which other jobs
on a shared machine disturb far less.

    .venv/bin/python benchmarks/plant_style.py [--repeats 3] [--json out.json]
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from common import render_costs, scan_poses, summary, timed

from renderloop.config import Config, load_config
from renderloop.io.atomic import dumps_json
from renderloop.scene.generate import generate_scene


def measure(style: str, repeats: int) -> dict:
    data = load_config("demo").model_dump(mode="json")
    data["plants"]["style"] = style
    config = Config.model_validate(data)
    builds = [timed(generate_scene, config) for _ in range(repeats)]
    scene = builds[0][0]
    poses = scan_poses(scene, 4) * repeats
    out = {
        "leaves_per_plant": summary([len(plant.leaves) for plant in scene.plants]),
        "scene_s": summary([wall for _, wall, _ in builds]),
        "scene_cpu_s": summary([cpu for *_, cpu in builds]),
        "scene_json_bytes": len(dumps_json(scene.model_dump(mode="json")).encode()),
    }
    out.update(render_costs(scene, config, poses))
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--json", type=Path)
    args = parser.parse_args()
    results = {style: measure(style, args.repeats) for style in ("simple", "pepper")}
    text = json.dumps(results, indent=1)
    print(text)
    if args.json:
        args.json.write_text(text + "\n")


if __name__ == "__main__":
    main()
