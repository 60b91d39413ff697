"""`renderloop dataset`: render the training set, resumably and in parallel, and write COCO files.

Image i is view i % K of dataset scene i // K (K views per scene), so it depends on
the seed and i only: a killed build resumes where it stopped, and a larger
`--images` adds images without touching the ones there. A worker builds one
Blender scene per dataset scene and returns encoded images and labels; the driver
alone writes, each image before its label file, both atomically, so an image
counts as done exactly when its label file exists.

Layout: `images/NNNNNN.jpg`, `labels/NNNNNN.json` (every pepper seen, with the
ignore rules' verdict), `annotations/instances_{train,val}.json` (COCO; validation
holds whole scenes), `dataset.json` (the spec), `preview.png`.
"""

from __future__ import annotations

import io
import json
from collections.abc import Callable
from pathlib import Path

import numpy as np
from PIL import Image

from renderloop.dataset.clutter import clutter_objects, standing_boards
from renderloop.dataset.coco import write_coco
from renderloop.dataset.labels import neighbour_fruit_boxes, pepper_boxes, pepper_vertices, relabelled
from renderloop.dataset.preview import draw_preview
from renderloop.dataset.picked import picked_fruit
from renderloop.config.dataset import DatasetSpec
from renderloop.dataset.scenes import DATASET_SENSOR, FORMAT_VERSION, PICKED_VIEWS, dataset_scene, manifest
from renderloop.dataset.views import close_view, picked_view, random_view
from renderloop.errors import UserError
from renderloop.io import ownership
from renderloop.io.atomic import write_bytes, write_json
from renderloop.parallel import LOCAL, Executor, map_tasks
from renderloop.render.camera import Intrinsics
from renderloop.render.executor import COLOUR_SENSOR_STREAM
from renderloop.render.sensor import sensor_rgb
from renderloop.scene.objects import greenhouse_objects, neighbour_fruit
from renderloop.scene.plant_meshes import pepper_mesh

VIEW_STREAM = 0x71E3
CLUTTER_STREAM = 0xC1A7
PICKED_STREAM = 0xF1C7
JPEG_QUALITY = 95
MANIFEST = "dataset.json"
PREVIEW = "preview.png"

Rendered = list[tuple[int, bytes, dict]]
Progress = Callable[[int, int], None]


def image_name(index: int, suffix: str) -> str:
    return f"{index:06d}.{suffix}"


def jpeg_bytes(rgb: np.ndarray) -> bytes:
    """The dataset's image encoding: JPEG keeps a set small enough to carry to a training machine."""
    buffer = io.BytesIO()
    Image.fromarray(rgb).save(buffer, format="JPEG", quality=JPEG_QUALITY)
    return buffer.getvalue()


def render_scene_views(spec: DatasetSpec, scene_index: int, view_indices: list[int], executor: Executor = LOCAL) -> Rendered:
    """Render the given views of one dataset scene, on a worker of `executor`: (image index, JPEG bytes, label record)
    each."""
    from renderloop.render.cycles import (
        CyclesRenderer,  # bpy only where frames are rendered
    )

    config, scene = dataset_scene(spec, scene_index)
    config = executor.share_cores(config)
    intrinsics = Intrinsics.from_config(config.camera)
    clutter_rng = np.random.default_rng(np.random.SeedSequence([spec.seed, CLUTTER_STREAM, scene_index]))
    boards = standing_boards(scene, clutter_rng) if spec.clutter else []
    picked_rng = np.random.default_rng(np.random.SeedSequence([spec.seed, PICKED_STREAM, scene_index]))
    picked = picked_fruit(scene, picked_rng, config.plants.peppers, boards) \
        if spec.picked > 0 and picked_rng.random() < spec.picked else None
    crates = list(picked.crates) if picked is not None else []
    rng = np.random.default_rng(np.random.SeedSequence([spec.seed, VIEW_STREAM, scene_index]))
    reach = intrinsics.corner_range(config.camera.clip[0])

    def draw_view() -> np.ndarray:
        if spec.close > 0 and rng.random() < spec.close:
            if picked is not None and picked.fruit and rng.random() < PICKED_VIEWS:  # drawn only where there are picked fruit
                return picked_view(scene, picked.fruit, rng, boards, crates, reach)
            return close_view(scene, rng, boards + crates, reach)
        return random_view(scene, rng, spec.distance, boards + crates)

    poses = [draw_view() for _ in range(spec.views_per_scene)]  # all drawn, so a view never depends on which are done
    picked_fruits = picked.fruit if picked is not None else ()
    peppers = {pepper.id: pepper for pepper in [*scene.peppers, *picked_fruits]}
    meshes = pepper_vertices(scene) | {pepper.id: pepper_mesh(pepper).vertices for pepper in picked_fruits}
    neighbours = neighbour_fruit(scene.environment)
    objects = greenhouse_objects(scene) + (clutter_objects(scene, clutter_rng, boards, picked_fruits) if spec.clutter else []) \
        + list(picked.objects if picked is not None else ())
    out = []
    with CyclesRenderer.from_objects(objects, config, intrinsics, scene.seed, scene.room, scene.environment) as renderer:
        for view in view_indices:
            frame = renderer.render(poses[view])
            index = scene_index * spec.views_per_scene + view
            record = {
                "image": f"images/{image_name(index, 'jpg')}", "scene": scene_index, "width": intrinsics.width,
                "height": intrinsics.height, "split": "val" if spec.is_val(scene_index) else "train",
                "samples": config.renderer.samples, "pose": np.round(poses[view], 9).tolist(),
                "peppers": pepper_boxes(frame.mask, peppers, meshes, poses[view], intrinsics, config.camera.clip[0])
                + neighbour_fruit_boxes(frame.mask, frame.depth, neighbours, poses[view], intrinsics, config.camera.clip[0]),
            }
            rgb = frame.rgb
            sensor = np.random.default_rng(np.random.SeedSequence([spec.seed, COLOUR_SENSOR_STREAM, index]))
            if spec.sensor >= 1 or (spec.sensor > 0 and sensor.random() < spec.sensor):  # a share of 1 draws nothing
                rgb = sensor_rgb(rgb, frame.depth, DATASET_SENSOR, sensor)
                record["sensor"] = True
            out.append((index, jpeg_bytes(rgb), record))
    return out


PARTS = ("images", "labels", "annotations")  # the folders of a dataset


def claim_dataset(out: Path) -> Path:
    return ownership.claim(out, ownership.DATASET)


def _check_spec(out: Path, spec: DatasetSpec, force: bool) -> None:
    claim_dataset(out)
    path = out / MANIFEST
    if path.is_file() and not force:
        try:
            recorded = json.loads(path.read_text(encoding="utf-8"))
        except (OSError, UnicodeDecodeError, json.JSONDecodeError):
            recorded = None
        made = recorded.get("format_version") if isinstance(recorded, dict) else None
        if made != FORMAT_VERSION and isinstance(made, int):
            raise UserError(f"{out}: holds a dataset of format {made}, made by another renderloop (this one renders format "
                            f"{FORMAT_VERSION}, whose images differ); grow it with that version or use --force to replace it")
        if recorded != manifest(spec):
            raise UserError(f"{out}: holds a dataset of other settings (see {MANIFEST}); use --force to replace it")
    elif force:
        ownership.remove_recorded(out, PARTS)
    for sub in PARTS:
        (out / sub).mkdir(parents=True, exist_ok=True)
    write_json(path, manifest(spec))


def _pending(out: Path, spec: DatasetSpec, images: int) -> dict[int, list[int]]:
    todo: dict[int, list[int]] = {}
    for index in range(images):
        if not (out / "labels" / image_name(index, "json")).is_file():
            todo.setdefault(index // spec.views_per_scene, []).append(index % spec.views_per_scene)
    return todo


def build_dataset(out: Path, images: int, spec: DatasetSpec, executor: Executor = LOCAL, force: bool = False,
                  progress: Progress | None = None) -> int:
    """Render the missing images of the first `images`, a scene a task, then (re)write the COCO files; returns images
    rendered."""
    if images < 1:
        raise UserError(f"--images {images}: need at least one image")
    out = Path(out)
    _check_spec(out, spec, force)
    todo = _pending(out, spec, images)
    done = images - sum(len(views) for views in todo.values())
    if progress:
        progress(done, images)
    rendered = 0
    for batch in map_tasks(executor, render_scene_views, [(spec, s, v, executor) for s, v in todo.items()]):
        for index, jpeg, record in batch:
            write_bytes(out / "images" / image_name(index, "jpg"), jpeg)
            write_json(out / "labels" / image_name(index, "json"), record)
        rendered += len(batch)
        if progress:
            progress(done + rendered, images)
    records = []
    for i in range(images):
        path = out / "labels" / image_name(i, "json")
        record = json.loads(path.read_text(encoding="utf-8"))
        if (current := relabelled(record)) != record:  # labelled by an earlier rule: the images stand, the labels follow
            write_json(path, current)
        records.append(current)
    write_coco(out / "annotations", records)
    draw_preview(out, records[:24], out / PREVIEW)
    return rendered
