"""Overlapping windows of a frame that the detector also searches, so that small fruit reach it at full size.

The network sees a 640x480 frame squeezed to 320x320: fruit of 20-30 px become 10-15 px,
where it is least sure of them (paper seed 7: at score 0.5 it found 41 % of the ripe fruit
of 20-30 px against 83 % of those over 110 px, while at 0.1 it boxed 85 % of them). A
layout of columns x rows windows, each a little over 1/columns by 1/rows of the frame,
shows them larger; the whole frame is still searched too, for fruit larger than a window.
A window's box that touches one of the window's inner edges belongs to a fruit the
window cut: the whole frame or the neighbouring window holds that fruit whole, so the
cut box is dropped.

A layout whose windows the network input would enlarge more than `detector.max_window_enlargement`
times on either side is not searched. Such a window shows no pixel the frame does not; what it
adds is one more look at them, which fusion rewards where the looks agree. On 640x480 frames the
3x2 windows (235x264, enlarged 1.36 times) found more fruit together with the 2x2 ones than the
2x2 alone at the same rate of false detections, the 3x3 windows (176 px high, 1.82 times) fewer
(step 10's network), so the default, 1.5, gives the demo's 320x240 frames no windows. The
greenhouse preset's 320x240 frames gain from the 2x2 windows (176x132, enlarged 2.9 times) with
the shipped network, and its preset allows 3 (docs/stages/perception.md).
"""

from __future__ import annotations

import math
import re
from collections.abc import Sequence

from renderloop.config.perception import LAYOUT_PATTERN, MAX_ENLARGEMENT, Layout, layout
from renderloop.errors import UserError

Box = tuple[float, float, float, float]
Window = tuple[int, int, int, int]

OVERLAP = 0.1  # a window is (1 + OVERLAP) / columns of the frame's width (rows: height): neighbours share a strip
EDGE = 2.0  # px: a box this close to a window's inner edge was cut by it


def parse_layouts(text: str) -> list[Layout]:
    """'2x2,3x2' (columns x rows, comma-separated) or 'none' to layouts; anything else is a one-line UserError."""
    if text.strip().lower() == "none":
        return []
    items = [item.strip() for item in text.split(",")]
    if not all(re.fullmatch(LAYOUT_PATTERN, item) for item in items):
        raise UserError(f"--windows {text}: give columns x rows layouts from 1x1 to 8x8, comma-separated (e.g. 2x2,3x2), or none")
    return [layout(item) for item in items]


def layout_names(layouts: Sequence[Layout]) -> list[str]:
    return [f"{columns}x{rows}" for columns, rows in layouts]


def windows(width: int, height: int, columns: int, rows: int, input_size: int,
            max_enlargement: float = MAX_ENLARGEMENT) -> list[Window]:
    """(x0, y0, x1, y1) of the columns x rows windows, the outer ones on the frame's corners, row by row;
    none for 1x1 or when the network input would enlarge a window more than `max_enlargement` times."""
    window_width = min(width, math.ceil(width * (1 + OVERLAP) / columns))
    window_height = min(height, math.ceil(height * (1 + OVERLAP) / rows))
    if (columns, rows) == (1, 1) or input_size > max_enlargement * min(window_width, window_height):
        return []
    xs = [round(i * (width - window_width) / max(1, columns - 1)) for i in range(columns)]
    ys = [round(i * (height - window_height) / max(1, rows - 1)) for i in range(rows)]
    return [(x, y, x + window_width, y + window_height) for y in ys for x in xs]


def all_windows(width: int, height: int, layouts: Sequence[Layout], input_size: int,
                max_enlargement: float = MAX_ENLARGEMENT) -> list[Window]:
    return [window for columns, rows in layouts
            for window in windows(width, height, columns, rows, input_size, max_enlargement)]


def cut_by_window(box: Box, window: Window, width: int, height: int) -> bool:
    """Whether `box` (frame pixels) touches an edge of `window` that lies inside the frame."""
    x0, y0, x1, y1 = window
    return ((x0 > 0 and box[0] < x0 + EDGE) or (y0 > 0 and box[1] < y0 + EDGE)
            or (x1 < width and box[2] > x1 - EDGE) or (y1 < height and box[3] > y1 - EDGE))
