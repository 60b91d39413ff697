"""Shared fixtures: generated scenes are cached per session because several tests read them."""

from __future__ import annotations

import functools

import pytest

from renderloop.config import Config, load_config
from renderloop.scene.generate import generate_scene
from renderloop.scene.model import Scene


@functools.cache
def scene_for(preset: str, seed: int) -> tuple[Config, Scene]:
    config = load_config(preset, seed=seed)
    return config, generate_scene(config)


@pytest.fixture(scope="session")
def paper() -> tuple[Config, Scene]:
    return scene_for("paper", 7)


@pytest.fixture(scope="session")
def demo() -> tuple[Config, Scene]:
    return scene_for("demo", 0)
