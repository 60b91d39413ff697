"""Read image files that a user hands us (run frames, photos, training images) without trusting them.

The header is read first (Pillow's `Image.open` decodes nothing) and its width x height
is checked against MAX_PIXELS before any pixel is decoded, so a small file that claims
a huge image (a decompression bomb) is refused without the memory it asks for. Only
PNG and JPEG are identified: every image the project reads is one, and the other
formats Pillow knows (EPS runs Ghostscript, for one) are attack surface for nothing.
A reader that knows the type and the channels of its pixels (`read_image_as`) checks
them too, so a grey image where colour belongs, or a colour one where depth belongs, is
refused by name instead of reaching a stage in the wrong shape.
Every way a file can be wrong ends in a one-line UserError naming it.
"""

from __future__ import annotations

import re
import struct
import warnings
from collections.abc import Sequence
from pathlib import Path

import numpy as np
from PIL import Image, ImageFile, UnidentifiedImageError

from renderloop.errors import UserError

# 64 million pixels: well above any image the project makes (640 x 480 camera frames,
# dataset views) and above a 50-megapixel phone photo (8160 x 6120), yet far below what
# exhausts memory: decoded as RGBA it is 256 MB. It is also below Pillow's own
# decompression-bomb threshold (about 89 million), so this check is the one that decides.
MAX_PIXELS = 64_000_000

FORMATS = ("PNG", "JPEG")

# Errors Pillow raises for a file whose bytes are wrong: a bad chunk, a short read, a bad field.
_CORRUPT = (OSError, ValueError, SyntaxError, EOFError, struct.error)


def _name(path: Path) -> str:
    """The path as it goes into a message: quoted when it is not one printable line (a file name may hold a newline)."""
    text = str(path)
    return text if text.isprintable() else repr(text)


def _too_large(path: Path, claim: str) -> UserError:
    return UserError(f"{_name(path)}: its header claims {claim} pixels, more than the {MAX_PIXELS:,} allowed")


def _noun(formats: Sequence[str]) -> str:
    return formats[0] if len(formats) == 1 else "image"


def _open_header(path: Path, formats: Sequence[str]) -> Image.Image:
    """The image with only its header read, its size checked; the caller closes it."""
    if ImageFile.LOAD_TRUNCATED_IMAGES:  # set by some library: a truncated frame would read as grey, not fail
        raise RuntimeError("PIL.ImageFile.LOAD_TRUNCATED_IMAGES is set; truncated images would not be detected")
    with warnings.catch_warnings():
        # Pillow warns (and lets the image decode) between its limit and twice it; an error here instead, never printed
        warnings.simplefilter("error", Image.DecompressionBombWarning)
        try:
            image = Image.open(path, formats=list(formats))
        except FileNotFoundError:
            raise UserError(f"{_name(path)}: no such file") from None
        except IsADirectoryError:
            raise UserError(f"{_name(path)}: a folder, not an image") from None
        except (Image.DecompressionBombError, Image.DecompressionBombWarning) as error:
            found = re.search(r"\((\d+) pixels\)", str(error))
            raise _too_large(path, f"{int(found.group(1)):,}" if found else "too many") from None
        except PermissionError:
            raise  # the machine, not the input: the CLI names the file with exit code 1
        except (UnidentifiedImageError, *_CORRUPT):
            raise UserError(f"{_name(path)}: not a readable {_noun(formats)}") from None
    width, height = image.size
    if width * height > MAX_PIXELS:
        image.close()
        raise _too_large(path, f"{width} x {height} = {width * height:,}")
    return image


def check_image(path: Path, formats: Sequence[str] = FORMATS) -> tuple[int, int]:
    """Width and height from the header alone: the file exists, is one of `formats` and is not too large.
    Cheap (nothing is decoded), so a whole dataset can be checked before work starts; truncated data shows only on reading."""
    with _open_header(Path(path), formats) as image:
        return image.size


def open_image(path: Path, mode: str | None = None, formats: Sequence[str] = FORMATS) -> Image.Image:
    """The decoded image, converted to `mode` when given; the file is closed.

    `formats` are the Pillow formats accepted; a file of any other is "not a readable image"
    (with one format, the message names it: "not a readable PNG").
    """
    path = Path(path)
    with _open_header(path, formats) as image:
        try:
            image.load()
            return image.convert(mode) if mode else image.copy()
        except _CORRUPT:
            raise UserError(f"{_name(path)}: not a readable {_noun(formats)} (truncated or corrupt data)") from None


def read_image(path: Path, mode: str | None = None, formats: Sequence[str] = FORMATS) -> np.ndarray:
    """The pixels as an array (height x width, x channels for colour), converted to `mode` when given."""
    return np.array(open_image(path, mode, formats))


def read_image_as(path: Path, dtype: type, formats: Sequence[str] = FORMATS, channels: int | None = None) -> np.ndarray:
    """The pixels as stored (no mode conversion) in `dtype`; values that do not fit it are an error, not wrapped.
    `channels`: how many the stored pixels must have (1: grey, depth or ids, height x width; 3: RGB)."""
    image = open_image(path, formats=formats)
    array = np.array(image)
    target = np.dtype(dtype)
    if target.kind in "ui" and array.size and not np.can_cast(array.dtype, target):
        limits = np.iinfo(target)
        if array.min() < limits.min or array.max() > limits.max:
            raise UserError(f"{_name(path)}: holds {array.dtype.name} values up to {array.max()}, more than {target.name} holds")
    found = array.shape[2] if array.ndim == 3 else 1  # a palette image has one: its indices
    if channels is not None and found != channels:
        raise UserError(f"{_name(path)}: holds {found}-channel {image.mode} pixels, not {channels}-channel")
    return array.astype(target, copy=False)
