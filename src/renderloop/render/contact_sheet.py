"""A contact sheet of rendered frames: RGB, depth colour-mapped and instance masks, side by side."""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from renderloop.io.atomic import atomic_path  # noqa: E402
from renderloop.render.frames import read_frame  # noqa: E402

ROWS = 6


def mask_colours(mask: np.ndarray) -> np.ndarray:
    """A fixed colour per instance id (hashed), black background."""
    ids = mask.astype(np.uint32)
    hashed = (ids * np.uint32(2654435761)) >> np.uint32(8)
    rgb = np.stack([(hashed >> shift) & 255 for shift in (0, 8, 16)], axis=-1).astype(np.uint8)
    rgb[ids == 0] = 0
    return rgb


def pick_frames(run_dir: Path, count: int, rows: int = ROWS) -> list[int]:
    """Frames spread over the run, preferring ones that show peppers."""
    candidates = np.linspace(0, count - 1, min(count, rows * 4)).astype(int)
    shown = [(int(np.count_nonzero(read_frame(run_dir, int(i)).mask)), int(i)) for i in np.unique(candidates)]
    best = sorted(sorted(shown, reverse=True)[:rows], key=lambda item: item[1])
    return [index for _, index in best]


def draw_contact_sheet(run_dir: Path, count: int, path: Path) -> None:
    frames = pick_frames(run_dir, count)
    figure, axes = plt.subplots(len(frames), 3, figsize=(12, 3.1 * len(frames)), dpi=80, squeeze=False)
    for row, index in zip(axes, frames):
        frame = read_frame(run_dir, index)
        depth = np.ma.masked_equal(frame.depth, 0.0)
        row[0].imshow(frame.rgb)
        far = float(np.percentile(depth.compressed(), 90)) if depth.count() else 1.0  # the plant, not the far wall
        shown = row[1].imshow(depth, cmap="turbo", vmin=0.2, vmax=max(far, 0.5))
        figure.colorbar(shown, ax=row[1], fraction=0.035, label="depth (m)")
        row[2].imshow(mask_colours(frame.mask))
        ids = np.unique(frame.mask[frame.mask > 0])
        row[0].set_title(f"frame {index}", fontsize=9)
        row[2].set_title(f"peppers: {', '.join(map(str, ids[:8]))}{'…' if len(ids) > 8 else ''}", fontsize=9)
        for axis in row:
            axis.set_axis_off()
    figure.tight_layout()
    with atomic_path(Path(path)) as tmp:
        figure.savefig(tmp, format="png")
    plt.close(figure)
