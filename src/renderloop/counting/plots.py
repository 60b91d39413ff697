"""One clustering figure per row, like the reference work's counting figure: what OPTICS saw and found.

Top view (x across the row, up) and side view (z, up) stacked on the one y axis, which
the row runs along: detections coloured by their cluster (grey: left as noise), their
augmented copies faint, removed false positives as black crosses, counted peppers as
stars (ripe) or diamonds (unripe), the true fruit centres of scene.json as open circles,
and the plant volumes. Drawn 1280 px wide with 13 pt text, to stay readable where
report.html scales it to its content width.
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

VIEWS = (("top view", (1, 0), "y (m)", "x (m)"), ("side view", (1, 2), "y (m)", "z (m)"))
WIDTH_IN, DPI = 12.8, 100  # 1280 px
STYLE = {"font.size": 13, "axes.titlesize": 14, "axes.labelsize": 13, "xtick.labelsize": 12, "ytick.labelsize": 12,
         "legend.fontsize": 12, "figure.titlesize": 15}
CENTER_MARKER = {"ripe": "*", "unripe": "D"}
TRUTH_COLOR = {"ripe": "red", "unripe": "green"}


def _cluster_colors(labels: np.ndarray) -> np.ndarray:
    palette = plt.get_cmap("tab20")(np.arange(20))
    colors = np.tile(np.array([0.6, 0.6, 0.6, 1.0]), (len(labels), 1))
    clustered = labels >= 0
    colors[clustered] = palette[labels[clustered] % 20]
    return colors


def draw_row(scene: Scene, counts: list[RowCount], truth: dict[int, dict[str, int]], path: Path) -> None:
    """`counts` holds the row's RowCount of each class; `truth[plant id][class]` the true fruit numbers."""
    with plt.rc_context(STYLE):
        _draw_row(scene, counts, truth, path)


def _draw_row(scene: Scene, counts: list[RowCount], truth: dict[int, dict[str, int]], path: Path) -> None:
    row = next(r for r in scene.rows if r.id == counts[0].row)
    plants = [scene.plant(plant_id) for plant_id in row.plants]
    low = np.min([plant.bounds.min for plant in plants], axis=0)
    high = np.max([plant.bounds.max for plant in plants], axis=0)
    pad = 0.05
    # panel heights in proportion to what they show (x across the row, z up), at one scale with the shared y
    heights = [high[dims[1]] - low[dims[1]] + 2 * pad for _, dims, _, _ in VIEWS]
    along = high[1] - low[1] + 2 * pad
    plot_width = WIDTH_IN * 0.62  # inches of the panels, the legend to their right
    figure, axes = plt.subplots(2, 1, figsize=(WIDTH_IN, 2.3 + plot_width * sum(heights) / along), dpi=DPI, sharex=True,
                                gridspec_kw={"height_ratios": heights})
    for view, (title, dims, xlabel, ylabel) in zip(axes, VIEWS):
        for plant in plants:
            corner, far = np.array(plant.bounds.min)[list(dims)], np.array(plant.bounds.max)[list(dims)]
            view.add_patch(Rectangle(corner, *(far - corner), fill=False, ec="#2a7a2a", lw=1.0))
            view.annotate(f"plant {plant.id}", (corner[0], far[1]), xytext=(3, -3), textcoords="offset points",
                          fontsize=11, color="#2a7a2a", va="top")
        for count in counts:
            found = count.clusters
            colors = _cluster_colors(found.labels)
            copies = ~found.original
            if copies.any():
                view.scatter(*found.points[copies][:, dims].T, s=4, c=colors[copies], alpha=0.15, lw=0)
            view.scatter(*found.points[found.original][:, dims].T, s=14, c=colors[found.original], lw=0,
                         label=f"{count.label} detections ({found.n_init}, MinPts {found.min_samples})")
            if len(count.removed):
                view.scatter(*count.removed[:, dims].T, s=24, c="k", marker="x", lw=0.9,
                             label=f"{count.label} removed ({len(count.removed)})")
            if len(found.centers):
                view.scatter(*found.centers[:, dims].T, s=110, marker=CENTER_MARKER[count.label],
                             c=TRUTH_COLOR[count.label], edgecolors="k", lw=0.6, alpha=0.75, zorder=3,
                             label=f"{count.label} counted ({len(found.centers)})")
            true_centers = np.array([p.center for p in scene.peppers if scene.plant(p.plant).row == row.id
                                     and (p.ripe == (count.label == "ripe"))], dtype=float).reshape(-1, 3)
            if len(true_centers):
                view.scatter(*true_centers[:, dims].T, s=190, facecolors="none", edgecolors=TRUTH_COLOR[count.label],
                             lw=1.4, zorder=4, label=f"{count.label} true ({len(true_centers)})")
        view.set_xlim(low[dims[0]] - pad, high[dims[0]] + pad)
        view.set_ylim(low[dims[1]] - pad, high[dims[1]] + pad)
        view.set_aspect("equal")
        view.set_title(title, loc="left")
        view.set_ylabel(ylabel)
        view.grid(alpha=0.3)
    axes[1].set_xlabel(VIEWS[1][2])
    axes[0].legend(loc="upper left", bbox_to_anchor=(1.02, 1.0), frameon=False, markerscale=0.8)
    ripe_true = sum(truth.get(plant.id, {}).get("ripe", 0) for plant in plants)
    ripe_found = sum(len(c.clusters.centers) for c in counts if c.label == "ripe")
    figure.suptitle(f"row {row.id}: {ripe_found} ripe fruit counted, {ripe_true} true (OPTICS per row and class)")
    figure.subplots_adjust(left=0.07, right=0.07 + 0.62, top=1 - 0.9 / figure.get_figheight(),
                           bottom=0.75 / figure.get_figheight(), hspace=0.35)
    with atomic_path(Path(path)) as tmp:
        figure.savefig(tmp, format="png")
    plt.close(figure)
