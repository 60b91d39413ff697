"""Per-plant cards of the report: the plant's estimate beside its truth, and the frame that shows it best.

The best frame of a plant is the one with the most detections of its fruit; ties go to
the frame whose mask shows most of its fruit big enough to find, then most of its fruit's
pixels. With masks a detection belongs to the fruit it matches (IoU 0.5, as the
detector is scored); without masks, to the plant whose volume holds its 3D point (as
it is counted). The frame is drawn with every detection (ripe red, unripe cyan, as in
detections.png) and the outline of the plant's own true fruit (white; grey when too
small to find), scaled to a card's width and stored as a JPEG to keep the page small.
"""

from __future__ import annotations

import base64
import html
import io
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from PIL import Image, ImageDraw, ImageFont

from renderloop.counting.assign import plants_by_volume
from renderloop.perception.scoring import MIN_SIDE, findable, mask_boxes, match
from renderloop.render.frames import read_png
from renderloop.report.words import FINDABLE
from renderloop.rundir import names
from renderloop.rundir.models import Counts, DetectionFrame, Detections
from renderloop.scene.model import Scene

CARD_WIDTH = 400  # px of a card's frame
JPEG_QUALITY = 80
DETECTION = {"ripe": (255, 40, 40), "unripe": (0, 220, 255)}  # as detections.png draws them
TRUTH, TRUTH_SMALL = (255, 255, 255), (150, 150, 150)
DEFAULT_MARGIN = 0.02  # m, the counting's volume margin when counts.json does not record one


@dataclass(frozen=True)
class View:
    """How well one frame shows one plant."""

    frame: DetectionFrame
    detected: int  # detections of the plant's fruit
    findable: int  # its fruit in view big enough to find (0 without masks)
    pixels: int  # pixels of its fruit (0 without masks)
    boxes: dict[int, tuple[int, int, int, int]]  # its fruit's boxes in the mask: pepper id -> box

    @property
    def rank(self) -> tuple[int, int, int, int]:
        return self.detected, self.findable, self.pixels, -self.frame.index


def best_views(run_dir: Path, scene: Scene, detections: Detections, margin: float = DEFAULT_MARGIN) -> dict[int, View]:
    """Plant id -> its best frame; plants no frame showed are left out."""
    plant_of = {pepper.id: pepper.plant for pepper in scene.peppers}
    best: dict[int, View] = {}
    for frame in detections.frames:
        mask_path = Path(run_dir) / names.frame_file(names.MASKS, frame.index)
        boxes: dict[int, tuple[int, int, int, int]] = {}
        pixels = np.zeros(0, dtype=np.int64)
        if mask_path.is_file():
            mask = read_png(mask_path, np.uint16)
            boxes = {pepper: box for pepper, box in mask_boxes(mask).items() if pepper in plant_of}
            pixels = np.bincount(mask.ravel())
            matched = match([d.model_dump() for d in frame.detections], boxes)
            owners = [plant_of[matched[i]] if i in matched else -1 for i in range(len(frame.detections))]
        else:
            owners = [-1] * len(frame.detections)
            placed = [i for i, d in enumerate(frame.detections) if d.position is not None]
            if placed:
                points = np.array([frame.detections[i].position for i in placed], dtype=float)
                for i, owner in zip(placed, plants_by_volume(scene, points, margin)):
                    owners[i] = int(owner)
        for plant in scene.plants:
            own = {pepper: box for pepper, box in boxes.items() if plant_of[pepper] == plant.id}
            view = View(frame, sum(owner == plant.id for owner in owners), sum(findable(box) for box in own.values()),
                        int(sum(pixels[pepper] for pepper in own if pepper < len(pixels))), own)
            if (view.detected or view.pixels) and (plant.id not in best or view.rank > best[plant.id].rank):
                best[plant.id] = view
    return best


def _jpeg(image: Image.Image) -> str:
    buffer = io.BytesIO()
    image.save(buffer, format="JPEG", quality=JPEG_QUALITY, optimize=True)
    return "data:image/jpeg;base64," + base64.b64encode(buffer.getvalue()).decode("ascii")


def draw_view(run_dir: Path, view: View, width: int = CARD_WIDTH) -> str:
    """The frame with its detections and the plant's true fruit drawn, as a JPEG data URI."""
    return _jpeg(drawn_view(run_dir, view, width))


def drawn_view(run_dir: Path, view: View, width: int = CARD_WIDTH) -> Image.Image:
    """The frame with its detections and the plant's true fruit drawn, `width` px wide."""
    image = Image.fromarray(read_png(Path(run_dir) / view.frame.image, np.uint8)).convert("RGB")
    scale = width / image.width
    image = image.resize((width, round(image.height * scale)), Image.Resampling.BILINEAR)
    draw = ImageDraw.Draw(image)
    font = ImageFont.load_default(size=13)
    for box in view.boxes.values():
        draw.rectangle([v * scale for v in box], outline=TRUTH if findable(box) else TRUTH_SMALL, width=1)
    for detection in view.frame.detections:
        box = [v * scale for v in detection.bbox]
        draw.rectangle(box, outline=DETECTION[detection.label], width=2)
        draw.text((box[0] + 3, box[1] + 2), f"{detection.score:.2f}", fill=DETECTION[detection.label], font=font)
    return image


def _count_table(estimate: int, truth: int, unripe_estimate: int, unripe_truth: int) -> str:
    def row(label: str, got: int, true: int) -> str:
        off = f"{got - true:+d}" if got != true else "0"
        return (f'<tr class="{"off" if got != true else "ok"}"><td class="left">{label}</td><td>{got}</td><td>{true}</td>'
                f"<td>{off}</td></tr>")

    return ('<table class="est"><tr><th class="left">fruit</th><th>estimated</th><th>true</th><th>off by</th></tr>'
            + row("ripe", estimate, truth) + row("unripe", unripe_estimate, unripe_truth) + "</table>")


def legend() -> str:
    """What the boxes drawn on the cards' frames mean."""
    def swatch(color: tuple[int, int, int], label: str) -> str:
        return f'<span><i class="swatch" style="border-color:rgb{color}"></i>{html.escape(label)}</span>'

    return ('<p class="legend">' + swatch(DETECTION["ripe"], "ripe detection (with its score)")
            + swatch(DETECTION["unripe"], "unripe detection") + swatch(TRUTH, "the plant's true fruit")
            + swatch(TRUTH_SMALL, f"its true fruit too small to find (under {MIN_SIDE} x {MIN_SIDE} px)") + "</p>")


def plant_cards(run_dir: Path, scene: Scene, counts: Counts, detections: Detections) -> str:
    margin = float(counts.settings.get("volume_margin", DEFAULT_MARGIN))
    views = best_views(run_dir, scene, detections, margin)
    cards = []
    for plant in counts.plants:
        misses = ""
        if plant.unseen is not None:
            misses = (f'<p class="misses">Ripe fruit never in view: {plant.unseen}; only seen too small: '
                      f'{plant.too_small}.</p>')
        view = views.get(plant.id)
        if view is None:
            picture = '<p class="noframe">No frame showed this plant.</p>'
        else:
            what = f"{view.detected} detection{'s' if view.detected != 1 else ''} of its fruit"
            if view.boxes:
                what += f", {view.findable} of its fruit in view {FINDABLE.split(',')[0]}"
            picture = (f'<figure><img alt="frame {view.frame.index}, plant {plant.id}" src="{draw_view(run_dir, view)}">'
                       f"<figcaption>Frame {view.frame.index} (t = {view.frame.timestamp:.1f} s): {html.escape(what)}."
                       "</figcaption></figure>")
        state = "exact" if plant.estimate == plant.truth else "off"
        verdict = "ripe count exact" if state == "exact" else f"ripe count off by {plant.estimate - plant.truth:+d}"
        cards.append(f'<div class="card {state}" id="plant-{plant.id}"><h3>Plant {plant.id} '
                     f'<span class="sub">row {plant.row} · {verdict}</span></h3>'
                     + _count_table(plant.estimate, plant.truth, plant.unripe_estimate, plant.unripe_truth)
                     + misses + picture + "</div>")
    return '<div class="cards">' + "".join(cards) + "</div>"
