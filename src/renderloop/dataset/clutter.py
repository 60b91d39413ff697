"""Things that are not peppers, for the training set: distractors and patterned surfaces round the plants.

A detector that has only ever seen peppers among leaves learns that anything round,
glossy and red is a ripe pepper, and anything on a bright patterned ground is too:
on real photos it boxes apples, tomatoes, oranges and cloth. Domain randomisation's
remedy (Tobin et al. 2017; Tremblay et al. 2018) is to show it such things, labelled
as background, in every colour: round and elongated fruit-like shapes, cans and
cartons among and beside the plants, mats on the tables and the floor, and boards
standing in the room, in stripes or checks. None of them has an instance id, so the
masks, and so the labels, stay the peppers' alone; a pepper a distractor hides is
labelled by what of it is still visible.

Numpy only: a dataset worker adds these to the scene's own object list.
"""

from __future__ import annotations

import colorsys
from collections.abc import Sequence

import numpy as np

from renderloop.scene.meshes import box, ellipsoid, tube
from renderloop.scene.model import Pepper, Scene
from renderloop.scene.objects import Box, COLUMN_SIDES, SceneObject

__all__ = ["clutter_objects", "standing_boards", "DISTRACTORS", "PEPPER_CLEARANCE"]

DISTRACTORS = (6, 20)  # distractors per scene, low and high
PEPPER_CLEARANCE = 0.05  # m between a distractor's bounding sphere and any pepper's
REACH = 0.25  # m: distractors stand up to this far outside a plant's box
MATS = (1, 4)  # patterned mats on the tables and the floor, low and high
BOARDS = (0, 3)  # patterned boards standing in the room, low and high
BOARD_GAP = 0.3  # m: a board stands at least this far from every plant's box
PEPPER_HUES = ((0.97, 1.03), (0.05, 0.1), (0.12, 0.17), (0.22, 0.33))  # red, orange, yellow, green: hard negatives
MAX_TRIES = 50


def _colour(rng: np.random.Generator) -> tuple[float, float, float]:
    """An sRGB colour: half in the peppers' own hues, saturated (an apple, a tomato, a lemon), half anything."""
    if rng.random() < 0.5:
        low, high = PEPPER_HUES[int(rng.integers(len(PEPPER_HUES)))]
        hue, saturation, value = rng.uniform(low, high) % 1.0, rng.uniform(0.55, 1.0), rng.uniform(0.3, 0.95)
    else:
        hue, saturation, value = rng.random(), rng.uniform(0.0, 1.0), rng.uniform(0.15, 1.0)
    return tuple(float(c) for c in colorsys.hsv_to_rgb(hue, saturation, value))


def _rotation(rng: np.random.Generator) -> np.ndarray:
    """A uniformly random rotation (QR of a Gaussian matrix, signs fixed)."""
    q, r = np.linalg.qr(rng.normal(size=(3, 3)))
    q = q * np.sign(np.diag(r))
    return q if np.linalg.det(q) > 0 else -q


def _distractor(name: str, center: np.ndarray, rng: np.random.Generator) -> tuple[SceneObject, float]:
    """One random thing at `center` and its bounding radius: a round or an elongated fruit-like shape, a carton
    or a can, glossy or matte, in a random colour."""
    kind = rng.choice(["round", "long", "carton", "can"], p=[0.5, 0.2, 0.15, 0.15])
    material = "clutter_gloss" if rng.random() < 0.6 else "clutter_matte"
    if kind == "round":  # apple, tomato, orange, plum, kiwi, ball
        radius = rng.uniform(0.025, 0.06)
        radii = radius * rng.uniform(0.85, 1.15, 3)
        mesh = ellipsoid(center, radii, _rotation(rng), rings=10, segments=20)
    elif kind == "long":  # lemon, cucumber, aubergine, banana-like
        radius = rng.uniform(0.02, 0.04)
        radii = radius * np.array([1.0, rng.uniform(0.8, 1.0), rng.uniform(1.5, 3.5)])
        mesh = ellipsoid(center, radii, _rotation(rng), rings=12, segments=20)
    elif kind == "carton":
        radii = rng.uniform(0.02, 0.12, 3)
        mesh = box((0.0, 0.0, 0.0), 2 * radii).transformed(_rotation(rng), center)
        material = "clutter_pattern" if rng.random() < 0.5 else material
    else:  # can, bottle, jar: a standing cylinder
        radii = np.array([rng.uniform(0.02, 0.05), 0.0, rng.uniform(0.04, 0.12)])
        mesh = tube(np.array([center - (0, 0, radii[2]), center + (0, 0, radii[2])]), float(radii[0]), sides=COLUMN_SIDES)
    alpha = float(rng.random())  # the pattern material's kind and scale; unused by the others
    return SceneObject(name, mesh=mesh, material=material, rgb=_colour(rng), alpha=alpha, smooth=kind != "carton"), \
        float(np.linalg.norm(radii))


def _clear_of_peppers(center: np.ndarray, radius: float, peppers: np.ndarray, radii: np.ndarray) -> bool:
    if len(peppers) == 0:
        return True
    return bool(np.all(np.linalg.norm(peppers - center, axis=1) > radii + radius + PEPPER_CLEARANCE))


def _place(scene: Scene, rng: np.random.Generator) -> np.ndarray:
    """A point among or beside a random plant's canopy, or on its table top."""
    plant = scene.plants[int(rng.integers(len(scene.plants)))]
    low, high = np.asarray(plant.bounds.min), np.asarray(plant.bounds.max)
    top = plant.position[2]  # the table top the pot stands on
    if rng.random() < 0.35:  # lying on the table or hanging low by the pot
        return np.array([rng.uniform(low[0] - REACH, high[0] + REACH), rng.uniform(low[1], high[1]), top + 0.05])
    return np.array([rng.uniform(low[0] - REACH, high[0] + REACH), rng.uniform(low[1] - REACH, high[1] + REACH),
                     rng.uniform(top + plant.pot.height, high[2])])


def _mats(scene: Scene, rng: np.random.Generator) -> list[SceneObject]:
    """Thin patterned mats on the table tops (under the pots) and on the floor."""
    out = []
    for k in range(int(rng.integers(MATS[0], MATS[1] + 1))):
        row = scene.rows[int(rng.integers(len(scene.rows)))]
        (x, y, _), (sx, sy, height) = row.table.center, row.table.size
        on_floor = rng.random() < 0.4
        size = np.array([rng.uniform(0.4, 1.5) if on_floor else sx * rng.uniform(0.6, 1.0),
                         rng.uniform(0.4, 1.5) if on_floor else sy * rng.uniform(0.3, 1.0), 0.004])
        if on_floor:  # beside the table, across the aisle a camera looks down into
            center = (x + rng.choice([-1, 1]) * (sx / 2 + size[0] / 2 + rng.uniform(0.0, 0.3)),
                      y + rng.uniform(-sy / 2, sy / 2), 0.002)
        else:
            center = (x, y + rng.uniform(-(sy - size[1]) / 2, (sy - size[1]) / 2), height + 0.002)
        out.append(SceneObject(f"clutter_mat_{k}", mesh=box(center, size), material="clutter_pattern", rgb=_colour(rng),
                               alpha=float(rng.random())))
    return out


def standing_boards(scene: Scene, rng: np.random.Generator) -> list[Box]:
    """Upright boards on the floor (cloth on a frame, a screen, a door), clear of every plant's box."""
    length, width, _ = scene.room
    boards: list[Box] = []
    for _ in range(int(rng.integers(BOARDS[0], BOARDS[1] + 1))):
        for _ in range(MAX_TRIES):
            half = np.array([rng.uniform(0.2, 0.8), 0.01, rng.uniform(0.3, 0.8)])
            if rng.random() < 0.5:  # across the room (normal along x) or along it
                half = half[[1, 0, 2]]
            center = np.array([rng.uniform(-length / 2, length / 2), rng.uniform(-width / 2, width / 2), half[2]])
            board = Box(f"clutter_board_{len(boards)}", tuple(center), tuple(half))
            if all(board.apart(Box.bounding("plant", p.bounds.min, p.bounds.max), BOARD_GAP) for p in scene.plants):
                boards.append(board)
                break
    return boards


def clutter_objects(scene: Scene, rng: np.random.Generator, boards: list[Box], picked: Sequence[Pepper] = ()) -> list[SceneObject]:
    """The distractors and mats of one dataset scene, and the `boards` (from `standing_boards`) as objects; the
    distractors keep clear of the scene's fruit and of the `picked` ones."""
    fruit = [*scene.peppers, *picked]
    peppers = np.array([p.center for p in fruit]).reshape(-1, 3)
    radii = np.array([p.radius for p in fruit])
    out = _mats(scene, rng)
    out += [SceneObject(board.name, mesh=board.mesh(), material="clutter_pattern", rgb=_colour(rng), alpha=float(rng.random()))
            for board in boards]
    for k in range(int(rng.integers(DISTRACTORS[0], DISTRACTORS[1] + 1))):
        for _ in range(MAX_TRIES):
            thing, radius = _distractor(f"clutter_{k}", _place(scene, rng), rng)
            if _clear_of_peppers(np.asarray(thing.mesh.vertices).mean(axis=0), radius, peppers, radii):
                out.append(thing)
                break
    return out
