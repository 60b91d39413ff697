"""Frame files of a run: rgb/, depth/, masks/ (and depth_sensor/), one PNG per camera pose.

Depth PNGs are uint16 at 5000 units per metre (TUM), 0 = no return; masks are uint16
instance ids, 0 = background, 32767 = a neighbouring row's fruit. Every file is written
under a temporary name and renamed, and a frame counts as done only when all of its
files exist, so a render killed at any moment resumes without a missing, duplicated or
half-written frame.
"""

from __future__ import annotations

import io
import zlib
from pathlib import Path

import numpy as np
from PIL import Image

from renderloop.io.atomic import write_bytes
from renderloop.io.images import read_image_as
from renderloop.config import Config
from renderloop.errors import UserError
from renderloop.render.frame import RenderedFrame
from renderloop.rundir import names

DEPTH_SCALE = 5000.0  # PNG units per metre (TUM RGB-D)
MAX_DEPTH = 65535 / DEPTH_SCALE
# zlib's fastest level, matching runs of equal bytes only (Z_RLE): PNG's row filters leave mostly those, so a frame is
# smaller and quicker to compress than with the level's usual search (docs/stages/render.md)
PNG_LEVEL, PNG_STRATEGY = 1, zlib.Z_RLE


def streams_of(config: Config) -> tuple[str, ...]:
    """The image streams a run renders: the ideal ones, and the sensor's where the config asks for them."""
    sensor = ((names.DEPTH_SENSOR,) if config.renderer.depth_noise.enabled else ()) + (
        (names.RGB_SENSOR,) if config.camera.sensor.enabled else ())
    return (names.RGB, names.DEPTH, names.MASKS, *sensor)


def sensor_depth_dir(run_dir: Path) -> str:
    """The depth a real camera would give: the sensor stream when the run rendered one, else the ideal depth."""
    return names.DEPTH_SENSOR if (Path(run_dir) / names.DEPTH_SENSOR).is_dir() else names.DEPTH


def sensor_rgb_dir(run_dir: Path) -> str:
    """The colour a real camera would give: the sensor stream when the run rendered one, else the ideal colour."""
    return names.RGB_SENSOR if (Path(run_dir) / names.RGB_SENSOR).is_dir() else names.RGB


def frame_done(run_dir: Path, index: int, streams: tuple[str, ...]) -> bool:
    return all((run_dir / names.frame_file(stream, index)).is_file() for stream in streams)


def _png(array: np.ndarray) -> bytes:
    buffer = io.BytesIO()
    Image.fromarray(array).save(buffer, format="PNG", compress_level=PNG_LEVEL, compress_type=PNG_STRATEGY)
    return buffer.getvalue()


def encode_depth(depth: np.ndarray) -> np.ndarray:
    """Metres to TUM uint16; beyond what uint16 holds (13.1 m) counts as no return."""
    units = np.rint(np.where((depth > 0) & (depth <= MAX_DEPTH), depth, 0.0) * DEPTH_SCALE)
    return units.astype(np.uint16)


def decode_depth(units: np.ndarray) -> np.ndarray:
    return units.astype(np.float32) / DEPTH_SCALE


def stored_images(frame: RenderedFrame, sensor_depth: np.ndarray | None,
                  sensor_rgb: np.ndarray | None = None) -> dict[str, np.ndarray]:
    """Each file of a frame as its PNG holds it (uint8 colour, uint16 depth units and instance ids), keyed by directory."""
    images = {names.RGB: frame.rgb, names.DEPTH: encode_depth(frame.depth)}
    if sensor_depth is not None:
        images[names.DEPTH_SENSOR] = encode_depth(sensor_depth)
    if sensor_rgb is not None:
        images[names.RGB_SENSOR] = sensor_rgb
    images[names.MASKS] = frame.mask.astype(np.uint16)
    return images


def encode_images(images: dict[str, np.ndarray]) -> dict[str, bytes]:
    return {name: _png(array) for name, array in images.items()}


def encode_frame(frame: RenderedFrame, sensor_depth: np.ndarray | None, sensor_rgb: np.ndarray | None = None) -> dict[str, bytes]:
    """PNG bytes of each file of a frame, keyed by directory; workers send these to the one writer."""
    return encode_images(stored_images(frame, sensor_depth, sensor_rgb))


def write_frame(run_dir: Path, index: int, files: dict[str, bytes]) -> None:
    """Masks last: its presence says the frame's other files are complete too."""
    for name in sorted(files, key=lambda n: n == names.MASKS):
        path = run_dir / names.frame_file(name, index)
        path.parent.mkdir(parents=True, exist_ok=True)
        write_bytes(path, files[name])


def read_png(path: Path, dtype: type) -> np.ndarray:
    """A frame file as stored, size-checked before decoding: anything but a readable PNG whose values fit `dtype`
    is a UserError. A run's 8-bit frames are RGB (rgb/, rgb_sensor/), its 16-bit ones one channel (depth, ids)."""
    return read_image_as(path, dtype, formats=("PNG",), channels=3 if np.dtype(dtype) == np.uint8 else 1)


def read_frame(run_dir: Path, index: int) -> RenderedFrame:
    return RenderedFrame(
        rgb=read_png(run_dir / names.frame_file(names.RGB, index), np.uint8),
        depth=decode_depth(read_png(run_dir / names.frame_file(names.DEPTH, index), np.uint16)),
        mask=read_png(run_dir / names.frame_file(names.MASKS, index), np.uint16),
    )


def read_rgb_frame(run_dir: Path, index: int) -> np.ndarray:
    """Frame `index` as the camera delivered it: the sensor's colour stream when the run has one."""
    path = Path(run_dir) / names.frame_file(sensor_rgb_dir(run_dir), index)
    rgb = read_png(path, np.uint8)
    if rgb.ndim != 3 or rgb.shape[2] != 3:
        raise UserError(f"{path}: not an RGB image")
    return rgb
