"""What the scoring's one choice about the neighbouring rows does to the false detections: the detections of finished
runs (`renderloop eval`'s detections.json) scored as `renderloop detect` scores them, the neighbouring rows' fruit
ignored (`perception.scoring`), and again with those fruit scored as any other background, summed over the runs.

    .venv/bin/python benchmarks/perception_greenhouse.py RUN... [--name NAME]

The perception page's figures come from the greenhouse preset's static scans of its held-out seeds, with the
shipped detector's defaults:

    renderloop eval --preset greenhouse --seeds 10-14 --mission static --workers 2 --out runs/gh_heldout
    .venv/bin/python benchmarks/perception_greenhouse.py runs/gh_heldout/seed_{10,11,12,13,14}

Writes `benchmarks/results/NAME.json` (default perception_greenhouse).
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from common import save_result

from renderloop.errors import UserError
from renderloop.perception.scoring import FrameTruth, RunScore
from renderloop.render.frames import read_png
from renderloop.rundir import files, names
from renderloop.scene.model import read_scene

TALLIES = ("findable_ripe", "found_ripe", "detections", "false")


def tallies(run_dir: Path) -> tuple[dict[str, int], dict[str, int]]:
    """A run's detections against its masks, with the neighbouring rows' fruit ignored and scored as background."""
    scene = read_scene(run_dir)
    ignored, scored = RunScore.of_scene(scene), RunScore.of_scene(scene)
    _, poses = files.read_poses(run_dir)
    for frame in files.read_detections(run_dir, len(poses)).frames:
        truth = FrameTruth.of_mask(read_png(run_dir / names.frame_file(names.MASKS, frame.index), np.uint16))
        detections = [d.model_dump() for d in frame.detections]
        ignored.add_truth(detections, truth)
        scored.add_truth(detections, FrameTruth(truth.peppers, []))
    return tuple({name: getattr(score, name) for name in TALLIES} for score in (ignored, scored))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("runs", nargs="+", type=Path)
    parser.add_argument("--name", default="perception_greenhouse")
    args = parser.parse_args()
    total = {"ignored": dict.fromkeys(TALLIES, 0), "scored": dict.fromkeys(TALLIES, 0)}
    for run_dir in args.runs:
        try:
            for sums, run in zip(total.values(), tallies(run_dir)):
                for name in TALLIES:
                    sums[name] += run[name]
        except UserError as error:  # not a finished run, or one without detections: nothing is saved
            parser.error(str(error))
    ignored, scored = total["ignored"], total["scored"]
    save_result(args.name, {
        "runs": [str(r) for r in args.runs],
        "ripe_recall": round(ignored["found_ripe"] / ignored["findable_ripe"], 3),
        "scored": ignored["detections"], "false": ignored["false"],
        "false_pct": round(100 * ignored["false"] / ignored["detections"], 1),
        "scored_neighbours_scored": scored["detections"], "false_neighbours_scored": scored["false"],
        "false_pct_neighbours_scored": round(100 * scored["false"] / scored["detections"], 1),
    })


if __name__ == "__main__":
    main()
