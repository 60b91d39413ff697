"""The paper's experiment table: one row per scenario (seed), then the mean absolute error and the worst one."""

from __future__ import annotations

import io
from dataclasses import asdict, astuple, dataclass, fields
from pathlib import Path

from renderloop.io.atomic import write_json, write_text
from renderloop.rundir.files import read_counts, read_mission, read_trajectory

EVAL_CSV, EVAL_JSON = "eval.csv", "eval.json"


@dataclass(frozen=True)
class Scenario:
    seed: int
    mission: str  # static or adaptive (mission.kind)
    frames: int  # frames rendered
    flight_time_s: float  # s, the planned motion (the hover at its end not included)
    truth: int  # ripe fruit in the scene: the yield
    estimate: int
    error_pct: float | None  # None when the scene has no ripe fruit
    exact_plants: float  # share of plants whose ripe count is exact
    unripe_truth: int
    unripe_estimate: int


def scenario(seed: int, mission: str, run_dir: Path) -> Scenario:
    counts = read_counts(run_dir)
    total, plants = counts.total, counts.plants
    exact = sum(plant.estimate == plant.truth for plant in plants) / max(1, len(plants))
    flown = read_mission(run_dir).flight_time_s if mission == "adaptive" else float(read_trajectory(run_dir)[-1, 0])
    return Scenario(seed, mission, counts.detections.frames, round(flown, 3), total.truth, total.estimate, total.error_pct,
                    round(exact, 4), total.unripe_truth, total.unripe_estimate)


def summary(scenarios: list[Scenario]) -> dict[str, float | int | None]:
    errors = [(abs(s.error_pct), s.seed) for s in scenarios if s.error_pct is not None]
    worst = max(errors, default=(None, None))
    return {
        "scenarios": len(scenarios),
        "frames": round(sum(s.frames for s in scenarios) / max(1, len(scenarios)), 1),
        "flight_time_s": round(sum(s.flight_time_s for s in scenarios) / max(1, len(scenarios)), 1),
        "mean_abs_error_pct": round(sum(e for e, _ in errors) / len(errors), 2) if errors else None,
        "worst_abs_error_pct": worst[0],
        "worst_seed": worst[1],
        "within_10_pct": sum(e <= 10 for e, _ in errors),
        "exact_plants": round(sum(s.exact_plants for s in scenarios) / max(1, len(scenarios)), 4),
    }


def missions_of(scenarios: list[Scenario]) -> list[str]:
    return list(dict.fromkeys(s.mission for s in scenarios))


def write_eval(out: Path, scenarios: list[Scenario]) -> None:
    """eval.csv, one row per scenario (for spreadsheets), and eval.json with each mission's summary beside them."""
    buffer = io.StringIO()
    buffer.write(",".join(f.name for f in fields(Scenario)) + "\n")
    for row in scenarios:
        buffer.write(",".join("" if value is None else str(value) for value in astuple(row)) + "\n")
    write_text(Path(out) / EVAL_CSV, buffer.getvalue())
    summaries = {kind: summary([s for s in scenarios if s.mission == kind]) for kind in missions_of(scenarios)}
    write_json(Path(out) / EVAL_JSON, {"scenarios": [asdict(s) for s in scenarios], "summary": summaries})


def format_table(scenarios: list[Scenario]) -> str:
    """Plain text, so it reads the same in a terminal, a log and an issue note; missions side by side, seed by seed."""
    lines = ["| seed | mission | frames | flight s | true ripe | estimate | error % | plants exact | unripe (true) |",
             "| --- | --- | --- | --- | --- | --- | --- | --- | --- |"]
    for s in sorted(scenarios, key=lambda s: s.seed):
        error = "n/a" if s.error_pct is None else f"{s.error_pct:+.1f}"
        lines.append(f"| {s.seed} | {s.mission} | {s.frames} | {s.flight_time_s:.0f} | {s.truth} | {s.estimate} | {error} "
                     f"| {s.exact_plants:.0%} | {s.unripe_estimate} ({s.unripe_truth}) |")
    for kind in missions_of(scenarios):
        totals = summary([s for s in scenarios if s.mission == kind])
        mae = "n/a" if totals["mean_abs_error_pct"] is None else f"{totals['mean_abs_error_pct']:.1f} %"
        worst = "n/a" if totals["worst_seed"] is None else f"seed {totals['worst_seed']} ({totals['worst_abs_error_pct']:.1f} %)"
        lines.append(f"\n{kind}: mean absolute error {mae}; worst {worst}; {totals['within_10_pct']} of {totals['scenarios']} "
                     f"within 10 %; plants counted exactly {totals['exact_plants']:.0%}; {totals['frames']:g} frames and "
                     f"{totals['flight_time_s']:g} s of flight a seed")
    return "\n".join(lines)
