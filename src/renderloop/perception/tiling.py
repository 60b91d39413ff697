"""Overlapping windows of a frame that the detector also searches, so that small fruit reach it at full size.

The network sees a 640x480 frame squeezed to 320x320: fruit of 20-30 px become 10-15 px,
where it is least sure of them (paper seed 7: at score 0.5 it found 41 % of the ripe fruit
of 20-30 px against 83 % of those over 110 px, while at 0.1 it boxed 85 % of them). A grid
of windows, each a little over 1/grid of the frame, shows them about twice as large; the
whole frame is still searched too, for fruit larger than a window. A window's box that
touches one of the window's inner edges belongs to a fruit the window cut: the whole
frame or the neighbouring window holds that fruit whole, so the cut box is dropped.
"""

from __future__ import annotations

import math

Box = tuple[float, float, float, float]
Window = tuple[int, int, int, int]

OVERLAP = 0.1  # a window is (1 + OVERLAP) / grid of the frame's side: neighbours share a strip
EDGE = 2.0  # px: a box this close to a window's inner edge was cut by it


def windows(width: int, height: int, grid: int, min_width: int) -> list[Window]:
    """(x0, y0, x1, y1) of the grid x grid windows, the outer ones on the frame's corners; none when grid is 1
    or when a window would be narrower than `min_width` (the network input): it would only be upscaled."""
    window_width = min(width, math.ceil(width * (1 + OVERLAP) / grid))
    window_height = min(height, math.ceil(height * (1 + OVERLAP) / grid))
    if grid == 1 or window_width < min_width:
        return []
    xs = [round(i * (width - window_width) / (grid - 1)) for i in range(grid)]
    ys = [round(i * (height - window_height) / (grid - 1)) for i in range(grid)]
    return [(x, y, x + window_width, y + window_height) for y in ys for x in xs]


def cut_by_window(box: Box, window: Window, width: int, height: int) -> bool:
    """Whether `box` (frame pixels) touches an edge of `window` that lies inside the frame."""
    x0, y0, x1, y1 = window
    return ((x0 > 0 and box[0] < x0 + EDGE) or (y0 > 0 and box[1] < y0 + EDGE)
            or (x1 < width and box[2] > x1 - EDGE) or (y1 < height and box[3] > y1 - EDGE))
