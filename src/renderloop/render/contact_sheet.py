"""How a run's frames are shown: the frames picked, depth on one colour scale, a colour per instance; and the
render stage's contact sheet of them (colour, depth and masks side by side, one PNG). The report's frames
(`report/frames.py`) show the same frames with the same colours.

Every depth image is coloured on one scale, so a colour is one distance in all of them: from the nearest depth
any shown frame holds (its 1st percentile, rounded down to the decimetre) to the farthest fruit they show (the
99th percentile of the fruit pixels' depth, rounded up; the median depth of the frames when the run has no
masks). Nearer than the scale's start is drawn as its start; farther than its end (tables, walls) in grey, and
pixels with no depth reading in white, so the plants stand out.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from PIL import Image, ImageDraw, ImageFont

from renderloop.io.atomic import atomic_path
from renderloop.render.frames import read_frame, read_png
from renderloop.rundir import names

ROWS = 6  # frames shown
LEVELS = 254  # colours of the scale; two more for too far and no reading make a 256-colour palette
FAR_COLOR, NONE_COLOR = (200, 200, 200), (255, 255, 255)
TILE_WIDTH = 320  # px of each image on the contact sheet, whatever the frame size: small frames stay readable
GAP, TEXT = 6, 18  # px between tiles; of a line of text
HEAD = 3 * TEXT + GAP  # px above the first row: the column names, the scale's ramp and its ends


def mask_colours(mask: np.ndarray) -> np.ndarray:
    """A fixed colour per instance id (hashed), black background."""
    ids = mask.astype(np.uint32)
    hashed = (ids * np.uint32(2654435761)) >> np.uint32(8)
    rgb = np.stack([(hashed >> shift) & 255 for shift in (0, 8, 16)], axis=-1).astype(np.uint8)
    rgb[ids == 0] = 0
    return rgb


def pick_frames(run_dir: Path, count: int, rows: int = ROWS) -> list[int]:
    """Frames spread over the run, preferring ones that show peppers."""
    candidates = np.linspace(0, count - 1, min(count, rows * 4)).astype(int)
    shown = [(int(np.count_nonzero(read_png(run_dir / names.frame_file(names.MASKS, int(i)), np.uint16))), int(i))
             for i in np.unique(candidates)]
    best = sorted(sorted(shown, reverse=True)[:rows], key=lambda item: item[1])
    return [index for _, index in best]


@functools.cache
def _palette() -> np.ndarray:
    """Every scale's colours, built once: a sheet colours each of its frames with them."""
    import matplotlib  # its colour maps only: the import is why it waits until a palette is asked for

    turbo = matplotlib.colormaps["turbo"](np.linspace(0.0, 1.0, LEVELS))[:, :3]
    palette = np.vstack([np.round(255 * turbo), FAR_COLOR, NONE_COLOR]).astype(np.uint8)
    palette.flags.writeable = False
    return palette


@dataclass(frozen=True)
class DepthScale:
    """The one colour scale of the shown depth images, m."""

    near: float
    far: float

    def palette(self) -> np.ndarray:
        """(256, 3) uint8, read-only: the scale's LEVELS colours (turbo, near to far), then too far, then no reading."""
        return _palette()

    def indices(self, depth: np.ndarray) -> np.ndarray:
        """Each pixel's palette index: its level on the scale, LEVELS when farther, LEVELS + 1 with no reading."""
        level = np.clip(np.round((depth - self.near) / (self.far - self.near) * (LEVELS - 1)), 0, LEVELS - 1)
        index = np.where(depth > self.far, LEVELS, level)
        return np.where(depth > 0, index, LEVELS + 1).astype(np.uint8)

    def colour(self, depth: np.ndarray) -> np.ndarray:
        """(H, W, 3) uint8: the depth image as the report and the contact sheet draw it."""
        return self.palette()[self.indices(depth)]

    def words(self) -> str:
        return f"{self.near:.1f} m to {self.far:.1f} m"


def depth_scale(depths: list[np.ndarray], masks: list[np.ndarray | None]) -> DepthScale:
    """The one scale for the frames whose planar depth (m, 0 = no reading) and instance masks (or None) are given."""
    valid = np.concatenate([d[d > 0] for d in depths]) if depths else np.zeros(0)
    if not len(valid):
        return DepthScale(0.0, 1.0)
    fruit = np.concatenate([d[(m > 0) & (d > 0)] for d, m in zip(depths, masks) if m is not None] or [np.zeros(0)])
    near = math.floor(float(np.percentile(valid, 1)) * 10) / 10
    far = float(np.percentile(fruit, 99)) if len(fruit) else float(np.median(valid))
    far = math.ceil(far * 10) / 10
    return DepthScale(near, max(far, near + 0.1))


def _tile(pixels: np.ndarray, resample: Image.Resampling) -> Image.Image:
    image = Image.fromarray(pixels)
    return image.resize((TILE_WIDTH, round(image.height * TILE_WIDTH / image.width)), resample)


def tile_origin(row: int, column: int, height: int) -> tuple[int, int]:
    """(left, top) px of a tile on the sheet, whose tiles are `height` px high: each row is headed by a line of text."""
    return column * (TILE_WIDTH + GAP), HEAD + row * (TEXT + height + GAP) + TEXT


def draw_contact_sheet(run_dir: Path, count: int, path: Path) -> None:
    """Colour, depth on the one scale and masks of the picked frames, a row each, under a head that names the columns
    and draws the scale; each row headed by its frame and the fruit it shows."""
    frames = [(index, read_frame(run_dir, index)) for index in pick_frames(run_dir, count)]
    scale = depth_scale([frame.depth for _, frame in frames], [frame.mask for _, frame in frames])
    rows = [(_tile(frame.rgb, Image.Resampling.BILINEAR), _tile(scale.colour(frame.depth), Image.Resampling.NEAREST),
             _tile(mask_colours(frame.mask), Image.Resampling.NEAREST)) for _, frame in frames]
    font = ImageFont.load_default(size=TEXT - 4)
    height = rows[0][0].height
    sheet = Image.new("RGB", (3 * TILE_WIDTH + 2 * GAP, tile_origin(len(rows), 0, height)[1] - TEXT), "white")
    draw = ImageDraw.Draw(sheet)
    for column, name in enumerate(("colour", "depth, m: farther in grey, no reading white", "instance masks")):
        draw.text((column * (TILE_WIDTH + GAP), 0), name, fill="black", font=font)
    ramp = scale.palette()[np.linspace(0, LEVELS - 1, TILE_WIDTH).round().astype(int)]
    sheet.paste(Image.fromarray(np.repeat(ramp[None], TEXT, axis=0)), (TILE_WIDTH + GAP, TEXT))
    draw.text((TILE_WIDTH + GAP, 2 * TEXT), f"{scale.near:.1f}", fill="black", font=font)
    draw.text((2 * TILE_WIDTH + GAP, 2 * TEXT), f"{scale.far:.1f}", fill="black", font=font, anchor="ra")
    for row, ((index, frame), tiles) in enumerate(zip(frames, rows)):
        ids = np.unique(frame.mask[frame.mask > 0])
        fruit = f"fruit {', '.join(map(str, ids[:10]))}{', …' if len(ids) > 10 else ''}" if len(ids) else "no fruit"
        left, top = tile_origin(row, 0, height)
        draw.text((left, top - TEXT), f"frame {index}: {fruit}", fill="black", font=font)
        for column, tile in enumerate(tiles):
            sheet.paste(tile, tile_origin(row, column, height))
    with atomic_path(Path(path)) as tmp:
        sheet.save(tmp, format="PNG")
