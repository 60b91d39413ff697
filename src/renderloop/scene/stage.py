"""`renderloop scene`: config and seed in; config.yaml, scene.json, world.xml and a top view out."""

from __future__ import annotations

from pathlib import Path

import mujoco

from renderloop.config import Config
from renderloop.io.atomic import write_text
from renderloop.rundir import files, names
from renderloop.rundir.stage import Job, Stage, claim
from renderloop.scene.capacity import check_capacity
from renderloop.scene.generate import generate_scene
from renderloop.scene.model import write_scene
from renderloop.scene.topview import draw_top_view
from renderloop.scene.world import world_xml


def _same_config(run_dir: Path, config: Config) -> bool:
    """A run directory belongs to one config: another one is refused (unless --force), never mixed in."""
    files.check_config(run_dir, config)
    return True


def _scene(run_dir: Path, config: Config, job: Job) -> None:
    """Everything is generated and checked in memory first, so bad input leaves no file behind; a greenhouse this
    machine cannot hold is refused before anything is grown."""
    check_capacity(config, run_dir)
    scene = generate_scene(config)
    world = world_xml(scene, config)
    mujoco.MjModel.from_xml_string(world)  # a world MuJoCo rejects must never reach the disk
    claim(run_dir)
    files.write_config(run_dir, config)
    write_text(run_dir / names.WORLD, world)
    draw_top_view(scene, run_dir / names.TOP_VIEW)
    write_scene(run_dir, scene)


STAGE = Stage("scene", needs=(), work=_scene, current=_same_config)
run_scene = STAGE.run
