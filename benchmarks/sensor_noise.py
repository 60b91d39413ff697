"""Is the colour-sensor model as noisy as the real camera? Flat-region noise of real RealSense D435 colour frames
beside the same figure for ideal renders and for those renders through the sensor model (`render/sensor.py`).

Noise is measured where a frame is flat: Immerkær's estimator (1996: the mean absolute response to a 3x3 kernel that
cancels planes, times sqrt(pi/2)/6) over each 8x8 block of the grey image, on blocks with no pixel clipped (below 8
or above 247), and the 10th percentile of a frame's blocks, so that texture counts as little as it can; the figure is
the median over frames, in grey levels. The model's noise is stated for SENSOR_STREAM_WIDTH px wide frames, so it is
measured there, on ideal renders (the views of --dataset that did not go through the model) scaled up to that width
with the sensor's defaults (its defocus off: upscaled frames carry no depth), and at the renders' own width. The real
frames are looked at and measured only: the noise defaults were set to match them, and nothing else is.

    .venv/bin/python benchmarks/sensor_noise.py --real ../shared/real/greenhouse-unlabelled --dataset DATASET \
        [--views 24] [--name sensor_noise]
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np
from PIL import Image
from scipy.signal import convolve2d

from common import save_result

from renderloop.config import SensorConfig
from renderloop.config.camera import SENSOR_STREAM_WIDTH
from renderloop.io.images import open_image
from renderloop.render.sensor import sensor_rgb

PLANE_CANCELLING = np.array([[1, -2, 1], [-2, 4, -2], [1, -2, 1]], float)
BLOCK = 8  # px
UNCLIPPED = (8, 247)  # grey levels a flat block's pixels lie strictly between
PERCENTILE = 10


def flat_noise(rgb: np.ndarray) -> float:
    """Noise sigma in grey levels where `rgb` (uint8) is flat: see the module's docstring."""
    grey = np.asarray(Image.fromarray(rgb).convert("L"), float)
    response = np.abs(convolve2d(grey, PLANE_CANCELLING, mode="valid")) * np.sqrt(np.pi / 2) / 6
    inner = grey[1:-1, 1:-1]
    rows, cols = response.shape[0] // BLOCK, response.shape[1] // BLOCK
    blocks = response[:rows * BLOCK, :cols * BLOCK].reshape(rows, BLOCK, cols, BLOCK).mean(axis=(1, 3))
    pixels = inner[:rows * BLOCK, :cols * BLOCK].reshape(rows, BLOCK, cols, BLOCK)
    flat = (pixels.min(axis=(1, 3)) > UNCLIPPED[0]) & (pixels.max(axis=(1, 3)) < UNCLIPPED[1])
    return float(np.percentile(blocks[flat], PERCENTILE)) if flat.any() else float("nan")


def at_width(rgb: np.ndarray, width: int) -> np.ndarray:
    if rgb.shape[1] == width:
        return rgb
    height = round(rgb.shape[0] * width / rgb.shape[1])
    return np.asarray(Image.fromarray(rgb).resize((width, height), Image.BILINEAR))


def ideal_views(dataset: Path, views: int) -> list[np.ndarray]:
    found = []
    for path in sorted((dataset / "labels").glob("*.json")):
        label = json.loads(path.read_text())
        if not label.get("sensor"):
            found.append(np.asarray(open_image(dataset / label["image"]).convert("RGB")))
        if len(found) == views:
            break
    return found


def through_sensor(rgb: np.ndarray, index: int) -> np.ndarray:
    settings = SensorConfig(enabled=True, defocus=(0.0, 0.0))
    return sensor_rgb(rgb, np.ones(rgb.shape[:2], np.float32), settings, np.random.default_rng(index))


def median(values: list[float]) -> float:
    return round(float(np.nanmedian(values)), 2)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--real", type=Path, required=True, help="real D435 colour frames (PNG)")
    parser.add_argument("--dataset", type=Path, required=True, help="a folder made by `renderloop dataset`")
    parser.add_argument("--views", type=int, default=24, help="ideal views of the dataset measured")
    parser.add_argument("--name", default="sensor_noise", help="Results file: benchmarks/results/NAME.json.")
    args = parser.parse_args()

    real = [np.asarray(open_image(path).convert("RGB")) for path in sorted(args.real.glob("*.png"))]
    renders = ideal_views(args.dataset, args.views)
    if not real or not renders:
        raise SystemExit("sensor_noise: no real frames or no ideal views to measure")
    width = renders[0].shape[1]
    real_full = [flat_noise(at_width(frame, SENSOR_STREAM_WIDTH)) for frame in real]
    rows = [
        ["real D435 frames", median(real_full), median([flat_noise(at_width(frame, width)) for frame in real])],
        ["renders, ideal", median([flat_noise(at_width(view, SENSOR_STREAM_WIDTH)) for view in renders]),
         median([flat_noise(view) for view in renders])],
        ["renders through the sensor model",
         median([flat_noise(through_sensor(at_width(view, SENSOR_STREAM_WIDTH), i)) for i, view in enumerate(renders)]),
         median([flat_noise(through_sensor(view, i)) for i, view in enumerate(renders)])],
    ]
    figures = {"real_frames": len(real), "views": len(renders), "real_per_frame": [round(v, 2) for v in real_full],
               "table": {"columns": ["frames", f"{SENSOR_STREAM_WIDTH} px wide", f"{width} px wide"], "rows": rows}}
    for row in rows:
        print(row)
    print(save_result(args.name, figures))


if __name__ == "__main__":
    main()
