"""The 'pepper' plant style: a sweet-pepper plant as it grows, branching, dense and hung with fruit.

The fruit are placed first and exactly as the 'simple' style places them (`plant.place_fruit`: the
same draws from the plant's generator), so one seed gives the same fruit, the truth the pipeline
counts, in both styles. Then, each from its own named stream of the plant's seed:

- the skeleton: the main stem up to the first fork, then dichotomous branching (pepper forks at
  every node into two shoots), internodes bent and kept inside the plant's box and out of the fruit;
- the fruit's nodes: each fruit hangs on a curved peduncle from a node of a shoot that branches off
  the skeleton, and the shoot goes on beyond the node, so the fruit sits in a fork as on a real plant;
  a calyx covers its stalk end;
- the leaves: copies of a few templates (scene/plant_meshes.LEAF_SHAPES) on the petioles along the
  shoots, younger ones smaller; a few yellowed, damaged or dusty;
- the flowers, nodding at the nodes.

Every leaf and flower is resampled while it would leave the box, cut into a fruit's bounding
sphere or cover the middle of a fruit as the scan sees it (from the fruit's side of the row), so
the box stays a true bound and the fruit stay findable.
"""

from __future__ import annotations

import math

import numpy as np

from renderloop.config import PlantConfig
from renderloop.scene import meshes
from renderloop.scene.model import Box, Calyx, Flower, Leaf, Pepper, Plant, Pot, Tube
from renderloop.scene.plant import PlantGrower, _round, _unit, place_fruit
from renderloop.scene.plant_meshes import HEALTHY_SHAPES, LEAF_SHAPES, PEPPER_SEPALS, leaf_template, leaf_transform

# Streams of the plant's seed, one per kind of draw: more leaves never move a branch.
SKELETON_STREAM, FRUIT_STREAM, LEAF_STREAM, FLOWER_STREAM, TINT_STREAM = 0x51, 0x52, 0x53, 0x54, 0x55

LEAF_RGB = (0.19, 0.37, 0.09)  # a healthy leaf's colour before its own variation, sRGB
LIGHT_LEAF_RGB = (0.45, 0.52, 0.15)  # a light yellow-green crop's (pepper_style.leaf_tint 1), sRGB
YELLOWED_RGB = (0.62, 0.58, 0.16)  # where an ageing leaf's colour goes, sRGB
PEDUNCLE_RADIUS = 0.0035  # m
BREAKING = 0.25  # share of coloured fruit still turning (the breaker stage: green, brown and their colour)
BRANCH_MARGIN = 0.008  # m between a shoot's axis and the box or a fruit's bounding sphere
ATTEMPTS = 12
MAX_ORDER = 4  # forks above the first: a pot-grown plant's canopy in a few forks


def _stream(rng: np.random.Generator, label: int) -> np.random.Generator:
    """The child stream `label` of the seed behind `rng` (the plant's own SeedSequence)."""
    seed = rng.bit_generator.seed_seq
    return np.random.default_rng(np.random.SeedSequence(seed.entropy, spawn_key=(*seed.spawn_key, label)))


def _rotate(vector: np.ndarray, axis: np.ndarray, angle: float) -> np.ndarray:
    """Rodrigues: `vector` turned by `angle` about the unit `axis`."""
    return (vector * math.cos(angle) + np.cross(axis, vector) * math.sin(angle)
            + axis * (axis @ vector) * (1.0 - math.cos(angle)))


def _along(points: np.ndarray, step: float) -> np.ndarray:
    """Points along a polyline no farther than `step` apart, its vertices included."""
    out = [points[:1]]
    for a, b in zip(points[:-1], points[1:]):
        n = max(1, int(math.ceil(np.linalg.norm(b - a) / step)))
        out.append(a + (b - a) * (np.arange(1, n + 1) / n)[:, None])
    return np.concatenate(out)


class PepperPlantGrower:
    """Grows the skeleton, fruit nodes, leaves and flowers of one plant around its placed fruit."""

    def __init__(self, grower: PlantGrower, peppers: list[Pepper]) -> None:
        self.grower = grower
        self.config: PlantConfig = grower.config
        self.peppers = peppers
        self.box_min, self.box_max, self.pot_top = grower.box_min, grower.box_max, grower.pot_top
        self.centers = np.array([p.center for p in peppers]).reshape(-1, 3)
        self.radii = np.array([p.radius for p in peppers])
        self.sides = np.array([-1.0 if p.side == "left" else 1.0 for p in peppers])
        self.tubes: list[dict] = []  # points (a list of arrays) and order (forks from the stem); tube 0 is the main stem
        self.internodes: list[tuple[np.ndarray, np.ndarray, int]] = []  # start, end, order
        self.nodes: list[tuple[np.ndarray, int]] = []  # forks and tips, with their order

    # checks ------------------------------------------------------------------------------------

    def _inside(self, points: np.ndarray, margin: float) -> bool:
        return bool(np.all(points >= self.box_min + margin) and np.all(points <= self.box_max - margin)
                    and np.all(points[:, 2] > self.pot_top + margin))

    def _clear_of_fruit(self, points: np.ndarray, margin: float = 0.0) -> bool:
        if not len(self.radii):
            return True
        distance = np.linalg.norm(points[:, None, :] - self.centers[None], axis=2)
        return bool(np.all(distance >= self.radii + margin))

    def _out_of_windows(self, points: np.ndarray) -> bool:
        """No point in front of a fruit (toward its side of the row) within the window about its centre."""
        if not len(self.radii):
            return True
        offset = points[:, None, :] - self.centers[None]
        ahead = offset[..., 0] * self.sides > 0
        near = np.hypot(offset[..., 1], offset[..., 2]) < self.config.pepper_style.fruit_window * self.radii
        return not bool(np.any(ahead & near))

    def _shoot_ok(self, points: np.ndarray) -> bool:
        samples = _along(points, 0.01)
        return self._inside(samples, BRANCH_MARGIN) and self._clear_of_fruit(samples, BRANCH_MARGIN)

    def _axis_xy(self, point: np.ndarray) -> np.ndarray:
        """The (x, y) of the stem axis that `point` grows round: out from it is outward."""
        return self.grower.base[:2]

    def _leafy(self) -> list[tuple[np.ndarray, np.ndarray, int]]:
        """The internodes that carry leaves."""
        return self.internodes

    def _radius(self, order: int) -> float:
        return round(max(0.0015, self.config.stem_radius * 0.7**order), 6)

    # skeleton ----------------------------------------------------------------------------------

    def grow_skeleton(self, rng: np.random.Generator) -> None:
        height = self.box_max[2] - self.pot_top
        fork_z = self.pot_top + rng.uniform(0.18, 0.28) * height
        stem = self.grower.stem
        below = [point for point in stem if point[2] < fork_z - 0.01]
        fork = self.grower._stem_point_at(fork_z)
        self.tubes.append(dict(points=[*below, fork], order=0))
        main = self.tubes[0]["points"]
        self.internodes += [(a, b, 0) for a, b in zip(main[:-1], main[1:]) if b[2] > self.pot_top]
        self.nodes.append((fork, 0))
        internode = float(np.clip(0.2 * height, 0.045, 0.12))
        children = 3 if rng.random() < 0.25 else 2
        azimuth = rng.uniform(0.0, 2 * math.pi)
        for k in range(children):
            heading = azimuth + 2 * math.pi * k / children + rng.normal(0.0, 0.25)
            elevation = rng.uniform(0.6, 0.95)
            direction = np.array([math.cos(elevation) * math.cos(heading), math.cos(elevation) * math.sin(heading),
                                  math.sin(elevation)])
            self._grow(rng, fork, direction, 1, self._new_tube(fork, 1), internode)

    def _new_tube(self, start: np.ndarray, order: int) -> int:
        self.tubes.append(dict(points=[start], order=order))
        return len(self.tubes) - 1

    def _grow(self, rng: np.random.Generator, node: np.ndarray, direction: np.ndarray, order: int, tube: int,
              internode: float) -> None:
        """One internode from `node`, then a fork into two shoots, until the top, the box or a fruit stops it."""
        axis_xy = self.grower.base[:2]
        for attempt in range(8):
            length = internode * rng.uniform(0.8, 1.2) * 0.93**order * (1.0 - 0.08 * attempt)
            heading = direction
            if attempt:  # turn inward and up, away from the box's walls and the fruit
                inward = np.r_[axis_xy - node[:2], 0.0]
                heading = _unit(direction + 0.35 * attempt * (_unit(inward) if np.linalg.norm(inward) > 1e-6 else 0)
                                + np.array([0.0, 0.0, 0.15 * attempt]) + rng.normal(0.0, 0.2, 3))
            end = node + heading * length
            bend = np.cross(heading, [0.0, 0.0, 1.0])
            bend = _unit(bend) if np.linalg.norm(bend) > 1e-6 else np.array([1.0, 0.0, 0.0])
            middle = (node + end) / 2 + bend * rng.normal(0.0, 0.08) * length
            if self._shoot_ok(np.array([node, middle, end])):
                break
        else:
            self.nodes.append((node, order))  # a tip
            return
        self.tubes[tube]["points"] += [middle, end]
        self.internodes.append((node, middle, order))
        self.internodes.append((middle, end, order))
        self.nodes.append((end, order))
        if order >= MAX_ORDER or end[2] > self.box_max[2] - 0.05:
            return
        spread = rng.uniform(0.3, 0.55)
        plane = _rotate(_unit(np.cross(heading, [0.0, 0.0, 1.0]) if abs(heading[2]) < 0.99 else np.array([1.0, 0, 0])),
                        heading, rng.uniform(-0.6, 0.6))
        weak = order >= 2 and rng.random() < 0.4  # one shoot of a fork often stays short: it only carries leaves
        for k, sign in enumerate((1.0, -1.0)[: 1 if weak else 2]):
            child = _unit(_rotate(heading, plane, sign * spread) + np.array([0.0, 0.0, 0.12]))
            self._grow(rng, end, child, order + 1, tube if k == 0 else self._new_tube(end, order + 1), internode)

    # fruit -------------------------------------------------------------------------------------

    def hang_fruit(self, rng: np.random.Generator) -> list[Pepper]:
        """Each fruit on a peduncle from a node of its own shoot, the shoot branching off the skeleton."""
        hung = []
        for pepper in self.peppers:
            center, axis = np.array(pepper.center), np.array(pepper.axis)
            top = center - axis * pepper.length / 2
            inward = np.r_[self._axis_xy(center) - center[:2], 0.0]
            inward = _unit(inward) if np.linalg.norm(inward) > 1e-6 else np.array([1.0, 0.0, 0.0])
            node = top + inward * rng.uniform(0.005, 0.02) + np.array([0.0, 0.0, rng.uniform(0.012, 0.025)])
            for _ in range(40):  # up and in until clear of every fruit, its own included
                if self._clear_of_fruit(node[None], BRANCH_MARGIN) or node[2] >= self.box_max[2] - BRANCH_MARGIN:
                    break
                node += np.array([0.0, 0.0, 0.004]) + inward * 0.002
            node[2] = min(node[2], self.box_max[2] - BRANCH_MARGIN)
            self._join(rng, node)
            above = top - axis * rng.uniform(0.008, 0.014)  # the stalk enters the calyx along the fruit's axis
            bulge = (node + above) / 2 - inward * rng.uniform(0.004, 0.012) + np.array([0.0, 0.0, 0.006])
            peduncle = Tube(points=[_round(p) for p in (node, bulge, above, top)], radius=PEDUNCLE_RADIUS)
            breaking = rng.random() < BREAKING and pepper.color != "green"
            ripe_share = rng.uniform(0.55, 0.95) if breaking else 1.0
            calyx = Calyx(sepals=int(rng.integers(PEPPER_SEPALS[0], PEPPER_SEPALS[1] + 1)),
                          reach=_round(rng.uniform(0.2, 0.27) * pepper.width))
            hung.append(pepper.model_copy(update=dict(peduncle=peduncle, calyx=calyx, ripeness=_round(ripe_share))))
        return hung

    def _join(self, rng: np.random.Generator, node: np.ndarray) -> None:
        """A shoot from the nearest reachable point of the skeleton to `node`, going on beyond it."""
        along = [_along(np.array(tube["points"]), 0.01) for tube in self.tubes]
        candidates = np.concatenate(along)
        orders = np.concatenate([np.full(len(points), tube["order"]) for points, tube in zip(along, self.tubes)])
        distance = np.linalg.norm(candidates - node, axis=1) + 0.5 * np.maximum(candidates[:, 2] - node[2] - 0.02, 0.0)
        # Stable: where two points tie (a shoot starts on a point of its parent), the older tube's comes first. numpy's
        # default sort breaks ties by the SIMD instructions it runs on, which would grow another plant on another CPU.
        ranked = np.argsort(distance, kind="stable")
        chosen = ranked[0]  # when nothing is clear: the nearest, as a real shoot pushes past what is in its way
        for k in ranked[:40]:
            middle = (candidates[k] + node) / 2 + np.array([0.0, 0.0, 0.01 + 0.15 * np.linalg.norm(node - candidates[k])])
            if self._shoot_ok(np.array([candidates[k], middle, node])):
                chosen = k
                break
        start = candidates[chosen]
        path = [start, (start + node) / 2 + np.array([0.0, 0.0, 0.01 + 0.15 * np.linalg.norm(node - start)]), node]
        order = int(orders[chosen]) + 1
        outward = np.r_[node[:2] - self._axis_xy(node), 0.0]
        outward = _unit(outward) if np.linalg.norm(outward) > 1e-6 else np.array([1.0, 0.0, 0.0])
        drawn = [node + _unit(outward * rng.uniform(0.2, 0.8) + np.array([0.0, 0.0, 1.0]) + rng.normal(0.0, 0.3, 3))
                 * rng.uniform(0.03, 0.07) for _ in range(ATTEMPTS)]
        inward = np.array([-outward[0], -outward[1], 0.0])
        fallback = [node + _unit(d) * reach for reach in (0.03, 0.015) for d in ((0, 0, 1), inward + (0, 0, 1), inward)]
        for beyond in drawn + fallback:  # the shoot goes on beyond the fruit's node, so the fruit sits in a fork
            if self._shoot_ok(np.array([node, beyond])):
                path.append(beyond)
                self.internodes.append((node, beyond, order))
                self.nodes.append((beyond, order))
                break
        self.tubes.append(dict(points=path, order=order))
        self.internodes.append((path[0], path[1], order))
        self.internodes.append((path[1], path[2], order))
        self.nodes.append((node, order))

    # leaves and flowers ------------------------------------------------------------------------

    def grow_leaves(self, rng: np.random.Generator, tint: float = 0.0) -> list[Leaf]:
        """The plant's leaves; `tint` takes its healthy colour that share of the way to LIGHT_LEAF_RGB."""
        style = self.config.pepper_style
        healthy = np.array(LEAF_RGB) + (np.array(LIGHT_LEAF_RGB) - np.array(LEAF_RGB)) * tint
        leafy = self._leafy()
        starts = np.array([start for start, _, _ in leafy])
        ends = np.array([end for _, end, _ in leafy])
        orders = np.array([order for _, _, order in leafy], dtype=float)
        weights = np.linalg.norm(ends - starts, axis=1) * (1.0 + 0.25 * orders) + 1e-9
        weights /= weights.sum()
        oldest = orders.max() or 1.0
        leaves = []
        for _ in range(int(rng.integers(style.leaves[0], style.leaves[1] + 1))):
            for _attempt in range(ATTEMPTS):
                k = int(rng.choice(len(weights), p=weights))
                base = starts[k] + (ends[k] - starts[k]) * rng.uniform(0.1, 1.0)
                outward = base[:2] - self._axis_xy(base)
                heading = math.atan2(outward[1], outward[0]) + rng.normal(0.0, 1.0) if np.linalg.norm(outward) > 0.01 \
                    else rng.uniform(0.0, 2 * math.pi)
                elevation = rng.uniform(-0.35, 0.25)  # the petiole rises, the blade droops from it
                direction = np.array([math.cos(elevation) * math.cos(heading), math.cos(elevation) * math.sin(heading),
                                      math.sin(elevation)])
                up = _unit(np.array([*rng.normal(0.0, 0.25, size=2), 1.0]))
                low, high = style.leaf_length
                youth = orders[k] / oldest  # shoots far from the stem carry the young, small leaves
                length = low + (high - low) * rng.uniform(0.0, 1.0) * (1.0 - 0.3 * youth)
                width = length * rng.uniform(*style.leaf_width_ratio)
                damaged = rng.random() < style.damaged
                template = int(rng.integers(HEALTHY_SHAPES, len(LEAF_SHAPES))) if damaged else int(rng.integers(0, HEALTHY_SHAPES))
                leaf = Leaf(base=_round(base), direction=_round(direction), up=_round(up), length=_round(length),
                            width=_round(width), template=template, rgb=(0.0, 0.0, 0.0))
                transform = leaf_transform(leaf)
                blade = leaf_template(template).vertices @ transform[:3, :3].T + transform[:3, 3]
                if self._inside(blade, 0.0) and self._clear_of_fruit(blade) and self._out_of_windows(blade):
                    rgb = healthy * rng.lognormal(0.0, 0.12) * rng.uniform(0.9, 1.1, size=3)
                    if rng.random() < style.yellowed:
                        rgb = rgb + (np.array(YELLOWED_RGB) - rgb) * rng.uniform(0.4, 0.9)
                    dust = _round(rng.uniform(0.3, 0.8)) if rng.random() < style.dusty else None
                    leaves.append(leaf.model_copy(update=dict(rgb=_round(np.clip(rgb, 0.0, 1.0)), dust=dust)))
                    break
        return leaves

    def grow_flowers(self, rng: np.random.Generator) -> list[Flower]:
        anchors = [node for node, order in self.nodes if order >= 1] or [node for node, _ in self.nodes]
        flowers = []
        for _ in range(int(rng.integers(self.config.flowers[0], self.config.flowers[1] + 1))):
            for _attempt in range(ATTEMPTS):
                anchor = anchors[int(rng.integers(0, len(anchors)))]
                center = anchor + np.array([*rng.normal(0.0, 0.008, size=2), -rng.uniform(0.01, 0.025)])
                heading, elevation = rng.uniform(0.0, 2 * math.pi), rng.uniform(-1.3, -0.5)  # nodding
                normal = np.array([math.cos(elevation) * math.cos(heading), math.cos(elevation) * math.sin(heading),
                                   math.sin(elevation)])
                radius = rng.uniform(0.008, 0.013)
                petals = meshes.flower(center, normal, radius)
                if self._inside(petals.vertices, 0.0) and self._clear_of_fruit(petals.vertices) \
                        and self._out_of_windows(petals.vertices):
                    flowers.append(Flower(center=_round(center), normal=_round(normal), radius=_round(radius)))
                    break
        return flowers

    def strings(self) -> list[tuple[float, ...]] | None:
        """Where the plant's strings are tied: a pot-grown plant has none."""
        return None

    def branches(self) -> tuple[Tube, list[Tube]]:
        stem, *others = self.tubes
        as_tube = [Tube(points=[_round(p) for p in tube["points"]], radius=self._radius(tube["order"]))
                   for tube in others if len(tube["points"]) > 1]
        return Tube(points=[_round(p) for p in stem["points"]], radius=self.config.stem_radius), as_tube


def grow_pepper_plant(
    rng: np.random.Generator,
    config: PlantConfig,
    plant_id: int,
    row: int,
    position: tuple[float, float, float],
    peppers_per_side: tuple[int, int],
    first_pepper_id: int,
    grower_class: type[PepperPlantGrower] = PepperPlantGrower,
) -> tuple[Plant, list[Pepper]]:
    """One 'pepper' style plant with `peppers_per_side` = (left, right) fruit, ids counting from `first_pepper_id`;
    `grower_class` grows another skeleton round the same fruit, leaves and flowers (scene/highwire.py)."""
    grower = PlantGrower(rng, config, position)
    placed = place_fruit(grower, plant_id, peppers_per_side, first_pepper_id)
    plant = grower_class(grower, placed)
    plant.grow_skeleton(_stream(rng, SKELETON_STREAM))
    peppers = plant.hang_fruit(_stream(rng, FRUIT_STREAM))
    tint = _stream(rng, TINT_STREAM).uniform(*config.pepper_style.leaf_tint)
    leaves = plant.grow_leaves(_stream(rng, LEAF_STREAM), tint)
    flowers = plant.grow_flowers(_stream(rng, FLOWER_STREAM))
    stem, branches = plant.branches()
    return Plant(
        id=plant_id, row=row, position=_round(grower.base),
        bounds=Box(min=_round(grower.box_min), max=_round(grower.box_max)),
        bearing=sum(peppers_per_side) > 0,
        pot=Pot(radius_top=config.pot.radius_top, radius_bottom=config.pot.radius_bottom, height=config.pot.height),
        stem=stem, branches=branches, leaves=leaves, flowers=flowers, strings=plant.strings(),
    ), peppers
