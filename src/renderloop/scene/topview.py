"""Top view of the greenhouse: the picture a user checks first to see what was generated."""

from __future__ import annotations

import functools
from pathlib import Path

import matplotlib
import numpy as np

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
from matplotlib.collections import LineCollection, PatchCollection, PolyCollection  # noqa: E402
from matplotlib.patches import Circle, Rectangle  # noqa: E402

from renderloop.io.atomic import atomic_path  # noqa: E402
from renderloop.scene.model import Plant, Scene, placement  # noqa: E402
from renderloop.scene.plant_meshes import leaf_template, leaf_transform, plant_meshes  # noqa: E402

ZOOM_PLANTS = 8  # plants of the enlarged row drawn leaf by leaf: the first of a long row, all of a short one
PEPPER_FACE = {"red": "#c81e14", "yellow": "#f0c20a", "orange": "#f07814", "green": "#3c9a28"}


@functools.cache
def _outline(template: int) -> np.ndarray:
    """The outline of a leaf template, its longest loop of boundary edges (holes are shorter loops), as vertices in
    the template's frame: a copy of it is drawn as one polygon, not its few hundred triangles (a 'pepper' plant's
    hundreds of leaves would otherwise take matplotlib tens of seconds)."""
    mesh = leaf_template(template)
    edges = np.sort(mesh.faces[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2), axis=1)
    unique, counts = np.unique(edges, axis=0, return_counts=True)
    neighbours: dict[int, list[int]] = {}
    for a, b in unique[counts == 1]:
        neighbours.setdefault(int(a), []).append(int(b))
        neighbours.setdefault(int(b), []).append(int(a))
    loops, seen = [], set()
    for start in sorted(neighbours):
        if start in seen:
            continue
        loop, current = [start], start
        seen.add(start)
        while True:
            ahead = [n for n in neighbours[current] if n not in seen]
            if not ahead:
                break
            current = ahead[0]
            seen.add(current)
            loop.append(current)
        loops.append(loop)
    return mesh.vertices[max(loops, key=len)]


def _rectangle(center, size, **style) -> Rectangle:
    return Rectangle((center[0] - size[0] / 2, center[1] - size[1] / 2), size[0], size[1], **style)


def _draw_layout(axes, scene: Scene) -> None:
    length, width, _ = scene.room
    axes.add_patch(_rectangle((0, 0), (length, width), fill=False, lw=2, ec="0.3"))
    for row in scene.rows:
        table = row.table
        axes.add_patch(_rectangle(table.center, table.size, fc="0.85", ec="0.5"))
        axes.annotate(f"row {row.id}", (table.center[0], table.center[1] + table.size[1] / 2 + 0.08), ha="center", fontsize=8)
    station = scene.workstation
    axes.add_patch(_rectangle(station.center, station.size, fc="#8090b0", ec="0.3"))
    axes.annotate("workstation", (station.center[0], station.center[1] - station.size[1] / 2 - 0.2), ha="center", fontsize=8)


def _draw_environment(axes, scene: Scene) -> float:
    """The film greenhouse round the room: its walls, the neighbouring rows' benches and plants; returns how far it
    reaches beyond the room (0 without one)."""
    environment = scene.environment
    if environment is None:
        return 0.0
    length, width, _ = scene.room
    extent = environment.extent
    axes.add_patch(_rectangle((0, 0), (length + 2 * extent, width + 2 * extent), fill=False, lw=1, ls="--", ec="0.5"))
    for table in environment.tables:
        axes.add_patch(_rectangle(table.center, table.size, fc="0.93", ec="0.75", lw=0.5))
    points = [copy.position[:2] for copy in environment.plants]
    if points:
        axes.scatter(*zip(*points), s=6, c="#6a9a5a", lw=0)
    axes.annotate("film greenhouse (not scanned)", (0, width / 2 + extent - 0.3), ha="center", fontsize=8, color="0.4")
    return extent


def _draw_plants(axes, scene: Scene, plants: list[Plant], detailed: bool) -> None:
    """Each plant's box, pot, fruit and (`detailed`) leaf blades; without detail, the leaves of a plant grown in its
    place as strokes, and none of a copy of a prototype (a compartment's thousand copies would take minutes)."""
    # Boxes, pots and fruit go in as collections: a patch added alone updates the axes' limits from its curves, which
    # for a compartment's ten thousand fruit takes a minute.
    boxes, pots, fruit, strokes, stroke_colors = [], [], [], [], []
    for plant in plants:
        low, high = plant.bounds.min, plant.bounds.max
        boxes.append(Rectangle(low[:2], high[0] - low[0], high[1] - low[1], fill=False, ls=":", ec="#2a7a2a", lw=0.8))
        pots.append(Circle(plant.position[:2], plant.pot.radius_top, fc="0.2", alpha=0.5))
        if detailed:  # leaf blades seen from above, lowest first: a blade of its own by its triangles, a copy of a template by its outline
            body = scene.body(plant)
            moved = placement(plant, body) if plant.is_copy else np.eye(4)
            parts = plant_meshes(body, [])
            order = sorted(range(len(parts.leaves)), key=lambda i: parts.leaves[i].vertices[:, 2].mean())
            polygons, colors = [], []
            for i in order:
                leaf, mesh = body.leaves[i], parts.leaves[i]
                if leaf.template is None:
                    polygons += list((mesh.vertices @ moved[:3, :3].T + moved[:3, 3])[mesh.faces][:, :, :2])
                    colors += [leaf.rgb] * len(mesh.faces)
                else:
                    transform = moved @ leaf_transform(leaf)
                    polygons.append((_outline(leaf.template) @ transform[:3, :3].T + transform[:3, 3])[:, :2])
                    colors.append(leaf.rgb)
            axes.add_collection(PolyCollection(polygons, facecolors=colors, lw=0, alpha=0.9))
            axes.annotate(f"plant {plant.id}", (plant.position[0], high[1] - 0.03), ha="center", fontsize=8)
        else:
            for leaf in plant.leaves:
                strokes.append([leaf.base[:2], [leaf.base[i] + leaf.direction[i] * leaf.length for i in range(2)]])
                stroke_colors.append(leaf.rgb)
        for pepper in scene.peppers_of(plant.id):
            fruit.append(Circle(pepper.center[:2], pepper.radius, fc=PEPPER_FACE[pepper.color],
                                ec="k" if pepper.ripe else "#1a4a10", lw=0.6))
            if detailed:
                axes.annotate(str(pepper.id), pepper.center[:2], ha="center", va="center", fontsize=6, color="w", zorder=4)
    if strokes:  # one collection, not a line each: a row's hundreds of leaves as lines took most of the figure's second
        axes.add_collection(LineCollection(strokes, colors=stroke_colors, lw=1.2, alpha=0.8, zorder=2))
    for patches, zorder in ((boxes, 1), (pots, 1), (fruit, 3)):
        if patches:
            axes.add_collection(PatchCollection(patches, match_original=True, zorder=zorder))


def draw_top_view(scene: Scene, path: Path) -> None:
    """Whole greenhouse on the left, the row with most fruit enlarged on the right."""
    length, width, _ = scene.room
    figure, (overview, zoom) = plt.subplots(1, 2, figsize=(15, 8), dpi=100, gridspec_kw={"width_ratios": [2.2, 1]})
    margin = 0.2 + _draw_environment(overview, scene)
    _draw_layout(overview, scene)
    _draw_plants(overview, scene, scene.plants, detailed=False)
    counts = {color: sum(p.color == color for p in scene.peppers) for color in PEPPER_FACE}
    legend = ", ".join(f"{n} {color}" for color, n in counts.items() if n)
    overview.set_title(f"seed {scene.seed}: {len(scene.plants)} plants, "
                       f"{sum(p.bearing for p in scene.plants)} bearing, {len(scene.peppers)} peppers ({legend})")
    overview.set_xlim(-length / 2 - margin, length / 2 + margin)
    overview.set_ylim(-width / 2 - margin, width / 2 + margin)

    row = max(scene.rows, key=lambda r: sum(len(scene.peppers_of(plant_id)) for plant_id in r.plants))
    table = row.table
    zoom.add_patch(_rectangle(table.center, table.size, fc="0.85", ec="0.5"))
    shown = [scene.plant(plant_id) for plant_id in row.plants[:ZOOM_PLANTS]]
    _draw_plants(zoom, scene, shown, detailed=True)
    zoom.set_xlim(table.center[0] - 0.45, table.center[0] + 0.45)
    if len(shown) < len(row.plants):  # a long row: its first plants, from the table's end
        start = table.center[1] - table.size[1] / 2
        zoom.set_ylim(start - 0.05, max(p.bounds.max[1] for p in shown) + 0.05)
    else:
        zoom.set_ylim(table.center[1] - table.size[1] / 2 - 0.05, table.center[1] + table.size[1] / 2 + 0.05)
    zoom.set_title(f"row {row.id} (pepper ids; left side is -x)")
    for axes in (overview, zoom):
        axes.set_aspect("equal")
        axes.set_xlabel("x (m, east)")
        axes.set_ylabel("y (m, north)")
        axes.grid(alpha=0.3)
    figure.tight_layout()
    with atomic_path(Path(path)) as tmp:
        figure.savefig(tmp, format="png")
    plt.close(figure)
