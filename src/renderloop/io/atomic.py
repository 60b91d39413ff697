"""Write files so that a reader (or a resumed run) never sees half of one.

Every output goes to a temporary name in the same directory and is renamed into
place, which is atomic on POSIX file systems: a killed process leaves either the
old state or the complete new file, plus at most a stray temporary.

A temporary name is short and of fixed length (`.<hash of the final name>.<host>.<pid>.<n>.partial`,
about 50 bytes), so it fits wherever the final name fits, and it belongs to one write
of one process, so two processes (or threads) writing the same file at once never
rename or delete each other's half-written file. It is hidden and ends in `.partial`,
so no listing of outputs (`*.png`, a stage's named files) takes it for one. A stray
left by a process of this machine that has died is removed when its renderloop
directory is next claimed (`ownership.claim`), or, for a staged directory, when the
same directory is next written.
"""

from __future__ import annotations

import hashlib
import itertools
import json
import os
import re
import shutil
import socket
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

from renderloop.io import ownership

TEMP_SUFFIX = ".partial"
# The machine in each temporary name: a process id says whether its writer still lives only on the machine it ran on.
_HOST = hashlib.sha1(socket.gethostname().encode("utf-8", "surrogateescape")).hexdigest()[:8]
_TEMPORARY = re.compile(r"\.([0-9a-f]{16})\.([0-9a-f]{8})\.([0-9]+)\.([0-9a-f]+)" + re.escape(TEMP_SUFFIX))
_counter = itertools.count()  # next() on it is atomic under the GIL: each thread's temporaries differ too
# The final path of each temporary this process has made and not yet renamed into place: an error about a temporary
# (raised inside a write, or caught by the command line) names the file the user asked for instead.
_finals: dict[Path, Path] = {}


def _digest(name: str) -> str:
    return hashlib.sha1(os.fsencode(name)).hexdigest()[:16]


def temporary_path(path: Path) -> Path:
    """A new hidden name beside `path` for this one write: no other write, here or in another process, gets it."""
    path = Path(path)
    tmp = path.with_name(f".{_digest(path.name)}.{_HOST}.{os.getpid()}.{next(_counter):x}{TEMP_SUFFIX}")
    _finals[tmp] = path
    return tmp


def final_path(path: Path) -> Path:
    """The file a temporary name (or a file inside a staged directory) stands for: what an error message should name."""
    path = Path(path)
    for prefix in (path, *path.parents):
        final = _finals.get(prefix)
        if final is not None:
            return final / path.relative_to(prefix)
    return path


def stray(path: Path) -> bool:
    """Whether `path` is a temporary that a process of this machine left when it died: nothing will rename it."""
    match = _TEMPORARY.fullmatch(Path(path).name)
    if match is None or match[2] != _HOST:
        return False  # not ours, or another machine's (whose processes cannot be asked from here)
    pid = int(match[3])
    if pid == os.getpid():
        return False
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return True
    except (OSError, OverflowError):  # alive under another user, or not a number a process can have
        return False
    return False


def _naming(error: OSError, tmp: Path, path: Path) -> OSError:
    """`error` naming `path` where it named the temporary or nothing (a write through a file object from numpy or PIL
    does not say which file failed)."""
    named = error.filename
    if named is None or (isinstance(named, (str, bytes, os.PathLike)) and Path(os.fsdecode(named)) == tmp):
        return OSError(error.errno, error.strerror, str(path))
    return error


@contextmanager
def replaced(path: Path) -> Iterator[Path]:
    """Yield a temporary path to write to; rename it onto `path` only if the block succeeds (nothing is recorded)."""
    path = Path(path)
    tmp = temporary_path(path)
    try:
        yield tmp
        with open(tmp, "rb") as written:
            os.fsync(written.fileno())
        os.replace(tmp, path)
    except OSError as error:
        tmp.unlink(missing_ok=True)
        renamed = _naming(error, tmp, path)
        if renamed is not error:
            raise renamed from error
        raise
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise
    finally:
        _finals.pop(tmp, None)  # any error about it names `path` already


@contextmanager
def atomic_path(path: Path) -> Iterator[Path]:
    """Yield a temporary path to write to; rename it onto `path` only if the block succeeds.

    Inside a directory renderloop owns, the file is recorded as ours first (and a file there that is not ours is refused,
    as is a path that leads out of that directory through a link).
    """
    path = Path(path)
    ownership.record(path)
    with replaced(path) as tmp:
        yield tmp


def _clear_stray_stagings(path: Path) -> None:
    """Remove the staging folders for `path` that writers killed on this machine left beside it."""
    prefix = f".{_digest(path.name)}."
    try:
        entries = [entry for entry in os.scandir(path.parent) if entry.name.startswith(prefix)]
    except OSError:
        return
    for entry in entries:
        if entry.is_dir(follow_symlinks=False) and stray(Path(entry.path)):
            shutil.rmtree(entry.path, ignore_errors=True)


@contextmanager
def atomic_directory(path: Path, kind: str) -> Iterator[Path]:
    """Yield a path for a new directory (which does not exist yet) that appears at `path` only when the block succeeds.

    The directory is built inside a hidden staging folder beside `path` and renamed out,
    so it keeps its own name inside (a ROS 2 bag names its files after its folder). It is
    marked as a renderloop directory of `kind`; an existing `path` is replaced only if it
    carries that mark, and only once the new one is complete.
    """
    path = Path(path)
    if path.is_symlink() and path.is_dir():
        # the user's link stays and leads to the new directory: the one it leads to is the one replaced
        path = Path(os.path.realpath(path))
    _clear_stray_stagings(path)
    staging = temporary_path(path)
    staging.mkdir(parents=True)  # a fresh name: nothing there to clear first
    built = staging / path.name
    _finals[built] = path
    try:
        yield built
        ownership.replace_directory(built, path, kind)
    finally:
        shutil.rmtree(staging, ignore_errors=True)
    _finals.pop(staging, None)
    _finals.pop(built, None)


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
