"""Every number a run file holds is finite and within its bound, and no JSON or YAML document is parsed that nests
deeper than MAX_DEPTH: a damaged file is one line naming the file, the field or row, and the problem (exit 2 from
the CLI), never a MuJoCo traceback, an OverflowError or a RecursionError.

Each case copies the complete small run of conftest, damages one file and hands it to the verb that reads it (the
CLI for a few, the reader itself for the rest, to stay fast).
"""

from __future__ import annotations

import hashlib
import io
import json
import math
import re
import shutil
from pathlib import Path

import numpy as np
import pytest
import yaml
from conftest import cli
from PIL import Image

from renderloop.errors import UserError
from renderloop.io.bounded import MAX_DEPTH, json_depth, load_json, load_yaml
from renderloop.planning.waypoints import read_waypoints
from renderloop.render.camera import read_camera_info
from renderloop.render.frames import read_png
from renderloop.export import contents
from renderloop.rundir import files, names
from renderloop.scene.model import read_scene

ERROR = "renderloop: error: "


@pytest.fixture
def run(complete_run: Path, tmp_path: Path) -> Path:
    copy = tmp_path / "run"
    shutil.copytree(complete_run, copy)
    return copy


def _tree(root: Path) -> dict[str, str]:
    return {p.relative_to(root).as_posix(): hashlib.sha1(p.read_bytes()).hexdigest() for p in sorted(root.rglob("*")) if p.is_file()}


def _refused(monkeypatch, capsys, *args: str) -> str:
    """Run the CLI; it must end with exit code 2 and one error line, no traceback. The line, without its prefix."""
    code, out, err = cli(monkeypatch, capsys, *args)
    lines = [line for line in err.splitlines() if line.strip()]
    assert code == 2 and "Traceback" not in err and len(lines) == 1 and lines[0].startswith(ERROR), err
    assert out == ""
    return lines[0].removeprefix(ERROR)


def _one_line(error: pytest.ExceptionInfo[UserError]) -> str:
    message = str(error.value)
    assert "\n" not in message
    return message


def _edit_scene(run: Path, edit) -> None:
    scene = json.loads((run / names.SCENE).read_text())
    edit(scene)
    (run / names.SCENE).write_text(json.dumps(scene))  # json writes NaN and Infinity as JavaScript does


def _set_number(path: Path, row: int, column: int, value: str, separator: str = ",") -> None:
    """Set one number of a table: `row` counts the lines that are not comments (a CSV's header is row 0, a TUM
    file's first pose; -1 is the last)."""
    lines = path.read_text().splitlines()
    index = [i for i, line in enumerate(lines) if not line.startswith("#")][row]
    parts = lines[index].split(separator)
    parts[column] = value
    lines[index] = separator.join(parts)
    path.write_text("\n".join(lines) + "\n")


# scene.json -----------------------------------------------------------------------------------------------------------

@pytest.mark.parametrize(("field", "value", "problem"), [
    ("center", math.nan, "finite"),
    ("center", 1e308, "less than or equal to 1000"),
    ("radius", math.inf, "finite"),
])
def test_a_nan_or_huge_pepper_centre_or_an_infinite_radius_stops_plan_in_one_line(
        run: Path, monkeypatch, capsys, field: str, value: float, problem: str):
    def edit(scene: dict) -> None:
        if field == "center":
            scene["peppers"][0]["center"][0] = value
        else:
            scene["peppers"][0][field] = value
    _edit_scene(run, edit)
    before = _tree(run)

    line = _refused(monkeypatch, capsys, "plan", str(run), "--force")

    where = "peppers.0.center.0" if field == "center" else "peppers.0.radius"
    assert f"{run / names.SCENE}: {where}: " in line and problem in line
    assert _tree(run) == before


def test_a_scene_that_names_a_plant_it_lacks_is_refused_by_field(run: Path):
    _edit_scene(run, lambda scene: scene["peppers"][0].update(plant=len(scene["plants"])))
    with pytest.raises(UserError) as error:
        read_scene(run)
    assert "scene.json: peppers.0.plant:" in _one_line(error) and "is not a plant of the scene" in str(error.value)


def test_a_direction_that_is_not_a_unit_vector_is_refused(run: Path):
    _edit_scene(run, lambda scene: scene["peppers"][0].update(axis=[0.0, 0.0, 0.0]))
    with pytest.raises(UserError) as error:
        read_scene(run)
    assert "scene.json: peppers.0.axis: [0.0, 0.0, 0.0] is not a unit vector" in _one_line(error)


# Tables ---------------------------------------------------------------------------------------------------------------

def test_an_x_of_1e300_in_trajectory_csv_stops_fly_naming_the_row_and_column(run: Path, monkeypatch, capsys):
    _set_number(run / names.TRAJECTORY, 12, 1, "1e300")
    before = _tree(run)

    line = _refused(monkeypatch, capsys, "fly", str(run), "--force")

    assert line == f"{run / names.TRAJECTORY}: row 12 has 1e+300 in column x, out of range [-1000, 1000] m"
    assert _tree(run) == before  # no flight.csv with inf in it for the next verb to blame


def test_trajectory_times_rise_by_one_sample_step(run: Path):
    """A last row moved to a million seconds would have fly simulate for days: the planner's rows are one step apart."""
    rows = len((run / names.TRAJECTORY).read_text().splitlines()) - 1
    _set_number(run / names.TRAJECTORY, -1, 0, "1000000")
    with pytest.raises(UserError) as error:
        files.read_trajectory(run)
    assert re.search(rf"trajectory\.csv: row {rows} has 1000000 in column t, not one sample step \(0\.\d+ s\) after "
                     rf"row {rows - 1}$", _one_line(error))


def test_inf_in_flight_csv_stops_the_report_naming_the_row_and_column(run: Path, monkeypatch, capsys):
    _set_number(run / names.FLIGHT, 5, 2, "inf")

    line = _refused(monkeypatch, capsys, "report", str(run))

    assert line == f"{run / names.FLIGHT}: row 5 has inf in column y, not a finite number"
    assert not (run / names.REPORT).exists()


def test_a_rotor_faster_than_any_config_allows_is_refused(run: Path):
    _set_number(run / names.FLIGHT, 3, files.FLIGHT_HEADER.index("w2"), "25000")
    with pytest.raises(UserError, match=r"flight\.csv: row 3 has 25000 in column w2, out of range \[0, 20000\] rad/s"):
        files.read_flight(run)


def test_inf_in_groundtruth_txt_names_the_pose_and_column(run: Path):
    _set_number(run / names.POSES, 0, 2, "inf", separator=" ")
    with pytest.raises(UserError) as error:
        files.read_poses(run)
    assert re.search(r"groundtruth\.txt: pose 0 \(t=[\d.]+\) has inf in column ty, not a finite number$", _one_line(error))


def test_groundtruth_times_never_go_back(run: Path):
    _set_number(run / names.POSES, 3, 0, "0.0", separator=" ")
    with pytest.raises(UserError, match=r"groundtruth\.txt: pose 3 \(t=0\.0\) has 0 in column timestamp, before the [\d.]+ of pose 2"):
        files.read_poses(run)


def test_a_waypoint_of_an_unknown_side_or_plant_is_refused(run: Path):
    _set_number(run / names.WAYPOINTS, 1, 2, "9999999")
    with pytest.raises(UserError, match=r"waypoints\.csv: row 1 has 9999999 in column plant, out of range \[-1, 4999\]"):
        read_waypoints(run)


# camera_info.yaml -----------------------------------------------------------------------------------------------------

@pytest.mark.parametrize(("old", "new", "message"), [
    (r"image_width: \d+", "image_width: .inf", "image_width: inf is not a whole number of pixels"),
    (r"image_width: \d+", "image_width: 100000", "image_width: 100000 is out of range [16, 8192] px"),
    (r"image_height: \d+", "image_height: -3", "image_height: -3 is out of range [16, 8192] px"),
    (r"- 0\.0\n", "- .nan\n", "is not a finite number"),
])
def test_a_camera_info_size_or_matrix_out_of_bounds_is_one_line(run: Path, old: str, new: str, message: str):
    path = run / names.CAMERA_INFO
    path.write_text(re.sub(old, new, path.read_text(), count=1))
    with pytest.raises(UserError) as error:
        read_camera_info(run)
    assert _one_line(error).startswith(f"{path}: ") and message in str(error.value)


# Nesting --------------------------------------------------------------------------------------------------------------

DEEP = 5000


def _deep_yaml(section: str) -> str:
    return f"{section}:\n" + "".join("  " * level + "a:\n" for level in range(1, DEEP)) + "  " * DEEP + "1\n"


def test_a_yaml_config_nested_thousands_deep_is_one_line_and_writes_nothing(tmp_path: Path, monkeypatch, capsys):
    (tmp_path / "deep.yaml").write_text(_deep_yaml("camera"))

    line = _refused(monkeypatch, capsys, "scene", "--config", str(tmp_path / "deep.yaml"), "--out", str(tmp_path / "out"))

    assert line == f"{tmp_path / 'deep.yaml'}: nested more than {MAX_DEPTH} levels deep (line {MAX_DEPTH + 1})"
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize(("name", "text", "read"), [
    (names.CONFIG, _deep_yaml("camera"), files.read_config),
    (names.CAMERA_INFO, "[" * DEEP + "]" * DEEP, read_camera_info),
    (names.CAMERA_INFO, "camera_matrix: " + "{a: " * DEEP + "1" + "}" * DEEP, read_camera_info),
    (names.SCENE, "[" * DEEP + "]" * DEEP, read_scene),
    (names.SCENE, '{"rows": ' + '{"a": ' * DEEP + "1" + "}" * DEEP + "}", read_scene),
    (names.COUNTS, "[" * DEEP + "]" * DEEP, files.read_counts),
], ids=["config.yaml", "camera_info-flow", "camera_info-mapping", "scene-list", "scene-object", "counts"])
def test_a_run_file_nested_thousands_deep_is_one_line_naming_it(run: Path, name: str, text: str, read):
    (run / name).write_text(text)
    with pytest.raises(UserError) as error:
        read(run)
    assert _one_line(error).startswith(f"{run / name}: nested more than {MAX_DEPTH} levels deep")


def test_nesting_is_counted_outside_strings_and_up_to_the_limit_allowed(tmp_path: Path):
    assert json_depth(b'{"a": "[[[[{{{{", "b": [1, [2, "]]]"]]}') == 3
    assert json_depth(b'["\\"[[[", [[]]]') == 3
    allowed = "[" * MAX_DEPTH + "]" * MAX_DEPTH
    assert load_json(allowed, "ok.json") == load_yaml(allowed, "ok.yaml")
    with pytest.raises(UserError, match="nested more than"):
        load_json("[" + allowed + "]", "deep.json")


def test_a_yaml_alias_bomb_is_refused_before_it_expands():
    lines = ["a0: &a0 [x, x, x, x, x, x, x, x, x, x]"]
    lines += [f"a{i}: &a{i} [{', '.join([f'*a{i - 1}'] * 10)}]" for i in range(1, 9)]
    with pytest.raises(UserError, match=r"bomb\.yaml: stands for more than 1,000,000 values"):
        load_yaml("\n".join(lines) + "\n", "bomb.yaml")


def test_a_number_too_long_for_python_is_one_line():
    with pytest.raises(UserError, match=r"long\.yaml: not valid YAML"):
        load_yaml("seed: " + "9" * 5000 + "\n", "long.yaml")
    with pytest.raises(UserError, match=r"long\.json: not a readable JSON file"):
        load_json("[" + "9" * 5000 + "]", "long.json")


# Images ---------------------------------------------------------------------------------------------------------------

def _png(array: np.ndarray) -> bytes:
    buffer = io.BytesIO()
    Image.fromarray(array).save(buffer, format="PNG")
    return buffer.getvalue()


def test_a_frame_with_the_wrong_channels_is_refused_from_its_header(run: Path):
    rgb, mask = run / names.frame_file(names.RGB, 1), run / names.frame_file(names.MASKS, 1)
    height, width = read_png(rgb, np.uint8).shape[:2]
    rgb.write_bytes(_png(np.zeros((height, width), np.uint16)))
    mask.write_bytes(_png(np.zeros((height, width, 3), np.uint8)))
    with pytest.raises(UserError, match=re.escape(f"{rgb}: holds 1-channel I;16 pixels, not 3-channel")):
        read_png(rgb, np.uint8)
    with pytest.raises(UserError, match=re.escape(f"{mask}: holds 3-channel RGB pixels, not 1-channel")):
        read_png(mask, np.uint16)


def test_a_frame_of_another_size_than_camera_info_stops_an_export_before_decoding(run: Path, monkeypatch, capsys):
    depth = run / names.frame_file(files_depth_dir(run), 2)
    depth.write_bytes(_png(np.zeros((10, 12), np.uint16)))

    line = _refused(monkeypatch, capsys, "export", str(run), "--rerun", str(run.parent / "run.rrd"))

    assert line.startswith(f"{depth}: 12x10 px, but {run / names.CAMERA_INFO} says ")
    assert not (run.parent / "run.rrd").exists()


def files_depth_dir(run: Path) -> str:
    from renderloop.render.frames import sensor_depth_dir

    return sensor_depth_dir(run)


# What the pipeline writes ---------------------------------------------------------------------------------------------

def test_every_file_the_pipeline_writes_reads_within_its_bounds(complete_run: Path):
    """The bounds let every real run through: all of the complete run reads, table by table and as a whole."""
    everything = contents.read_run(complete_run)
    assert everything.missing == [] and everything.scene is not None and len(everything.frames) > 0
    assert np.isfinite(everything.trajectory).all() and all(np.isfinite(c).all() for c in everything.flight.values())
    assert files.read_harvest(complete_run)
    assert files.read_detection_scores(complete_run) and files.read_timings(complete_run) is not None
    assert yaml.safe_load((complete_run / names.CAMERA_INFO).read_text())["image_width"] == everything.intrinsics.width
