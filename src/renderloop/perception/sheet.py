"""detections.png: frames with the detector's boxes (left) next to the truth from the masks (right)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from PIL import Image, ImageDraw

from renderloop.io.atomic import atomic_path
from renderloop.perception.scoring import FrameTruth, findable
from renderloop.render.frames import read_png
from renderloop.rundir import names
from renderloop.rundir.models import DetectionFrame
from renderloop.scene.model import read_scene

ROWS = 6
COLORS = {"ripe": (255, 40, 40), "unripe": (0, 220, 255)}
IGNORED = (160, 160, 160)  # truth not scored: too small, or a neighbouring row's fruit


def _pick(frames: list[DetectionFrame], rows: int) -> list[DetectionFrame]:
    """Frames spread over the run, those with most detections first among neighbours."""
    if len(frames) <= rows:
        return frames
    groups = np.array_split(np.arange(len(frames)), rows)
    return [frames[max(group, key=lambda i: len(frames[i].detections))] for group in groups]


def draw_detection_sheet(run_dir: Path, frames: list[DetectionFrame], path: Path, rows: int = ROWS) -> None:
    if not frames:
        return
    ripe = {p.id: p.ripe for p in read_scene(run_dir).peppers}
    tiles = []
    for frame in _pick(frames, rows):
        rgb = Image.fromarray(read_png(run_dir / frame.image, np.uint8))
        left, right = rgb.copy(), rgb.copy()
        draw = ImageDraw.Draw(left)
        for d in frame.detections:
            draw.rectangle(d.bbox, outline=COLORS[d.label], width=2)
            draw.text((d.bbox[0] + 2, d.bbox[1] + 1), f"{d.score:.2f}", fill=COLORS[d.label])
        draw = ImageDraw.Draw(right)
        truth = FrameTruth.of_mask(read_png(run_dir / names.frame_file(names.MASKS, frame.index), np.uint16))
        for pepper, box in truth.peppers.items():
            color = COLORS["ripe" if ripe[pepper] else "unripe"] if findable(box) else IGNORED
            draw.rectangle(box, outline=color, width=2)
        for box in truth.neighbours:
            draw.rectangle(box, outline=IGNORED, width=1)
        tiles.append((left, right))
    width, height = tiles[0][0].size
    sheet = Image.new("RGB", (2 * width + 4, len(tiles) * (height + 4)), (255, 255, 255))
    for row, (left, right) in enumerate(tiles):
        sheet.paste(left, (0, row * (height + 4)))
        sheet.paste(right, (width + 4, row * (height + 4)))
    with atomic_path(path) as tmp:
        sheet.save(tmp, format="PNG")
