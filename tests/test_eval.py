"""`renderloop eval`: one run per seed in parallel, the table from their counts, resumable, strict about seeds."""

from __future__ import annotations

import csv
import io
import json
from pathlib import Path

import pytest
import yaml
from conftest import cli

from renderloop.errors import UserError
from renderloop.evaluation.seeds import parse_seeds


def test_seed_lists_parse_as_people_type_them():
    assert parse_seeds("0-3") == [0, 1, 2, 3]
    assert parse_seeds("7, 0,4-5,4") == [7, 0, 4, 5]
    for bad in ("", "a", "3-1", "1,,2", "-2", "1-2-3", "0-99999"):
        with pytest.raises(UserError, match="--seeds"):
            parse_seeds(bad)


@pytest.fixture(scope="module")
def fast_config(tmp_path_factory) -> Path:
    """The demo scenario with the raster renderer and a frame every 4 s: a whole run in seconds."""
    path = tmp_path_factory.mktemp("eval") / "fast.yaml"
    path.write_text(yaml.safe_dump({"renderer": {"backend": "raster"}, "camera": {"rate_hz": 0.25}}))
    return path


def _eval_args(config: Path, seeds: str, out: Path, *extra: str) -> tuple[str, ...]:
    return ("eval", "--preset", "demo", "--config", str(config), "--seeds", seeds, "--out", str(out), *extra)


@pytest.fixture(scope="module")
def local_eval(fast_config: Path, tmp_path_factory) -> tuple[Path, str]:
    """Seeds 3 and 1 on two local processes: the run directories and the printed table."""
    from renderloop.cli import main

    out = tmp_path_factory.mktemp("eval") / "local"
    with pytest.MonkeyPatch.context() as patch:
        patch.setattr("sys.argv", ["renderloop", *_eval_args(fast_config, "3,1", out, "--workers", "2")])
        buffer = io.StringIO()
        patch.setattr("sys.stdout", buffer)
        with pytest.raises(SystemExit) as ended:
            main()
    assert not ended.value.code
    return out, buffer.getvalue()


def test_eval_runs_every_seed_in_parallel_and_tables_their_counts(local_eval, fast_config: Path, monkeypatch, capsys):
    out, stdout = local_eval
    with open(out / "eval.csv", encoding="utf-8") as handle:
        rows = list(csv.DictReader(handle))
    assert [int(row["seed"]) for row in rows] == [3, 1]
    for row in rows:
        counts = json.loads((out / f"seed_{row['seed']}" / "counts.json").read_text())
        assert (int(row["truth"]), int(row["estimate"])) == (counts["total"]["truth"], counts["total"]["estimate"])
        assert yaml.safe_load((out / f"seed_{row['seed']}" / "config.yaml").read_text())["seed"] == int(row["seed"])
        assert row["mission"] == "static" and int(row["frames"]) == counts["detections"]["frames"]
        assert f"| {row['seed']} | static | {row['frames']} | {float(row['flight_time_s']):.0f} | {row['truth']} | {row['estimate']} |" in stdout
    summary = json.loads((out / "eval.json").read_text())["summary"]["static"]
    assert summary["scenarios"] == 2 and "mean absolute error" in stdout
    errors = [abs(float(row["error_pct"])) for row in rows]
    assert summary["mean_abs_error_pct"] == pytest.approx(sum(errors) / 2, abs=0.01)

    before = {path: path.stat().st_mtime_ns for path in out.rglob("*.png")}
    code, again, _ = cli(monkeypatch, capsys, *_eval_args(fast_config, "3,1", out, "--workers", "1"))  # other thread count
    assert code == 0 and again == stdout
    assert {path: path.stat().st_mtime_ns for path in out.rglob("*.png")} == before  # every stage was complete
    code, _, err = cli(monkeypatch, capsys, "run", "--preset", "demo", "--config", str(fast_config), "--seed", "1",
                       "--out", str(out / "seed_1"))
    assert code == 0 and "skipped" in err and "done)" not in err


def test_ray_tasks_give_the_files_of_local_processes(local_eval, fast_config: Path, tmp_path: Path, monkeypatch, capsys):
    local, _ = local_eval
    code, _, err = cli(monkeypatch, capsys, *_eval_args(fast_config, "1", tmp_path, "--executor", "ray", "--workers", "2"))
    assert code == 0, err
    for name in ("scene.json", "groundtruth.txt", "depth/000003.png", "detections.json", "counts.json"):
        assert (tmp_path / "seed_1" / name).read_bytes() == (local / "seed_1" / name).read_bytes(), name


@pytest.mark.parametrize("seeds, message", [("", "is not a seed"), ("9-2", "runs backwards"), ("x", "is not a seed")])
def test_bad_seed_lists_exit_2_with_one_line(seeds: str, message: str, tmp_path: Path, monkeypatch, capsys):
    code, _, err = cli(monkeypatch, capsys, "eval", "--seeds", seeds, "--out", str(tmp_path / "eval"))
    assert code == 2 and message in err and len(err.strip().splitlines()) == 1
    assert not (tmp_path / "eval").exists()
