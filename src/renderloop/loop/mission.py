"""The adaptive mission (`mission.kind: adaptive`): a coarse pass, then next-best views where the count is uncertain.

The robot flies the static scan's path with the camera at `mission.adaptive.first_pass_rate_hz`. When a row's
plants have been passed on both sides (an instant the plan fixes), the mission takes that row's frames, asks the
online counter for each plant's count interval, and for every plant that is not settled chooses next-best views
(`renderloop.loop.nbv`) through the voxel map its depth frames built. It flies them by replanning from where the
reference is, checked clear of the greenhouse, with one frame at each view and the periodic frames held back, then
rejoins the scan at the next row. When a round's frames are in, the plants are asked again, up to
`mission.adaptive.rounds` times or until a plant's flight-time budget is spent. After every decision the harvest
plan is drawn again from the latest estimates of the plants counted so far.

Decisions are taken at those instants of simulated time only, and wait for the frames they read, so the mission
is the same whatever the renderers' speed.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from renderloop.config import Config, CountingConfig
from renderloop.counting.harvest import plan_harvest
from renderloop.counting.online import OnlineCounter
from renderloop.counting.summary import run_counting, scanned_rows
from renderloop.counting.uncertainty import PlantUncertainty, Uncertainty
from renderloop.errors import UserError
from renderloop.loop.nbv import (
    Candidate,
    ChosenView,
    candidate_views,
    canopy_box,
    select,
)
from renderloop.loop.sensors import Camera, Frame
from renderloop.loop.simulation import Simulation
from renderloop.loop.viewpoints import Projector, view_at
from renderloop.loop.voxels import VoxelMap
from renderloop.planning.check import Clash
from renderloop.planning.transit import TransitPlanner
from renderloop.planning.waypoints import Waypoint, footprint_radius, read_waypoints, transit
from renderloop.render.camera import Intrinsics
from renderloop.rundir import names
from renderloop.rundir.models import (
    Estimate,
    HarvestUpdate,
    Mission,
    MissionPlant,
    MissionRound,
    MissionView,
)
from renderloop.scene.model import Plant

SETTLE = 0.1  # s after a row's last scan waypoint, or a round's last view, before deciding: every frame is exposed
MAP_MARGIN = 0.15  # m of free space kept round a plant's box in its voxel map: the occluders just outside it
MAP_RANGE = 1.5  # m: a frame is added to the maps of the plants whose middle is this near the camera


@dataclass
class _PlantLog:
    plant: Plant
    budget: float  # s of re-scan flight left
    first_pass: Estimate | None = None
    rounds: list[dict] = field(default_factory=list)
    fallback: str | None = None


@dataclass(frozen=True)
class _Decision:
    time: float  # simulation s
    row: int
    round: int


class AdaptiveMission:
    """Decides, at its instants, which plants to look at again and from where; see the module docstring."""

    def __init__(self, sim: Simulation, camera: Camera, counter: OnlineCounter, config: Config) -> None:
        self.sim, self.camera, self.counter, self.config = sim, camera, counter, config
        self.settings = config.mission.adaptive
        self.intrinsics = Intrinsics.from_config(config.camera)
        self.scene = sim.scene
        self.static = read_waypoints(sim.run_dir)
        self.passes = {index: waypoint.time for index, waypoint in enumerate(self.static)}  # static index -> passed at
        self.router = TransitPlanner(self.scene, footprint_radius(config))
        rows = scanned_rows(config)  # the plants of the rows the scan visits: those it decides on and counts
        self.plants = [plant for plant in self.scene.plants if rows is None or plant.row in rows]
        self.maps = {plant.id: VoxelMap(canopy_box(plant)[0] - MAP_MARGIN, canopy_box(plant)[1] + MAP_MARGIN,
                                        self.settings.voxel) for plant in self.plants}
        self.logs = {plant.id: _PlantLog(plant, self.settings.budget_s) for plant in self.plants}
        self._candidate_views: dict[int, list[Candidate]] = {}
        self.view_frames: list[tuple[float, dict]] = []  # (trigger time, view record) to match frames to at the end
        self.ripe: dict[int, int] = {}  # plant id -> its latest ripe estimate, for the plants decided so far
        self.harvest: list[HarvestUpdate] = []
        self.row_end = {}  # row id -> static index of its last scan waypoint
        for index, waypoint in enumerate(self.static):
            if waypoint.kind == "scan":
                self.row_end[self.scene.plant(waypoint.plant).row] = index
        self.pending = sorted((_Decision(self.passes[index] + SETTLE, row, 0) for row, index in self.row_end.items()),
                              key=lambda d: d.time)

    # Frames -----------------------------------------------------------------------------------------------------------

    def take(self, frame: Frame) -> None:
        """A perceived frame's depth into the voxel maps of the plants it can show."""
        camera = frame.pose[:3, 3]
        for plant in self.plants:
            lower, upper = canopy_box(plant)
            if np.linalg.norm((lower + upper) / 2 - camera) <= MAP_RANGE:
                self.maps[plant.id].integrate(frame.depth, frame.pose, self.intrinsics)

    # Decisions --------------------------------------------------------------------------------------------------------

    def due(self) -> bool:
        return bool(self.pending) and self.sim.t >= self.pending[0].time - 1e-9

    def decide(self) -> None:
        """The decision due now: the caller has taken every frame asked for so far."""
        decision = self.pending.pop(0)
        plants = [plant for plant in self.scene.plants if plant.row == decision.row]
        uncertainty = self._uncertainty(plants)
        state = {plant.id: _estimate(uncertainty.plants[plant.id]) for plant in plants}
        self._update_harvest(decision, state)
        views: list[tuple[Plant, list, str]] = []
        for plant in self._nearest_first(plants):
            log, estimate = self.logs[plant.id], state[plant.id]
            if decision.round == 0:
                log.first_pass = estimate
            elif log.rounds and log.rounds[-1]["after"] is None:
                log.rounds[-1]["after"] = estimate
            if estimate.low == estimate.high == estimate.estimate or decision.round >= self.settings.rounds:
                continue
            if log.budget <= 0:
                log.fallback = log.fallback or ("no flight time budget (mission.adaptive.budget_s is 0)"
                                                if self.settings.budget_s == 0 else None)
                continue
            found = uncertainty.plants[plant.id]
            chosen, reason = self._views(plant, np.vstack([found.weak_centers, found.lone_points]))
            if not chosen:
                if decision.round == 0:
                    log.fallback = reason
                continue
            views.append((plant, chosen, self._why(estimate)))
        if views:
            self._fly(decision, views, state)

    def _update_harvest(self, decision: _Decision, state: dict[int, Estimate]) -> None:
        """The harvest plan from every plant's latest estimate: a grower's plan as the counts settle."""
        self.ripe.update({plant_id: estimate.estimate for plant_id, estimate in state.items()})
        plan = plan_harvest(self.scene, self.ripe, self.config.counting.harvest_min_ripe)
        self.harvest.append(HarvestUpdate(time=round(self.sim.t, 6), row=decision.row, round=decision.round,
                                          plants_counted=len(self.ripe), stops=[stop["id"] for stop in plan["stops"]],
                                          expected_ripe=plan["total_expected_ripe"], total_distance=plan["total_distance"]))

    def _uncertainty(self, plants: list[Plant], model: CountingConfig | None = None) -> Uncertainty:
        """The counter's intervals, the plants' unseen canopy from their voxel maps."""
        unseen = {plant.id: self.maps[plant.id].unknown_fraction(*canopy_box(plant)) for plant in plants}
        return self.counter.uncertainty(unseen=unseen, model=model)

    def _nearest_first(self, plants: list[Plant]) -> list[Plant]:
        here = self.sim.reference[0][:2]
        return sorted(plants, key=lambda plant: (math.dist(here, plant.position[:2]), plant.id))

    def _candidates(self, plant: Plant) -> list[Candidate]:
        """The plant's candidate views (reachable, clear in MuJoCo) whose body the transit router can also reach."""
        if plant.id not in self._candidate_views:
            projector = Projector(self.config, self.scene, plant, self.sim.run_dir / names.WORLD)
            self._candidate_views[plant.id] = [c for c in candidate_views(projector) if self.router.grid.is_free(c.dofs)]
        return self._candidate_views[plant.id]

    def _views(self, plant: Plant, uncertain: np.ndarray) -> tuple[list[ChosenView], str]:
        """Views chosen to see the uncertain fruit (weak clusters, fruit seen once) and the unseen canopy."""
        budget = self.logs[plant.id].budget
        if budget <= 0:  # before the candidates: they cost MuJoCo checks
            return [], "no flight time budget left"
        start = view_at(plant, self.sim.state.camera_pose[:3, 3])
        return select(self._candidates(plant), self.maps[plant.id], self.intrinsics, canopy_box(plant), uncertain,
                      start=start, velocity_limits=self.config.planner.velocity_limits, budget_s=budget,
                      max_views=self.settings.views_per_round, min_gain=self.settings.min_gain)

    @staticmethod
    def _why(estimate: Estimate) -> str:
        reasons = [f"interval {estimate.low}-{estimate.high} about {estimate.estimate}"]
        if estimate.weak:
            reasons.append(f"{estimate.weak} weakly supported fruit")
        if estimate.seen_once:
            reasons.append(f"{estimate.seen_once} fruit seen once")
        if estimate.unseen is not None:
            reasons.append(f"{100 * estimate.unseen:.0f} % of the canopy unseen")
        return ", ".join(reasons)

    def _fly(self, decision: _Decision, plan: list[tuple[Plant, list, str]], state: dict[int, Estimate]) -> None:
        """Replan through the chosen views, rejoining the scan where it goes on after this row. Each view was checked
        clear, but the trajectory through them may bend too near a plant: then the view it was heading for is dropped
        (the last view, when past them all) and the rest tried again, and a plant left with none falls back to its
        first pass."""
        rejoin = next((i for i in range(self.row_end[decision.row] + 1, len(self.static))
                       if self.static[i].kind in ("scan", "end")), len(self.static) - 1)
        rest = self.static[rejoin:]
        plan = [(plant, list(chosen), why) for plant, chosen, why in plan]
        while True:
            marks: list[tuple] = []
            try:
                path, marks = self._path(plan, self.static[rejoin])
                times = self.sim.replan(np.array([w.dofs for w in path + rest]), check=True)
                break
            except UserError as problem:
                refused = f"the re-scan path was refused: {problem}"
                _drop_view(plan, marks, problem.waypoint if isinstance(problem, Clash) else None)
                for plant, chosen, _ in plan:
                    if not chosen and decision.round == 0:
                        self.logs[plant.id].fallback = refused
                plan = [entry for entry in plan if entry[1]]
                if not plan:
                    return
        for offset, index in enumerate(range(rejoin, len(self.static))):
            self.passes[index] = float(times[len(path) + offset])
        self._retime(decision.row)
        last = max(float(times[i]) for i, _, _ in marks)
        for plant, chosen, why in plan:
            records = []
            for i, owner, view in marks:
                if owner is plant:
                    self.camera.trigger(float(times[i]))
                    record = {"azimuth": view.view.azimuth, "height": view.view.height, "distance": view.view.distance,
                              "time": float(times[i]), "frame": None, "unknown_cells": int(view.gain_cells),
                              "uncertain_fruit": int(view.gain_fruit)}
                    self.view_frames.append((float(times[i]), record))
                    records.append(record)
            log = self.logs[plant.id]
            log.budget -= max(view.flight_s for view in chosen)
            log.rounds.append({"decided_at": round(self.sim.t, 6), "why": why, "before": state[plant.id], "after": None,
                               "views": records})
        self.camera.pause(until=last)
        self.pending.append(_Decision(last + SETTLE, decision.row, decision.round + 1))
        self.pending.sort(key=lambda d: d.time)

    def _path(self, plan: list[tuple[Plant, list, str]], rejoin: Waypoint) -> tuple[list[Waypoint], list[tuple]]:
        """The waypoints from the reference through every chosen view to `rejoin`, and (index in them, plant, view)
        of each view."""
        path: list[Waypoint] = []
        marks: list[tuple[int, Plant, object]] = []
        previous = Waypoint("transit", self.sim.reference[0].copy())
        for plant, chosen, _ in plan:
            for view in chosen:
                stop = Waypoint("view", np.asarray(view.dofs, dtype=float), plant.id)
                path.extend(transit(self.router, previous, stop))
                marks.append((len(path), plant, view))
                path.append(stop)
                previous = stop
        path.extend(transit(self.router, previous, rejoin))
        return path, marks

    def _retime(self, row: int) -> None:
        """Later rows' decisions at the instants the new plan passes their last scan waypoints."""
        self.pending = [_Decision(self.passes[self.row_end[d.row]] + SETTLE, d.row, d.round)
                        if d.round == 0 and d.row != row else d for d in self.pending]

    # The record -------------------------------------------------------------------------------------------------------

    def record(self, timestamps: list[float], flight_time: float) -> Mission:
        """`mission.json` once the flight is over and every frame is in; the final estimates are the run's count's
        (`run_counting`: an adaptive run's own interval and lone credit)."""
        uncertainty = self._uncertainty(self.plants, run_counting(self.config))
        final = {plant.id: _estimate(uncertainty.plants[plant.id]) for plant in self.plants}
        for trigger, view in self.view_frames:
            taken = [i for i, stamp in enumerate(timestamps) if stamp >= trigger - 1e-9]
            view["frame"] = taken[0] if taken else None
        plants = []
        for plant in self.plants:
            log = self.logs[plant.id]
            rounds = [MissionRound(decided_at=r["decided_at"], why=r["why"], before=r["before"],
                                   after=r["after"] or final[plant.id],
                                   views=[MissionView(**view) for view in r["views"]]) for r in log.rounds]
            plants.append(MissionPlant(id=plant.id, row=plant.row, first_pass=log.first_pass or final[plant.id],
                                       final=final[plant.id], rounds=rounds, fallback=log.fallback))
        at_views = {view["frame"] for _, view in self.view_frames if view["frame"] is not None}
        return Mission(kind="adaptive", settings=self.settings.model_dump(mode="json"), frames=len(timestamps),
                       first_pass_frames=len(timestamps) - len(at_views), flight_time_s=round(flight_time, 6),
                       plants=plants, harvest=self.harvest)


def _estimate(plant: PlantUncertainty) -> Estimate:
    return Estimate(estimate=plant.estimate, low=plant.low, high=plant.high, weak=len(plant.weak_centers),
                    seen_once=len(plant.lone_points),
                    unseen=None if plant.unseen is None else round(float(plant.unseen), 6))


def _drop_view(plan: list[tuple[Plant, list, str]], marks: list[tuple], heading: int | None) -> None:
    """Drop the view a refused path was heading for when it clashed (`heading`: that waypoint's index in the path,
    `marks`: each view's), or the last view when the clash came after them all or the path was not made."""
    ahead = [view for index, _, view in marks if heading is not None and index >= heading]
    if ahead:
        for _, chosen, _ in plan:
            chosen[:] = [view for view in chosen if view is not ahead[0]]
    else:
        [chosen for _, chosen, _ in plan if chosen][-1].pop()
