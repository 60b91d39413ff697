"""What the 'film' greenhouse environment costs next to the 'plain' one in Cycles.

The demo preset (seed 0, 4 plants, 'simple' style, 320x240, the config's default quality: 1 sample,
fast denoise) with `greenhouse.environment.kind` plain and film, and the greenhouse preset (film,
its tall 'highwire' plants): the time `generate_scene` takes, the Cycles renderer's build, its first
frame (which also syncs the scene) and then frames from scan-like poses, and the raster backend's
build and frames beside them; the greenhouse preset with the plain environment too, to tell the tall
plants' cost from the environment's. Medians with min and max of wall seconds and of the process's CPU
seconds (all its threads), which other jobs on a shared machine disturb far less.

    .venv/bin/python benchmarks/environment.py [--repeats 2] [--json out.json] [--no-save]

It saves the table the render docs show to benchmarks/results/render_environment.json.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from common import render_costs, save_result, scan_poses, timed

from renderloop.config import Config, load_config
from renderloop.scene.generate import generate_scene


CASES = (("demo", "plain"), ("demo", "film"), ("greenhouse", "plain"), ("greenhouse", "film"))
HEADINGS = {("demo", "plain"): "demo `plain`", ("demo", "film"): "demo `film`",
            ("greenhouse", "plain"): "greenhouse preset, `plain`", ("greenhouse", "film"): "greenhouse preset, `film`"}


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
    parser.add_argument("--no-save", action="store_true", help="print only; do not write benchmarks/results/")
    args = parser.parse_args()
    results = {f"{preset} {kind}": measure(preset, kind, args.repeats) for preset, kind in CASES}
    text = json.dumps(results, indent=1)
    print(text)
    if args.json:
        args.json.write_text(text + "\n")
    if not args.no_save:
        print(save_result("render_environment", {"table": table(results)}))


def _spread(values: dict, digits: int) -> str:
    """A median with its min-max, thousands apart by a space: '993 (963-1 131)'."""
    def number(value: float) -> str:
        return f"{value:,.{digits}f}".replace(",", " ")
    return f"{number(values['median'])} ({number(values['min'])}-{number(values['max'])})"


def table(results: dict) -> dict:
    """The measured cases as the docs' table: a row a figure, a column a case."""
    figures = (("`generate_scene`, s", lambda r: round(r["scene_s"], 2)),
               ("Cycles: building the Blender scene, s", lambda r: round(r["cycles_build_s"], 2)),
               ("Cycles: first frame (syncs the scene), s", lambda r: round(r["cycles_first_frame_s"], 2)),
               ("Cycles: s per frame", lambda r: _spread(r["cycles_frame_s"], 2)),
               ("Cycles: CPU s per frame", lambda r: _spread(r["cycles_frame_cpu_s"], 2)),
               ("raster: building the MuJoCo scene, s", lambda r: round(r["raster_build_s"], 2)),
               ("raster: ms per frame", lambda r: _spread(r["raster_frame_ms"], 0)))
    cases = [results[f"{preset} {kind}"] for preset, kind in CASES]
    return {"columns": ["figure", *(HEADINGS[case] for case in CASES)],
            "rows": [[name, *(value(case) for case in cases)] for name, value in figures]}


if __name__ == "__main__":
    main()
