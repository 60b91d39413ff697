"""Write files so that a reader (or a resumed run) never sees half of one.

Every output goes to a temporary name in the same directory and is renamed into
place, which is atomic on POSIX file systems: a killed process leaves either the
old state or the complete new file, plus at most a stray temporary that the
next write of that file replaces.
"""

from __future__ import annotations

import json
import os
import shutil
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

from renderloop.rundir import ownership

TEMP_SUFFIX = ".partial"


def temporary_path(path: Path) -> Path:
    return path.with_name(f".{path.name}{TEMP_SUFFIX}")


def final_path(path: Path) -> Path:
    """The file a temporary name stands for: what an error message should name."""
    name = path.name
    if name.startswith(".") and name.endswith(TEMP_SUFFIX):
        return path.with_name(name[1 : -len(TEMP_SUFFIX)])
    return path


@contextmanager
def atomic_path(path: Path) -> Iterator[Path]:
    """Yield a temporary path to write to; rename it onto `path` only if the block succeeds.

    Inside a directory renderloop owns, the file is recorded as ours first (and a file there that is not ours is refused).
    """
    path = Path(path)
    ownership.record(path)
    tmp = temporary_path(path)
    try:
        yield tmp
        with open(tmp, "rb") as written:
            os.fsync(written.fileno())
        os.replace(tmp, path)
    except OSError as error:
        tmp.unlink(missing_ok=True)
        if error.filename is None:  # a write through a file object (numpy, PIL) does not say which file failed
            raise OSError(error.errno, error.strerror, str(path)) from error
        raise
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise


@contextmanager
def atomic_directory(path: Path, kind: str) -> Iterator[Path]:
    """Yield a path for a new directory (which does not exist yet) that appears at `path` only when the block succeeds.

    The directory is built inside a hidden staging folder beside `path` and renamed out,
    so it keeps its own name inside (a ROS 2 bag names its files after its folder). It is
    marked as a renderloop directory of `kind`; an existing `path` is replaced only if it
    carries that mark, and only once the new one is complete.
    """
    path = Path(path)
    staging = temporary_path(path)
    shutil.rmtree(staging, ignore_errors=True)
    staging.mkdir(parents=True)
    try:
        yield staging / path.name
        ownership.replace_directory(staging / path.name, path, kind)
    finally:
        shutil.rmtree(staging, ignore_errors=True)


def write_text(path: Path, text: str) -> None:
    with atomic_path(path) as tmp:
        tmp.write_text(text, encoding="utf-8")


def write_bytes(path: Path, data: bytes) -> None:
    with atomic_path(path) as tmp:
        tmp.write_bytes(data)


def dumps_json(data: Any) -> str:
    """Stable JSON text: sorted keys and fixed indentation, so the same data gives the same bytes."""
    return json.dumps(data, indent=1, sort_keys=True, ensure_ascii=False, allow_nan=False) + "\n"


def write_json(path: Path, data: Any) -> None:
    write_text(path, dumps_json(data))
