from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import mujoco
import pytest
import typer
from conftest import cli

from renderloop.cli import app
from renderloop.config import load_config
from renderloop.io.atomic import dumps_json
from renderloop.io.ownership import BOOKKEEPING
from renderloop.scene.generate import generate_scene

SCENE_FILES = {*BOOKKEEPING, "config.yaml", "scene.json", "world.xml", "scene_topview.png"}  # and our mark and file list




def test_every_verb_has_help(monkeypatch, capsys):
    result = subprocess.run([sys.executable, "-m", "renderloop", "--help"], capture_output=True, text=True)
    assert result.returncode == 0 and "Usage" in result.stdout, result.stderr
    verbs = sorted(typer.main.get_command(app).commands)
    assert {"scene", "plan", "fly", "render", "dataset", "train", "detect", "count", "report", "run", "eval"} <= set(verbs)
    for verb in verbs:
        code, out, err = cli(monkeypatch, capsys, verb, "--help")
        assert code == 0 and "Usage" in out, (verb, err)


def test_scene_writes_the_run_directory_and_resumes(monkeypatch, capsys, tmp_path: Path):
    out = tmp_path / "run"
    code, stdout, _ = cli(monkeypatch, capsys, "scene", "--preset", "paper", "--seed", "7", "--out", str(out))
    assert code == 0 and "wrote" in stdout
    assert {p.name for p in out.iterdir()} == SCENE_FILES
    expected = dumps_json(generate_scene(load_config("paper", seed=7)).model_dump(mode="json"))
    assert (out / "scene.json").read_text() == expected
    mujoco.MjModel.from_xml_path(str(out / "world.xml"))
    assert (out / "scene_topview.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"

    before = {p.name: p.stat().st_mtime_ns for p in out.iterdir()}
    code, stdout, _ = cli(monkeypatch, capsys, "scene", "--preset", "paper", "--seed", "7", "--out", str(out))
    assert code == 0 and "already complete" in stdout
    assert {p.name: p.stat().st_mtime_ns for p in out.iterdir()} == before

    code, _, stderr = cli(monkeypatch, capsys, "scene", "--preset", "paper", "--seed", "8", "--out", str(out))
    assert code == 2 and "another config" in stderr
    code, _, _ = cli(monkeypatch, capsys, "scene", "--preset", "paper", "--seed", "8", "--out", str(out), "--force")
    assert code == 0 and (out / "scene.json").read_text() != expected


def test_half_written_scene_is_completed(monkeypatch, capsys, tmp_path: Path):
    out = tmp_path / "run"
    cli(monkeypatch, capsys, "scene", "--out", str(out))
    reference = (out / "scene.json").read_bytes()
    (out / "scene.json").unlink()
    code, stdout, _ = cli(monkeypatch, capsys, "scene", "--out", str(out))
    assert code == 0 and "wrote" in stdout
    assert (out / "scene.json").read_bytes() == reference
    assert not [p for p in out.iterdir() if p.name.endswith(".partial")]


RUN_FILES = SCENE_FILES | {
    "waypoints.csv", "trajectory.csv", "flight.csv", "groundtruth.txt", "flight_paths.png", "tracking_error.png",
    "render.json", "rgb", "depth", "depth_sensor", "masks", "rgb.txt", "depth.txt", "depth_sensor.txt",
    "camera_info.yaml", "contact_sheet.png", "detections.json", "detection_scores.json", "detections.png",
    "counts.json", "harvest.json", "counts", "timings.json", "report.html",
}


def test_run_on_the_demo_preset_resumes_and_redoes_what_is_stale(monkeypatch, capsys, tmp_path: Path):
    fast = tmp_path / "fast.yaml"
    fast.write_text("renderer:\n  backend: raster\ncamera:\n  rate_hz: 0.5\n")
    out = tmp_path / "demo"
    code, stdout, stderr = cli(monkeypatch, capsys, "run", "--config", str(fast), "--out", str(out))
    assert code == 0, stderr
    assert {"scene (done)", "plan (done)", "fly (done)", "render (done)", "detect (done)", "count (done)"} <= {
        line.split("  ")[0].strip() for line in stderr.splitlines()}
    assert {p.name for p in out.iterdir()} == RUN_FILES
    stamps = {p.name: p.stat().st_mtime_ns for p in out.iterdir()}

    code, _, stderr = cli(monkeypatch, capsys, "run", "--config", str(fast), "--out", str(out))
    assert code == 0 and stderr.count("complete, skipped") == 6
    assert {p.name: p.stat().st_mtime_ns for p in out.iterdir()} == stamps

    code, stdout, _ = cli(monkeypatch, capsys, "report", str(out))
    page = (out / "report.html").read_text()
    assert code == 0 and "report.html" in stdout
    assert page.count('<img alt="') >= 6 and 'src="http' not in page and "<script src=" not in page  # all inline
    counts = json.loads((out / "counts.json").read_text())
    assert f"<td>{counts['total']['truth']}</td>" in page
    assert all(f">{stage}</td>" in page for stage in ("scene", "render", "count"))
    (out / "report.html").unlink()

    flight = (out / "flight.csv").read_bytes()
    cli(monkeypatch, capsys, "scene", "--config", str(fast), "--out", str(out), "--force")  # an earlier stage redone...
    code, stdout, _ = cli(monkeypatch, capsys, "plan", str(out))
    assert code == 0 and "wrote" in stdout  # ...makes the later ones stale
    code, stdout, _ = cli(monkeypatch, capsys, "fly", str(out))
    assert code == 0 and "wrote" in stdout
    assert (out / "flight.csv").read_bytes() == flight  # same seed, same flight


def test_stages_refuse_missing_or_broken_inputs(monkeypatch, capsys, tmp_path: Path):
    out = tmp_path / "run"
    code, _, stderr = cli(monkeypatch, capsys, "plan", str(out))
    assert code == 2 and "not a run directory" in stderr
    cli(monkeypatch, capsys, "scene", "--out", str(out))
    code, _, stderr = cli(monkeypatch, capsys, "fly", str(out))
    assert code == 2 and "missing waypoints.csv, trajectory.csv (run `renderloop plan` first)" in stderr
    cli(monkeypatch, capsys, "plan", str(out))
    trajectory = out / "trajectory.csv"
    text = trajectory.read_text()
    trajectory.write_text(text[: len(text) // 2].rsplit(",", 3)[0] + "\n")  # cut off mid-row
    code, _, stderr = cli(monkeypatch, capsys, "fly", str(out))
    assert code == 2 and "trajectory.csv: not a numeric table" in stderr and stderr.count("\n") == 1
    assert not (out / "flight.csv").exists()
    code, _, stderr = cli(monkeypatch, capsys, "report", str(out))
    assert code == 2 and "missing flight_paths.png, tracking_error.png (run `renderloop fly` first)" in stderr and stderr.count("\n") == 1
    assert not (out / "report.html").exists()


def test_plan_with_a_take_off_point_outside_the_room_exits_2(monkeypatch, capsys, tmp_path: Path):
    config = tmp_path / "far.yaml"
    config.write_text("robot:\n  home: [5.9, 0.0, 0.0]\n")
    out = tmp_path / "run"
    cli(monkeypatch, capsys, "scene", "--config", str(config), "--out", str(out))
    code, _, stderr = cli(monkeypatch, capsys, "plan", str(out))
    assert code == 2 and "transit start" in stderr and stderr.count("\n") == 1
    assert not (out / "trajectory.csv").exists()


BAD_CONFIGS = {
    "unknown key": ("greenhouse:\n  colour: red\n", "greenhouse.colour: unknown field"),
    "zero count": ("greenhouse:\n  plants_per_table: 0\n", "greenhouse.plants_per_table"),
    "negative count": ("plants:\n  leaves: [-3, 4]\n", "plants.leaves"),
    "peppers cannot fit": ("plants:\n  peppers:\n    per_side: [40, 60]\n", "plants.peppers.per_side"),
    "not yaml": ("greenhouse: {tables: [\n", "not valid YAML"),
    "not a mapping": ("42\n", "expected a mapping"),
}


@pytest.mark.parametrize("case", sorted(BAD_CONFIGS))
def test_bad_config_exits_2_with_one_line_and_writes_nothing(monkeypatch, capsys, tmp_path: Path, case: str):
    text, message = BAD_CONFIGS[case]
    config = tmp_path / "bad.yaml"
    config.write_text(text)
    out = tmp_path / "run"
    code, _, stderr = cli(monkeypatch, capsys, "scene", "--config", str(config), "--out", str(out))
    assert code == 2
    assert message in stderr and stderr.count("\n") == 1 and "Traceback" not in stderr
    assert not out.exists()


def test_other_bad_input(monkeypatch, capsys, tmp_path: Path):
    code, _, stderr = cli(monkeypatch, capsys, "scene", "--preset", "nope", "--out", str(tmp_path / "a"))
    assert code == 2 and "unknown preset 'nope'" in stderr and stderr.count("\n") == 1

    unreadable = tmp_path / "binary.yaml"
    unreadable.write_bytes(b"\xff\xfe\x00garbage")
    code, _, stderr = cli(monkeypatch, capsys, "scene", "--config", str(unreadable), "--out", str(tmp_path / "b"))
    assert code == 2 and "binary.yaml: cannot read config" in stderr

    code, _, stderr = cli(monkeypatch, capsys, "scene", "--config", str(tmp_path / "missing.yaml"), "--out", str(tmp_path / "c"))
    assert code == 2 and "missing.yaml: cannot read config" in stderr

    a_file = tmp_path / "file.txt"
    a_file.write_text("not a directory")
    code, _, stderr = cli(monkeypatch, capsys, "scene", "--out", str(a_file))
    assert code == 2 and "is a file, not a directory" in stderr
    assert a_file.read_text() == "not a directory"
    assert not any(tmp_path.glob("[abc]"))


def test_a_training_stack_that_is_missing_or_fails_to_load_is_named_in_one_line(monkeypatch, capsys, tmp_path: Path):
    import importlib.abc

    class Broken(importlib.abc.MetaPathFinder):  # torchvision's compiled ops failing to load raise an ImportError with no name
        def find_spec(self, name, path, target=None):
            if name == "renderloop.perception.training.train":
                raise ImportError("libtorchvision.so: undefined symbol")

    monkeypatch.delitem(sys.modules, "renderloop.perception.training.train", raising=False)
    monkeypatch.setattr(sys, "meta_path", [Broken(), *sys.meta_path])
    code, _, stderr = cli(monkeypatch, capsys, "train", str(tmp_path), "--out", str(tmp_path / "m.onnx"))
    assert code == 2 and stderr.count("\n") == 1
    assert "train extra" in stderr and "(libtorchvision.so: undefined symbol)" in stderr

    monkeypatch.setitem(sys.modules, "renderloop.perception.training.train", None)  # not importable: named
    code, _, stderr = cli(monkeypatch, capsys, "train", str(tmp_path), "--out", str(tmp_path / "m.onnx"))
    assert code == 2 and "(renderloop.perception.training.train is missing)" in stderr
    assert not any(tmp_path.iterdir())


def test_entry_point_reports_bad_input_without_traceback(tmp_path: Path):
    result = subprocess.run(
        [sys.executable, "-m", "renderloop", "scene", "--preset", "nope", "--out", str(tmp_path / "x")],
        capture_output=True, text=True,
    )
    assert result.returncode == 2
    assert result.stderr.strip() == "renderloop: error: unknown preset 'nope' (choose from: demo, paper, greenhouse, commercial)"


def test_config_prints_the_resolved_config_and_the_schema_of_every_field(monkeypatch, capsys, tmp_path: Path):
    code, stdout, _ = cli(monkeypatch, capsys, "config", "--preset", "paper", "--seed", "7")
    assert code == 0 and load_config("paper", seed=7).to_yaml() == stdout
    code, stdout, _ = cli(monkeypatch, capsys, "config", "--schema", "--format", "json")
    schema = json.loads(stdout)
    rate = schema["$defs"]["CameraConfig"]["properties"]["rate_hz"]
    assert code == 0 and "Hz" in rate["description"] and rate["default"] == 5.0 and "maximum" in rate
