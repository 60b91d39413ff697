"""Which Cycles sample count is enough: the shipped detector's recall on the same paper frames at each count.

The render issue asks for the default quality to be chosen by measurement: the recall at
the default samples within 2 points of the recall at 128. Frames are poses of a flown
paper run (every Nth camera pose of its groundtruth.txt); each is rendered once per sample
count in one Blender scene, detected with the shipped model and scored against its mask
(ripe fruit at least 20x20 px visible, IoU 0.5), the same scoring as `renderloop detect`.

    .venv/bin/python benchmarks/quality.py RUN_DIR [--samples 2 4 8 16 128] [--frames 20] [--json out.json]
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np
from common import summary

from renderloop.perception.detector import Detector
from renderloop.perception.scoring import RunScore
from renderloop.render.camera import Intrinsics
from renderloop.render.cycles import CyclesRenderer
from renderloop.rundir.files import read_config, read_poses
from renderloop.scene.model import read_scene


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("run_dir", type=Path, help="a flown paper run (scene.json, groundtruth.txt)")
    parser.add_argument("--samples", type=int, nargs="+", default=[2, 4, 8, 16, 128])
    parser.add_argument("--frames", type=int, default=20)
    parser.add_argument("--json", type=Path)
    args = parser.parse_args()

    config = read_config(args.run_dir)
    scene = read_scene(args.run_dir)
    _, poses = read_poses(args.run_dir)
    chosen = poses[np.linspace(0, len(poses) - 1, args.frames).round().astype(int)]
    detector = Detector()
    results = {}
    for samples in args.samples:
        quality = config.override({"renderer": {"samples": samples}})
        score, seconds = RunScore.of_scene(scene), []
        with CyclesRenderer(scene, quality, Intrinsics.from_config(config.camera)) as renderer:
            for pose in chosen:
                frame = renderer.render(pose)
                seconds.append(frame.timings["total"])
                score.add([d.to_json() for d in detector.search(frame.rgb, config.detector)], frame.mask)
        results[samples] = {"s_per_frame": summary(seconds[1:] or seconds), **score.summary()}  # the first frame syncs the scene
    best = results[max(args.samples)]["ripe_recall"] or 0.0
    print(f"{'samples':>8}{'s/frame':>10}{'ripe recall':>13}{'vs max':>9}{'false':>8}  ({len(chosen)} frames of {args.run_dir})")
    for samples, row in results.items():
        recall = row["ripe_recall"] or 0.0
        print(f"{samples:>8}{row['s_per_frame']['median']:>10.2f}{recall:>13.3f}{100 * (recall - best):>+8.1f}p"
              f"{row['false_rate'] or 0:>8.3f}")
    if args.json:
        args.json.write_text(json.dumps(results, indent=1) + "\n")


if __name__ == "__main__":
    main()
