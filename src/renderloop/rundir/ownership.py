"""Which directories renderloop owns, and which files in them it wrote.

A directory renderloop writes into (a run, a dataset, an evaluation, a ROS bag) holds a
small mark file, `.renderloop.json`, with the kind of directory and the format
version. renderloop writes only into a directory that does not exist, is empty, or
carries the mark of the same kind; any other directory is refused before anything is
written, so a user's folder that happens to hold `rgb/` and `groundtruth.txt` (the
TUM RGB-D layout) is never mixed with ours.

Inside an owned directory, `.renderloop-files` lists every file renderloop wrote, one
path a line relative to the directory, appended before the file is renamed into
place (a kill between the two leaves a listed file that does not exist, which is
harmless; the other order could leave one of ours unlisted). Starting over removes
only listed files, and renderloop refuses to replace a file at one of its own names
that it did not write. A user's notes beside our outputs stay, `--force` or not.

Runs and datasets written before the mark existed are adopted when they are plainly
ours: their key file parses as renderloop's and every entry has one of our names.
"""

from __future__ import annotations

import json
import os
import shutil
from collections.abc import Callable, Iterable
from pathlib import Path

from pydantic import BaseModel, ConfigDict, ValidationError

from renderloop.errors import UserError

MARK = ".renderloop.json"
LEDGER = ".renderloop-files"
FORMAT_VERSION = 1
BOOKKEEPING = frozenset({MARK, LEDGER})
# The kinds of directory renderloop writes: a verb writes only into its own kind.
RUN, DATASET, EVAL, BAG = "run", "dataset", "evaluation", "ROS 2 bag"
PHOTO_SCORE = "photo score"  # `score-photos`: the detector scored on the user's labelled photos
# How far below an owned directory renderloop writes (run/rgb/000000.png, eval/seed_3/...): the search for
# the owner of a written file stops there, so a write elsewhere on the disk costs a few stat calls only.
MAX_DEPTH = 3


class Mark(BaseModel):
    """The mark file's content: what kind of directory this is and which format wrote it."""

    model_config = ConfigDict(extra="forbid", frozen=True)
    renderloop: int  # the format version of the directory's files
    kind: str


class _Ledger:
    """The recorded files of one owned directory, read once and appended to; read again when another
    process (or a start-over) has changed the file since."""

    def __init__(self, root: Path) -> None:
        self.path = root / LEDGER
        names = read_ledger(root)
        if self.path.is_file() and not self.path.read_bytes().endswith(b"\n") and self.path.stat().st_size:
            _write_ledger(root, names)  # a torn last line is dropped before anything is appended after it
        self.names = set(names)
        self.stamp = self._stamp()

    def _stamp(self) -> tuple[int, int, int] | None:
        try:
            stat = self.path.stat()
        except FileNotFoundError:
            return None
        return stat.st_ino, stat.st_size, stat.st_mtime_ns

    def current(self) -> bool:
        return self._stamp() == self.stamp

    def add(self, name: str) -> None:
        if name not in self.names:
            with open(self.path, "a", encoding="utf-8") as ledger:
                ledger.write(name + "\n")
            self.names.add(name)
            self.stamp = self._stamp()


_ledgers: dict[Path, _Ledger] = {}


def read_ledger(root: Path) -> list[str]:
    """The files the ledger lists; a torn last line (a kill mid-append) is not a name we can trust, so it is dropped."""
    try:
        text = (Path(root) / LEDGER).read_text(encoding="utf-8")
    except FileNotFoundError:
        return []
    except (OSError, UnicodeDecodeError):
        raise UserError(f"{Path(root) / LEDGER}: not a readable renderloop file list") from None
    lines = text.split("\n")
    return list(dict.fromkeys(line for line in lines[:-1] if line))


def read_mark(directory: Path) -> Mark | None:
    path = Path(directory) / MARK
    if not path.is_file():
        return None
    try:
        return Mark.model_validate_json(path.read_bytes())
    except (OSError, ValidationError):
        raise UserError(f"{path}: not a renderloop mark file; this directory is not one renderloop can use") from None


def _write_mark(directory: Path, kind: str) -> None:
    tmp = directory / f"{MARK}.partial"
    tmp.write_text(json.dumps({"renderloop": FORMAT_VERSION, "kind": kind}) + "\n", encoding="utf-8")
    os.replace(tmp, directory / MARK)


def _write_ledger(directory: Path, listed: list[str]) -> None:
    tmp = directory / f"{LEDGER}.partial"
    tmp.write_text("".join(name + "\n" for name in listed), encoding="utf-8")
    os.replace(tmp, directory / LEDGER)


def _files_under(directory: Path, names: Iterable[str]) -> list[str]:
    found = []
    for name in names:
        path = directory / name
        if path.is_file():
            found.append(name)
        elif path.is_dir():
            found += sorted(p.relative_to(directory).as_posix() for p in path.rglob("*") if p.is_file())
    return found


def claim(directory: Path, kind: str, adopt: Callable[[Path], bool] | None = None, write: bool = True) -> Path:
    """Make `directory` ours to write into, or refuse it in one line before anything is written.

    `adopt` says whether a directory without the mark is one renderloop made before the mark existed.
    With `write` false the directory is only checked (nothing is created or marked), for a verb that
    must first make sure its input is good.
    """
    directory = Path(directory)
    if directory.exists() and not directory.is_dir():
        raise UserError(f"{directory}: is a file, not a directory")
    if not directory.exists():
        if write:
            directory.mkdir(parents=True)
            _write_mark(directory, kind)
        return directory
    mark = read_mark(directory)
    if mark is not None:
        if mark.kind != kind:
            raise UserError(f"{directory}: a renderloop {mark.kind} directory, not a {kind} directory; give another path")
        if mark.renderloop > FORMAT_VERSION:
            raise UserError(f"{directory}: written by a newer renderloop (format {mark.renderloop}); update renderloop")
        return directory
    entries = [entry.name for entry in directory.iterdir()]
    if entries and not (adopt is not None and adopt(directory)):
        raise UserError(f"{directory}: not empty and not made by renderloop (no {MARK}); give a new or empty directory")
    if not write:
        return directory
    if entries:  # an older renderloop's directory: everything in it is ours
        with open(directory / LEDGER, "a", encoding="utf-8") as ledger:
            ledger.writelines(name + "\n" for name in _files_under(directory, entries) if name not in BOOKKEEPING)
    _write_mark(directory, kind)
    return directory


def owner_of(path: Path) -> Path | None:
    """The nearest owned directory above `path`, at most MAX_DEPTH levels up."""
    parent = Path(path).parent
    for _ in range(MAX_DEPTH):
        if (parent / MARK).is_file():
            return parent
        if parent.parent == parent:
            break
        parent = parent.parent
    return None


def _ledger(root: Path) -> _Ledger:
    ledger = _ledgers.get(root)
    if ledger is None or not ledger.current():
        ledger = _ledgers[root] = _Ledger(root)
    return ledger


def record(path: Path) -> None:
    """Note that renderloop is about to write `path`; refuse to replace a file of an owned directory that it did not write."""
    path = Path(path).absolute()
    root = owner_of(path)
    if root is None:
        return
    name = path.relative_to(root).as_posix()
    ledger = _ledger(root)
    if name not in ledger.names and path.exists():
        raise UserError(f"{path}: exists and renderloop did not write it; move it away or choose another directory")
    ledger.add(name)


def remove_recorded(directory: Path, names: Iterable[str]) -> None:
    """Delete the files renderloop recorded under each of `names` (files or folders of `directory`), then the folders
    left empty; nothing that is not listed is removed."""
    directory = Path(directory).absolute()
    prefixes = tuple(names)
    listed = read_ledger(directory)
    gone = [name for name in listed if name in prefixes or name.startswith(tuple(f"{p}/" for p in prefixes))]
    for name in gone:
        (directory / name).unlink(missing_ok=True)
    for prefix in prefixes:
        folder = directory / prefix
        if folder.is_dir():
            for sub in sorted((p for p in folder.rglob("*") if p.is_dir()), key=lambda p: len(p.parts), reverse=True):
                if not any(sub.iterdir()):
                    sub.rmdir()
            if not any(folder.iterdir()):
                folder.rmdir()
    removed = set(gone)
    _write_ledger(directory, [name for name in listed if name not in removed])
    _ledgers.pop(directory, None)


def check_replaceable(target: Path, kind: str) -> None:
    """An existing `target` may be replaced whole only if it is a renderloop directory of this kind."""
    if Path(target).exists():
        mark = read_mark(target) if Path(target).is_dir() else None
        if mark is None or mark.kind != kind:
            raise UserError(f"{target}: exists and is not a renderloop {kind}; give another path")


def replace_directory(staged: Path, target: Path, kind: str) -> None:
    """Move a finished directory built at `staged` to `target`; an existing `target` is replaced only if it is a
    renderloop directory of this kind (a user's folder of the same name is refused, never deleted)."""
    staged, target = Path(staged), Path(target)
    _write_mark(staged, kind)
    check_replaceable(target, kind)
    if target.exists():
        old = staged.parent / f"{target.name}.old"
        os.replace(target, old)
        try:
            os.replace(staged, target)
        except OSError:
            os.replace(old, target)  # the earlier one stays rather than nothing
            raise
        shutil.rmtree(old)
        return
    os.replace(staged, target)
