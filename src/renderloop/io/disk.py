"""Free disk space where a stage is about to write: the one check every stage that estimates its files makes."""

from __future__ import annotations

import shutil
from pathlib import Path


def free_bytes(path: Path) -> float:
    """Bytes free on the file system that holds `path`, or would hold it: its nearest existing ancestor's."""
    place = Path(path).resolve()
    while not place.exists() and place != place.parent:
        place = place.parent
    return float(shutil.disk_usage(place).free)
