"""`renderloop run --online`: fly, render and detect at once, the camera in the loop.

The planned scan is flown in a `Simulation`; the camera asks for a frame at each of its
instants and the physics goes on stepping while the frame renders; perception takes each
frame as it arrives, in frame order, and feeds the online counter. What comes out is the
run directory of the batch stages fly, render and detect, file for file (the same flight,
the same frames, the same detections), so `count`, `report`, `export` and `eval` read it
unchanged and count what the batch pipeline counts.
"""

from __future__ import annotations

from contextlib import ExitStack
from pathlib import Path

import numpy as np

from renderloop.config import Config
from renderloop.counting.online import OnlineCounter
from renderloop.loop.mission import AdaptiveMission
from renderloop.loop.perceive import OnlinePerception
from renderloop.loop.simulation import Simulation
from renderloop.perception.stage import write_detections
from renderloop.render.frames import write_frame
from renderloop.render.stage import clear_frames, finish_render, render_record
from renderloop.rundir import files, names
from renderloop.rundir.stage import Job, Stage
from renderloop.sim.stage import NEEDS as FLY_NEEDS
from renderloop.sim.stage import write_flight


def _fly_in_loop(run_dir: Path, config: Config, job: Job) -> None:
    """The scan flown with the camera in the loop; with `mission.kind: adaptive`, steered by `AdaptiveMission`."""
    adaptive = config.mission.kind == "adaptive"
    clear_frames(run_dir)  # the frames of an earlier or interrupted run: these are rendered again as the robot flies
    with ExitStack() as stack:
        sim = stack.enter_context(Simulation(config, run_dir))
        sim.follow(sim.scan_trajectory())
        rate = config.mission.adaptive.first_pass_rate_hz if adaptive else None
        executor = job.executor
        camera = sim.add_camera(rate_hz=rate, workers=executor.workers, executor=executor.kind, address=executor.address,
                                encode=True)
        counter = OnlineCounter(sim.scene, config.counting, config.seed)
        perception = stack.enter_context(OnlinePerception(config, counter, thread=True))
        mission = AdaptiveMission(sim, camera, counter, config) if adaptive else None
        written = 0

        def take_ready(wait: bool) -> None:
            """Frames are taken in order; without `wait`, only as far as they have arrived (the physics never waits)."""
            nonlocal written
            while written < len(camera) and (wait or camera.ready(written)):
                frame = camera.frame(written)
                write_frame(run_dir, frame.index, frame.files)
                perception.submit(frame)
                if mission is not None:
                    mission.take(frame)
                camera.release(frame.index)  # the perception thread holds the frame until it is done with it
                written += 1
                if job.progress:
                    job.progress(written, max(len(camera), 1))
            perception.collect(wait)

        while not sim.finished:
            sim.step()
            if mission is not None and mission.due():
                take_ready(wait=True)  # a decision reads every frame taken before it, whenever they render and are perceived
                mission.decide()
            elif not sim.tick % 10:  # a look every 10 ticks is plenty for frames that come at 5 Hz at most
                take_ready(wait=False)
        take_ready(wait=True)

        log = sim.log()
        frames = np.searchsorted(log.t, np.array(camera.timestamps) - 1e-9)
        poses = np.array(camera.poses)
        record = mission.record(camera.timestamps, sim.end) if mission is not None else None
    # the files of the batch stages, in their order, from the same flight and frames
    write_flight(run_dir, config, log, frames)
    files.write_model(run_dir / names.RENDER_RECORD, render_record(run_dir, config, poses))
    finish_render(run_dir, config, log.t[frames])
    depth_dir = names.DEPTH_SENSOR if config.renderer.depth_noise.enabled else names.DEPTH
    write_detections(run_dir, perception.detector, config.detector, depth_dir, perception.frames)
    if record is not None:
        files.write_model(run_dir / names.MISSION, record)


STAGE = Stage("online", needs=FLY_NEEDS, work=_fly_in_loop, covers=("fly", "render", "detect"))
run_online = STAGE.run
ADAPTIVE_STAGE = Stage("adaptive", needs=FLY_NEEDS, work=_fly_in_loop, covers=("fly", "render", "detect", "mission"))
