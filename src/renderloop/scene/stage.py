"""`renderloop scene`: config and seed in; config.yaml, scene.json, world.xml and a top view out."""

from __future__ import annotations

from pathlib import Path

import mujoco

from renderloop.config import Config
from renderloop.io import rundir
from renderloop.io.atomic import dumps_json, write_text
from renderloop.scene.generate import generate_scene
from renderloop.scene.topview import draw_top_view
from renderloop.scene.world import world_xml

OUTPUTS = ("config.yaml", "scene.json", "world.xml", "scene_topview.png")


def run_scene(run_dir: Path, config: Config, force: bool = False) -> bool:
    """Make the scene files; False when they were already complete for this config.

    Everything is generated and checked in memory first, so bad input leaves no file behind.
    """
    run_dir = rundir.check_target(run_dir)
    if not force:
        rundir.check_config(run_dir, config)
        if rundir.complete(run_dir, OUTPUTS):
            return False
    scene = generate_scene(config)
    world = world_xml(scene, config)
    mujoco.MjModel.from_xml_string(world)  # a world MuJoCo rejects must never reach the disk
    rundir.write_config(run_dir, config)
    write_text(run_dir / "world.xml", world)
    draw_top_view(scene, run_dir / "scene_topview.png")
    write_text(run_dir / "scene.json", dumps_json(scene.model_dump(mode="json")))
    return True
