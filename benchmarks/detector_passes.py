"""Detector models and passes side by side on rendered runs the models never trained on: for each case, the
recall of the findable ripe fruit at the lowest threshold with at most 5 % false detections (`renderloop
threshold`'s rule), that recall by the fruit's shorter side in pixels, where small fruit show, and by the share of
its silhouette in sight (the visible fraction of `dataset.labels`), where leaves hide fruit, and the recall of the
findable green fruit at that threshold.

    .venv/bin/python benchmarks/detector_passes.py RUN... --case NAME=MODEL:WINDOWS:MIRROR[:MIN_BOX] ... [--name NAME]
        [--window-enlargement X]

WINDOWS is `2x2,3x2` or `none`, MIRROR `mirror` or `none`, MIN_BOX the shorter side in px a box needs
(`detector.min_box_px`, default 0); MODEL `shipped` or an ONNX file; X `detector.max_window_enlargement` for every
case (default 1.5: a 320x240 frame takes no windows). Writes
`benchmarks/results/NAME.json` (default detector_passes) with a row a case.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from common import as_table, save_result

from renderloop.config import Config
from renderloop.config.perception import MAX_ENLARGEMENT
from renderloop.dataset.labels import MIN_VISIBLE, pepper_boxes, pepper_vertices
from renderloop.errors import UserError
from renderloop.perception.boxes import shorter_side
from renderloop.perception.detector import Detector
from renderloop.perception.scoring import findable, match
from renderloop.perception.threshold import choose, score_thresholds, search_run
from renderloop.perception.tiling import all_windows, layout_names, parse_layouts
from renderloop.render.camera import read_camera_info
from renderloop.render.frames import read_png, read_rgb_frame
from renderloop.rundir import files, names
from renderloop.scene.model import read_scene

SIDES = ((20, 30), (30, 50), (50, 100), (100, None))  # px, the shorter side of a fruit's mask box at the frame's size
BINS = [f"{low}-{high or 'up'}" for low, high in SIDES]
IN_SIGHT = ((0.0, MIN_VISIBLE), (MIN_VISIBLE, 0.5), (0.5, None))  # share of a fruit's silhouette that the mask shows
SIGHT_BINS = [f"in sight {low:g}-{high or 1:g}" for low, high in IN_SIGHT]
MAX_FALSE = 0.05


def shares_in_sight(run_dir: Path) -> list[dict[int, float]]:
    """Each frame's pepper id -> the share of its silhouette in sight, as `dataset-from-runs` labels it."""
    scene, config = read_scene(run_dir), files.read_config(run_dir)
    _, poses = files.read_poses(run_dir)
    intrinsics, meshes = read_camera_info(run_dir), pepper_vertices(scene)
    peppers = {pepper.id: pepper for pepper in scene.peppers}
    return [{record["pepper_id"]: record["visible_fraction"]
             for record in pepper_boxes(read_png(run_dir / names.frame_file(names.MASKS, index), np.uint16), peppers, meshes,
                                        pose, intrinsics, config.camera.clip[0])}
            for index, pose in enumerate(poses)]


def recall_by_bin(runs, shares: list[list[dict[int, float]]], threshold: float) -> dict[str, float]:
    """Recall of the findable ripe fruit in each bin of SIDES and of IN_SIGHT, and of the findable green fruit
    (`unripe`; None where the runs hold none), at `threshold`; a box of either class finds a fruit, as `renderloop
    threshold` scores."""
    names = [*BINS, *SIGHT_BINS, "unripe"]
    found, total = dict.fromkeys(names, 0), dict.fromkeys(names, 0)
    for run, run_shares in zip(runs, shares):
        ripe = {p.id: p.ripe for p in run.scene.peppers}
        for (detections, truth), in_sight in zip(run.frames, run_shares):
            hits = set(match([d for d in detections if d["score"] >= threshold], truth.peppers).values())
            for pepper, box in truth.peppers.items():
                if not findable(box):
                    continue
                side = shorter_side(box)
                bins = [next(name for name, (_, high) in zip(BINS, SIDES) if high is None or side < high),
                        next(name for name, (_, high) in zip(SIGHT_BINS, IN_SIGHT) if high is None or in_sight[pepper] < high)
                        ] if ripe[pepper] else ["unripe"]
                for name in bins:
                    found[name] += pepper in hits
                    total[name] += 1
    return {name: round(found[name] / total[name], 3) if total[name] else None for name in names}


def passes_label(layouts: list[str], mirror: str, min_box: float) -> str:
    """'frame, mirror, 2x2 and 3x2 windows[, boxes of 10 px and up]': what a case searches each frame with."""
    return ", ".join(["frame", *(["mirror"] if mirror == "mirror" else []), *([" and ".join(layouts) + " windows"] if layouts else []),
                      *([f"boxes of {min_box:g} px and up"] if min_box else [])])


def measure(run_dirs: list[Path], shares: list[list[dict[int, float]]], model: str, windows: str, mirror: str,
            min_box: float, enlargement: float) -> dict:
    settings = Config().override({"detector": {"windows": layout_names(parse_layouts(windows)), "mirror": mirror == "mirror",
                                               "min_box_px": min_box, "max_window_enlargement": enlargement}}).detector
    detector = Detector(None if model == "shipped" else Path(model), threads=1)
    runs = [search_run(run_dir, detector, settings) for run_dir in run_dirs]
    # The label names the layouts whose windows ran: `tiling` skips those the input would enlarge too much.
    height, width = read_rgb_frame(run_dirs[0], 0).shape[:2]
    searched = [name for name, layout in zip(settings.windows, settings.layouts)
                if all_windows(width, height, [layout], detector.input_size, enlargement)]
    passes = passes_label(searched, mirror, min_box)
    chosen = choose(score_thresholds(runs), MAX_FALSE)
    if chosen is None:
        return {"passes": passes, "threshold": None, "recall": 0.0, "false_pct": None}
    return {"passes": passes, "threshold": chosen.threshold, "recall": round(chosen.recall, 3), "false_pct": round(100 * chosen.false_rate, 1),
            **recall_by_bin(runs, shares, chosen.threshold)}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("runs", nargs="+", type=Path)
    parser.add_argument("--case", action="append", required=True, help="NAME=MODEL:WINDOWS:MIRROR[:MIN_BOX]")
    parser.add_argument("--name", default="detector_passes")
    parser.add_argument("--window-enlargement", type=float, default=MAX_ENLARGEMENT)
    args = parser.parse_args()
    cases = []
    for case in args.case:  # every case read, and its model opened, before minutes of measuring
        name, _, spec = case.partition("=")
        parts = spec.split(":")
        if not name or len(parts) not in (3, 4) or parts[2] not in ("mirror", "none"):
            parser.error(f"--case {case}: give NAME=MODEL:WINDOWS:MIRROR[:MIN_BOX], MIRROR mirror or none")
        model, windows, mirror = parts[:3]
        try:
            min_box = float(parts[3]) if len(parts) == 4 else 0.0
        except ValueError:
            parser.error(f"--case {case}: MIN_BOX {parts[3]!r} is not a number of pixels")
        try:
            Detector(None if model == "shipped" else Path(model))
            parse_layouts(windows)
            cases.append((name, model, windows, mirror, min_box))
        except UserError as error:  # no such model, not a detector, or windows that are not layouts
            parser.error(f"--case {case}: {error}")
    records = []
    try:
        shares = [shares_in_sight(run) for run in args.runs]
    except UserError as error:  # a run that is not a finished run; nothing is saved
        parser.error(str(error))
    for name, model, windows, mirror, min_box in cases:
        try:
            record = {"case": name, **measure(args.runs, shares, model, windows, mirror, min_box, args.window_enlargement)}
        except UserError as error:  # a run that is not a finished run; nothing is saved
            parser.error(str(error))
        print(record, flush=True)
        records.append(record)
    columns = {"case": "model", "passes": "passes", "recall": "ripe recall", "false_pct": "false, %", "threshold": "threshold",
               **{name: f"recall, {name} px" for name in BINS}, **{name: f"recall, {name}" for name in SIGHT_BINS},
               "unripe": "green recall"}
    save_result(args.name, {"runs": [str(r) for r in args.runs], "max_false_pct": 100 * MAX_FALSE,
                            "max_window_enlargement": args.window_enlargement,
                            "table": as_table(records, columns)})


if __name__ == "__main__":
    main()
