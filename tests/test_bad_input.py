"""Bad input ends in one clear line and exit code 2: never a traceback, never a touched or half-written run directory.

Every case copies one complete small run (demo preset, raster frames at 0.5 Hz, detected and counted), breaks one
thing and runs the real CLI on it. The run directory is compared file by file (bytes and mtime) before and after,
so a stage that rewrites an output and then fails on a later input is caught, not only one that dies mid-write.
"""

from __future__ import annotations

import ast
import hashlib
import io
import json
import shutil
import tempfile
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest
import yaml
from conftest import cli
from hypothesis import given, settings
from hypothesis import strategies as st
from PIL import Image
from pydantic import BaseModel

import renderloop
from renderloop.config import Config, load_config
from renderloop.errors import UserError
from renderloop.rundir.names import DETECT_CACHE as CACHE

SRC = Path(renderloop.__file__).parent
ERROR_PREFIX = "renderloop: error:"


def snapshot(root: Path) -> dict[str, tuple[str, int] | str]:
    """Every file under root by bytes hash and mtime, every folder by name: what "nothing changed" compares."""
    state: dict[str, tuple[str, int] | str] = {}
    for path in sorted(root.rglob("*")):
        key = path.relative_to(root).as_posix()
        state[key] = "dir" if path.is_dir() else (hashlib.sha256(path.read_bytes()).hexdigest(), path.stat().st_mtime_ns)
    return state


# --- corruptions: each takes (tmp_path, run copy or None) and returns the CLI arguments ---------------------------

def _config_case(text: str) -> Callable[[Path, Path | None], list[str]]:
    """`renderloop scene --config F --out D` with F holding `text` ({tmp} is the case's folder)."""
    def prepare(tmp: Path, _run: Path | None) -> list[str]:
        (tmp / "bad.yaml").write_text(text.replace("{tmp}", str(tmp)), encoding="utf-8")
        return ["scene", "--config", str(tmp / "bad.yaml"), "--out", str(tmp / "out")]
    return prepare


def _missing_config(tmp: Path, _run: Path | None) -> list[str]:
    return ["scene", "--config", str(tmp / "nowhere.yaml"), "--out", str(tmp / "out")]


def _unknown_preset(tmp: Path, _run: Path | None) -> list[str]:
    return ["scene", "--preset", "gigantic", "--out", str(tmp / "out")]


def _truncated_trajectory(tmp: Path, run: Path) -> list[str]:
    path = run / "trajectory.csv"
    data = path.read_bytes()
    cut = len(data) // 2
    while data[cut - 1:cut] in (b"\n", b","):  # mid-number, so the last row is short, not merely missing
        cut += 1
    path.write_bytes(data[:cut])
    return ["fly", str(run), "--force"]


def _waypoints_header(tmp: Path, run: Path) -> list[str]:
    path = run / "waypoints.csv"
    lines = path.read_text().splitlines(keepends=True)
    path.write_text(lines[0].replace(",t,", ",time,") + "".join(lines[1:]))
    return ["fly", str(run), "--force"]


def _flight_header(tmp: Path, run: Path) -> list[str]:
    path = run / "flight.csv"
    lines = path.read_text().splitlines(keepends=True)
    path.write_text(lines[0].replace("cam_err", "camera_error") + "".join(lines[1:]))
    return ["export", str(run), "--rosbag", str(tmp / "bag")]


def _groundtruth(column: int | None, value: str = "") -> Callable[[Path, Path], list[str]]:
    """Set one number of the first pose (or, column None, empty the file) and render."""
    def prepare(tmp: Path, run: Path) -> list[str]:
        path = run / "groundtruth.txt"
        lines = path.read_text().splitlines(keepends=True)
        if column is None:
            lines = []
        else:
            first = next(i for i, line in enumerate(lines) if not line.startswith("#"))
            parts = lines[first].split()
            parts[column] = value
            lines[first] = " ".join(parts) + "\n"
        path.write_text("".join(lines))
        return ["render", str(run)]
    return prepare


def _write(name: str, data: str | bytes, *args: str) -> Callable[[Path, Path], list[str]]:
    """Replace run file `name` with `data`; the arguments ({run}, {tmp}) follow."""
    def prepare(tmp: Path, run: Path) -> list[str]:
        path = run / name
        path.write_bytes(data if isinstance(data, bytes) else data.encode())
        return [arg.format(run=run, tmp=tmp) for arg in args]
    return prepare


def _args(*args: str) -> Callable[[Path, Path], list[str]]:
    """Nothing broken in the run: the bad input is on the command line."""
    def prepare(tmp: Path, run: Path) -> list[str]:
        return [arg.format(run=run, tmp=tmp) for arg in args]
    return prepare


def _half_png(tmp: Path, run: Path) -> list[str]:
    path = run / "rgb" / "000001.png"
    data = path.read_bytes()
    path.write_bytes(data[: len(data) // 2])
    return ["detect", str(run), "--force"]


def _small_depth(tmp: Path, run: Path) -> list[str]:
    buffer = io.BytesIO()
    Image.fromarray(np.full((10, 12), 5000, np.uint16)).save(buffer, format="PNG")
    for folder in ("depth", "depth_sensor"):
        if (run / folder).is_dir():
            (run / folder / "000001.png").write_bytes(buffer.getvalue())
    return ["detect", str(run), "--force"]


def _escaping_image(tmp: Path, run: Path) -> list[str]:
    path = run / "detections.json"
    document = json.loads(path.read_text())
    document["frames"][0]["image"] = "../../etc/passwd"
    path.write_text(json.dumps(document))
    return ["count", str(run), "--force"]


def _random_onnx(tmp: Path, run: Path) -> list[str]:
    (tmp / "model.onnx").write_bytes(np.random.default_rng(0).bytes(4096))
    return ["detect", str(run), "--model", str(tmp / "model.onnx"), "--force"]


def _empty_images(tmp: Path, _run: Path | None) -> list[str]:
    (tmp / "empty").mkdir()
    return ["detect", "--images", str(tmp / "empty"), "--out", str(tmp / "found.json")]


def _reversed_seeds(tmp: Path, _run: Path | None) -> list[str]:
    return ["eval", "--preset", "demo", "--seeds", "5-2", "--out", str(tmp / "eval")]


def _export_exists(tmp: Path, run: Path) -> list[str]:
    (tmp / "bag").mkdir()
    (tmp / "bag" / "keep.txt").write_text("an earlier export")
    return ["export", str(run), "--rosbag", str(tmp / "bag")]


@dataclass(frozen=True)
class Case:
    id: str
    prepare: Callable[[Path, Path | None], list[str]]
    names: tuple[str, ...]  # what the error line must name: the file and, where there is one, the field or problem
    needs_run: bool = True
    may_leave: tuple[str, ...] = ()  # files the failing stage is documented to keep (detect's resume cache)


CASES = [
    # config YAML through `renderloop scene --config`
    Case("config-list", _config_case("- camera\n- plants\n"), ("bad.yaml", "mapping"), False),
    Case("config-yaml-syntax", _config_case("camera: {width: 320\nplants: [\n"), ("bad.yaml", "not valid YAML"), False),
    Case("config-unknown-field", _config_case("camera:\n  zoom: 2\n"), ("bad.yaml", "camera.zoom", "unknown field"), False),
    Case("config-key-with-newline", _config_case('camera: {"zo\\nom": 2}\n'), ("bad.yaml", "camera.'zo\\nom'", "unknown field"), False),
    Case("config-wrong-type", _config_case("camera: {rate_hz: fast}\n"), ("bad.yaml", "camera.rate_hz"), False),
    Case("config-huge-number", _config_case("camera: {width: 1000000000000000000000000000000}\n"), ("bad.yaml", "camera.width"), False),
    Case("config-nan", _config_case("camera: {rate_hz: .nan}\n"), ("bad.yaml", "camera.rate_hz"), False),
    Case("config-negative-count", _config_case("greenhouse: {plants_per_table: -4}\n"), ("bad.yaml", "greenhouse.plants_per_table"), False),
    Case("config-python-tag", _config_case("camera: !!python/object/apply:os.system ['touch {tmp}/MARKER']\n"),
         ("bad.yaml", "not valid YAML"), False),
    Case("config-missing-file", _missing_config, ("nowhere.yaml", "cannot read"), False),
    Case("config-unknown-preset", _unknown_preset, ("gigantic", "preset"), False),
    # run-directory files
    Case("run-config-unknown-field", _write("config.yaml", "seed: 0\nbogus: 1\n", "plan", "{run}", "--force"),
         ("config.yaml", "bogus", "unknown field")),
    Case("trajectory-truncated", _truncated_trajectory, ("trajectory.csv",)),
    Case("waypoints-wrong-header", _waypoints_header, ("waypoints.csv", "header")),
    Case("flight-wrong-header", _flight_header, ("flight.csv", "header")),
    Case("groundtruth-nan", _groundtruth(1, "nan"), ("groundtruth.txt", "NaN")),
    Case("groundtruth-non-unit-quaternion", _groundtruth(7, "2.0"), ("groundtruth.txt", "quaternion")),
    Case("groundtruth-empty", _groundtruth(None), ("groundtruth.txt", "no poses")),
    Case("scene-not-json", _write("scene.json", "{not json", "plan", "{run}", "--force"), ("scene.json", "JSON")),
    Case("scene-list", _write("scene.json", "[1, 2, 3]", "plan", "{run}", "--force"), ("scene.json", "dictionary")),
    Case("rgb-png-truncated", _half_png, ("rgb/000001.png", "PNG"), may_leave=(CACHE,)),
    Case("depth-size-differs", _small_depth, ("000001.png", "12x10"), may_leave=(CACHE,)),
    Case("camera-info-not-mapping", _write("camera_info.yaml", "- 1\n- 2\n", "detect", "{run}", "--force"),
         ("camera_info.yaml", "camera_info")),
    Case("detections-list", _write("detections.json", "[]", "count", "{run}", "--force"), ("detections.json", "object")),
    Case("detections-image-escapes", _escaping_image, ("detections.json", "frames.0", "../../etc/passwd")),
    Case("counts-not-json", _write("counts.json", "{\"plants\": [", "report", "{run}"), ("counts.json", "JSON")),
    Case("model-random-bytes", _random_onnx, ("model.onnx", "ONNX")),
    Case("images-empty-folder", _empty_images, ("--images", "empty", "no PNG or JPEG"), False),
    Case("eval-seeds-reversed", _reversed_seeds, ("--seeds", "5-2", "backwards"), False),
    Case("render-unknown-backend", _args("render", "{run}", "--backend", "vulkan"), ("vulkan", "backend")),
    Case("export-target-exists", _export_exists, ("bag", "exists", "--force")),
    Case("option-out-of-range", _args("eval", "--seeds", "1", "--workers", "0", "--out", "{tmp}/eval"), ("--workers", "greater than"), False),
    Case("option-unknown", _args("scene", "--out", "{tmp}/run", "--zoom", "2"), ("--zoom",), False),
]


@pytest.mark.parametrize("case", CASES, ids=[case.id for case in CASES])
def test_bad_input_is_one_line_exit_2_and_touches_nothing(case: Case, complete_run: Path, tmp_path: Path, monkeypatch, capsys):
    run = None
    if case.needs_run:
        run = tmp_path / "run"
        shutil.copytree(complete_run, run)
    args = case.prepare(tmp_path, run)
    before = snapshot(tmp_path)

    code, out, err = cli(monkeypatch, capsys, *args)

    assert "Traceback" not in err, err
    lines = [line for line in err.splitlines() if line.strip()]
    errors = [line for line in lines if ERROR_PREFIX in line]
    assert len(errors) == 1 and lines[-1] == errors[0] and lines[-1].startswith(ERROR_PREFIX), err
    assert code == 2, err
    for name in case.names:
        assert name in errors[0], f"{name!r} not named in: {errors[0]}"
    assert out == "", "a failing command must not report having written anything"
    after = snapshot(tmp_path)
    for name in case.may_leave:  # documented resume state: whole JSON lines only, never half of one
        key = f"run/{name}"
        if key in after and key not in before:
            for line in (run / name).read_text().splitlines():
                json.loads(line)
            del after[key]
    assert after == before
    assert not (tmp_path / "MARKER").exists()


def test_bad_input_covers_at_least_twenty_distinct_cases():
    """The standard is checked on many kinds of input, not a token few: keep the list from shrinking."""
    assert len({case.id for case in CASES}) == len(CASES) >= 20


# --- random config documents --------------------------------------------------------------------------------------

SECTIONS = ("greenhouse", "plants", "robot", "camera", "planner", "controller", "renderer", "detector", "counting", "seed")


def _field_names(model: type[BaseModel], found: set[str]) -> set[str]:
    """Every field name of the config tree, so random documents reach the nested validators, not just 'unknown field'."""
    for name, field in model.model_fields.items():
        found.add(name)
        if isinstance(field.annotation, type) and issubclass(field.annotation, BaseModel):
            _field_names(field.annotation, found)
    return found


FIELD_NAMES = sorted(_field_names(Config, set()))
TEXT = st.text(st.characters(blacklist_categories=("Cs",)), max_size=8)
LEAVES = (st.none() | st.booleans() | TEXT | st.integers() | st.integers(min_value=-(10**40), max_value=10**40)
          | st.floats(allow_nan=True, allow_infinity=True) | st.sampled_from([0, -1, 1, 2**63, 1e308, float("nan"), float("inf")]))
VALUES = st.recursive(
    LEAVES,
    lambda children: st.lists(children, max_size=5) | st.dictionaries(st.sampled_from(FIELD_NAMES) | TEXT, children, max_size=4),
    max_leaves=12,
)
SECTION_FIELDS = {name: sorted(_field_names(field.annotation, set())) for name, field in Config.model_fields.items()
                  if isinstance(field.annotation, type) and issubclass(field.annotation, BaseModel)}


@st.composite
def documents(draw: st.DrawFn) -> dict:
    """A few real sections, each mostly a mapping of its own field names (else any value), so validators get exercised."""
    document = {}
    for section in draw(st.lists(st.sampled_from(SECTIONS), unique=True, max_size=4)):
        fields = SECTION_FIELDS.get(section)
        own = st.dictionaries(st.sampled_from(fields), VALUES, max_size=4) if fields else VALUES
        document[section] = draw(own | VALUES)
    return document


DOCUMENTS = documents()


@settings(max_examples=60, deadline=None)
@given(document=DOCUMENTS)
def test_any_yaml_config_gives_a_config_or_a_user_error(document: dict):
    """Whatever a user writes, load_config answers with a Config or a UserError: no other exception reaches the CLI."""
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "random.yaml"
        path.write_text(yaml.safe_dump(document, allow_unicode=True), encoding="utf-8")
        try:
            assert isinstance(load_config("demo", path), Config)
        except UserError as error:
            assert "\n" not in str(error) and str(path) in str(error)


# --- configs never run code --------------------------------------------------------------------------------------

UNSAFE_CALLS = {("yaml", "load"), ("yaml", "unsafe_load"), ("yaml", "full_load"), ("yaml", "load_all"), ("yaml", "unsafe_load_all"),
                ("pickle", "load"), ("pickle", "loads"), ("marshal", "loads"), ("dill", "load")}


def _unsafe_calls(tree: ast.AST) -> list[str]:
    found = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Attribute) and node.attr in ("open_mainfile", "UnsafeLoader", "FullLoader"):
            found.append(f"line {node.lineno}: .{node.attr}")
        if not isinstance(node, ast.Call):
            continue
        func = node.func
        if isinstance(func, ast.Name) and func.id in ("eval", "exec"):
            found.append(f"line {node.lineno}: {func.id}()")
        if isinstance(func, ast.Attribute) and isinstance(func.value, ast.Name):
            call = (func.value.id, func.attr)
            if call in UNSAFE_CALLS:
                found.append(f"line {node.lineno}: {'.'.join(call)}()")
            if call == ("torch", "load") and not any(
                k.arg == "weights_only" and isinstance(k.value, ast.Constant) and k.value.value is True for k in node.keywords
            ):
                found.append(f"line {node.lineno}: torch.load() without weights_only=True")
    return found


def test_configs_and_files_never_run_code():
    """YAML, checkpoints and .blend files come from users: no loader in the package may construct objects or run scripts."""
    offenders = {
        str(path.relative_to(SRC)): calls
        for path in sorted(SRC.rglob("*.py"))
        if (calls := _unsafe_calls(ast.parse(path.read_text(encoding="utf-8"), str(path))))
    }
    assert offenders == {}


def test_blender_factory_settings_always_disable_script_auto_execution():
    """Every read_factory_settings is followed in its block by use_scripts_auto_execute = False: a scene must not run Python."""
    source = (SRC / "render" / "cycles.py").read_text(encoding="utf-8")
    resets = 0
    for node in ast.walk(ast.parse(source)):
        for body in (getattr(node, name, None) for name in ("body", "orelse", "finalbody", "handlers")):
            if not isinstance(body, list):
                continue
            for index, statement in enumerate(body):
                if "read_factory_settings" not in ast.unparse(statement) or not isinstance(statement, ast.Expr):
                    continue
                resets += 1
                later = body[index + 1:]
                assert any(
                    isinstance(s, ast.Assign) and isinstance(s.value, ast.Constant) and s.value.value is False
                    and any(isinstance(t, ast.Attribute) and t.attr == "use_scripts_auto_execute" for t in s.targets)
                    for s in later
                ), f"cycles.py line {statement.lineno}: read_factory_settings without use_scripts_auto_execute = False"
    assert resets == source.count("read_factory_settings(")
