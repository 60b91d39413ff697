"""The report's frames: colour, depth and masks of a few frames spread over the scan, side by side.

The frames picked and their colours are the contact sheet's (`render/contact_sheet.py`): every depth image on one
scale, drawn once above the frames with its range in words. Depth and masks are palette PNGs (exact: a depth
image's colours are the scale's colours), the colour frames JPEGs, at most FRAME_WIDTH px wide.
"""

from __future__ import annotations

import base64
import html
import io
from pathlib import Path

import numpy as np
from PIL import Image

from renderloop.render.contact_sheet import (FAR_COLOR, LEVELS, NONE_COLOR, ROWS, DepthScale, depth_scale, mask_colours,
                                             pick_frames)
from renderloop.render.frames import decode_depth, read_png
from renderloop.rundir import names

FRAME_WIDTH = 400  # px, at most
JPEG_QUALITY = 85


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
