"""Triangle meshes of a scene's plants, built from `scene.json` alone.

Every consumer (the Blender and MuJoCo renderers, tests, plots) calls these, so all
of them see the same geometry. Parts are kept apart because each gets its own
material and, for peppers, its own instance id.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from renderloop.scene import meshes
from renderloop.scene.meshes import Mesh
from renderloop.scene.model import Pepper, Plant


@dataclass(frozen=True)
class PlantMeshes:
    pot: Mesh
    stem: Mesh  # stem, branches and the peduncles of the fruit
    leaves: list[Mesh]  # one per leaf, in scene order, so each can keep its own colour
    flowers: Mesh | None
    peppers: dict[int, Mesh]  # by pepper id

    def all_vertices(self) -> np.ndarray:
        parts = [self.pot, self.stem, *self.leaves, *self.peppers.values()]
        if self.flowers is not None:
            parts.append(self.flowers)
        return np.vstack([part.vertices for part in parts])


def pepper_mesh(pepper: Pepper) -> Mesh:
    return meshes.pepper(pepper.center, pepper.axis, pepper.length, pepper.width, pepper.lobes, pepper.lobe_depth, twist=pepper.twist)


def plant_meshes(plant: Plant, peppers: list[Pepper]) -> PlantMeshes:
    tubes = [plant.stem, *plant.branches, *(pepper.peduncle for pepper in peppers)]
    stem = meshes.merge([meshes.tube(np.array(t.points), t.radius) for t in tubes])
    leaves = [
        meshes.leaf(leaf.base, leaf.direction, leaf.up, leaf.length, leaf.width, leaf.curvature, leaf.fold, leaf.twist)
        for leaf in plant.leaves
    ]
    flowers = [meshes.flower(flower.center, flower.normal, flower.radius) for flower in plant.flowers]
    pot = meshes.pot(plant.position, plant.pot.radius_bottom, plant.pot.radius_top, plant.pot.height)
    return PlantMeshes(
        pot=pot,
        stem=stem,
        leaves=leaves,
        flowers=meshes.merge(flowers) if flowers else None,
        peppers={pepper.id: pepper_mesh(pepper) for pepper in peppers},
    )
