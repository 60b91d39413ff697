"""Directories renderloop does not own are never written to, and nothing of the user's inside a run is deleted."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest
from conftest import cli

from renderloop.errors import UserError
from renderloop.io import ownership
from renderloop.rundir.names import frame_file


def _tum_folder(root: Path) -> Path:
    """A user's TUM RGB-D sequence: the same names as our outputs, none of it ours."""
    folder = root / "rgbd_dataset_freiburg1_xyz"
    for stream in ("rgb", "depth"):
        (folder / stream).mkdir(parents=True)
        (folder / stream / "1305031102.175304.png").write_bytes(b"\x89PNG user frame " + stream.encode())
        (folder / f"{stream}.txt").write_text(f"# {stream}\n1305031102.175304 {stream}/1305031102.175304.png\n")
    (folder / "groundtruth.txt").write_text("1305031102.1758 1.3405 0.6266 1.6575 0.6574 0.6126 -0.2949 -0.3248\n")
    (folder / "model.onnx").write_bytes(b"the user's own network")
    (folder / "existing.rrd").write_bytes(b"the user's recording")
    return folder


def _tree(folder: Path) -> dict[str, bytes]:
    return {p.relative_to(folder).as_posix(): p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()}


@pytest.fixture
def foreign(tmp_path: Path) -> Path:
    return _tum_folder(tmp_path)


def _verbs(foreign: Path, run: Path, photos: Path) -> dict[str, list[str]]:
    return {
        "scene": ["scene", "--out", str(foreign)],
        "run": ["run", "--out", str(foreign)],
        "plan": ["plan", str(foreign)],
        "fly": ["fly", str(foreign)],
        "render": ["render", str(foreign), "--backend", "raster"],
        "detect": ["detect", str(foreign)],
        "count": ["count", str(foreign), "--force"],
        "report": ["report", str(foreign)],
        "report --out": ["report", str(run), "--out", str(foreign / "rgb.txt")],
        "detect --images": ["detect", "--images", str(photos), "--out", str(foreign / "groundtruth.txt")],
        "dataset": ["dataset", "--out", str(foreign), "--images", "1"],
        "dataset --force": ["dataset", "--out", str(foreign), "--images", "1", "--force"],
        "dataset-from-runs": ["dataset-from-runs", str(run), "--out", str(foreign), "--val-runs", "0"],
        "train": ["train", str(foreign), "--out", str(foreign / "model.onnx")],
        "export --rosbag": ["export", str(run), "--rosbag", str(foreign), "--force"],
        "export --rerun": ["export", str(run), "--rerun", str(foreign / "existing.rrd")],
        "eval": ["eval", "--out", str(foreign), "--seeds", "0", "--preset", "demo"],
    }


VERBS = ("scene", "run", "plan", "fly", "render", "detect", "count", "report", "report --out", "detect --images", "dataset",
         "dataset --force", "dataset-from-runs", "train", "export --rosbag", "export --rerun", "eval")


@pytest.mark.parametrize("verb", VERBS)
def test_every_verb_that_writes_refuses_a_folder_of_the_users_and_leaves_it_byte_identical(
        verb: str, foreign: Path, complete_run: Path, tmp_path: Path, monkeypatch, capsys):
    photos = tmp_path / "photos"
    photos.mkdir()
    shutil.copy(complete_run / frame_file("rgb", 0), photos / "a.png")
    before = _tree(foreign)
    code, _, stderr = cli(monkeypatch, capsys, *_verbs(foreign, complete_run, photos)[verb])
    assert code == 2 and stderr.count("\n") == 1 and "Traceback" not in stderr, stderr
    assert str(foreign) in stderr
    assert _tree(foreign) == before  # nothing changed, nothing added (no mark either)
    assert not list(foreign.parent.glob(".*partial"))


def test_a_users_files_inside_a_run_survive_force_and_a_renders_start_over(complete_run: Path, tmp_path: Path,
                                                                           monkeypatch, capsys):
    run = tmp_path / "run"
    shutil.copytree(complete_run, run)
    mine = {run / "notes.txt": b"flown on a windy day", run / "rgb" / "my_photo.png": b"not a frame of ours",
            run / "counts" / "by_hand.csv": b"plant,fruit\n0,3\n"}
    for path, data in mine.items():
        path.write_bytes(data)
    ours = _tree(run / "rgb")

    for args in (["render", str(run), "--force"], ["detect", str(run), "--force"], ["count", str(run), "--force"],
                 ["report", str(run)]):
        code, _, stderr = cli(monkeypatch, capsys, *args)
        assert code == 0, stderr
    (run / "render.json").write_text("{}")  # another record: the render starts over
    code, _, stderr = cli(monkeypatch, capsys, "render", str(run))
    assert code == 0, stderr

    assert all(path.read_bytes() == data for path, data in mine.items())
    assert _tree(run / "rgb") == ours  # the frames are rendered again, the same, beside the user's photo
    assert "my_photo.png" not in ownership.read_ledger(run)


def test_a_file_at_one_of_our_names_that_we_did_not_write_is_not_replaced(complete_run: Path, tmp_path: Path,
                                                                          monkeypatch, capsys):
    run = tmp_path / "run"
    shutil.copytree(complete_run, run)
    (run / "report.html").write_text("the user's own page")
    code, _, stderr = cli(monkeypatch, capsys, "report", str(run))
    assert code == 2 and "report.html: exists and renderloop did not write it" in stderr and stderr.count("\n") == 1
    assert (run / "report.html").read_text() == "the user's own page"


def test_a_run_without_the_mark_is_refused_whatever_files_it_holds(complete_run: Path, tmp_path: Path,
                                                                   monkeypatch, capsys):
    """Only a marked directory is ours: one with our files and no mark is the user's copy, never adopted."""
    run = tmp_path / "run"
    shutil.copytree(complete_run, run)
    for name in ownership.BOOKKEEPING:
        (run / name).unlink()
    code, _, stderr = cli(monkeypatch, capsys, "count", str(run), "--force")
    assert code == 2 and "not empty and not made by renderloop" in stderr and stderr.count("\n") == 1
    assert ownership.read_mark(run) is None and not (run / ownership.LEDGER).exists()


def test_a_directory_of_another_kind_or_a_newer_format_is_refused(tmp_path: Path):
    dataset = ownership.claim(tmp_path / "data", ownership.DATASET)
    with pytest.raises(UserError, match="a renderloop dataset directory, not a run directory"):
        ownership.claim(dataset, ownership.RUN)
    newer = tmp_path / "newer"
    newer.mkdir()
    (newer / ownership.MARK).write_text('{"renderloop": 99, "kind": "run"}')
    with pytest.raises(UserError, match="written by a newer renderloop"):
        ownership.claim(newer, ownership.RUN)
    (newer / ownership.MARK).write_text("not json")
    with pytest.raises(UserError, match="not a renderloop mark file"):
        ownership.claim(newer, ownership.RUN)


def test_starting_over_removes_only_listed_files_and_a_torn_ledger_line_is_not_trusted(tmp_path: Path):
    run = ownership.claim(tmp_path / "run", ownership.RUN)
    (run / "rgb").mkdir()
    for name in ("rgb/000000.png", "rgb/000001.png", "rgb.txt"):
        ownership.record(run / name)
        (run / name).write_bytes(b"ours")
    (run / "rgb" / "theirs.png").write_bytes(b"theirs")
    with open(run / ownership.LEDGER, "a", encoding="utf-8") as ledger:
        ledger.write("rgb/theirs.p")  # a kill mid-append: no newline
    assert ownership.read_ledger(run) == ["rgb/000000.png", "rgb/000001.png", "rgb.txt"]
    ownership.remove_recorded(run, ("rgb", "rgb.txt"))
    assert _tree(run / "rgb") == {"theirs.png": b"theirs"} and not (run / "rgb.txt").exists()
    assert ownership.read_ledger(run) == []
