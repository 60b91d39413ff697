"""One clustering figure per row, like the reference work's counting figure: what OPTICS saw and found.

Top view (x-y) and side view (y-z, the row runs along y): detections coloured by
their cluster (grey: left as noise), their augmented copies faint, removed false
positives as black crosses, counted peppers as stars (ripe) or diamonds (unripe),
the true fruit centres of scene.json as open circles, and the plant volumes.
"""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
from matplotlib.patches import Rectangle

from renderloop.counting.cluster import RowCount
from renderloop.io.atomic import atomic_path
from renderloop.scene.model import Scene

VIEWS = (("top view", (0, 1), "x (m)", "y (m)"), ("side view", (1, 2), "y (m)", "z (m)"))
CENTER_MARKER = {"ripe": "*", "unripe": "D"}
TRUTH_COLOR = {"ripe": "red", "unripe": "green"}


def _save(figure, path: Path) -> None:
    figure.tight_layout()
    with atomic_path(Path(path)) as tmp:
        figure.savefig(tmp, format="png")
    plt.close(figure)


def _cluster_colors(labels: np.ndarray) -> np.ndarray:
    palette = plt.get_cmap("tab20")(np.arange(20))
    colors = np.tile(np.array([0.6, 0.6, 0.6, 1.0]), (len(labels), 1))
    clustered = labels >= 0
    colors[clustered] = palette[labels[clustered] % 20]
    return colors


def draw_row(scene: Scene, counts: list[RowCount], truth: dict[int, dict[str, int]], path: Path) -> None:
    """`counts` holds the row's RowCount of each class; `truth[plant id][class]` the true fruit numbers."""
    row = next(r for r in scene.rows if r.id == counts[0].row)
    plants = [scene.plant(plant_id) for plant_id in row.plants]
    figure, axes = plt.subplots(1, 2, figsize=(15, 6.5), dpi=90)
    for view, (title, dims, xlabel, ylabel) in zip(axes, VIEWS):
        for plant in plants:
            low, high = np.array(plant.bounds.min)[list(dims)], np.array(plant.bounds.max)[list(dims)]
            view.add_patch(Rectangle(low, *(high - low), fill=False, ec="#2a7a2a", lw=0.8))
            view.annotate(f"plant {plant.id}", (low[0], high[1]), fontsize=8, color="#2a7a2a", va="bottom")
        for count in counts:
            found = count.clusters
            colors = _cluster_colors(found.labels)
            copies = ~found.original
            if copies.any():
                view.scatter(*found.points[copies][:, dims].T, s=3, c=colors[copies], alpha=0.15, lw=0)
            view.scatter(*found.points[found.original][:, dims].T, s=9, c=colors[found.original], lw=0,
                         label=f"{count.label} detections ({found.n_init}, MinPts {found.min_samples})")
            if len(count.removed):
                view.scatter(*count.removed[:, dims].T, s=14, c="k", marker="x", lw=0.7,
                             label=f"{count.label} removed ({len(count.removed)})")
            if len(found.centers):
                view.scatter(*found.centers[:, dims].T, s=80, marker=CENTER_MARKER[count.label],
                             c=TRUTH_COLOR[count.label], edgecolors="k", lw=0.6, alpha=0.75, zorder=3,
                             label=f"{count.label} counted ({len(found.centers)})")
            true_centers = np.array([p.center for p in scene.peppers if scene.plant(p.plant).row == row.id
                                     and (p.ripe == (count.label == "ripe"))], dtype=float).reshape(-1, 3)
            if len(true_centers):
                view.scatter(*true_centers[:, dims].T, s=150, facecolors="none", edgecolors=TRUTH_COLOR[count.label],
                             lw=1.2, zorder=4, label=f"{count.label} true ({len(true_centers)})")
        view.set_aspect("equal")
        view.set_title(title)
        view.set_xlabel(xlabel)
        view.set_ylabel(ylabel)
        view.grid(alpha=0.3)
        view.autoscale_view()
    axes[1].legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=8)
    ripe_true = sum(truth.get(plant.id, {}).get("ripe", 0) for plant in plants)
    ripe_found = sum(len(c.clusters.centers) for c in counts if c.label == "ripe")
    figure.suptitle(f"row {row.id}: {ripe_found} ripe fruit counted, {ripe_true} true (OPTICS per row and class)")
    _save(figure, path)
