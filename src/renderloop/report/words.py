"""The report's words: what each figure of a run means, with its unit, and the lines `renderloop run` ends with.

Field names of the run's files (`ripe_findable`, `position_error_p90_m`) stay in the
files; people read these sentences instead.
"""

from __future__ import annotations

from pathlib import Path

from renderloop.perception.scoring import MIN_SIDE
from renderloop.rundir.models import CountInterval, Counts, DetectionScores, DetectionTally

# What each stage does, in the order `renderloop run` runs them.
STAGE_WORDS = {
    "scene": "generating the greenhouse",
    "plan": "planning the scan path",
    "fly": "flying it in MuJoCo",
    "online": "flying, rendering and detecting as one loop",
    "render": "rendering the camera frames",
    "detect": "detecting peppers in the frames",
    "count": "counting fruit per plant and planning the harvest",
}
FINDABLE = f"big enough to find, {MIN_SIDE} x {MIN_SIDE} px or more"


def number(value: float | None, digits: int = 1) -> str:
    return "n/a" if value is None else f"{value:.{digits}f}"


def signed_pct(value: float | None) -> str:
    """An error in per cent with its sign: +12.5 %, -40.0 %, 0.0 %."""
    if value is None:
        return "n/a"
    return "0.0 %" if round(value, 1) == 0 else f"{value:+.1f} %"


def share(part: int, whole: int) -> str:
    """`23 of 61 (38 %)`."""
    return f"{part} of {whole}" + (f" ({100 * part / whole:.0f} %)" if whole else "")


def seconds(value: float) -> str:
    if value < 60:
        return f"{value:.1f} s"
    minutes, rest = divmod(round(value), 60)
    return f"{minutes} min {rest:02d} s" if minutes < 60 else f"{minutes // 60} h {minutes % 60:02d} min"


def count_range(interval: CountInterval | None) -> str:
    """A count's interval as people write a range: '7-9', or the count alone when it is sure."""
    if interval is None:
        return "n/a"
    return str(interval.low) if interval.low == interval.high else f"{interval.low}-{interval.high}"


def exact_plants(counts: Counts) -> str:
    """`2 of 4 plants (50 %)`: plants whose ripe count is exactly right."""
    exact = sum(plant.estimate == plant.truth for plant in counts.plants)
    return f"{share(exact, len(counts.plants))}" if counts.plants else "n/a"


def score_lines(scores: DetectionScores) -> list[tuple[str, str]]:
    """The detector against the masks, figure by figure: (what it is, its value)."""

    def cm(value: float | None) -> str:
        return "n/a" if value is None else f"{100 * value:.1f} cm"

    labelled = scores.detections_scored - scores.false_detections
    right = None if scores.label_accuracy is None else round(scores.label_accuracy * labelled)
    return [
        (f"Ripe fruit found (of those {FINDABLE})", share(scores.ripe_found, scores.ripe_findable)),
        ("Detections that were no fruit at all", share(scores.false_detections, scores.detections_scored)),
        ("Ripeness called right (of the detections that were a fruit)",
         "n/a" if right is None else share(right, labelled)),
        ("Position error of a fruit's 3D point, median, cm", cm(scores.position_error_median_m)),
        ("Position error of a fruit's 3D point, 90th percentile, cm", cm(scores.position_error_p90_m)),
    ]


def recall_sentence(scores: DetectionScores, counts: Counts) -> str:
    """Why a detector that misses many views still gives a right count: recall counts views, the count counts fruit."""
    total = counts.total
    shown = total.truth - total.unseen - total.too_small if total.unseen is not None and total.too_small is not None else total.truth
    fruit = f"the {shown} ripe fruit it showed big enough to find" if shown != total.truth else f"the {shown} ripe fruit"
    each = f" (about {scores.ripe_findable / shown:.0f} views each)" if shown else ""
    views = counts.settings.get("min_views")
    needed = f"{views} or more of its views" if isinstance(views, int) else "enough of its views"
    found = f"{scores.ripe_found} of those {scores.ripe_findable} views" + (
        f" ({100 * scores.ripe_found / scores.ripe_findable:.0f} %)" if scores.ripe_findable else "")
    return (f"Recall is counted per view, not per fruit: the scan showed {fruit} {scores.ripe_findable} times in all{each} "
            f"and the detector found the fruit in {found}; the count instead gathers the 3D points of all views into one "
            f"cluster a fruit and counts a fruit found in {needed}, so a fruit missed in many views is still counted: "
            f"here {total.estimate} estimated against {total.truth} true.")


def tally_sentence(tally: DetectionTally) -> str:
    """What the count was made from."""
    text = (f"The count used {tally.ripe} ripe and {tally.unripe} unripe detections with a 3D point, "
            f"from {tally.frames} frames")
    if tally.no_position:
        text += f"; {tally.no_position} more had no depth reading and no point"
    removed = tally.removed + tally.unripe_removed
    text += (f"; {tally.removed} ripe and {tally.unripe_removed} unripe points were dropped as lying on no plant."
             if removed else "; no point was dropped as lying on no plant.")
    return text


def misses_sentence(counts: Counts) -> str:
    """The scan's misses (from the masks): fruit no detector could have found."""
    total = counts.total
    if total.unseen is None or total.too_small is None:
        return "This run has no instance masks, so which fruit the scan never showed is not known."
    seen = total.truth - total.unseen - total.too_small
    if not total.unseen and not total.too_small:
        return (f"The scan showed every ripe fruit at {MIN_SIDE} x {MIN_SIDE} px or more in some frame, big enough to find: "
                "any error is the detector's and the counting's.")
    return (f"The scan never had {total.unseen} ripe fruit in view, and showed {total.too_small} more only smaller than "
            f"{MIN_SIDE} x {MIN_SIDE} px. Against the {seen} it showed {FINDABLE}, the estimate is off by "
            f"{signed_pct(total.seen_error_pct)}.")


def timing_sentence(timings: dict[str, float], order: tuple[str, ...]) -> str:
    """`24.3 s in all; most of it rendering the camera frames (11.2 s, 46 %).`"""
    stages = [name for name in order if name in timings] + sorted(set(timings) - set(order))
    total = sum(timings[name] for name in stages)
    if not stages or total <= 0:
        return "The stages were all complete before this run, so their times are not known."
    slowest = max(stages, key=lambda name: timings[name])
    return (f"{seconds(total)} in all; most of it went to {STAGE_WORDS.get(slowest, slowest)} "
            f"({seconds(timings[slowest])}, {100 * timings[slowest] / total:.0f} %).")


def run_summary(counts: Counts, report: Path) -> list[str]:
    """The three lines `renderloop run` ends with."""
    total = counts.total
    return [
        f"ripe yield: {total.estimate} estimated, {total.truth} true ({signed_pct(total.error_pct)})",
        f"plants counted exactly: {exact_plants(counts)}",
        f"report: {report}",
    ]
