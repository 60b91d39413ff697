"""What the raster view's look costs: the sun's shadows and the multisampling (`renderer.raster`), side by side.

The paper preset (seed 7, 640x480) and the greenhouse preset (seed 0, its 320x240): one raster renderer a look,
built once, then frames from scan-like poses (0.44 m from a bearing plant, aimed at it), each pose `--repeats` times.
Medians in ms a frame, the whole of `RasterRenderer.render` (colour, id and depth passes, the sky, the mask).

    .venv/bin/python benchmarks/raster_look.py [--poses 4] [--repeats 3] [--name render_raster_look]
"""

from __future__ import annotations

import argparse
import statistics

from common import save_result, scan_poses

from renderloop.config import load_config
from renderloop.render.camera import Intrinsics
from renderloop.render.raster import RasterRenderer
from renderloop.scene.generate import generate_scene

LOOKS = (("the default: 4x multisampling, no shadows", {}),
         ("with the sun's shadows", {"shadows": True}),
         ("without multisampling", {"antialias": 0}),
         ("shadows, no multisampling", {"shadows": True, "antialias": 0}))
SCENES = (("paper", 7), ("greenhouse", 0))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--poses", type=int, default=4)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--name", default="render_raster_look", help="Results file: benchmarks/results/NAME.json.")
    args = parser.parse_args()

    columns, medians = ["look"], {name: [] for name, _ in LOOKS}
    for preset, seed in SCENES:
        config = load_config(preset, seed=seed)
        scene = generate_scene(config)
        poses = scan_poses(scene, args.poses)
        columns.append(f"{preset} preset, {config.camera.width}x{config.camera.height}")
        for name, look in LOOKS:
            with RasterRenderer(scene, config.override({"renderer": {"raster": look}}),
                                Intrinsics.from_config(config.camera)) as renderer:
                renderer.render(poses[0])  # the first frame also compiles the shaders and fills the GL buffers
                ms = [1000 * renderer.render(pose).timings["total"] for pose in poses * args.repeats]
            medians[name].append(round(statistics.median(ms)))
            print(f"{preset:<11}{name:<45}{medians[name][-1]:>6} ms", flush=True)
    print(save_result(args.name, {"table": {"columns": columns, "rows": [[name, *medians[name]] for name, _ in LOOKS]}}))


if __name__ == "__main__":
    main()
