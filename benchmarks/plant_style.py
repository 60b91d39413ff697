"""What the 'pepper' plant style costs next to the 'simple' one: scene, file, Blender scene, frames.

Demo preset (seed 0, 4 plants, 320x240, the config's default quality: 1 sample, fast denoise), per
style: the time `generate_scene` takes, the size of `scene.json`, the time the Cycles renderer
takes to build its Blender scene, the first frame (which also syncs the scene into Cycles), and
then frames from scan-like poses; the raster backend's build and frames beside them; and the time
`generate_scene` takes for the paper preset's plants in the 'pepper' style. Medians with min and
max of wall seconds and of the process's CPU seconds (all its threads), which other jobs on a
shared machine disturb far less; the docs' table shows the wall seconds.

    .venv/bin/python benchmarks/plant_style.py [--repeats 3] [--name scene_styles]
"""

from __future__ import annotations

import argparse
import json

from common import render_costs, save_result, scan_poses, summary, timed

from renderloop.config import Config, load_config
from renderloop.io.atomic import dumps_json
from renderloop.scene.generate import generate_scene

STYLES = ("simple", "pepper")


def styled(preset: str, style: str) -> Config:
    data = load_config(preset).model_dump(mode="json")
    data["plants"]["style"] = style
    return Config.model_validate(data)


def measure(style: str, repeats: int) -> dict:
    config = styled("demo", style)
    builds = [timed(generate_scene, config) for _ in range(repeats)]
    scene = builds[0][0]
    poses = scan_poses(scene, 4) * repeats
    out = {
        "plants": len(scene.plants),
        "leaves_per_plant": summary([len(plant.leaves) for plant in scene.plants]),
        "scene_s": summary([wall for _, wall, _ in builds]),
        "scene_cpu_s": summary([cpu for *_, cpu in builds]),
        "scene_json_bytes": len(dumps_json(scene.model_dump(mode="json")).encode()),
    }
    out.update(render_costs(scene, config, poses))
    return out


def spread(values: dict[str, float], digits: int) -> str:
    """A summary as the docs' table shows it: median (min-max)."""
    return f"{values['median']:.{digits}f} ({values['min']:.{digits}f}-{values['max']:.{digits}f})"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--name", default="scene_styles", help="Results file: benchmarks/results/NAME.json.")
    args = parser.parse_args()
    results = {style: measure(style, args.repeats) for style in STYLES}
    paper = styled("paper", "pepper")
    results["pepper_paper_scene_s"] = summary([timed(generate_scene, paper)[1] for _ in range(args.repeats)])
    print(json.dumps(results, indent=1))
    pepper = results["pepper"]
    cells = {  # each style's column of the docs' table, wall seconds
        "leaves per plant, median (min-max)": lambda r: spread(r["leaves_per_plant"], 0),
        f"`generate_scene`, s ({pepper['plants']} plants)": lambda r: spread(r["scene_s"], 2),
        "`scene.json`, bytes": lambda r: f"{r['scene_json_bytes']:,}".replace(",", " "),
        "Cycles: building the Blender scene, s": lambda r: round(r["cycles_build_s"], 2),
        "Cycles: first frame (syncs the scene), s": lambda r: round(r["cycles_first_frame_s"], 1),
        "Cycles: s per frame": lambda r: spread(r["cycles_frame_s"], 2),
        "raster: building the MuJoCo scene, s": lambda r: round(r["raster_build_s"], 2),
        "raster: ms per frame": lambda r: spread(r["raster_frame_ms"], 0),
    }
    figures = {
        "table": {"columns": ["figure", *(f"`{style}`" for style in STYLES)],
                  "rows": [[name, *(cell(results[style]) for style in STYLES)] for name, cell in cells.items()]},
        "pepper_plant_ms": round(1000 * pepper["scene_s"]["median"] / pepper["plants"]),
        "pepper_paper_scene_s": round(results["pepper_paper_scene_s"]["median"], 1),
    }
    print(save_result(args.name, figures))


if __name__ == "__main__":
    main()
