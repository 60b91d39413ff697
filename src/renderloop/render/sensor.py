"""The colour stream of a RealSense D435-class camera, made from an ideal render.

A real scan camera in a greenhouse looks at dark foliage in front of a bright film wall.
Its auto exposure meters the frame (centre-weighted) and sets a gain that brings the
foliage up, so the background clips white; its auto white balance misjudges the light's
colour temperature (too warm or too cool) and is off by a few per cent more; the small
sensor adds shot noise (that the gain amplifies, so dark regions are noisy) and read
noise; the cheap lens darkens the corners (vignetting) and blurs what lies far from its
fixed focus; the ISP sharpens, and the stream is often JPEG-compressed. Noise and defocus
are stated for the full-width stream (SENSOR_STREAM_WIDTH px): a frame W px wide bins
(SENSOR_STREAM_WIDTH / W)^2 of its pixels into each of its own, which averages their noise
down to W / SENSOR_STREAM_WIDTH of its sigma and shrinks a blur's circle in pixels as much.
`sensor_rgb` applies these in that order to the ideal sRGB frame, in linear light; with
Cycles that frame is first rendered again blurred by the camera's motion over the exposure
(`render/motion.py`, `CyclesRenderer.render_blurred`), the raster backend has no blur.

Every setting is a range (`renderloop.config.SensorConfig`) and each frame draws its own
values from a generator seeded by the run's seed and the frame index, so a frame is the
same whichever worker renders it; a fixed value is a range of one value. The ideal frame
stays in `rgb/`, the sensor's in `rgb_sensor/`, as depth has `depth/` and `depth_sensor/`.
"""

from __future__ import annotations

import io

import numpy as np
from PIL import Image, ImageFilter
from scipy.ndimage import gaussian_filter

from renderloop.config import SensorConfig
from renderloop.config.camera import SENSOR_STREAM_WIDTH
from renderloop.render.srgb import decode_u8, encode_u8

LUMA = np.array([0.2126, 0.7152, 0.0722])  # Rec. 709 luminance of linear RGB


def _draw(rng: np.random.Generator, bounds: tuple[float, float]) -> float:
    low, high = bounds
    return float(low if high <= low else rng.uniform(low, high))


def metered(linear: np.ndarray) -> float:
    """Centre-weighted mean luminance: what an auto-exposure loop settles on (a Gaussian weight, sigma a third of the
    frame), so a bright wall at the edges counts less than the plant the camera looks at."""
    height, width = linear.shape[:2]
    y, x = np.mgrid[0:height, 0:width]
    r2 = ((x - (width - 1) / 2) / width) ** 2 + ((y - (height - 1) / 2) / height) ** 2
    weight = np.exp(-r2 / (2 * (1 / 3) ** 2))
    return float(np.sum((linear @ LUMA) * weight) / np.sum(weight))


def _defocus(linear: np.ndarray, depth: np.ndarray, focus: float, strength: float) -> np.ndarray:
    """A fixed-focus lens: blur grows with |1/z - 1/focus| (the circle of confusion; `strength` in px m of this
    frame); pixels are blended between the sharp image and one blurred by the largest circle, which is cheap and
    looks the same at these small amounts."""
    if strength <= 0:
        return linear
    with np.errstate(divide="ignore"):
        circle = strength * np.abs(np.where(depth > 0, 1.0 / np.maximum(depth, 1e-3), 0.0) - 1.0 / focus)
    radius = float(np.max(circle))
    if radius < 0.3:
        return linear
    blurred = gaussian_filter(linear, sigma=(radius, radius, 0))
    share = np.clip(circle / radius, 0.0, 1.0)[..., None]
    return linear * (1 - share) + blurred * share


def _sharpen(rgb: np.ndarray, amount: float) -> np.ndarray:
    if amount <= 0:
        return rgb
    image = Image.fromarray(rgb).filter(ImageFilter.UnsharpMask(radius=1.2, percent=int(round(amount * 100)), threshold=2))
    return np.asarray(image)


def _jpeg(rgb: np.ndarray, quality: float) -> np.ndarray:
    if quality >= 100:
        return rgb
    buffer = io.BytesIO()
    Image.fromarray(rgb).save(buffer, format="JPEG", quality=int(round(quality)))
    with Image.open(io.BytesIO(buffer.getvalue())) as image:
        return np.array(image.convert("RGB"))


def sensor_rgb(rgb: np.ndarray, depth: np.ndarray, settings: SensorConfig, rng: np.random.Generator) -> np.ndarray:
    """The frame the camera would deliver for the ideal sRGB `rgb` (uint8) with planar `depth` (m, 0 = no return)."""
    linear = decode_u8(rgb)
    balance = 1.0 + rng.normal(0.0, _draw(rng, settings.white_balance_error), 3)
    warmth = _draw(rng, settings.white_balance_warmth)  # most of an auto white balance's error lies on the daylight axis
    balance = balance * np.exp([warmth / 2, 0.0, -warmth / 2])
    linear = linear * (balance / balance[1]).astype(np.float32)  # a white-balance error relative to green
    target = _draw(rng, settings.exposure_target)
    gain = float(np.clip(target / max(metered(linear), 1e-6), settings.gain[0], settings.gain[1]))
    linear = linear * np.float32(gain)
    height, width = linear.shape[:2]
    y, x = np.mgrid[0:height, 0:width]
    r2 = (((x - (width - 1) / 2) / (width / 2)) ** 2 + ((y - (height - 1) / 2) / (height / 2)) ** 2) / 2
    linear = linear * (1.0 - _draw(rng, settings.vignetting) * r2)[..., None].astype(np.float32)
    binning = width / SENSOR_STREAM_WIDTH
    linear = _defocus(linear, depth, _draw(rng, settings.focus_distance), _draw(rng, settings.defocus) * binning)
    # shot noise (variance proportional to the light collected, made larger by the gain) and read noise
    shot, read = _draw(rng, settings.shot_noise), _draw(rng, settings.read_noise)
    sigma = np.sqrt(np.maximum(linear, 0.0) * shot * gain + (read * gain) ** 2) * binning
    linear = linear + rng.standard_normal(linear.shape).astype(np.float32) * sigma.astype(np.float32)
    encoded = _sharpen(encode_u8(linear), _draw(rng, settings.sharpen))
    return _jpeg(encoded, _draw(rng, settings.jpeg_quality))
