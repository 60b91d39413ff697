"""What the 'film' greenhouse environment costs next to the 'plain' one in Cycles.

The demo preset (seed 0, 4 plants, 'simple' style, 320x240, the config's default quality: 1 sample,
fast denoise) with `greenhouse.environment.kind` plain and film, and the greenhouse preset (film,
its tall 'highwire' plants): the time `generate_scene` takes, the Cycles renderer's build, its first
frame (which also syncs the scene) and then frames from scan-like poses, and the raster backend's
build and frames beside them; the greenhouse preset with the plain environment too, to tell the tall
plants' cost from the environment's. Medians with min and max of wall seconds and of the process's CPU
seconds (all its threads), which other jobs on a shared machine disturb far less.

    .venv/bin/python benchmarks/environment.py [--repeats 2] [--json out.json]
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from common import render_costs, scan_poses, timed

from renderloop.config import Config, load_config
from renderloop.scene.generate import generate_scene


def measure(preset: str, kind: str, repeats: int) -> dict:
    data = load_config(preset).model_dump(mode="json")
    data["greenhouse"]["environment"]["kind"] = kind
    data["camera"].update(width=320, height=240)
    config = Config.model_validate(data)
    scene, scene_s, _ = timed(generate_scene, config)
    poses = scan_poses(scene, 4) * repeats
    out: dict = {"scene_s": scene_s}
    out.update(render_costs(scene, config, poses))
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=2)
    parser.add_argument("--json", type=Path)
    args = parser.parse_args()
    results = {f"{preset} {kind}": measure(preset, kind, args.repeats)
               for preset, kind in (("demo", "plain"), ("demo", "film"), ("greenhouse", "plain"), ("greenhouse", "film"))}
    text = json.dumps(results, indent=1)
    print(text)
    if args.json:
        args.json.write_text(text + "\n")


if __name__ == "__main__":
    main()
