"""What renderloop writes or deletes inside a directory it owns stays inside it, and its temporary names are short and
its own: a long legal name is written, and two processes writing one file at once do not trip over each other."""

from __future__ import annotations

import errno
import hashlib
import os
import shutil
import subprocess
import sys
import time
from pathlib import Path

import pytest
from conftest import cli

from renderloop.errors import UserError
from renderloop.io import atomic
from renderloop.io import ownership


def _tree(folder: Path) -> dict[str, bytes]:
    return {p.relative_to(folder).as_posix(): p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()}


def _sha1(path: Path) -> str:
    return hashlib.sha1(path.read_bytes()).hexdigest()


@pytest.fixture
def run(complete_run: Path, tmp_path: Path) -> Path:
    copy = tmp_path / "run"
    shutil.copytree(complete_run, copy)
    return copy


@pytest.fixture
def sentinel(tmp_path: Path) -> Path:
    """A user's file beside the run, at the place a tampered file list points to."""
    path = tmp_path / "elsewhere" / "file"
    path.parent.mkdir()
    path.write_bytes(b"the user's only copy")
    return path


@pytest.mark.parametrize("climbing", [True, False], ids=["dot-dot", "absolute"])
def test_a_listed_name_that_leaves_the_run_is_refused_by_render_force_and_nothing_outside_is_deleted(
        climbing: bool, run: Path, sentinel: Path, monkeypatch, capsys):
    name = "rgb/../../elsewhere/file" if climbing else str(sentinel)
    with open(run / ownership.LEDGER, "a", encoding="utf-8") as ledger:
        ledger.write(name + "\n")
    before = _sha1(sentinel)
    code, _, stderr = cli(monkeypatch, capsys, "render", str(run), "--force")
    assert code == 2 and stderr.count("\n") == 1 and "Traceback" not in stderr, stderr
    assert name in stderr and ownership.LEDGER in stderr
    assert sentinel.is_file() and _sha1(sentinel) == before
    assert (run / "rgb" / "000000.png").is_file()  # refused before anything was removed


def test_a_listed_file_that_a_link_leads_out_of_the_directory_is_not_deleted(tmp_path: Path):
    run = ownership.claim(tmp_path / "run", ownership.RUN)
    (run / "rgb").mkdir()
    ownership.record(run / "rgb" / "000000.png")
    (run / "rgb" / "000000.png").write_bytes(b"ours")
    photos = tmp_path / "photos"
    photos.mkdir()
    (photos / "000000.png").write_bytes(b"the user's photo")
    shutil.rmtree(run / "rgb")
    (run / "rgb").symlink_to(photos)  # the user put a link where our folder was
    with pytest.raises(UserError, match=r"lists rgb/000000.png, which leads out of .* through a link") as refused:
        ownership.remove_recorded(run, ("rgb",))
    assert "\n" not in str(refused.value)
    assert _tree(photos) == {"000000.png": b"the user's photo"}
    assert ownership.read_ledger(run) == ["rgb/000000.png"]  # nothing was removed, not even from the list


def test_a_run_folder_that_is_a_link_to_the_users_folder_is_refused_by_render_force_and_left_as_it_was(
        run: Path, tmp_path: Path, monkeypatch, capsys):
    photos = tmp_path / "photos"
    shutil.copytree(run / "rgb", photos)  # the user's own pictures, under our frame names
    (photos / "000000.png").write_bytes(b"the user's holiday")
    shutil.rmtree(run / "rgb")
    (run / "rgb").symlink_to(photos)
    before = _tree(photos)
    code, _, stderr = cli(monkeypatch, capsys, "render", str(run), "--force")
    assert code == 2 and stderr.count("\n") == 1 and "Traceback" not in stderr, stderr
    assert "rgb/000000.png" in stderr and "through a link" in stderr
    assert _tree(photos) == before and sorted(p.name for p in photos.iterdir()) == sorted(before)


def test_a_write_through_a_linked_folder_is_refused_and_creates_nothing_outside(tmp_path: Path):
    run = ownership.claim(tmp_path / "run", ownership.RUN)
    outside = tmp_path / "outside"
    outside.mkdir()
    (outside / "keep.txt").write_text("the user's")
    (run / "rgb").symlink_to(outside)
    with pytest.raises(UserError, match=r"rgb/000000.png: leads out of .* through a link") as refused:
        atomic.write_bytes(run / "rgb" / "000000.png", b"frame")
    assert "\n" not in str(refused.value)
    assert sorted(p.name for p in outside.iterdir()) == ["keep.txt"]  # no frame, no temporary
    assert ownership.read_ledger(run) == []


def test_a_run_of_an_evaluation_that_is_a_link_out_of_it_is_refused_and_nothing_is_made_there(tmp_path: Path):
    evaluation = ownership.claim(tmp_path / "eval", ownership.EVAL)
    outside = tmp_path / "empty"
    outside.mkdir()
    (evaluation / "seed_0").symlink_to(outside)
    with pytest.raises(UserError, match=r"seed_0: leads out of .* through a link"):
        ownership.claim(evaluation / "seed_0", ownership.RUN)
    assert list(outside.iterdir()) == []


def test_an_output_path_below_a_linked_parent_is_written_and_started_over_as_usual(tmp_path: Path):
    (tmp_path / "real").mkdir()
    (tmp_path / "link").symlink_to(tmp_path / "real")  # as /tmp -> /private/tmp on macOS
    run = ownership.claim(tmp_path / "link" / "run", ownership.RUN)
    (run / "rgb").mkdir()
    atomic.write_bytes(run / "rgb" / "000000.png", b"frame")
    assert ownership.read_ledger(run) == ["rgb/000000.png"]
    ownership.remove_recorded(run, ("rgb",))
    assert not (tmp_path / "real" / "run" / "rgb").exists() and ownership.read_ledger(run) == []


def test_a_250_byte_file_name_is_written_atomically_and_recorded(tmp_path: Path):
    run = ownership.claim(tmp_path / "run", ownership.RUN)
    name = "n" * 246 + ".txt"
    atomic.write_text(run / name, "long")
    assert (run / name).read_text() == "long"
    assert ownership.read_ledger(run) == [name]
    assert sorted(p.name for p in run.iterdir()) == sorted({name, *ownership.BOOKKEEPING})


def test_a_temporary_name_is_short_hidden_and_error_messages_name_the_final_file(tmp_path: Path):
    final = tmp_path / ("n" * 250)
    with pytest.raises(OSError) as failed, atomic.atomic_path(final) as tmp:
        assert tmp.parent == final.parent and tmp.name.startswith(".") and tmp.name.endswith(atomic.TEMP_SUFFIX)
        assert len(tmp.name) < 64 and atomic.final_path(tmp) == final
        tmp.write_bytes(b"half")
        raise OSError(errno.ENOSPC, "No space left on device", str(tmp))
    assert failed.value.filename == str(final) and failed.value.errno == errno.ENOSPC
    assert list(tmp_path.iterdir()) == []  # neither the file nor its temporary
    with atomic.atomic_directory(tmp_path / "bag", ownership.BAG) as built:
        assert atomic.final_path(built / "bag_0.mcap") == tmp_path / "bag" / "bag_0.mcap"
        built.mkdir()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bag"]


_WRITER = """
import sys, threading, time
from pathlib import Path
from renderloop.io import atomic
path, data, start = Path(sys.argv[1]), sys.argv[2].encode() * 1000, float(sys.argv[3])
time.sleep(max(0.0, start - time.time()))  # both processes start writing together, past their imports
failed = []
def write():
    try:
        atomic.write_bytes(path, data)  # at least once, however late a loaded machine started this process
        while time.time() < start + 0.5:
            atomic.write_bytes(path, data)
    except OSError as error:
        failed.append(error)
threads = [threading.Thread(target=write) for _ in range(2)]
[t.start() for t in threads]
[t.join() for t in threads]
sys.exit(str(failed[0]) if failed else 0)
"""


def test_two_processes_writing_the_same_file_at_once_never_collide(tmp_path: Path):
    run = ownership.claim(tmp_path / "run", ownership.RUN)
    path = run / "scene_topview.png"
    start = str(time.time() + 2.0)
    writers = [subprocess.Popen([sys.executable, "-c", _WRITER, str(path), tag, start], stderr=subprocess.PIPE, text=True)
               for tag in ("a", "b")]
    errors = [writer.communicate(timeout=120)[1] for writer in writers]
    assert [writer.returncode for writer in writers] == [0, 0], errors
    assert path.read_bytes() in (b"a" * 1000, b"b" * 1000)
    assert sorted(p.name for p in run.iterdir()) == sorted({path.name, *ownership.BOOKKEEPING})  # no temporary left
    assert ownership.read_ledger(run) == [path.name]


def test_a_temporary_left_by_a_killed_process_is_cleared_when_the_run_is_claimed_and_nothing_else_is(tmp_path: Path):
    run = ownership.claim(tmp_path / "run", ownership.RUN)
    (run / "rgb").mkdir()
    dead = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"], check=True, capture_output=True,
                          text=True)
    ours = atomic.temporary_path(run / "rgb" / "000000.png")
    stray = ours.with_name(ours.name.replace(f".{os.getpid()}.", f".{int(dead.stdout)}."))
    stray.write_bytes(b"half a frame")
    live = atomic.temporary_path(run / "rgb" / "000001.png")  # this process is still writing it
    live.write_bytes(b"being written")
    users = run / ".notes.partial"
    users.write_text("the user's")
    ownership.claim(run, ownership.RUN)
    assert not stray.exists() and live.exists() and users.exists()


def test_a_staging_folder_left_by_a_killed_export_is_cleared_when_the_same_directory_is_written_again(tmp_path: Path):
    dead = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"], check=True, capture_output=True,
                          text=True)
    ours = atomic.temporary_path(tmp_path / "bag")
    stray = ours.with_name(ours.name.replace(f".{os.getpid()}.", f".{int(dead.stdout)}."))
    (stray / "bag").mkdir(parents=True)
    (stray / "bag" / "bag_0.mcap").write_bytes(b"half a bag")
    with atomic.atomic_directory(tmp_path / "bag", ownership.BAG) as built:
        built.mkdir()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bag"]
