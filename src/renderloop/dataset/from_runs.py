"""`renderloop dataset-from-runs`: a COCO dataset of the frames that scan runs flew and rendered.

Random views (`renderloop dataset`) teach the detector what a pepper looks like; the
frames of a scan show it the way the flight will: the camera's distances and angles,
640 x 480 frames with small fruit at the edges, clusters of touching fruit. Runs of
other seeds are other greenhouses, so a run kept out of this set still scores the
detector on scenes it has not seen.

Labels follow `renderloop dataset` (`renderloop.dataset.labels`), the neighbouring rows'
fruit included (told apart by the run's depth frames), with the tiny-fruit side scaled to
the frame width so that the rule means the same at the detector's input.
Validation holds whole runs (the last `val_runs` given). The layout is the dataset's:
`images/NNNNNN.jpg`, `labels/NNNNNN.json`, `annotations/instances_{train,val}.json`,
`dataset.json` (the runs, their scene hashes and the frame step), `preview.png`.
"""

from __future__ import annotations

import hashlib
import json
from collections.abc import Callable
from pathlib import Path

import numpy as np

from renderloop.dataset.build import MANIFEST, PARTS, PREVIEW, claim_dataset, image_name, jpeg_bytes
from renderloop.dataset.coco import write_coco
from renderloop.dataset.labels import MIN_SIDE, neighbour_fruit_boxes, pepper_boxes, pepper_vertices
from renderloop.dataset.preview import draw_preview
from renderloop.errors import UserError
from renderloop.io import ownership
from renderloop.io.atomic import write_bytes, write_json
from renderloop.render.camera import read_camera_info
from renderloop.render.frames import decode_depth, read_png
from renderloop.rundir import files, names
from renderloop.scene.model import read_scene
from renderloop.scene.objects import neighbour_fruit

NEEDS = (names.CONFIG, names.SCENE, names.POSES, names.CAMERA_INFO)
LABEL_WIDTH = 320  # the width at which `labels.MIN_SIDE` is set: the detector's input
PREVIEW_IMAGES = 12

Progress = Callable[[int, int], None]


def _frames(run_dir: Path, every: int) -> tuple[np.ndarray, list[int]]:
    """The run's camera poses and the indices of its chosen frames, each checked to be rendered with its mask."""
    files.require(run_dir, NEEDS)
    _, poses = files.read_poses(run_dir)
    indices = list(range(0, len(poses), every))
    for stream in (names.RGB, names.DEPTH, names.MASKS):
        missing = next((i for i in indices if not (run_dir / names.frame_file(stream, i)).is_file()), None)
        if missing is not None:
            raise UserError(f"{run_dir / names.frame_file(stream, missing)}: missing (render the run with masks first)")
    return poses, indices


def _run_records(run_dir: Path, poses: np.ndarray, indices: list[int], first: int, split: str, out: Path) -> list[dict]:
    """Write the run's chosen frames as JPEG images and label files; their records in order."""
    scene = read_scene(run_dir)
    near = files.read_config(run_dir).camera.clip[0]
    intrinsics = read_camera_info(run_dir)
    peppers = {pepper.id: pepper for pepper in scene.peppers}
    meshes, neighbours = pepper_vertices(scene), neighbour_fruit(scene.environment)
    min_side = MIN_SIDE * intrinsics.width / LABEL_WIDTH
    records = []
    for offset, index in enumerate(indices):
        rgb_path, mask_path = run_dir / names.frame_file(names.RGB, index), run_dir / names.frame_file(names.MASKS, index)
        rgb, mask = read_png(rgb_path, np.uint8), read_png(mask_path, np.uint16)
        if rgb.shape[:2] != mask.shape or rgb.shape[:2] != (intrinsics.height, intrinsics.width):
            raise UserError(f"{mask_path}: its size does not match {rgb_path} and camera_info.yaml")
        name = image_name(first + offset, "jpg")
        write_bytes(out / "images" / name, jpeg_bytes(rgb))
        record = {
            "image": f"images/{name}", "scene": str(run_dir), "frame": index, "width": intrinsics.width,
            "height": intrinsics.height, "split": split, "pose": np.round(poses[index], 9).tolist(),
            "peppers": pepper_boxes(mask, peppers, meshes, poses[index], intrinsics, near, min_side),
        }
        if neighbours:  # the neighbouring rows' fruit, told apart by the depth
            depth = decode_depth(read_png(run_dir / names.frame_file(names.DEPTH, index), np.uint16))
            record["peppers"] += neighbour_fruit_boxes(mask, depth, neighbours, poses[index], intrinsics, near, min_side)
        write_json(out / "labels" / image_name(first + offset, "json"), record)
        records.append(record)
    return records


def _source(manifest: Path) -> str | None:
    try:
        return json.loads(manifest.read_text(encoding="utf-8")).get("source")
    except (OSError, UnicodeDecodeError, json.JSONDecodeError, AttributeError):
        return None


def dataset_from_runs(runs: list[Path], out: Path, every: int = 1, val_runs: int = 1, progress: Progress | None = None) -> int:
    """Convert every `every`-th frame of each run; the last `val_runs` runs are the validation split. Returns images."""
    runs, out = [Path(r) for r in runs], Path(out)
    if every < 1:
        raise UserError(f"--every {every}: must be at least 1")
    if not 0 <= val_runs < len(runs):
        raise UserError(f"--val-runs {val_runs}: must leave at least one of the {len(runs)} runs for training")
    chosen = [_frames(run, every) for run in runs]  # every run checked before anything is written
    claim_dataset(out)
    if (out / MANIFEST).is_file() and _source(out / MANIFEST) != "runs":
        raise UserError(f"{out}: holds a rendered dataset (see {MANIFEST}); give another --out")
    ownership.remove_recorded(out, PARTS)  # the last conversion's images, not one of them left to mix in
    for sub in PARTS:
        (out / sub).mkdir(parents=True, exist_ok=True)
    total, records = sum(len(indices) for _, indices in chosen), []
    for number, (run, (poses, indices)) in enumerate(zip(runs, chosen)):
        split = "val" if number >= len(runs) - val_runs else "train"
        records += _run_records(run, poses, indices, len(records), split, out)
        if progress:
            progress(len(records), total)
    write_coco(out / "annotations", records)
    write_json(out / MANIFEST, {
        "source": "runs", "every": every, "val_runs": val_runs,
        "runs": [{"path": str(run), "frames": len(indices),
                  "scene_sha256": hashlib.sha256((run / names.SCENE).read_bytes()).hexdigest()} for run, (_, indices) in zip(runs, chosen)],
    })
    draw_preview(out, records[::max(1, len(records) // PREVIEW_IMAGES)][:PREVIEW_IMAGES], out / PREVIEW)
    return len(records)
