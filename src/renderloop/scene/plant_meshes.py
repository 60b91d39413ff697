"""Triangle meshes of a scene's plants, built from `scene.json` alone.

Every consumer (the Blender and MuJoCo renderers, tests, plots) calls these, so all
of them see the same geometry. Parts are kept apart because each gets its own
material and, for peppers, its own instance id.

The 'pepper' style's leaves are scaled copies of a few fixed templates (`LEAF_SHAPES`):
a leaf in `scene.json` names its template and its placement, `leaf_transform` turns that
into the one affine map every view applies, and Cycles shares a template's mesh between
all its copies.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np

from renderloop.scene import meshes
from renderloop.scene.meshes import PEPPER_LEAF_WIDTH, LeafShape, Mesh
from renderloop.scene.model import Leaf, Pepper, Plant

# Healthy shapes first; the damaged ones after them. Fixed numbers, not draws: a scene names a template by
# its index, so changing this table changes every 'pepper' style scene (not the 'simple' one).
LEAF_SHAPES: tuple[LeafShape, ...] = (
    LeafShape(droop=0.90, rise=0.45, fold=0.30, curl=0.015, twist=0.10, wrinkle=0.010, wave=0.010, phase=0.0),
    LeafShape(droop=1.20, rise=0.55, fold=0.20, curl=0.025, twist=-0.15, wrinkle=0.014, wave=0.012, phase=0.3),
    LeafShape(droop=0.65, rise=0.30, fold=0.40, curl=0.010, twist=0.25, wrinkle=0.008, wave=0.015, phase=0.55),
    LeafShape(droop=1.45, rise=0.70, fold=0.15, curl=0.030, twist=-0.05, wrinkle=0.016, wave=0.010, phase=0.8),
    LeafShape(droop=1.00, rise=0.40, fold=0.35, curl=0.020, twist=-0.30, wrinkle=0.012, wave=0.018, phase=0.15),
    LeafShape(droop=0.80, rise=0.60, fold=0.10, curl=0.035, twist=0.30, wrinkle=0.018, wave=0.008, phase=0.45),
    LeafShape(droop=1.30, rise=0.35, fold=0.25, curl=0.020, twist=0.05, wrinkle=0.010, wave=0.014, phase=0.65),
    LeafShape(droop=0.55, rise=0.25, fold=0.45, curl=0.012, twist=-0.20, wrinkle=0.009, wave=0.010, phase=0.9),
    LeafShape(droop=0.95, rise=0.45, fold=0.25, curl=0.020, twist=0.10, wrinkle=0.012, wave=0.012, phase=0.2,
              hole=(0.45, 0.45, 0.07)),
    LeafShape(droop=1.10, rise=0.50, fold=0.20, curl=0.025, twist=-0.10, wrinkle=0.014, wave=0.010, phase=0.7,
              bite=(0.35, 0.7, 0.55)),
)
HEALTHY_SHAPES = 8  # LEAF_SHAPES[:8] are whole leaves, the rest damaged
PETIOLE = 0.25  # petiole length over blade length
PEPPER_SEPALS = (5, 7)  # a sweet pepper's calyx has 5 to 7 sepals


@functools.cache
def leaf_template(index: int) -> Mesh:
    """The mesh of template `index` of LEAF_SHAPES (blade length 1), built once per process."""
    return meshes.pepper_leaf(LEAF_SHAPES[index], petiole=PETIOLE)


def leaf_transform(leaf: Leaf) -> np.ndarray:
    """4x4 affine map from a template's frame to the world: the template's x along `direction`, its z along
    `up` (made perpendicular to it), scaled to the leaf's length and width, its origin at `base`."""
    d = np.asarray(leaf.direction, dtype=float)
    d = d / np.linalg.norm(d)
    n = np.asarray(leaf.up, dtype=float)
    n = n - (n @ d) * d
    n = n / np.linalg.norm(n)
    # n x d written out: np.cross costs more than the rest of this map, and a commercial house places 10 000 leaves
    side = np.array([n[1] * d[2] - n[2] * d[1], n[2] * d[0] - n[0] * d[2], n[0] * d[1] - n[1] * d[0]])
    rotation = np.column_stack([d, side, n])
    transform = np.eye(4)
    transform[:3, :3] = rotation * np.array([leaf.length, leaf.width / PEPPER_LEAF_WIDTH, leaf.length])
    transform[:3, 3] = leaf.base
    return transform


def leaf_mesh(leaf: Leaf) -> Mesh:
    """One leaf's blade: its own mesh ('simple' style), or its template scaled and placed."""
    if leaf.template is None:
        return meshes.leaf(leaf.base, leaf.direction, leaf.up, leaf.length, leaf.width, leaf.curvature, leaf.fold, leaf.twist)
    transform = leaf_transform(leaf)
    return leaf_template(leaf.template).transformed(transform[:3, :3], transform[:3, 3])


@dataclass(frozen=True)
class PlantMeshes:
    pot: Mesh
    stem: Mesh  # stem, branches and the peduncles of the fruit
    leaves: list[Mesh]  # one per leaf, in scene order, so each can keep its own colour
    flowers: Mesh | None
    peppers: dict[int, Mesh]  # by pepper id
    calyces: Mesh | None = None  # the calyx of every fruit that has one ('pepper' style)

    def all_vertices(self) -> np.ndarray:
        parts = [self.pot, self.stem, *self.leaves, *self.peppers.values()]
        parts += [part for part in (self.flowers, self.calyces) if part is not None]
        return np.vstack([part.vertices for part in parts])


def pepper_mesh(pepper: Pepper) -> Mesh:
    return meshes.pepper(pepper.center, pepper.axis, pepper.length, pepper.width, pepper.lobes, pepper.lobe_depth, twist=pepper.twist)


def calyx_mesh(pepper: Pepper) -> Mesh:
    calyx = pepper.calyx
    return meshes.calyx(pepper.center, pepper.axis, pepper.length, pepper.width, pepper.lobes, pepper.lobe_depth,
                        pepper.twist, calyx.sepals, calyx.reach, pepper.radius)


def plant_meshes(plant: Plant, peppers: list[Pepper]) -> PlantMeshes:
    """A plant's parts in the world. A copy of a prototype (`plant.prototype`) has no stem, branches, leaves or
    flowers of its own: its parts here are its pot, its fruit with their stalks and calyces; its body is its
    prototype's (`Scene.body`), which `scene/objects.py` stands in its place."""
    tubes = [*([plant.stem] if plant.stem is not None else []), *plant.branches, *(pepper.peduncle for pepper in peppers)]
    stem = meshes.merge([meshes.tube(np.array(t.points), t.radius) for t in tubes])
    flowers = [meshes.flower(flower.center, flower.normal, flower.radius) for flower in plant.flowers]
    calyces = [calyx_mesh(pepper) for pepper in peppers if pepper.calyx is not None]
    pot = meshes.pot(plant.position, plant.pot.radius_bottom, plant.pot.radius_top, plant.pot.height)
    return PlantMeshes(
        pot=pot,
        stem=stem,
        leaves=[leaf_mesh(leaf) for leaf in plant.leaves],
        flowers=meshes.merge(flowers) if flowers else None,
        peppers={pepper.id: pepper_mesh(pepper) for pepper in peppers},
        calyces=meshes.merge(calyces) if calyces else None,
    )
