"""Fuzzing the files of a run directory: whatever a damaged file holds, its reader, and a verb that reads it, end in
one UserError line naming the file (exit 2 from the CLI) or read it fine, every number finite; never another
exception. Nothing outside the run directory changes: a sentinel tree beside the run is hashed before and after.

The mutations are what a disk, a crash or a hand edit does to a file: truncation, a number made NaN, infinite,
huge, negative or of another type, nesting thousands deep, random bytes, lines lost or repeated. Hypothesis draws
them derandomized (the same examples every run) and few, so the harness takes seconds: the readers take most
examples, the CLI a handful, and the ledger (`.renderloop-files`) gets the paths that climb out of the run.
"""

from __future__ import annotations

import dataclasses
import hashlib
import math
import re
import shutil
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest
from conftest import cli
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from pydantic import BaseModel

from renderloop.errors import UserError
from renderloop.export import contents
from renderloop.planning.waypoints import read_waypoints
from renderloop.render.camera import read_camera_info
from renderloop.rundir import files, names
from renderloop.io.ownership import LEDGER
from renderloop.scene.model import read_scene

Reader = Callable[[Path], object]

# Every file of a run that a verb parses, with its reader.
READERS: dict[str, Reader] = {
    names.SCENE: read_scene,
    names.CONFIG: files.read_config,
    names.WAYPOINTS: read_waypoints,
    names.TRAJECTORY: files.read_trajectory,
    names.FLIGHT: files.read_flight,
    names.POSES: files.read_poses,
    names.CAMERA_INFO: read_camera_info,
    names.DETECTIONS: lambda run: files.read_detections(run, len(files.read_poses(run)[0])),
    names.DETECTION_SCORES: files.read_detection_scores,
    names.COUNTS: files.read_counts,
    names.HARVEST: files.read_harvest,
    names.TIMINGS: files.read_timings,
}
# A verb that reads each (report reads most; the exporters read the plan through export.contents).
VERBS: dict[str, tuple[str, ...]] = {
    **dict.fromkeys((names.SCENE, names.CONFIG, names.POSES, names.FLIGHT, names.CAMERA_INFO, names.DETECTIONS,
                     names.COUNTS, names.HARVEST), ("report", "{run}")),
    **dict.fromkeys((names.WAYPOINTS, names.TRAJECTORY), ("export", "{run}", "--rerun", "{out}/run.rrd", "--every", "1000")),
}

NUMBER = re.compile(rb"-?\d+(?:\.\d+)?(?:[eE][+-]?\d+)?")
REPLACEMENTS = [
    b"NaN", b"nan", b".nan", b"Infinity", b"-Infinity", b"inf", b"-inf", b".inf", b"-.inf",
    b"1e308", b"-1e308", b"1e300", b"1.0e400", b"1e-320", b"-1", b"-1e9", b"0", b"0.5", b"99999999999999999999999",
    b"9" * 5000, b'"x"', b"x", b"true", b"null", b"[]", b"{}", b"", b"1,2", b"\n", b"\x00", b"\xff\xfe",
]


def _hash_tree(root: Path) -> str:
    digest = hashlib.sha1()
    for path in sorted(root.rglob("*")):
        digest.update(path.relative_to(root).as_posix().encode())
        if path.is_file() and not path.is_symlink():
            digest.update(hashlib.sha1(path.read_bytes()).digest())
    return digest.hexdigest()


@dataclasses.dataclass
class Workspace:
    pristine: Path  # the complete run, never changed
    run: Path  # the run the mutations are written into, beside the sentinel
    sentinel: Path  # files a verb must never touch
    out: Path  # where a verb's own output outside the run goes
    originals: dict[str, bytes]
    numbers: dict[str, list[tuple[int, int]]]  # spans of the numbers of each file
    sentinel_hash: str

    def fresh_run(self) -> Path:
        shutil.rmtree(self.run)
        shutil.copytree(self.pristine, self.run, symlinks=True)
        shutil.rmtree(self.out, ignore_errors=True)
        self.out.mkdir()
        return self.run

    def untouched(self) -> bool:
        return _hash_tree(self.sentinel) == self.sentinel_hash


@pytest.fixture(scope="module")
def workspace(complete_run: Path, tmp_path_factory) -> Workspace:
    root = tmp_path_factory.mktemp("fuzz")
    pristine, run, sentinel, out = root / "pristine", root / "run", root / "sentinel", root / "out"
    shutil.copytree(complete_run, pristine)
    files.record_timing(pristine, "scene", 1.5)  # what `renderloop run` adds
    shutil.copytree(pristine, run)
    sentinel.mkdir()
    (sentinel / "keep.txt").write_text("the user's notes\n")
    (sentinel / names.frame_file(names.RGB, 0)).parent.mkdir()
    for index in range(3):  # a folder that looks like a run's frames
        shutil.copy(complete_run / names.frame_file(names.RGB, index), sentinel / names.frame_file(names.RGB, index))
    out.mkdir()
    originals = {name: (run / name).read_bytes() for name in READERS}
    numbers = {name: [match.span() for match in NUMBER.finditer(data)] for name, data in originals.items()}
    return Workspace(pristine, run, sentinel, out, originals, numbers, _hash_tree(sentinel))


@st.composite
def mutations(draw: st.DrawFn, original: bytes, numbers: list[tuple[int, int]]) -> bytes:
    """`original` as a disk, a crash or a hand edit may leave it."""
    kind = draw(st.sampled_from(["number", "number", "number", "nest", "truncate", "bytes", "noise", "lines"]))
    if kind in ("number", "nest") and numbers:
        start, end = numbers[draw(st.integers(0, len(numbers) - 1))]
        token = original[start:end]
        if kind == "number":
            token = draw(st.sampled_from(REPLACEMENTS))
        else:
            depth = draw(st.sampled_from([63, 64, 65, 300, 5000]))
            token = b"[" * depth + token + b"]" * depth
        return original[:start] + token + original[end:]
    if kind == "truncate":
        return original[:draw(st.integers(0, max(len(original) - 1, 0)))]
    if kind == "bytes":
        return draw(st.binary(max_size=256))
    if kind == "noise":
        start = draw(st.integers(0, len(original)))
        return original[:start] + draw(st.binary(min_size=1, max_size=32)) + original[start + draw(st.integers(0, 32)):]
    lines = original.split(b"\n")
    index = draw(st.integers(0, len(lines) - 1))
    action = draw(st.sampled_from(["drop", "repeat", "swap", "nest"]))
    if action == "drop":
        del lines[index]
    elif action == "repeat":
        lines.insert(index, lines[index])
    elif action == "swap":
        other = draw(st.integers(0, len(lines) - 1))
        lines[index], lines[other] = lines[other], lines[index]
    else:  # the whole document thousands deep, as JSON arrays or YAML block mappings
        return b"[" * 5000 + original + b"]" * 5000 if original[:1] in (b"{", b"[") else \
            b"".join(b"  " * level + b"a:\n" for level in range(3000)) + original
    return b"\n".join(lines)


def _all_finite(value: object) -> bool:
    """Every number of what a reader returned is finite (arrays, models, dataclasses, containers)."""
    if isinstance(value, BaseModel):
        return _all_finite(value.model_dump())
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return _all_finite(vars(value))
    if isinstance(value, np.ndarray):
        return value.dtype.kind not in "fc" or bool(np.isfinite(value).all())
    if isinstance(value, float):
        return math.isfinite(value)
    if isinstance(value, dict):
        return all(_all_finite(v) for v in value.values())
    if isinstance(value, (list, tuple)):
        return all(_all_finite(v) for v in value)
    return True


def _check_reader(workspace: Workspace, name: str, damaged: bytes) -> None:
    path = workspace.run / name
    path.write_bytes(damaged)
    try:
        value = READERS[name](workspace.run)
    except UserError as error:
        message = str(error)
        assert "\n" not in message and name in message, message
    else:
        assert _all_finite(value)
    finally:
        path.write_bytes(workspace.originals[name])
    assert workspace.untouched()


@pytest.mark.parametrize("name", list(READERS))
@settings(max_examples=25, deadline=None, derandomize=True, database=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow, HealthCheck.data_too_large])
@given(data=st.data())
def test_a_damaged_run_file_reads_fine_or_is_one_user_error_naming_it(workspace: Workspace, name: str, data: st.DataObject):
    damaged = data.draw(mutations(workspace.originals[name], workspace.numbers[name]), label="damaged")
    _check_reader(workspace, name, damaged)


def test_every_reader_reads_the_undamaged_run(workspace: Workspace):
    for name in READERS:
        _check_reader(workspace, name, workspace.originals[name])
    assert contents.read_run(workspace.run).missing == []


@settings(max_examples=10, deadline=None, derandomize=True, database=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow, HealthCheck.data_too_large])
@given(data=st.data())
def test_a_verb_given_a_damaged_run_file_exits_2_in_one_line_or_succeeds(workspace: Workspace, monkeypatch, capsys,
                                                                       data: st.DataObject):
    name = data.draw(st.sampled_from(sorted(VERBS)), label="file")
    damaged = data.draw(mutations(workspace.originals[name], workspace.numbers[name]), label="damaged")
    run = workspace.fresh_run()
    (run / name).write_bytes(damaged)
    args = [arg.format(run=run, out=workspace.out) for arg in VERBS[name]]
    try:
        code, _, err = cli(monkeypatch, capsys, *args)
    finally:
        workspace.fresh_run()

    assert "Traceback" not in err, err
    if code != 0:
        lines = [line for line in err.splitlines() if line.strip()]
        assert code == 2 and len(lines) == 1 and lines[0].startswith("renderloop: error: ") and name in lines[0], err
    assert workspace.untouched()


# The ledger: names that climb out of the run ---------------------------------------------------------------------

def _ledger_lists(*lines: str) -> Callable[[Workspace], None]:
    def damage(workspace: Workspace) -> None:
        with open(workspace.run / LEDGER, "a", encoding="utf-8") as ledger:
            ledger.writelines(f"{line}\n" for line in lines)
    return damage


def _relative_escape(workspace: Workspace) -> None:
    _ledger_lists(f"rgb/../../{workspace.sentinel.name}/keep.txt")(workspace)


def _absolute(workspace: Workspace) -> None:
    _ledger_lists(str(workspace.sentinel / names.frame_file(names.RGB, 0)))(workspace)


def _linked_folder(workspace: Workspace) -> None:
    """rgb/ is a link to the sentinel's look-alike frames; the ledger lists rgb/000000.png as ever."""
    shutil.rmtree(workspace.run / names.RGB)
    (workspace.run / names.RGB).symlink_to(workspace.sentinel / names.RGB, target_is_directory=True)


def _linked_file(workspace: Workspace) -> None:
    frame = workspace.run / names.frame_file(names.RGB, 1)
    frame.unlink()
    frame.symlink_to(workspace.sentinel / "keep.txt")


LEDGER_CASES = {"listed-dotdot": _relative_escape, "listed-absolute": _absolute, "rgb-links-out": _linked_folder,
                "frame-links-out": _linked_file}


@pytest.mark.parametrize("damage", list(LEDGER_CASES.values()), ids=list(LEDGER_CASES))
def test_starting_a_stage_over_never_deletes_outside_the_run(workspace: Workspace, monkeypatch, capsys, damage):
    """`render --force` removes the files the ledger lists: a listed name or a link that leads out of the run is
    refused in one line (or left alone), and the sentinel beside the run stays as it was."""
    run = workspace.fresh_run()
    damage(workspace)
    try:
        code, _, err = cli(monkeypatch, capsys, "render", str(run), "--force")
    finally:
        workspace.fresh_run()  # the readers' tests expect the run undamaged

    assert "Traceback" not in err, err
    assert code in (0, 2), err
    if code == 2:
        lines = [line for line in err.splitlines() if line.strip()]
        assert len(lines) == 1 and lines[0].startswith("renderloop: error: "), err
    assert workspace.untouched()
