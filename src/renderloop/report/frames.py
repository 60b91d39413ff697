"""The report's frames: colour, depth and masks of a few frames spread over the scan, side by side.

Every depth image is coloured on one scale, so a colour is one distance in all of them:
from the nearest depth any shown frame holds (its 1st percentile, rounded down to the
decimetre) to the farthest fruit they show (the 99th percentile of the fruit pixels'
depth, rounded up; the median depth of the frames when the run has no masks). Nearer
than the scale's start is drawn as its start; farther than its end (tables, walls) in
grey, and pixels with no depth reading in white, so the plants stand out. The scale is
drawn once above the frames, with its range in words.

Depth and masks are palette PNGs (exact: a depth image's colours are the scale's
colours), the colour frames JPEGs, at most FRAME_WIDTH px wide.
"""

from __future__ import annotations

import base64
import html
import io
import math
from dataclasses import dataclass
from pathlib import Path

import matplotlib
import numpy as np
from PIL import Image

from renderloop.render.contact_sheet import mask_colours, pick_frames
from renderloop.render.frames import decode_depth, read_png
from renderloop.rundir import names

ROWS = 6  # frames shown
FRAME_WIDTH = 400  # px, at most
JPEG_QUALITY = 85
LEVELS = 254  # colours of the scale; two more for too far and no reading make a 256-colour palette
FAR_COLOR, NONE_COLOR = (200, 200, 200), (255, 255, 255)


@dataclass(frozen=True)
class DepthScale:
    """The one colour scale of the report's depth images, m."""

    near: float
    far: float

    def palette(self) -> np.ndarray:
        """(256, 3) uint8: the scale's LEVELS colours (turbo, near to far), then too far, then no reading."""
        turbo = matplotlib.colormaps["turbo"](np.linspace(0.0, 1.0, LEVELS))[:, :3]
        return np.vstack([np.round(255 * turbo), FAR_COLOR, NONE_COLOR]).astype(np.uint8)

    def indices(self, depth: np.ndarray) -> np.ndarray:
        """Each pixel's palette index: its level on the scale, LEVELS when farther, LEVELS + 1 with no reading."""
        level = np.clip(np.round((depth - self.near) / (self.far - self.near) * (LEVELS - 1)), 0, LEVELS - 1)
        index = np.where(depth > self.far, LEVELS, level)
        return np.where(depth > 0, index, LEVELS + 1).astype(np.uint8)

    def colour(self, depth: np.ndarray) -> np.ndarray:
        """(H, W, 3) uint8: the depth image as the report draws it."""
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


def _data_uri(image: Image.Image, kind: str) -> str:
    buffer = io.BytesIO()
    if kind == "jpeg":
        image.save(buffer, format="JPEG", quality=JPEG_QUALITY, optimize=True)
    else:
        image.save(buffer, format="PNG", optimize=True)
    return f"data:image/{kind};base64," + base64.b64encode(buffer.getvalue()).decode("ascii")


def _smaller(image: Image.Image, resample: Image.Resampling) -> Image.Image:
    if image.width <= FRAME_WIDTH:
        return image
    return image.resize((FRAME_WIDTH, round(image.height * FRAME_WIDTH / image.width)), resample)


def _palette_image(indices: np.ndarray, palette: np.ndarray) -> Image.Image:
    image = Image.fromarray(indices, mode="P")
    image.putpalette(palette.reshape(-1).tolist())
    return _smaller(image, Image.Resampling.NEAREST)  # a resized palette image keeps its palette's colours


def _mask_image(mask: np.ndarray) -> Image.Image:
    image = Image.fromarray(mask_colours(mask)).quantize(256, method=Image.Quantize.FASTOCTREE)
    return _smaller(image, Image.Resampling.NEAREST)


def scale_bar(scale: DepthScale) -> str:
    """The scale as a bar with its range in metres, and the two colours off it."""
    stops = ", ".join(f"rgb{tuple(int(v) for v in colour)} {100 * i / 10:.0f}%"
                      for i, colour in enumerate(scale.palette()[np.linspace(0, LEVELS - 1, 11).round().astype(int)]))
    ticks = "".join(f"<span>{value:.1f}</span>" for value in np.linspace(scale.near, scale.far, 5))

    def swatch(colour: tuple[int, int, int], label: str) -> str:
        return f'<span class="off"><i style="background:rgb{colour}"></i>{html.escape(label)}</span>'

    return (f'<div class="depthscale" data-near="{scale.near:.1f}" data-far="{scale.far:.1f}">'
            f"<b>Depth, m</b><div class='ramp'><div class='gradient' style='background:linear-gradient(to right, {stops})'></div>"
            f"<div class='ticks'>{ticks}</div></div>"
            + swatch(FAR_COLOR, f"farther than {scale.far:.1f} m") + swatch(NONE_COLOR, "no depth reading") + "</div>")


def frames_section(run_dir: Path, times: np.ndarray) -> str:
    """A few frames of the run (`times`: each frame's time, s): colour, depth on the one scale, and the masks when the
    run has them."""
    run_dir = Path(run_dir)
    count = len(times)
    if not count:
        return "<p>The run has no frames.</p>"
    has_masks = all((run_dir / names.frame_file(names.MASKS, i)).is_file() for i in range(count))
    shown = (pick_frames(run_dir, count, ROWS) if has_masks
             else [int(i) for i in np.unique(np.linspace(0, count - 1, min(count, ROWS)).round().astype(int))])
    depths = [decode_depth(read_png(run_dir / names.frame_file(names.DEPTH, i), np.uint16)) for i in shown]
    masks = [read_png(run_dir / names.frame_file(names.MASKS, i), np.uint16) if has_masks else None for i in shown]
    scale = depth_scale(depths, masks)
    palette = scale.palette()
    head = ["colour", f"depth ({scale.words()})"] + (["instance masks, a colour per fruit"] if has_masks else [])
    cells = [f"<div class='colhead'>{html.escape(h)}</div>" for h in head]
    for index, depth, mask in zip(shown, depths, masks):
        rgb = Image.fromarray(read_png(run_dir / names.frame_file(names.RGB, index), np.uint8)).convert("RGB")
        label = f"frame {index}, t = {times[index]:.1f} s"
        cells.append(f'<figure><img alt="colour of frame {index}" src="{_data_uri(_smaller(rgb, Image.Resampling.LANCZOS), "jpeg")}">'
                     f"<figcaption>{html.escape(label)}</figcaption></figure>")
        cells.append(f'<figure><img class="depth" data-frame="{index}" alt="depth of frame {index}" '
                     f'src="{_data_uri(_palette_image(scale.indices(depth), palette), "png")}"></figure>')
        if mask is not None:
            ids = np.unique(mask[mask > 0])
            fruit = ", ".join(map(str, ids[:10])) + (", …" if len(ids) > 10 else "")
            cells.append(f'<figure><img alt="masks of frame {index}" src="{_data_uri(_mask_image(mask), "png")}">'
                         f"<figcaption>{html.escape(f'fruit {fruit}' if len(ids) else 'no fruit')}</figcaption></figure>")
    words = (f"<p>{len(shown)} frames spread over the scan{', those showing the most fruit' if has_masks else ''}. "
             f"Every depth image is coloured on the one scale below, {html.escape(scale.words())}: a colour is the same "
             "distance in each.</p>")
    return words + scale_bar(scale) + f"<div class='frames' style='--columns:{len(head)}'>{''.join(cells)}</div>"
