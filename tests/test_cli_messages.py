"""What a new user meets first: the help of every verb, the config reference, and the one line a mistake ends in.

Every refusal here is exit code 2 and one line on stderr, with no traceback and nothing left on disk; the messages
name what was wrong and, where a name was mistyped, the closest right one.
"""

from __future__ import annotations

import json
import re
from pathlib import Path

import pytest
import typer
from conftest import cli
from test_bad_input import snapshot

from renderloop.cli import app
from renderloop.config import PRESETS, Config, MissionConfig, RendererConfig, choices, config_schema, describe_changes, load_config
from renderloop.config.reference import SECTION, config_sections
from renderloop.errors import UserError

VERBS = sorted(typer.main.get_command(app).commands)
PRESET_VALUES = "[" + "|".join(PRESETS) + "]"


def refused(code: int, out: str, err: str) -> str:
    """The one error line of a refused command (and that it was one: exit 2, nothing on stdout, no traceback)."""
    assert code == 2, err
    assert "Traceback" not in err and out == "", err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("renderloop: error: "), err
    return lines[0].removeprefix("renderloop: error: ")


# --- help --------------------------------------------------------------------------------------------------------

@pytest.mark.parametrize("verb", VERBS)
def test_help_shows_flags_without_a_value_and_arguments_by_name(verb: str, monkeypatch, capsys):
    monkeypatch.setenv("COLUMNS", "100")
    code, out, err = cli(monkeypatch, capsys, verb, "--help")
    assert code == 0, err
    assert "<bool>" not in out
    usage = next(line for line in out.splitlines() if "Usage:" in line)
    assert "{" not in usage and not re.search(r"\b[a-z]+_[a-z_]+\b", usage.split("[OPTIONS]")[1]), usage


def listed_values(help_text: str, option: str) -> str:
    """The values `--help` lists after `option`, joined again where the help's column wrapped them."""
    lines = help_text.splitlines()
    row = next(i for i, line in enumerate(lines) if re.match(rf"│\s+{option}\s", line))  # its row, not a mention
    column = re.search(rf"{option}\s+", lines[row]).end()
    values = lines[row][column:].split("  ")[0]
    while values.count("[") > values.count("]"):  # wrapped at a '|': the rest lies below, in the same column
        row += 1
        values += lines[row][column:].split("  ")[0].strip()
    return values


def test_help_lists_the_values_of_every_option_with_a_fixed_set(monkeypatch, capsys):
    monkeypatch.setenv("COLUMNS", "100")
    expected = {
        "render": ["--backend", "[" + "|".join(choices(RendererConfig, "backend")) + "]", "--executor", "[local|ray]"],
        "run": ["--preset", PRESET_VALUES, "--mission", "[" + "|".join(choices(MissionConfig, "kind")) + "]"],
        "eval": ["--mission", "[static|adaptive],...", "--preset", PRESET_VALUES],
        "train": ["--device", "[auto|cpu|cuda]", "--backbone", "[efficientnet-lite0|mobilenet-v3|efficientnet-lite0-s8]",
                  "--photo-class", "[ripe|unripe]"],
        "config": ["--format", "[table|json]"],
    }
    for verb, pieces in expected.items():
        code, out, _ = cli(monkeypatch, capsys, verb, "--help")
        for option, values in zip(pieces[::2], pieces[1::2]):
            assert listed_values(out, option) == values, (verb, option, out)
    code, out, _ = cli(monkeypatch, capsys, "render", "--help")
    assert re.search(r"Usage: .* render \[OPTIONS\] RUN_DIR\s*$", out, re.MULTILINE), out
    code, out, _ = cli(monkeypatch, capsys, "train", "--help")
    assert re.search(r"Usage: .* train \[OPTIONS\] \[DATASET_DIRS\.\.\.\]\s*$", out, re.MULTILINE), out


def test_eval_defaults_to_the_demo_preset_like_every_other_verb():
    commands = typer.main.get_command(app).commands
    defaults = {name: param.default for name, command in commands.items() for param in command.params
                if param.name == "preset"}
    assert {"scene", "run", "eval", "config"} <= set(defaults)
    assert set(defaults.values()) == {"demo"}, defaults


# --- the config reference ----------------------------------------------------------------------------------------

def test_config_schema_prints_every_field_by_section_within_100_columns(monkeypatch, capsys):
    monkeypatch.setenv("COLUMNS", "100")
    code, out, err = cli(monkeypatch, capsys, "config", "--schema")
    assert code == 0, err
    lines = out.splitlines()
    assert max(len(line) for line in lines) <= 100
    assert not out.lstrip().startswith("{")
    sections = config_sections()
    assert {section.name for section in sections} >= {"camera", "mission", "controller"}
    for section in sections:
        if section.name:
            assert any(line.startswith(f"{section.name}: ") or line == section.name for line in lines), section.name
        for row in section.rows:
            name = row.path.removeprefix(f"{section.name}.")
            assert any(line.startswith(f"  {name} ") for line in lines), row.path
    rate = lines.index(next(line for line in lines if line.startswith("  rate_hz ") and "0.001" in line))
    assert lines[rate].split() == ["rate_hz", "5", "number", "in", "[0.001,", "100]"]
    assert "Hz" in lines[rate + 1]  # the unit, in the description under the field


def test_config_schema_format_json_is_the_json_schema(monkeypatch, capsys):
    code, out, _ = cli(monkeypatch, capsys, "config", "--schema", "--format", "json")
    assert code == 0 and json.loads(out) == config_schema()


def test_the_docs_reference_and_the_terminal_reference_walk_the_same_fields():
    import sys

    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "docs" / "hooks"))
    try:
        import config_reference
    finally:
        sys.path.pop(0)
    page = config_reference.config_reference()
    rows = [row for section in config_sections() for row in section.rows]
    assert len(rows) > 100 and page.count("\n| <code>") == len(rows)
    assert all(config_reference.dotted(row.path) in page for row in rows)
    assert sum(row.kind == SECTION for row in rows) == page.count("| section |")


# --- unknown keys ------------------------------------------------------------------------------------------------

def test_an_unknown_key_in_a_config_file_names_the_closest_field(monkeypatch, capsys, tmp_path: Path):
    config = tmp_path / "mine.yaml"
    config.write_text("camera:\n  rate_hx: 1\n")
    before = snapshot(tmp_path)
    line = refused(*cli(monkeypatch, capsys, "scene", "--config", str(config), "--out", str(tmp_path / "run")))
    assert line == f"{config}: camera.rate_hx: unknown field; did you mean camera.rate_hz?"
    assert snapshot(tmp_path) == before


@pytest.mark.parametrize("patch, message", [
    ({"camera": {"rate_hx": 1}}, "camera.rate_hx: unknown field; did you mean camera.rate_hz?"),
    ({"camra": {"rate_hz": 1}}, "camra: unknown field; did you mean camera?"),
    ({"mission": {"adaptive": {"vxel": 0.01}}}, "mission.adaptive.vxel: unknown field; did you mean mission.adaptive.voxel?"),
    ({"controller": {"position_xy": {"pp": 1}}}, "controller.position_xy.pp: unknown field; did you mean controller.position_xy.p?"),
    ({"camera": {"zoom": 2}}, "camera.zoom: unknown field"),  # nothing close: no guess
    ({"renderer": {"backend": "rastr"}}, "renderer.backend: Input should be 'cycles' or 'raster'; did you mean raster?"),
    ({"renderer": {"backend": "vulkan"}}, "renderer.backend: Input should be 'cycles' or 'raster'"),
])
def test_config_override_names_the_closest_field_or_value_of_a_mistyped_one(patch: dict, message: str):
    with pytest.raises(UserError) as refusal:
        Config().override(patch)
    assert str(refusal.value) == message


# --- a run directory of another config ---------------------------------------------------------------------------

def test_a_run_directory_of_another_config_is_refused_naming_the_fields_before_any_progress(monkeypatch, capsys, tmp_path):
    run = tmp_path / "run"
    code, _, err = cli(monkeypatch, capsys, "scene", "--out", str(run))
    assert code == 0, err
    before = snapshot(tmp_path)
    line = refused(*cli(monkeypatch, capsys, "run", "--out", str(run), "--seed", "3"))  # stderr holds no progress bar
    assert line == (f"{run / 'config.yaml'}: this run directory was made with another config (seed: 0 -> 3); "
                    "use --force to start it again, or another --out")
    line = refused(*cli(monkeypatch, capsys, "scene", "--out", str(run), "--preset", "paper"))
    assert "another config (" in line and "greenhouse.tables: " in line and "plants.bearing: null -> 20" in line
    assert snapshot(tmp_path) == before


def test_the_fields_that_differ_are_named_five_at_most():
    demo, paper = load_config("demo"), load_config("paper")
    text = describe_changes(demo, paper)
    assert text.count(" -> ") == 5 and re.search(r"; and \d+ more$", text)
    assert describe_changes(demo, demo.override({"camera": {"rate_hz": 0.5}})) == "camera.rate_hz: 2.0 -> 0.5"
    assert describe_changes(demo, demo) == ""


# --- wrong values of choice options ------------------------------------------------------------------------------

CHOICE_CASES = {
    "mission": (["run", "--out", "{tmp}/run", "--mission", "adaptiv"],
                "--mission adaptiv: choose from static, adaptive; did you mean adaptive?"),
    "eval-missions": (["eval", "--seeds", "0", "--out", "{tmp}/eval", "--mission", "static,adaptiv"],
                      "--mission static,adaptiv: choose from static, adaptive; did you mean adaptive?"),
    "backend": (["render", "{tmp}/run", "--backend", "rastr"], "--backend rastr: choose from cycles, raster; did you mean raster?"),
    "executor": (["render", "{tmp}/run", "--executor", "rey"], "--executor rey: choose from local, ray; did you mean ray?"),
    "device": (["train", "--out", "{tmp}/m.onnx", "--device", "cud"], "--device cud: choose from auto, cpu, cuda; did you mean cuda?"),
    "backbone": (["train", "--out", "{tmp}/m.onnx", "--backbone", "mobilenet"],
                 "--backbone mobilenet: choose from efficientnet-lite0, mobilenet-v3, efficientnet-lite0-s8; "
                 "did you mean mobilenet-v3?"),
    "photo-class": (["train", "--out", "{tmp}/m.onnx", "--photo-class", "rip"],
                    "--photo-class rip: choose from ripe, unripe; did you mean ripe?"),
    "format": (["config", "--schema", "--format", "jsn"], "--format jsn: choose from table, json; did you mean json?"),
    "format-alone": (["config", "--format", "json"], "--format json goes with --schema (the config itself prints as YAML)"),
    "preset": (["scene", "--out", "{tmp}/run", "--preset", "papr"],
               f"unknown preset 'papr' (choose from: {', '.join(PRESETS)}); did you mean paper?"),
}


@pytest.mark.parametrize("case", sorted(CHOICE_CASES))
def test_a_wrong_choice_names_the_option_its_values_and_the_closest_one(case: str, monkeypatch, capsys, tmp_path):
    args, message = CHOICE_CASES[case]
    before = snapshot(tmp_path)
    line = refused(*cli(monkeypatch, capsys, *(arg.format(tmp=tmp_path) for arg in args)))
    assert line == message
    assert snapshot(tmp_path) == before


# --- nothing left behind -----------------------------------------------------------------------------------------

INPUTS = {
    "missing": lambda tmp: tmp / "nowhere",
    "a file": lambda tmp: tmp / "notes.txt",
    "not ours": lambda tmp: tmp / "photos",
}
VERB_ARGS = {
    "report": ["report", "{input}"],
    "report-out": ["report", "{input}", "--out", "{tmp}/page.html"],
    "detect": ["detect", "{input}"],
    "detect-images": ["detect", "--images", "{input}", "--out", "{tmp}/found.json"],
    "count": ["count", "{input}"],
    "export": ["export", "{input}", "--rosbag", "{tmp}/bag", "--rerun", "{tmp}/run.rrd"],
    "score-photos": ["score-photos", "{input}", "--coco", "{input}", "--out", "{tmp}/score"],
    "threshold": ["threshold", "{input}"],
    "eval-config": ["eval", "--seeds", "0", "--config", "{input}", "--out", "{tmp}/eval"],
    "eval-out": ["eval", "--seeds", "0", "--out", "{input}"],
}


WRONG = [(verb, kind) for verb in sorted(VERB_ARGS) for kind in sorted(INPUTS)
         if (verb, kind) != ("eval-out", "missing")]  # a missing --out is where eval writes, not a wrong input


@pytest.mark.parametrize("verb, kind", WRONG)
def test_a_verb_refusing_its_input_leaves_nothing_behind(verb: str, kind: str, monkeypatch, capsys, tmp_path: Path):
    (tmp_path / "notes.txt").write_text("not a run\n")
    (tmp_path / "photos").mkdir()
    (tmp_path / "photos" / "holiday.txt").write_text("a folder renderloop did not make\n")
    target = INPUTS[kind](tmp_path)
    before = snapshot(tmp_path)
    args = [arg.format(input=target, tmp=tmp_path) for arg in VERB_ARGS[verb]]
    line = refused(*cli(monkeypatch, capsys, *args))
    assert target.name in line or "--coco" in line, line
    assert snapshot(tmp_path) == before
