"""The sRGB transfer functions, once: display values to the linear light renderers shade with, and back to 8 bits.

Encoding quantises as Blender's Standard view transform writes its 8-bit output (round half up, no dither), so the
raster sky, the sensor model and Cycles' own frames agree to the level.
"""

from __future__ import annotations

import numpy as np


def to_linear(rgb) -> np.ndarray:
    """sRGB display values in [0, 1] (any shape) to linear values."""
    c = np.clip(np.asarray(rgb, dtype=float), 0.0, 1.0)
    return np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)


def decode_u8(rgb: np.ndarray) -> np.ndarray:
    """8-bit sRGB pixels to linear float32."""
    return to_linear(np.asarray(rgb, dtype=np.float32) / 255.0).astype(np.float32)


def encode_u8(linear: np.ndarray) -> np.ndarray:
    """Linear values to 8-bit sRGB."""
    x = np.clip(np.asarray(linear, dtype=np.float64), 0.0, 1.0)
    encoded = np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.power(x, 1.0 / 2.4) - 0.055)
    return np.floor(encoded * 255.0 + 0.5).astype(np.uint8)
