"""The 'highwire' plant style: a plant of a commercial high-wire crop, its stems trained up strings.

Growers keep two to four stems per plant from the first forks and train each up its own string to the
crop wire. A stem winds round its string and grows a node every 6-11 cm, shorter towards the growing
head; each node carries a leaf and a side shoot that the grower stops after its first leaf or fruit, and
the old leaves low on the stems are stripped. This module grows that skeleton inside the plant's box;
the fruit, leaves and flowers come exactly as in the 'pepper' style (scene/pepper_plant.py): the fruit are
placed first, as the truth the pipeline counts, the strings are set where no fruit is in their way, and
every shoot hanging a fruit starts on the nearest stem.
"""

from __future__ import annotations

import math

import numpy as np

from renderloop.scene.model import Pepper
from renderloop.scene.pepper_plant import BRANCH_MARGIN, PepperPlantGrower
from renderloop.scene.plant import _round

STEM_ORDER, SHOOT_ORDER = 1, 2  # a trained stem is one fork from the main stem; a side shoot one more
STRING_LAYOUTS = 40  # draws of the strings' places along the row before the one with fewest fruit in the way
SHOOT_LENGTH = (0.03, 0.07)  # m: a stopped side shoot
HEAD_SHORTENING = 0.4  # internodes at the head are this much shorter than at the foot


class HighWireGrower(PepperPlantGrower):
    """Grows stems up strings (`feet`: where each string is tied), with a side shoot at most nodes."""

    def __init__(self, grower, peppers: list[Pepper]) -> None:
        super().__init__(grower, peppers)
        self.feet = np.zeros((0, 3))

    def _axis_xy(self, point: np.ndarray) -> np.ndarray:
        """The nearest string: a leaf or a fruit's shoot grows out from the stem that winds round it."""
        if not len(self.feet):
            return super()._axis_xy(point)
        return self.feet[int(np.argmin(np.linalg.norm(self.feet[:, :2] - point[:2], axis=1))), :2]

    def _leafy(self) -> list[tuple[np.ndarray, np.ndarray, int]]:
        floor = self.pot_top + self.config.highwire.leafless * (self.box_max[2] - self.pot_top)
        return [internode for internode in self.internodes if internode[1][2] >= floor] or self.internodes

    def _blocked(self, ys: np.ndarray) -> int:
        """How many fruit a string at each of `ys` (on the row's line) and its winding stem would touch."""
        if not len(self.radii):
            return 0
        reach = self.config.highwire.wind + self._radius(STEM_ORDER) + BRANCH_MARGIN
        dx = self.centers[:, 0] - self.grower.base[0]
        dy = self.centers[:, 1][None, :] - ys[:, None]
        return int(np.sum(np.hypot(dx[None, :], dy) < self.radii[None, :] + reach))

    def grow_skeleton(self, rng: np.random.Generator) -> None:
        style = self.config.highwire
        base, height = self.grower.base, self.box_max[2] - self.pot_top
        fork_z = self.pot_top + min(rng.uniform(0.06, 0.12), 0.3 * height)
        below = [point for point in self.grower.stem if point[2] < fork_z - 0.01]
        fork = self.grower._stem_point_at(fork_z)
        self.tubes.append(dict(points=[*below, fork], order=0))
        main = self.tubes[0]["points"]
        self.internodes += [(a, b, 0) for a, b in zip(main[:-1], main[1:]) if b[2] > self.pot_top]
        self.nodes.append((fork, 0))

        count = int(rng.integers(style.stems[0], style.stems[1] + 1))
        half = (self.box_max[1] - self.box_min[1]) / 2 - style.wind - self._radius(STEM_ORDER) - 2 * BRANCH_MARGIN
        layouts = []
        for _ in range(STRING_LAYOUTS):
            spread = half * rng.uniform(0.55, 1.0)
            ys = base[1] + np.clip((np.linspace(-spread, spread, count) if count > 1 else np.zeros(1))
                                   + rng.normal(0.0, 0.02, count), -half, half)
            layouts.append((self._blocked(ys), ys))
            if layouts[-1][0] == 0:
                break
        ys = min(layouts, key=lambda layout: layout[0])[1]
        self.feet = np.column_stack([np.full(count, base[0]), ys, np.full(count, self.pot_top)])
        for foot in self.feet:
            self._climb(rng, fork, foot)

    def _climb(self, rng: np.random.Generator, fork: np.ndarray, foot: np.ndarray) -> None:
        """One stem from the fork over to its string, then up it node by node to just under the box's top."""
        style = self.config.highwire
        tube = self._new_tube(fork, STEM_ORDER)
        top = self.box_max[2] - BRANCH_MARGIN - rng.uniform(0.0, 0.1) * (self.box_max[2] - self.pot_top)
        phase = rng.uniform(0.0, 2 * math.pi)
        node = fork
        z = fork[2] + max(0.06, 1.2 * abs(foot[1] - fork[1]))
        while z < top:
            step = rng.uniform(1.5, 3.0)  # the stem turns round its string from node to node
            for turn in (0.0, 0.5 * math.pi, math.pi, 1.5 * math.pi, None):
                angle = phase + step + (turn or 0.0)
                end = foot + np.array([style.wind * math.cos(angle), style.wind * math.sin(angle), z - foot[2]])
                middle = (node + end) / 2 + np.r_[rng.normal(0.0, 0.2 * style.wind, 2), 0.0]
                if turn is None or self._shoot_ok(np.array([node, middle, end])):
                    break  # with every turn in a fruit's way, the stem pushes past as a real one does
            phase = angle
            self.tubes[tube]["points"] += [middle, end]
            self.internodes += [(node, middle, STEM_ORDER), (middle, end, STEM_ORDER)]
            self.nodes.append((end, STEM_ORDER))
            if rng.random() < style.side_shoots:
                self._side_shoot(rng, end)
            node = end
            climbed = (z - fork[2]) / max(top - fork[2], 1e-9)
            z += rng.uniform(*style.internode) * (1.0 - HEAD_SHORTENING * climbed)

    def _side_shoot(self, rng: np.random.Generator, node: np.ndarray) -> None:
        for _attempt in range(4):
            heading, elevation = rng.uniform(0.0, 2 * math.pi), rng.uniform(0.3, 0.9)
            direction = np.array([math.cos(elevation) * math.cos(heading), math.cos(elevation) * math.sin(heading),
                                  math.sin(elevation)])
            end = node + direction * rng.uniform(*SHOOT_LENGTH)
            if self._shoot_ok(np.array([node, end])):
                self.tubes.append(dict(points=[node, end], order=SHOOT_ORDER))
                self.internodes.append((node, end, SHOOT_ORDER))
                self.nodes.append((end, SHOOT_ORDER))
                return

    def strings(self) -> list[tuple[float, ...]]:
        return [_round(foot) for foot in self.feet]

