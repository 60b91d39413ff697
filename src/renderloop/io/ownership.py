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

What renderloop writes or deletes inside an owned directory stays inside it: each path
is resolved (links followed) and compared with the resolved directory, so a folder of
a run that is a link to a user's folder (`rgb -> ~/photos`), or a listed name that
climbs out (`rgb/../../elsewhere`, an absolute path), is refused in one line and
nothing outside is written, created or deleted. The path given for the directory
itself may pass through links (`/tmp -> /private/tmp`): only what lies below it is held
to it.
"""

from __future__ import annotations

import contextlib
import errno
import json
import os
import shutil
from collections.abc import Iterable
from pathlib import Path, PurePosixPath

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


def _real(path: Path | str) -> Path:
    return Path(os.path.realpath(path))


def _within(real: Path, root: Path) -> bool:
    """Whether the resolved `real` is the resolved `root` or lies below it."""
    return real == root or real.is_relative_to(root)


def _append(path: Path, lines: Iterable[str]) -> None:
    """Append to a bookkeeping file; one that is a link is refused, so the append never lands outside."""
    try:
        fd = os.open(path, os.O_WRONLY | os.O_APPEND | os.O_CREAT | os.O_NOFOLLOW, 0o666)
    except OSError as error:
        if error.errno == errno.ELOOP:
            raise UserError(f"{path}: a link, not renderloop's file list; move it away") from None
        raise
    with open(fd, "a", encoding="utf-8") as out:
        out.writelines(line + "\n" for line in lines)


class _Ledger:
    """The recorded files of one owned directory (by its resolved path), read once and appended to; read again when
    another process (or a start-over) has changed the file since."""

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
            _append(self.path, [name])
            self.names.add(name)
            self.stamp = self._stamp()


_ledgers: dict[Path, _Ledger] = {}


def _check_name(root: Path, name: str) -> str:
    """A listed name is a relative path that stays below the directory; anything else is a file list not to act on."""
    parts = PurePosixPath(name).parts
    if name.startswith("/") or not parts or ".." in parts or "\0" in name:
        raise UserError(f"{Path(root) / LEDGER}: lists {name!r}, which is not a path inside {root}; "
                        "renderloop touches nothing outside the directory it owns (remove that line)")
    return name


def read_ledger(root: Path) -> list[str]:
    """The files the ledger lists; a torn last line (a kill mid-append) is not a name we can trust, so it is dropped.
    A name that is absolute or climbs out with `..` is refused here, before anything acts on it."""
    try:
        text = (Path(root) / LEDGER).read_text(encoding="utf-8")
    except FileNotFoundError:
        return []
    except (OSError, UnicodeDecodeError):
        raise UserError(f"{Path(root) / LEDGER}: not a readable renderloop file list") from None
    lines = text.split("\n")
    return list(dict.fromkeys(_check_name(root, line) for line in lines[:-1] if line))


def read_mark(directory: Path) -> Mark | None:
    path = Path(directory) / MARK
    if not path.is_file():
        return None
    try:
        return Mark.model_validate_json(path.read_bytes())
    except (OSError, ValidationError):
        raise UserError(f"{path}: not a renderloop mark file; this directory is not one renderloop can use") from None


def _replace_text(path: Path, text: str) -> None:
    # atomic records its writes through this module, so it is imported here, when first needed
    from renderloop.io.atomic import replaced

    with replaced(path) as tmp:
        tmp.write_text(text, encoding="utf-8")


def _write_mark(directory: Path, kind: str) -> None:
    _replace_text(directory / MARK, json.dumps({"renderloop": FORMAT_VERSION, "kind": kind}) + "\n")


def _write_ledger(directory: Path, listed: list[str]) -> None:
    _replace_text(directory / LEDGER, "".join(name + "\n" for name in listed))


def _clear_strays(root: Path) -> None:
    """Remove the temporaries that processes of this machine left here when they were killed (a directory that carries
    its own mark is left to its own claim)."""
    from renderloop.io.atomic import TEMP_SUFFIX, stray

    for folder, folders, files in os.walk(root):
        depth = len(Path(folder).relative_to(root).parts)
        folders[:] = [] if depth >= MAX_DEPTH - 1 else [f for f in folders if not os.path.isfile(os.path.join(folder, f, MARK))]
        for file in files:
            path = Path(folder, file)
            if file.startswith(".") and file.endswith(TEMP_SUFFIX) and not path.is_symlink() and stray(path):
                path.unlink(missing_ok=True)


def claim(directory: Path, kind: str, write: bool = True) -> Path:
    """Make `directory` ours to write into, or refuse it in one line before anything is written.

    With `write` false the directory is only checked (nothing is created or marked), for a verb that
    must first make sure its input is good. One inside another owned directory (an evaluation's runs)
    must not lead out of it through a link. Claimed to write, an owned directory loses the temporaries
    that killed writers of this machine left in it (see `renderloop.io.atomic`).
    """
    directory = Path(directory)
    _contained(directory)
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
        if write:
            _clear_strays(directory)
        return directory
    if any(directory.iterdir()):
        raise UserError(f"{directory}: not empty and not made by renderloop (no {MARK}); give a new or empty directory")
    if not write:
        return directory
    _write_mark(directory, kind)
    return directory


def _plain(path: Path) -> Path:
    """`path` made absolute with each `..` resolved as the file system resolves it (through links), the rest as given:
    the directories above the rest are the ones the path really passes through."""
    path = Path(path).absolute()
    parts = path.parts
    if ".." not in parts:
        return path
    last = len(parts) - 1 - parts[::-1].index("..")
    return _real(Path(*parts[: last + 1])).joinpath(*parts[last + 1:])


def _owners(path: Path) -> list[Path]:
    """The owned directories above `path`, nearest first, at most MAX_DEPTH levels up."""
    found, parent = [], path.parent
    for _ in range(MAX_DEPTH):
        if (parent / MARK).is_file():
            found.append(parent)
        if parent.parent == parent:
            break
        parent = parent.parent
    return found


def _contained(path: Path) -> tuple[Path, Path, str] | None:
    """For a path inside an owned directory: the directory as given, its resolved path, and the path's name in it.

    The path and the folder it is in must resolve inside every owned directory above it, so that nothing written
    there (the file, its temporary beside it) lands outside through a link; otherwise it is refused in one line.
    None when no owned directory is above the path.
    """
    path = _plain(path)
    owners = _owners(path)
    if not owners:
        return None
    real, folder = _real(path), _real(path.parent)
    for root in owners:
        real_root = _real(root)
        if not (_within(real, real_root) and _within(folder, real_root)):
            leads = real if not _within(real, real_root) else folder
            raise UserError(f"{path}: leads out of {root} through a link (to {leads}); "
                            "renderloop writes nothing outside the directory it owns")
    root = owners[0]
    real_root = _real(root)
    return root, real_root, (folder / path.name).relative_to(real_root).as_posix()


def _ledger(root: Path) -> _Ledger:
    ledger = _ledgers.get(root)
    if ledger is None or not ledger.current():
        ledger = _ledgers[root] = _Ledger(root)
    return ledger


def record(path: Path) -> Path | None:
    """Note that renderloop is about to write `path`; refuse to replace a file of an owned directory that it did not
    write, and a path that leads out of that directory through a link. The owned directory, or None outside any."""
    found = _contained(path)
    if found is None:
        return None
    root, real_root, name = found
    ledger = _ledger(real_root)
    if name not in ledger.names and os.path.lexists(real_root / name):  # a dangling link at our name is not ours either
        raise UserError(f"{_plain(path)}: exists and renderloop did not write it; move it away or choose another directory")
    ledger.add(name)
    return root


def remove_recorded(directory: Path, names: Iterable[str]) -> None:
    """Delete the files renderloop recorded under each of `names` (files or folders of `directory`), then the folders
    left empty; nothing that is not listed is removed, and nothing outside `directory`: a listed file that a link
    leads out of it refuses the whole removal before anything is deleted."""
    shown = Path(directory).absolute()
    root = _real(shown)
    prefixes = tuple(names)
    listed = read_ledger(shown)
    gone = [name for name in listed if name in prefixes or name.startswith(tuple(f"{p}/" for p in prefixes))]
    for name in gone:
        path = root / name
        for leads in (_real(path.parent), _real(path)):
            if not _within(leads, root):
                raise UserError(f"{shown / LEDGER}: lists {name}, which leads out of {shown} through a link (to {leads}); "
                                "renderloop deletes nothing outside the directory it owns")
    for name in gone:
        path = root / name
        if path.is_symlink() or not path.is_dir():
            path.unlink(missing_ok=True)
    for prefix in prefixes:
        folder = root / prefix
        if folder.is_symlink() or not folder.is_dir() or not _within(_real(folder), root):
            continue  # a link is not entered: the folders it leads to are not ours to remove
        for parent, folders, _ in os.walk(folder, topdown=False):  # the deepest first; links are not followed
            for sub in folders:
                if not os.path.islink(os.path.join(parent, sub)):
                    with contextlib.suppress(OSError):  # not empty (the user's file, or another process's): it stays
                        os.rmdir(os.path.join(parent, sub))
        with contextlib.suppress(OSError):
            folder.rmdir()
    removed = set(gone)
    _write_ledger(root, [name for name in listed if name not in removed])
    _ledgers.pop(root, None)


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
    if target.is_symlink():  # moving a link aside and deleting "it" would delete what it leads to
        raise UserError(f"{target}: a link; give the directory it leads to")
    if target.exists():
        old = staged.parent / ("old" if staged.name != "old" else "old-")  # inside the staging folder, removed with it
        os.replace(target, old)
        try:
            os.replace(staged, target)
        except OSError:
            os.replace(old, target)  # the earlier one stays rather than nothing
            raise
        shutil.rmtree(old)
        return
    os.replace(staged, target)
