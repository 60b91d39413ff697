"""Shared fixtures: generated scenes are cached per session because several tests read them."""

from __future__ import annotations

import functools
import os
import sys
from pathlib import Path

import pytest

from renderloop.cli import main
from renderloop.config import Config, load_config
from renderloop.planning.stage import run_plan
from renderloop.scene.generate import generate_scene
from renderloop.scene.model import Scene
from renderloop.scene.stage import run_scene
from renderloop.sim.stage import run_fly


def pytest_configure(config: pytest.Config) -> None:
    """Each of the suite's test processes (pytest-xdist, `-n 2` in pyproject.toml) gets its share of the cores for
    torch's thread pool, set before the test modules import torch: with pools as wide as the machine in both
    processes, their threads spin on each other's cores and the detector's trainings take three times as long."""
    if hasattr(config, "workerinput"):  # a test process; one run without xdist has the machine to itself
        os.environ.setdefault("OMP_NUM_THREADS", str(max(1, (os.cpu_count() or 1) // config.workerinput["workercount"])))


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


@pytest.fixture(scope="session")
def paper_run(tmp_path_factory) -> tuple[Config, Path]:
    """The paper scenario planned and flown once (about 15 s): the closed-loop figures are read from it."""
    config = load_config("paper", seed=7)
    run_dir = tmp_path_factory.mktemp("paper7")
    run_scene(run_dir, config)
    run_plan(run_dir, config)
    run_fly(run_dir, config)
    return config, run_dir


def fly_demo_raster(run_dir: Path, rate_hz: float = 0.25) -> Path:
    """The demo scenario planned and flown, set to render with the raster backend at a few frames."""
    config = load_config("demo").override({"renderer": {"backend": "raster"}, "camera": {"rate_hz": rate_hz}})
    run_scene(run_dir, config)
    run_plan(run_dir, config)
    run_fly(run_dir, config)
    return run_dir


@pytest.fixture(scope="session")
def complete_run(tmp_path_factory) -> Path:
    """The demo scenario through every stage up to count, raster frames every 4 s: a test copies it before changing it."""
    from renderloop.counting.stage import run_count
    from renderloop.perception.stage import run_detect
    from renderloop.render.stage import run_render
    from renderloop.rundir.files import read_config

    run_dir = fly_demo_raster(tmp_path_factory.mktemp("complete") / "run")
    config = read_config(run_dir)
    run_render(run_dir, config)
    run_detect(run_dir, config)
    run_count(run_dir, config)
    return run_dir


def cli(monkeypatch, capsys, *args: str) -> tuple[int, str, str]:
    """Run the real entry point in-process: exit code, stdout, stderr."""
    monkeypatch.setattr(sys, "argv", ["renderloop", *args])
    with pytest.raises(SystemExit) as ended:
        main()
    captured = capsys.readouterr()
    return ended.value.code or 0, captured.out, captured.err


def jittered_model(seed: int, backbone: str | None = None):
    """A random detector network (on the default backbone unless told) whose scores differ between anchors (a fresh
    head scores every anchor alike)."""
    import torch

    from renderloop.config.training import DEFAULT_BACKBONE
    from renderloop.perception.training.ssd import build_model

    torch.manual_seed(seed)
    model = build_model(backbone or DEFAULT_BACKBONE).eval()
    with torch.no_grad():
        for parameter in model.parameters():
            parameter.add_(torch.randn_like(parameter) * 0.05)
    return model


def _fruit_image(rng, size=(96, 72)):
    """Green clutter with red (ripe) and dark green (unripe) blobs at known places."""
    from PIL import Image, ImageDraw

    image = Image.new("RGB", size, (60, 110, 50))
    draw = ImageDraw.Draw(image)
    for _ in range(6):
        x, y = rng.integers(0, size[0]), rng.integers(0, size[1])
        draw.ellipse([x, y, x + 20, y + 8], fill=(40, 140, 40))
    objects = []
    for _ in range(int(rng.integers(1, 3))):
        w, h = int(rng.integers(12, 24)), int(rng.integers(14, 26))
        x, y = int(rng.integers(0, size[0] - w)), int(rng.integers(0, size[1] - h))
        ripe = bool(rng.random() < 0.6)
        draw.ellipse([x, y, x + w - 1, y + h - 1], fill=(200, 30, 20) if ripe else (20, 80, 20))
        objects.append(([x, y, x + w, y + h], 1 if ripe else 2))
    return image, objects


@pytest.fixture(scope="module")
def tiny_dataset(tmp_path_factory) -> Path:
    """A COCO dataset of eight training and three validation images, 96x72, with one or two fruit each."""
    import numpy as np

    from renderloop.io.atomic import write_json

    root = tmp_path_factory.mktemp("tiny")
    (root / "images").mkdir()
    (root / "annotations").mkdir()
    rng = np.random.default_rng(0)
    for split, count in (("train", 8), ("val", 3)):
        images, annotations = [], []
        for i in range(count):
            image, objects = _fruit_image(rng)
            name = f"images/{split}{i}.jpg"
            image.save(root / name, quality=95)
            images.append({"id": 100 + i, "file_name": name, "width": 96, "height": 72})  # ids are not positions
            for box, label in objects:
                x0, y0, x1, y1 = box
                annotations.append({"id": len(annotations) + 1, "image_id": 100 + i, "category_id": label,
                                    "bbox": [x0, y0, x1 - x0, y1 - y0], "area": (x1 - x0) * (y1 - y0), "iscrowd": 0})
        write_json(root / "annotations" / f"instances_{split}.json",
                   {"images": images, "annotations": annotations,
                    "categories": [{"id": 1, "name": "ripe"}, {"id": 2, "name": "unripe"}]})
    return root
