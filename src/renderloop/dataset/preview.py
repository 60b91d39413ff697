"""A sheet of dataset images with their boxes (ripe red, unripe cyan, ignored grey dashed-thin), to look at."""

from __future__ import annotations

from pathlib import Path

from PIL import Image, ImageDraw

from renderloop.io.atomic import atomic_path
from renderloop.io.images import open_image

COLORS = {"ripe": (255, 40, 40), "unripe": (0, 230, 255)}
IGNORED = (150, 150, 150)
COLUMNS = 6


def draw_preview(root: Path, records: list[dict], path: Path) -> None:
    if not records:
        return
    tiles = []
    for record in records:
        image = open_image(root / record["image"], "RGB")
        draw = ImageDraw.Draw(image)
        for pepper in record["peppers"]:
            color = IGNORED if pepper["ignore"] else COLORS[pepper["label"]]
            draw.rectangle(pepper["bbox"], outline=color, width=1 if pepper["ignore"] else 2)
        tiles.append(image)
    width, height = tiles[0].size
    rows = (len(tiles) + COLUMNS - 1) // COLUMNS
    sheet = Image.new("RGB", (COLUMNS * width, rows * height), (0, 0, 0))
    for i, tile in enumerate(tiles):
        sheet.paste(tile, ((i % COLUMNS) * width, (i // COLUMNS) * height))
    with atomic_path(path) as tmp:
        sheet.save(tmp, format="PNG")
