"""`renderloop detect --images FOLDER --out FILE.json`: the detector on any photos, no depth.

FILE.json: {"model": path, "score_threshold": t, "windows": ["2x2", ...], "mirror": m, "complete": bool, "error": str | null,
            "images": {"name.jpg": {"width": w, "height": h, "detections": [{"bbox", "score", "label"}]}}}
A photo that cannot be read stops the run: the photos before it are written
(complete: false, with the error) and the command exits with code 2 naming it.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import numpy as np

from renderloop.config import DetectorConfig
from renderloop.errors import UserError
from renderloop.io.atomic import write_json
from renderloop.io.images import read_image
from renderloop.perception.detector import Detector
from renderloop.perception.tiling import layout_names

SUFFIXES = {".png", ".jpg", ".jpeg"}

Progress = Callable[[int, int], None]


def list_photos(folder: Path) -> list[Path]:
    folder = Path(folder)
    if not folder.is_dir():
        raise UserError(f"--images {folder}: not a folder")
    photos = sorted(p for p in folder.iterdir() if p.is_file() and p.suffix.lower() in SUFFIXES)
    if not photos:
        raise UserError(f"--images {folder}: no PNG or JPEG files in it")
    return photos


def _read_rgb(path: Path) -> np.ndarray:
    return read_image(path, "RGB")


def detect_photos(folder: Path, out: Path, settings: DetectorConfig, force: bool = False, progress: Progress | None = None) -> int:
    """Detect on every photo of `folder` into `out` with the model, threshold, windows and mirror of `settings`; an
    existing `out` is replaced only with `force`."""
    photos = list_photos(folder)
    if Path(out).is_dir():
        raise UserError(f"--out {out}: is a folder; give a .json file name")
    if Path(out).exists() and not force:
        raise UserError(f"{out}: exists; use --force to replace it")
    detector = Detector(settings.model)
    results: dict[str, dict] = {}
    record = {"model": str(detector.path), "score_threshold": settings.score_threshold, "windows": layout_names(settings.layouts),
              "mirror": settings.mirror, "complete": False, "error": None, "images": results}
    try:
        for done, path in enumerate(photos):
            if progress:
                progress(done, len(photos))
            rgb = _read_rgb(path)
            found = detector.search(rgb, settings)
            results[path.name] = {"width": rgb.shape[1], "height": rgb.shape[0], "detections": [d.to_json() for d in found]}
    except UserError as error:
        record["error"] = str(error)
        write_json(out, record)
        raise
    record["complete"] = True
    write_json(out, record)
    return len(photos)
