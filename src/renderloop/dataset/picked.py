"""Picked fruit for the training set: crates of harvested peppers in the aisles and on the workstation, and loose
fruit lying on the workstation's top.

A working greenhouse holds picked fruit beside the hanging ones: crates in the aisles, fruit on the packing
table. Picked fruit lie every way up (on their sides, stalk up or down), touch each other in a crate and, seen
from close by, fill the frame, all of which the hanging fruit never show a detector; a photo of harvested
peppers shows nothing else. They are peppers and are labelled as such (ripe or unripe by colour), but they are
not the scene's truth: each gets an instance id above the scene's own fruit, so its mask and label are its own
and the scene's counts never see it.

Each fruit is drawn as the plants' fruit are (the preset's sizes and colour mix, the 'pepper' style's calyx and
breaker stages) with a cut stalk, and rests on its support: the lowest point of its mesh on the crate's floor,
the workstation's top or a fruit below it (kept apart by bounding spheres, which leaves small gaps).

Numpy only: a dataset worker adds these to the scene's object list and their fruit to the labelled ones.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from renderloop.config import RIPE_COLORS, PepperConfig
from renderloop.scene import meshes
from renderloop.scene.model import Calyx, Pepper, Scene, Tube
from renderloop.scene.objects import Box, SceneObject
from renderloop.scene.pepper_plant import BREAKING, PEDUNCLE_RADIUS
from renderloop.scene.plant import pepper_rgb
from renderloop.scene.plant_meshes import PEPPER_SEPALS, calyx_mesh, pepper_mesh

__all__ = ["Picked", "picked_fruit", "CRATES", "LOOSE"]

CRATES = (1, 3)  # crates per scene, low and high: on the aisle floors, or one on the workstation
CRATE_INNER = ((0.3, 0.55), (0.25, 0.38), (0.1, 0.22))  # m: inner length, width and depth, low and high
CRATE_WALL = 0.01  # m
CRATE_RGB = ((0.06, 0.06, 0.07), (0.12, 0.32, 0.14), (0.12, 0.22, 0.5), (0.5, 0.5, 0.52), (0.75, 0.3, 0.08))
FILL = (0.3, 1.0)  # share of a crate's floor cells holding a fruit; a full crate's second layer likewise
LOOSE = (0, 6)  # fruit lying on the workstation's top, low and high
LYING_TILT = math.radians(25.0)  # a loose fruit's axis within this of level: it lies on its side
STALK = (0.01, 0.04)  # m: the cut stalk left on a picked fruit, along its axis from the calyx
GAP = 0.004  # m between two fruit's bounding spheres
AISLE_GAP = (0.1, 0.6)  # m from a table's side to a floor crate's
CRATE_GAP = 0.05  # m between a crate and any other crate, table, plant's box or board
MAX_TRIES = 60


@dataclass(frozen=True)
class Picked:
    """The picked fruit of one dataset scene: the fruit (ids above the scene's), their crates as boxes (obstacles
    for views) and everything to draw."""

    fruit: tuple[Pepper, ...]
    crates: tuple[Box, ...]
    objects: tuple[SceneObject, ...]


def _unit_vector(rng: np.random.Generator) -> np.ndarray:
    vector = rng.normal(size=3)
    return vector / np.linalg.norm(vector)


def _lying_axis(rng: np.random.Generator) -> np.ndarray:
    azimuth, tilt = rng.uniform(0.0, 2 * math.pi), rng.uniform(-LYING_TILT, LYING_TILT)
    return np.array([math.cos(tilt) * math.cos(azimuth), math.cos(tilt) * math.sin(azimuth), math.sin(tilt)])


class _Filler:
    """Draws fruit of the preset's shapes and colours and keeps every placed one's bounding sphere."""

    def __init__(self, rng: np.random.Generator, config: PepperConfig, first_id: int) -> None:
        self.rng, self.config, self.next_id = rng, config, first_id
        names = list(config.colors)
        weights = np.array([config.colors[name] for name in names], dtype=float)
        self.names, self.weights = names, weights / weights.sum()
        self.fruit: list[Pepper] = []

    def shape(self, axis: np.ndarray) -> dict:
        """A fruit's shape about the origin, `axis` from its stalk end to its blossom end."""
        rng, c = self.rng, self.config
        length = rng.uniform(*c.length)
        width = length * rng.uniform(*c.width_ratio)
        shape = dict(axis=axis, length=length, width=width, lobes=int(rng.integers(c.lobes[0], c.lobes[1] + 1)),
                     lobe_depth=rng.uniform(*c.lobe_depth), twist=rng.uniform(0.0, 2 * math.pi))
        vertices = meshes.pepper(np.zeros(3), **shape).vertices
        return {**shape, "radius": float(np.linalg.norm(vertices, axis=1).max()), "bottom": float(vertices[:, 2].min())}

    def clear(self, center: np.ndarray, radius: float) -> bool:
        return all(np.linalg.norm(center - np.asarray(p.center)) >= radius + p.radius + GAP for p in self.fruit)

    def add(self, center: np.ndarray, shape: dict) -> None:
        rng = self.rng
        color = self.names[int(rng.choice(len(self.names), p=self.weights))]
        axis = shape["axis"]
        top = center - axis * shape["length"] / 2
        bend = np.cross(axis, _unit_vector(rng))
        bend = bend / max(np.linalg.norm(bend), 1e-9)
        stalk = rng.uniform(*STALK)
        points = [top, top - axis * stalk * 0.5, top - axis * stalk + bend * stalk * rng.uniform(0.0, 0.4)]
        breaking = rng.random() < BREAKING and color != "green"
        self.fruit.append(Pepper(
            id=self.next_id, plant=0, side="left", center=tuple(center), radius=shape["radius"] + 1e-6, color=color,
            ripe=color in RIPE_COLORS, rgb=tuple(pepper_rgb(rng, color)), length=shape["length"], width=shape["width"],
            lobes=shape["lobes"], lobe_depth=shape["lobe_depth"], axis=tuple(axis), twist=shape["twist"],
            peduncle=Tube(points=[tuple(p) for p in points], radius=PEDUNCLE_RADIUS),
            calyx=Calyx(sepals=int(rng.integers(PEPPER_SEPALS[0], PEPPER_SEPALS[1] + 1)),
                        reach=rng.uniform(0.2, 0.27) * shape["width"]),
            ripeness=rng.uniform(0.55, 0.95) if breaking else 1.0,
        ))
        self.next_id += 1

    def fill_crate(self, low: np.ndarray, high: np.ndarray) -> None:
        """Fruit in the crate whose inside spans `low`-`high`: a layer on its floor, and over a full one a second."""
        cell = 2 * self.config.length[1] * 0.6 + GAP
        nx, ny = max(1, int((high[0] - low[0]) // cell)), max(1, int((high[1] - low[1]) // cell))
        share = self.rng.uniform(*FILL)
        for layer in range(2 if share > 0.8 else 1):
            for i in range(nx):
                for j in range(ny):
                    if self.rng.random() > share:
                        continue
                    for _ in range(6):
                        shape = self.shape(_unit_vector(self.rng))
                        xy = low[:2] + (np.array([i, j]) + 0.5 + layer * 0.5 + self.rng.uniform(-0.2, 0.2, 2)) * cell
                        reach = shape["radius"]
                        if np.any(xy - reach < low[:2]) or np.any(xy + reach > high[:2]):
                            continue
                        center = np.r_[xy, low[2] - shape["bottom"] + layer * cell * 0.8]
                        if center[2] - shape["radius"] > high[2] or not self.clear(center, shape["radius"]):
                            continue
                        self.add(center, shape)
                        break


def _crate_mesh(box: Box) -> meshes.Mesh:
    """An open crate: a floor and four walls round the inside of `box` (its outer bounds)."""
    (cx, cy, cz), (hx, hy, hz) = box.center, box.half
    w = CRATE_WALL
    panels = [((cx, cy, cz - hz + w / 2), (2 * hx, 2 * hy, w)),
              ((cx - hx + w / 2, cy, cz), (w, 2 * hy, 2 * hz)), ((cx + hx - w / 2, cy, cz), (w, 2 * hy, 2 * hz)),
              ((cx, cy - hy + w / 2, cz), (2 * hx, w, 2 * hz)), ((cx, cy + hy - w / 2, cz), (2 * hx, w, 2 * hz))]
    return meshes.merge([meshes.box(center, size) for center, size in panels])


def _crate_place(scene: Scene, rng: np.random.Generator, half: np.ndarray, station: Box | None) -> np.ndarray | None:
    """The centre of a crate of half size `half`: on the `station`'s top when given, else on the floor beside a table."""
    if station is not None:
        room = np.asarray(station.half[:2]) - half[:2]
        if np.any(room < 0):
            return None
        return np.r_[np.asarray(station.center[:2]) + rng.uniform(-room, room), station.center[2] + station.half[2] + half[2]]
    row = scene.rows[int(rng.integers(len(scene.rows)))]
    (x, y, _), (sx, sy, _) = row.table.center, row.table.size
    side = rng.choice([-1.0, 1.0])
    return np.array([x + side * (sx / 2 + rng.uniform(*AISLE_GAP) + half[0]), y + rng.uniform(-sy / 2, sy / 2), half[2]])


def picked_fruit(scene: Scene, rng: np.random.Generator, config: PepperConfig, obstacles: Sequence[Box] = ()) -> Picked:
    """Crates of picked fruit on the aisle floors and the workstation, and loose fruit on the workstation's top, clear
    of every plant's box, table and `obstacles` (the set's standing boards) and inside the room; fruit ids count
    on from the scene's highest."""
    filler = _Filler(rng, config, max((p.id for p in scene.peppers), default=0) + 1)
    length, width, _ = scene.room
    station = Box.sized("workstation", scene.workstation.center, scene.workstation.size)
    solid = [Box.sized(f"table_{row.id}", row.table.center, row.table.size) for row in scene.rows]
    solid += [Box.bounding(f"plant_{p.id}", p.bounds.min, p.bounds.max) for p in scene.plants]
    solid += list(obstacles)
    crates: list[Box] = []
    for k in range(int(rng.integers(CRATES[0], CRATES[1] + 1))):
        for _ in range(MAX_TRIES):
            inner = np.array([rng.uniform(*span) for span in CRATE_INNER])
            half = inner / 2 + np.array([CRATE_WALL, CRATE_WALL, CRATE_WALL / 2])
            on_station = k == 0 and rng.random() < 0.5
            center = _crate_place(scene, rng, half, station if on_station else None)
            if center is None:
                continue
            crate = Box(f"crate_{k}", tuple(center), tuple(half))
            others = [*crates, *solid] + ([] if on_station else [station])
            if np.all(np.abs(center[:2]) + half[:2] <= np.array([length, width]) / 2) \
                    and all(crate.apart(other, CRATE_GAP) for other in others):
                crates.append(crate)
                low = center - half + CRATE_WALL
                filler.fill_crate(low, center + half - np.array([CRATE_WALL, CRATE_WALL, 0.0]))
                break
    station_top = station.center[2] + station.half[2]
    for _ in range(int(rng.integers(LOOSE[0], LOOSE[1] + 1))):
        for _ in range(MAX_TRIES):
            shape = filler.shape(_lying_axis(rng))
            room = np.asarray(station.half[:2]) - shape["radius"]
            center = np.r_[np.asarray(station.center[:2]) + rng.uniform(-room, room), station_top - shape["bottom"]]
            fruit = Box("fruit", tuple(center), (shape["radius"],) * 3)
            if filler.clear(center, shape["radius"]) and all(fruit.apart(crate) for crate in crates):
                filler.add(center, shape)
                break
    colours = [CRATE_RGB[int(rng.integers(len(CRATE_RGB)))] for _ in crates]
    objects = [SceneObject(crate.name, mesh=_crate_mesh(crate), material="clutter_matte", rgb=rgb, alpha=float(rng.random()))
               for crate, rgb in zip(crates, colours)]
    objects += [SceneObject(f"picked_{p.id}", pepper_mesh(p), f"fruit_{p.color}", pass_index=p.id, rgb=tuple(p.rgb),
                            smooth=True, alpha=p.ripeness) for p in filler.fruit]
    if filler.fruit:
        objects.append(SceneObject("picked_calyces", meshes.merge([calyx_mesh(p) for p in filler.fruit]), "calyx", smooth=True))
        objects.append(SceneObject("picked_stalks", meshes.merge([meshes.tube(np.array(p.peduncle.points), p.peduncle.radius)
                                                                  for p in filler.fruit]), "stem", smooth=True))
    return Picked(tuple(filler.fruit), tuple(crates), tuple(objects))
