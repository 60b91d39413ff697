"""The figures of `renderloop score-photos`: pr_curve.png (precision against recall) and sheet.png (photos, found and labelled)."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
from PIL import Image, ImageDraw

from renderloop.io.atomic import atomic_path
from renderloop.perception.photo_score import ClassScore, PhotoScore, Searched, match
from renderloop.perception.sheet import COLORS
from renderloop.perception.threshold import threshold_text

CURVE_COLOR = {None: "k", "ripe": "red", "unripe": "green"}
MARKED_THRESHOLDS = (0.1, 0.3, 0.5, 0.7, 0.9)
TILE = 320  # px: the longer side of each photo on the sheet
PAIRS_PER_ROW = 2
CAPTION = 16  # px of text above each photo pair
GAP = 6
LABELLED = (255, 230, 0)  # a labelled box whose category names no ripeness
MISSED_WIDTH, FOUND_WIDTH = 3, 1


def _curve(axes, score: ClassScore, label: str | None) -> None:
    points = [f for f in score.curve if f.precision is not None and f.recall is not None]
    name = label or "all peppers"
    ap = "n/a" if score.ap50 is None else f"{score.ap50:.3f}"
    color = CURVE_COLOR[label]
    axes.plot([f.recall for f in points], [f.precision for f in points], color=color, lw=1.5,
              label=f"{name}: AP@0.5 {ap} ({score.boxes} boxes)")
    for f in points:
        if any(abs(f.threshold - t) < 1e-6 for t in MARKED_THRESHOLDS):
            axes.plot(f.recall, f.precision, "o", ms=3, color=color)
            axes.annotate(f"{f.threshold:.1f}", (f.recall, f.precision), fontsize=7, color=color,
                          xytext=(3, 3), textcoords="offset points")
    here = score.at_threshold
    if here.precision is not None and here.recall is not None:
        axes.plot(here.recall, here.precision, "o", ms=10, mfc="none", mec=color, mew=2,
                  label=f"{name} at {threshold_text(here.threshold)}: recall {here.recall:.3f}, precision {here.precision:.3f}")
    best = score.best_f1
    if best.precision is not None and best.recall is not None and best.f1 > 0:
        axes.plot(best.recall, best.precision, "*", ms=11, color=color, mec="k", mew=0.5,
                  label=f"{name} best F1 {best.f1:.3f} at {threshold_text(best.threshold)}")


def draw_pr_curve(record: PhotoScore, path: Path) -> None:
    """Precision against recall over the thresholds of the curve, the operating point circled, the best F1 starred."""
    figure, axes = plt.subplots(figsize=(8, 6.5), dpi=90)
    recall = np.linspace(0.01, 1, 200)
    for f1 in (0.2, 0.4, 0.6, 0.8):  # iso-F1 lines
        precision = f1 * recall / (2 * recall - f1)
        visible = (precision > 0) & (precision <= 1.05) & (2 * recall > f1)
        axes.plot(recall[visible], precision[visible], color="0.8", lw=0.7, zorder=0)
        axes.annotate(f"F1 {f1:.1f}", (0.98, f1 / (2 - f1)), fontsize=7, color="0.6", ha="right", va="bottom")
    _curve(axes, record.class_agnostic, None)
    for label, score in (record.by_class or {}).items():
        _curve(axes, score, label)
    axes.set_xlim(0, 1.02)
    axes.set_ylim(0, 1.02)
    axes.set_xlabel("recall")
    axes.set_ylabel("precision")
    axes.grid(alpha=0.3)
    axes.legend(loc="lower left", fontsize=7)
    windows = ",".join(record.windows) or "none"
    axes.set_title(f"{record.images} photos, {record.boxes} labelled boxes, IoU {record.match_iou}; "
                   f"windows {windows}, mirror {'on' if record.mirror else 'off'}\n"
                   f"{Path(record.model).name}; small numbers: score thresholds", fontsize=9)
    figure.tight_layout()
    with atomic_path(Path(path)) as tmp:
        figure.savefig(tmp, format="png")
    plt.close(figure)


def _tile(photo: Searched, image: Image.Image, threshold: float, by_class: bool) -> tuple[Image.Image, Image.Image, str]:
    """The photo with the detections at `threshold` (coloured by label, with scores), the photo with the labelled
    boxes (thick where no detection found them), and a caption."""
    scale = TILE / max(image.size)
    size = (max(1, round(image.width * scale)), max(1, round(image.height * scale)))
    base = image.convert("RGB").resize(size, Image.BILINEAR)
    found = [d for d in photo.detections if d.score >= threshold]
    truth = photo.image.boxes
    matched = match(np.array([d.bbox for d in found], dtype=float).reshape(-1, 4), np.array([d.score for d in found]), truth)
    hits = matched >= 0
    taken = set(matched[hits].tolist())
    left, right = base.copy(), base.copy()
    draw = ImageDraw.Draw(left)
    for d in found:
        box = [v * scale for v in d.bbox]
        draw.rectangle(box, outline=COLORS[d.label], width=2)
        draw.text((box[0] + 2, box[1] + 1), f"{d.score:.2f}", fill=COLORS[d.label])
    draw = ImageDraw.Draw(right)
    for index, (box, label) in enumerate(zip(truth.tolist(), photo.image.classes)):
        color = COLORS[label] if by_class and label in COLORS else LABELLED
        draw.rectangle([v * scale for v in box], outline=color, width=FOUND_WIDTH if index in taken else MISSED_WIDTH)
    name = photo.image.path.name
    caption = f"{name[:40]}: {int(hits.sum())}/{len(truth)} found, {int((~hits).sum())} false"
    return left, right, caption


def draw_photo_sheet(photos: Sequence[tuple[Searched, Image.Image]], threshold: float, by_class: bool, path: Path) -> None:
    """A grid of photo pairs: detections at `threshold` (left) beside the labelled boxes (right; thick: missed)."""
    if not photos:
        return
    tiles = [_tile(photo, image, threshold, by_class) for photo, image in photos]
    cell_width, cell_height = 2 * TILE + GAP, TILE + CAPTION
    columns = min(PAIRS_PER_ROW, len(tiles))
    rows = -(-len(tiles) // columns)
    sheet = Image.new("RGB", (columns * (cell_width + 2 * GAP), rows * (cell_height + GAP)), (255, 255, 255))
    draw = ImageDraw.Draw(sheet)
    for number, (left, right, caption) in enumerate(tiles):
        x = (number % columns) * (cell_width + 2 * GAP)
        y = (number // columns) * (cell_height + GAP)
        draw.text((x + 2, y + 2), caption, fill=(0, 0, 0))
        sheet.paste(left, (x, y + CAPTION))
        sheet.paste(right, (x + TILE + GAP, y + CAPTION))
    with atomic_path(Path(path)) as tmp:
        sheet.save(tmp, format="PNG")
