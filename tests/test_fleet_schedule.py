"""The fleet's schedule: several UAVs, one mission a row, no two in one aisle at once, checked by brute force."""

from __future__ import annotations

import itertools
import json

import numpy as np
import pytest

from renderloop.errors import UserError
from renderloop.fleet.schedule import Box, Mission, corridor, schedule
from renderloop.rundir.models import Flight, Schedule
from renderloop.rundir.files import read_model, write_model


def _shared_area(a: Box, b: Box) -> float:
    """The area two boxes share, computed apart from Box.overlaps."""
    return max(0.0, min(a.x1, b.x1) - max(a.x0, b.x0)) * max(0.0, min(a.y1, b.y1) - max(a.y0, b.y0))


def _meet(a: tuple[float, float], b: tuple[float, float]) -> bool:
    """Whether two [start, end) intervals share a moment."""
    return max(a[0], b[0]) < min(a[1], b[1])


def _random_case(seed: int) -> tuple[list[Mission], int]:
    """Rows in random places and order, on a coarse grid so that boxes often overlap, touch or coincide."""
    rng = np.random.default_rng(seed)
    count = int(rng.integers(1, 13))
    rows = rng.permutation(40)[:count]
    missions = []
    for row in rows:
        x0, y0 = rng.integers(0, 8, size=2) / 2
        width, length = rng.integers(1, 5, size=2) / 2
        # Whole and fractional seconds, and now and then a mission of no duration.
        duration = float(rng.choice([0.0, rng.integers(1, 50), rng.uniform(0.5, 50)], p=[0.1, 0.45, 0.45]))
        missions.append(Mission(int(row), duration, Box(x0, y0, x0 + width, y0 + length)))
    return missions, int(rng.integers(1, 5))


def _allowed(mission: Mission, earlier: list[tuple[Mission, Flight]], uav: int, start: float) -> bool:
    """Whether `mission` may start at `start` on `uav`, given the earlier missions' flights: after the UAV's last
    flight, and clear of every flight whose corridor shares area with its own."""
    after_its_last = all(f.end_s <= start for _, f in earlier if f.uav == uav)
    clear = all(not _meet((start, start + mission.duration_s), (f.start_s, f.end_s))
                for m, f in earlier if _shared_area(m.corridor, mission.corridor) > 0)
    return after_its_last and clear


SEEDS = range(300)


def test_the_random_cases_often_hold_overlapping_corridors_touching_ones_and_more_missions_than_uavs():
    """Guards the brute-force tests below against cases too easy to fail them."""
    cases = [_random_case(seed) for seed in SEEDS]
    pairs = [(a.corridor, b.corridor) for missions, _ in cases for a, b in itertools.combinations(missions, 2)]
    overlapping = sum(_shared_area(a, b) > 0 for a, b in pairs)
    touching = sum(_shared_area(a, b) == 0 and (a.x1 == b.x0 or b.x1 == a.x0) for a, b in pairs)
    crowded = sum(1 < uavs < len(missions) for missions, uavs in cases)
    assert overlapping > 1000 and touching > 100 and crowded > 100, (overlapping, touching, crowded)


def test_no_two_overlapping_corridors_ever_overlap_in_time():
    for seed in SEEDS:
        missions, uavs = _random_case(seed)
        flights = schedule(missions, uavs).flights
        for (a, fa), (b, fb) in itertools.combinations(zip(missions, flights), 2):
            if _shared_area(a.corridor, b.corridor) > 0:
                assert not _meet((fa.start_s, fa.end_s), (fb.start_s, fb.end_s)), (seed, fa, fb)


def test_no_uav_flies_two_missions_at_once():
    for seed in SEEDS:
        missions, uavs = _random_case(seed)
        result = schedule(missions, uavs)
        assert [flight.row for flight in result.flights] == [mission.row for mission in missions]
        assert all(0 <= flight.uav < uavs for flight in result.flights)
        for fa, fb in itertools.combinations(result.flights, 2):
            if fa.uav == fb.uav:
                assert not _meet((fa.start_s, fa.end_s), (fb.start_s, fb.end_s)), (seed, fa, fb)


def test_every_mission_goes_to_the_uav_that_can_start_it_earliest_at_the_earliest_time_the_rules_allow():
    """Against the earlier missions' flights, every candidate time (0 and each earlier flight's end; the earliest
    allowed start is one of them) before the chosen start is ruled out on every UAV, and the chosen start on every
    lower UAV."""
    for seed in SEEDS:
        missions, uavs = _random_case(seed)
        flights = schedule(missions, uavs).flights
        for i, (mission, flight) in enumerate(zip(missions, flights)):
            assert flight.end_s == flight.start_s + mission.duration_s
            earlier = list(zip(missions[:i], flights[:i]))
            for start in sorted({0.0, *(f.end_s for _, f in earlier)}):
                for uav in range(uavs):
                    if start < flight.start_s or (start == flight.start_s and uav < flight.uav):
                        assert not _allowed(mission, earlier, uav, start), (seed, i, uav, start)
            assert _allowed(mission, earlier, flight.uav, flight.start_s)


def test_one_uav_flies_the_missions_back_to_back_in_order_with_the_makespan_their_sum():
    durations = [30.0, 12.5, 0.0, 41.25]
    missions = [Mission(row, duration, Box(row, 0, row + 0.5, 1)) for row, duration in zip([3, 0, 2, 1], durations)]
    result = schedule(missions, 1)
    assert [flight.row for flight in result.flights] == [3, 0, 2, 1]
    assert [flight.uav for flight in result.flights] == [0] * 4
    assert [flight.start_s for flight in result.flights] == [0.0, 30.0, 42.5, 42.5]
    assert all(a.end_s == b.start_s for a, b in itertools.pairwise(result.flights))
    assert result.makespan_s == sum(durations)


def test_with_as_many_uavs_as_missions_and_disjoint_corridors_every_mission_starts_at_0():
    # Neighbours share an edge: touching corridors do not keep missions apart.
    missions = [Mission(row, 10.0 + row, Box(row, 0, row + 1, 5)) for row in range(5)]
    result = schedule(missions, 5)
    assert [flight.start_s for flight in result.flights] == [0.0] * 5
    assert [flight.uav for flight in result.flights] == [0, 1, 2, 3, 4]
    assert result.makespan_s == 14.0


def test_two_lines_scanned_from_one_middle_path_never_fly_together_in_the_commercial_compartment():
    # Four lines; lines 1 and 2 are scanned from the middle path, 0.05 m either side of its centre, the outer lines
    # from the paths by the walls.
    scan_x = [-2.35, 0.05, -0.05, 2.35]
    y = np.linspace(-10, 10, 21)
    missions = [Mission(row, 100.0, corridor(np.column_stack([np.full_like(y, x), y]), 0.64))
                for row, x in enumerate(scan_x)]
    assert missions[1].corridor == Box(0.05 - 0.64, -10.64, 0.05 + 0.64, 10.64)
    result = schedule(missions, 2)
    line1, line2 = result.flights[1], result.flights[2]
    assert not (line1.start_s < line2.end_s and line2.start_s < line1.end_s)
    assert [(f.uav, f.start_s) for f in result.flights] == [(0, 0.0), (1, 0.0), (0, 100.0), (1, 100.0)]
    assert result.makespan_s == 200.0


def test_the_schedule_comes_back_from_fleet_json_as_it_was_written(tmp_path):
    missions, uavs = _random_case(7)
    result = schedule(missions, uavs)
    write_model(tmp_path / "fleet.json", result)
    assert read_model(tmp_path / "fleet.json", Schedule) == result
    assert Schedule.model_validate(result.model_dump(mode="json")) == result


def test_a_fleet_json_whose_makespan_is_not_its_last_end_is_refused_in_one_line(tmp_path):
    data = schedule([Mission(0, 5.0, Box(0, 0, 1, 1))], 1).model_dump(mode="json")
    data["makespan_s"] = 4.0
    (tmp_path / "fleet.json").write_text(json.dumps(data))
    with pytest.raises(UserError, match=r"fleet.json: makespan_s 4.0 is not when the last flight ends$"):
        read_model(tmp_path / "fleet.json", Schedule)


BOX = Box(0, 0, 1, 1)


@pytest.mark.parametrize("make, words", [
    (lambda: schedule([Mission(0, 1.0, BOX)], 0), "a fleet has a whole number of UAVs"),
    (lambda: schedule([Mission(0, 1.0, BOX)], 1.5), "a fleet has a whole number of UAVs"),
    (lambda: Mission(2, -1.0, BOX), "row 2: a mission's duration is finite"),
    (lambda: Mission(2, float("nan"), BOX), "row 2: a mission's duration is finite"),
    (lambda: Mission(2, float("inf"), BOX), "row 2: a mission's duration is finite"),
    (lambda: Mission(-1, 1.0, BOX), "a mission's row is a whole number"),
    (lambda: schedule([Mission(4, 1.0, BOX), Mission(1, 1.0, BOX), Mission(4, 2.0, BOX)], 2), "row 4 has two missions"),
    (lambda: Box(0, float("nan"), 1, 1), "a corridor is a finite box"),
    (lambda: corridor(np.zeros((0, 2)), 0.5), "a scan's corridor needs an (N, 2) array"),
    (lambda: corridor(np.zeros((3, 2)), -0.5), "a corridor's radius is a finite distance"),
    (lambda: schedule([Mission(row, 6e6, Box(0, 0, 1, 1)) for row in range(2)], 1), "row 1: the missions would end"),
])
def test_bad_input_gives_one_line(make, words):
    with pytest.raises(UserError) as error:
        make()
    assert str(error.value).startswith(words) and "\n" not in str(error.value)
