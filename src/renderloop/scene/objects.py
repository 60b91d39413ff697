"""The greenhouse as a list of objects, the one description every view draws.

Kubric's pattern: one scene, and each simulator or renderer a view of it. An object
has a name, either a triangle mesh or primitive shapes (boxes, cylinders), a material
name of the table in `scene/materials.py`, and for a pepper its instance id. Cycles
(`render/cycles.py`) draws each object's triangles, the raster renderer
(`render/raster.py`) makes a MuJoCo geom of each mesh or shape, and the physics world
(`scene/world.py`) reads the same static shapes next to its own simple collision
volumes for the plants. Each view translates every kind of object in one function.

Numpy only (no bpy, no mujoco), so any process can build the list.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from renderloop.scene import meshes
from renderloop.scene.materials import MATERIALS, RGBA
from renderloop.scene.meshes import Mesh
from renderloop.scene.model import MAX_PEPPER_ID, Scene
from renderloop.scene.plant_meshes import plant_meshes

__all__ = ["Box", "Cylinder", "SceneObject", "greenhouse_objects", "collision_objects", "static_objects",
           "wall_boxes", "table_boxes", "WALL_THICKNESS", "WORKSTATION_COLUMN"]

TABLE_TOP_THICKNESS = 0.04
TABLE_LEG = 0.04
WALL_THICKNESS = 0.05
WORKSTATION_COLUMN = (0.6, 0.05)  # height above the workstation table and radius of its manipulator, m
COLUMN_SIDES = 24  # facets of a cylinder's triangle mesh


@dataclass(frozen=True)
class Box:
    """Axis-aligned box by centre and half size (MuJoCo's convention)."""

    name: str
    center: tuple[float, float, float]
    half: tuple[float, float, float]

    def mesh(self) -> Mesh:
        return meshes.box(self.center, 2 * np.asarray(self.half))


@dataclass(frozen=True)
class Cylinder:
    """Closed cylinder from `start` to `end` (the centres of its end faces)."""

    name: str
    start: tuple[float, float, float]
    end: tuple[float, float, float]
    radius: float

    def mesh(self) -> Mesh:
        return meshes.tube(np.array([self.start, self.end]), self.radius, sides=COLUMN_SIDES)


Shape = Box | Cylinder


@dataclass(frozen=True)
class SceneObject:
    """One object of a view: a mesh or primitive shapes, a material of `scene.materials.MATERIALS`,
    its instance id (`pass_index`, a pepper's id; 0 for everything else), an object colour
    (sRGB, for materials that take the object's colour), smooth shading, and an optional
    per-vertex sRGB colour (the leaf colour of each blade)."""

    name: str
    mesh: Mesh | None = None
    material: str = "object_color"
    pass_index: int = 0
    rgb: tuple[float, float, float] | None = None
    smooth: bool = False
    vertex_rgb: np.ndarray | None = None
    shapes: tuple[Shape, ...] = field(default=())

    def __post_init__(self) -> None:
        if (self.mesh is None) == (not self.shapes):
            raise ValueError(f"{self.name}: an object is a mesh or primitive shapes, not both nor neither")
        if self.material not in MATERIALS:
            raise ValueError(f"{self.name}: no material {self.material!r}")
        if not 0 <= self.pass_index <= MAX_PEPPER_ID:
            raise ValueError(f"{self.name}: pass_index {self.pass_index} outside 0..{MAX_PEPPER_ID}")

    def triangles(self) -> Mesh:
        """The mesh, or the shapes' meshes merged in order (what a triangle renderer draws)."""
        return self.mesh if self.mesh is not None else meshes.merge([shape.mesh() for shape in self.shapes])

    def display_rgba(self) -> RGBA:
        """The flat colour of a view without Cycles' materials: the object's own colour, else the mean
        of its vertex colours (a plant's leaves), else the material's display colour."""
        if self.rgb is not None:
            return (*map(float, self.rgb), 1.0)
        if self.vertex_rgb is not None and len(self.vertex_rgb):
            return (*map(float, np.asarray(self.vertex_rgb, dtype=float).reshape(-1, 3).mean(axis=0)), 1.0)
        return MATERIALS[self.material].rgba


def wall_boxes(room: Sequence[float]) -> list[Box]:
    """The four walls just outside the room."""
    length, width, height = room
    t = WALL_THICKNESS / 2
    return [
        Box("wall_east", (length / 2 + t, 0, height / 2), (t, width / 2, height / 2)),
        Box("wall_west", (-length / 2 - t, 0, height / 2), (t, width / 2, height / 2)),
        Box("wall_north", (0, width / 2 + t, height / 2), (length / 2, t, height / 2)),
        Box("wall_south", (0, -width / 2 - t, height / 2), (length / 2, t, height / 2)),
    ]


def table_boxes(name: str, center: Sequence[float], size: Sequence[float]) -> list[Box]:
    """A table's slab and four legs; `center` is the centre of the table's whole box, floor to top."""
    x, y, _ = center
    sx, sy, height = size
    leg_height = height - TABLE_TOP_THICKNESS
    boxes = [Box(name, (x, y, height - TABLE_TOP_THICKNESS / 2), (sx / 2, sy / 2, TABLE_TOP_THICKNESS / 2))]
    for index, (dx, dy) in enumerate(((-1, -1), (-1, 1), (1, -1), (1, 1))):
        leg_center = (x + dx * (sx / 2 - TABLE_LEG), y + dy * (sy / 2 - TABLE_LEG), leg_height / 2)
        boxes.append(Box(f"{name}_leg{index}", leg_center, (TABLE_LEG / 2, TABLE_LEG / 2, leg_height / 2)))
    return boxes


def static_objects(scene: Scene) -> list[SceneObject]:
    """Floor, walls, tables and workstation, each kind one object so that Cycles syncs few of them.
    The floor runs on under the walls, so no light leaks in where they meet it."""
    length, width, _ = scene.room
    t = WALL_THICKNESS
    station = scene.workstation
    column_height, column_radius = WORKSTATION_COLUMN
    top = (station.center[0], station.center[1], station.size[2])
    column = Cylinder("workstation_arm", top, (top[0], top[1], top[2] + column_height), column_radius)
    tables = [box for row in scene.rows for box in table_boxes(f"table_{row.id}", row.table.center, row.table.size)]
    return [
        SceneObject("floor", material="floor", shapes=(Box("floor", (0, 0, -0.05), ((length + 2 * t) / 2, (width + 2 * t) / 2, 0.05)),)),
        SceneObject("walls", material="wall", shapes=tuple(wall_boxes(scene.room))),
        SceneObject("tables", material="table", shapes=tuple(tables)),
        SceneObject("workstation", material="workstation",
                    shapes=(*table_boxes("workstation", station.center, station.size), column)),
    ]


def greenhouse_objects(scene: Scene) -> list[SceneObject]:
    """What the renderers draw: the static objects, then per plant one pot, one stem, one leaf and
    one flower object and one object per pepper (its pass_index is its id)."""
    objects = static_objects(scene)
    for plant in scene.plants:
        peppers = scene.peppers_of(plant.id)
        parts = plant_meshes(plant, peppers)
        objects.append(SceneObject(f"pot_{plant.id}", parts.pot, "pot"))
        objects.append(SceneObject(f"stem_{plant.id}", parts.stem, "stem", smooth=True))
        if parts.leaves:
            colors = np.concatenate([np.tile(leaf.rgb, (len(m.vertices), 1)) for leaf, m in zip(plant.leaves, parts.leaves)])
            objects.append(SceneObject(f"leaves_{plant.id}", meshes.merge(parts.leaves), "leaf", smooth=True, vertex_rgb=colors))
        if parts.flowers is not None:
            objects.append(SceneObject(f"flowers_{plant.id}", parts.flowers, "flower"))
        for pepper in peppers:
            objects.append(SceneObject(f"pepper_{pepper.id}", parts.peppers[pepper.id], f"pepper_{pepper.color}",
                                       pass_index=pepper.id, rgb=tuple(pepper.rgb), smooth=True))
    return objects


def collision_objects(scene: Scene) -> list[SceneObject]:
    """What the physics world holds: the same static objects, and per plant its pot as a cylinder and
    one box for the canopy (the plant's bounding volume above its pot: touching it counts as a
    collision with the plant), instead of thousands of leaf triangles."""
    objects = static_objects(scene)
    for plant in scene.plants:
        x, y, z = plant.position
        pot = plant.pot
        objects.append(SceneObject(f"pot_{plant.id}", material="pot",
                                   shapes=(Cylinder(f"pot_{plant.id}", (x, y, z), (x, y, z + pot.height), pot.radius_top),)))
        low, high = plant.bounds.min, plant.bounds.max
        bottom = z + pot.height
        canopy = Box(f"plant_{plant.id}", ((low[0] + high[0]) / 2, (low[1] + high[1]) / 2, (bottom + high[2]) / 2),
                     ((high[0] - low[0]) / 2, (high[1] - low[1]) / 2, (high[2] - bottom) / 2))
        objects.append(SceneObject(f"canopy_{plant.id}", material="canopy", shapes=(canopy,)))
    return objects
