"""What a Cycles frame of the commercial compartment costs against the same view of the one-row greenhouse preset.

The view: the scan's camera pose at the middle plant of the first scanned line (its first waypoint, on the lowest
of the three ellipses), which both presets reach from 1.0 m with the same ellipses, so the camera stands in the
same place relative to its plant. Each case runs in a fresh process (its peak memory is its own, no library or
import shared): the commercial compartment built whole, the commercial compartment built for this view only
(`scene/visible.py`: the plants whose box comes within the camera's reach, as far as its frame's corners reach to
the far clip) and the greenhouse preset built for this view. For each: the scene's generation, the renderer's build, the first frame (Cycles' first sync
and BVH) and the median of the next frames (wall seconds), the process's peak resident memory, and the plants,
neighbouring plants and Blender objects built.

    .venv/bin/python benchmarks/frame_scaling.py [--width 320 --height 240 --samples 1 --frames 3] [--no-save]

Target: the commercial frame, built for its view, within 20 % of the greenhouse preset's frame seconds. Its build,
first frame and peak memory are shown beside it: they follow the distinct plants within reach (the compartment's 24
prototypes against the greenhouse's 5 plants), not the frame.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
from pathlib import Path

from common import as_table, save_result

ROOT = Path(__file__).resolve().parent.parent

CHILD = """
import dataclasses, json, sys, time
import numpy as np
preset, culled, width, height, samples, frames = sys.argv[1], sys.argv[2] == "culled", *map(int, sys.argv[3:7])
config_file = sys.argv[7] if len(sys.argv) > 7 else None  # a file over the preset: it names the row itself
from pathlib import Path
from renderloop.config import load_config
from renderloop.planning.waypoints import plan_waypoints
from renderloop.render.camera import Intrinsics
from renderloop.render.cycles import CyclesRenderer
from renderloop.robot.kinematics import dofs_to_camera_pose
from renderloop.scene.generate import generate_scene
from renderloop.scene.visible import farthest_seen, visible_scene
import bpy

config = load_config(preset, Path(config_file) if config_file else None, seed=0)
if config_file is None:  # a mission of one line: line 1 of the compartment, from the middle path
    config = config.override({"planner": {"row": 1 if preset == "commercial" else None}})
config = config.override({
    "camera": {"width": width, "height": height},
    "renderer": {"backend": "cycles", "samples": samples, "denoise": False, "device": "cpu"}})
start = time.perf_counter()
scene = generate_scene(config)
generated = time.perf_counter() - start
scans = [w for w in plan_waypoints(scene, config) if w.kind == "scan"]
first_line = [w for w in scans if w.side == scans[0].side]
plants = list(dict.fromkeys(w.plant for w in first_line))
middle = plants[len(plants) // 2]
pose = dofs_to_camera_pose(next(w for w in first_line if w.plant == middle).dofs, config.robot.arm)
viewpoints = pose[None, :3, 3] if culled else None
intrinsics = Intrinsics.from_config(config.camera)
built = visible_scene(scene, viewpoints, farthest_seen(config.camera.clip[1], **dataclasses.asdict(intrinsics)))
start = time.perf_counter()
renderer = CyclesRenderer(scene, config, Intrinsics.from_config(config.camera), viewpoints)
build = time.perf_counter() - start
objects = len(bpy.data.objects)
start = time.perf_counter()
frame = renderer.render(pose)
first = time.perf_counter() - start
times = []
for _ in range(frames):
    start = time.perf_counter()
    renderer.render(pose)
    times.append(time.perf_counter() - start)
renderer.close()
import resource
print(json.dumps({"peak_rss_mb": round(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024, 1), "generate_s": generated, "build_s": build, "first_frame_s": first,
                  "frame_s": float(np.median(times)), "plants": len(built.plants), "scene_plants": len(scene.plants),
                  "neighbour_plants": len(built.environment.plants) if built.environment else 0,
                  "blender_objects": objects, "fruit_in_frame": int(len(set(np.unique(frame.mask)) - {0, 32767}))}))
"""

CASES = (("greenhouse", "culled"), ("commercial", "culled"), ("commercial", "whole"))


def run_case(preset: str, mode: str, args: argparse.Namespace, config_file: Path | None = None) -> dict:
    """One case in a fresh process: `args` gives width, height, samples and frames; `config_file` a YAML over the
    preset (its `planner.row` the row scanned)."""
    child = subprocess.Popen([sys.executable, "-c", CHILD, preset, mode, str(args.width), str(args.height),
                              str(args.samples), str(args.frames), *([str(config_file)] if config_file else [])],
                             cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    out, err = child.communicate()
    if child.returncode != 0:
        raise SystemExit(f"{preset} ({mode}) failed:\n{err[-2000:]}")
    return json.loads(out.strip().splitlines()[-1])


COLUMNS = {"preset": "preset", "build": "build", "plants": "plants built", "neighbour_plants": "neighbour plants built",
           "blender_objects": "Blender objects", "build_s": "build, s", "first_frame_s": "first frame, s",
           "frame_s": "frame, s", "peak_rss_mb": "peak memory, MB"}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--width", type=int, default=320)
    parser.add_argument("--height", type=int, default=240)
    parser.add_argument("--samples", type=int, default=1)
    parser.add_argument("--frames", type=int, default=3)
    parser.add_argument("--no-save", action="store_true")
    args = parser.parse_args()
    rows = []
    for preset, mode in CASES:
        figures = {"preset": preset, "build": mode, **run_case(preset, mode, args)}
        print(json.dumps(figures), flush=True)
        rows.append(figures)
    base = rows[0]
    ratios = {key: round(rows[1][key] / base[key], 3) for key in ("build_s", "first_frame_s", "frame_s", "peak_rss_mb")}
    figures = {"resolution": [args.width, args.height], "samples": args.samples, "table": as_table(rows, COLUMNS),
               "commercial_culled_over_greenhouse": ratios, "target": "frame_s at most 1.2"}
    print(json.dumps(ratios))
    if not args.no_save:
        save_result("frame_scaling", figures)


if __name__ == "__main__":
    main()
