"""The greenhouse in 3D for the report: one Plotly figure, its JavaScript inlined, no network.

Tables and the workstation as boxes, plants as their stems, branches and leaves (a
line per leaf) inside their bounding volumes, the flown path (flight.csv, thinned),
the camera at a few frames as a short pyramid (groundtruth.txt poses, camera_info
intrinsics), the detections' 3D points, the counted fruit (counts.json clusters), the ripe
fruit seen once (its seen_once, which counting.lone_credit credits) and the true fruit
(scene.json). Coordinates are rounded to the millimetre and long paths thinned, so the
figure's data stays small beside plotly.js itself. Every trace can be switched off in the
legend, which stands left of the scene, clear of plotly's toolbar; the view opens on the
plants, and the greenhouse around them is a scroll away.

plotly.js is the gl3d bundle in vendor/ (the trace types drawn here and no others, a third
of the full bundle), inlined gzip-compressed as base64 and unpacked by the browser's own
DecompressionStream before the figure is drawn: a page a quarter of the size it is with the
full bundle inlined as it is.
"""

from __future__ import annotations

import base64
import functools
import gzip
import json
from pathlib import Path

import numpy as np
import plotly.graph_objects as go
import plotly.io as pio

from renderloop.render.camera import Intrinsics
from renderloop.rundir.models import Counts, Detections
from renderloop.scene.model import Scene

DIV_ID = "greenhouse-3d"  # fixed, so the same run gives the same page
BUNDLE = Path(__file__).parent / "vendor" / "plotly-gl3d.min.js"
CONFIG = {"displaylogo": False, "responsive": True, "modeBarButtonsToRemove": ["toImage"]}
HEIGHT = 660  # px of the view
LEGEND_SHARE = 0.2  # of the view's width, left of the scene, for the legend
EYE_DIRECTION = np.array([-1.0, -0.6, 0.5])  # where the camera looks from: the front left, above
EYE_REACH = 2.3  # the camera's distance from the plants, in half diagonals of their box
PATH_POINTS = 1500  # flown path, thinned to at most this many points
FRUSTA = 8  # camera pyramids drawn along the scan
FRUSTUM_DEPTH = 0.12  # m, how far each pyramid reaches
RIPE, UNRIPE = "#d62728", "#2ca02c"
DETECTED = {"ripe": "#ff7f0e", "unripe": "#17becf"}
BOX_EDGES = ((0, 1), (1, 3), (3, 2), (2, 0), (4, 5), (5, 7), (7, 6), (6, 4), (0, 4), (1, 5), (2, 6), (3, 7))
# the 12 triangles of a box whose corners are numbered by bits (x: 1, y: 2, z: 4)
BOX_FACES = ((0, 1, 3), (0, 3, 2), (4, 5, 7), (4, 7, 6), (0, 1, 5), (0, 5, 4), (2, 3, 7), (2, 7, 6),
             (0, 2, 6), (0, 6, 4), (1, 3, 7), (1, 7, 5))


def _round(values) -> list:
    return [None if v is None else round(float(v), 3) for v in values]


def _corners(low, high) -> np.ndarray:
    low, high = np.asarray(low, float), np.asarray(high, float)
    return np.array([[(high if i & 1 else low)[0], (high if i & 2 else low)[1], (high if i & 4 else low)[2]] for i in range(8)])


def _segments(segments: list[np.ndarray]) -> dict[str, list]:
    """Polylines as one line trace's x, y, z, separated by gaps."""
    xyz: list[list] = [[], [], []]
    for points in segments:
        for axis in range(3):
            xyz[axis].extend([*points[:, axis], None])
    return dict(zip("xyz", (_round(values) for values in xyz)))


def _boxes(centres_sizes: list[tuple], name: str, color: str, hover: list[str], opacity: float = 0.55) -> go.Mesh3d:
    x, y, z, i, j, k, text = [], [], [], [], [], [], []
    for (centre, size), label in zip(centres_sizes, hover):
        corners = _corners(np.subtract(centre, np.divide(size, 2)), np.add(centre, np.divide(size, 2)))
        base = len(x)
        x += _round(corners[:, 0]); y += _round(corners[:, 1]); z += _round(corners[:, 2])  # noqa: E702
        text += [label] * 8
        for a, b, c in BOX_FACES:
            i.append(base + a); j.append(base + b); k.append(base + c)  # noqa: E702
    return go.Mesh3d(x=x, y=y, z=z, i=i, j=j, k=k, color=color, opacity=opacity, name=name, showlegend=True,
                     flatshading=True, text=text, hovertemplate="%{text}<extra></extra>")


def _frustum(pose: np.ndarray, intrinsics: Intrinsics) -> list[np.ndarray]:
    """A short pyramid from the camera centre to its image corners at FRUSTUM_DEPTH, in the world."""
    w, h = intrinsics.width - 0.5, intrinsics.height - 0.5
    pixels = np.array([[-0.5, -0.5], [w, -0.5], [w, h], [-0.5, h]])
    corners = intrinsics.back_project(pixels, np.full(4, FRUSTUM_DEPTH))
    world = corners @ pose[:3, :3].T + pose[:3, 3]
    apex = pose[:3, 3]
    top = world[[0, 1]] + 0.25 * (world[[0, 1]].mean(axis=0) - world[[3, 2]].mean(axis=0))  # a tick on the image's top edge
    return [np.vstack([world, world[:1]]), *(np.vstack([apex, corner]) for corner in world),
            np.vstack([world[0], top.mean(axis=0), world[1]])]


def greenhouse_figure(scene: Scene, counts: Counts, detections: Detections, flight: dict[str, np.ndarray],
                      times: np.ndarray, poses: np.ndarray, intrinsics: Intrinsics,
                      views: dict[int, str] | None = None) -> go.Figure:
    """`views`: frames an adaptive mission added (frame index -> why), drawn as frusta of their own."""
    traces: list = []
    traces.append(_boxes([(row.table.center, row.table.size) for row in scene.rows], "tables", "#b08d57",
                         [f"table of row {row.id}" for row in scene.rows]))
    traces.append(_boxes([(scene.workstation.center, scene.workstation.size)], "workstation", "#7f8fa6", ["workstation"]))
    traces.append(go.Scatter3d(
        **_segments([_corners(p.bounds.min, p.bounds.max)[list(edge)] for p in scene.plants for edge in BOX_EDGES]),
        mode="lines", line=dict(color="#9acd32", width=1.5, dash="dash"), name="plant volumes", hoverinfo="skip", visible="legendonly"))
    stems = [np.asarray(tube.points) for p in scene.plants for tube in (p.stem, *p.branches) if tube is not None]  # a copy's are its prototype's
    leaves = [np.array([leaf.base, np.add(leaf.base, np.multiply(leaf.direction, leaf.length))]) for p in scene.plants for leaf in p.leaves]
    traces.append(go.Scatter3d(**_segments(stems), mode="lines", line=dict(color="#3b6e22", width=5), name="plants: stems",
                               hoverinfo="skip"))
    traces.append(go.Scatter3d(**_segments(leaves), mode="lines", line=dict(color="#7fbf5f", width=3), name="plants: leaves",
                               hoverinfo="skip"))
    traces.append(go.Scatter3d(
        x=_round([(p.bounds.min[0] + p.bounds.max[0]) / 2 for p in scene.plants]),
        y=_round([(p.bounds.min[1] + p.bounds.max[1]) / 2 for p in scene.plants]),
        z=_round([p.bounds.max[2] + 0.05 for p in scene.plants]),
        mode="text", text=[f"plant {p.id}" for p in scene.plants], textfont=dict(size=11, color="#333"),
        name="plant numbers", hoverinfo="skip"))

    step = max(1, int(np.ceil(len(flight["t"]) / PATH_POINTS)))
    keep = np.unique(np.r_[np.arange(0, len(flight["t"]), step), len(flight["t"]) - 1]) if len(flight["t"]) else np.arange(0)
    traces.append(go.Scatter3d(
        x=_round(flight["x"][keep]), y=_round(flight["y"][keep]), z=_round(flight["z"][keep]),
        customdata=_round(flight["t"][keep]), mode="lines", line=dict(color="#1f3b73", width=3), name="flown path (body)",
        hovertemplate="flown path, t = %{customdata:.1f} s<extra></extra>"))
    traces.append(go.Scatter3d(
        x=_round(poses[:, 0, 3]), y=_round(poses[:, 1, 3]), z=_round(poses[:, 2, 3]), customdata=_round(times),
        text=[f"frame {i}" for i in range(len(poses))], mode="markers", marker=dict(size=1.8, color="#777777", opacity=0.7),
        name="camera at each frame", hovertemplate="%{text}, t = %{customdata:.1f} s<extra></extra>"))
    shown = np.unique(np.linspace(0, len(poses) - 1, min(FRUSTA, len(poses))).round().astype(int)) if len(poses) else []
    traces.append(go.Scatter3d(**_segments([segment for i in shown for segment in _frustum(poses[i], intrinsics)]),
                               mode="lines", line=dict(color="#6a3d9a", width=2), name=f"camera view ({len(shown)} frames)",
                               hoverinfo="skip"))

    if views:
        added = sorted(views)
        traces.append(go.Scatter3d(**_segments([segment for i in added for segment in _frustum(poses[i], intrinsics)]),
                                   mode="lines", line=dict(color="#e67e22", width=3),
                                   name=f"views the mission added ({len(added)})", hoverinfo="skip"))
        traces.append(go.Scatter3d(
            x=_round(poses[added, 0, 3]), y=_round(poses[added, 1, 3]), z=_round(poses[added, 2, 3]),
            text=[f"frame {i}: {views[i]}" for i in added], mode="markers", marker=dict(size=4, color="#e67e22"),
            name="added view positions", hovertemplate="%{text}<extra></extra>", showlegend=False))

    for label in ("ripe", "unripe"):
        points = [(frame.index, d) for frame in detections.frames for d in frame.detections
                  if d.label == label and d.position is not None]
        if not points:
            continue
        xyz = np.array([d.position for _, d in points])
        traces.append(go.Scatter3d(
            x=_round(xyz[:, 0]), y=_round(xyz[:, 1]), z=_round(xyz[:, 2]),
            text=[f"{label} detection, frame {index}, score {d.score:.2f}" for index, d in points],
            mode="markers", marker=dict(size=2.5, color=DETECTED[label], opacity=0.8),
            name=f"detected {label} (3D points)", hovertemplate="%{text}<extra></extra>"))
    for label, key, color in (("ripe", "clusters", RIPE), ("unripe", "unripe_clusters", UNRIPE)):
        found = [(plant.id, point) for plant in counts.plants for point in getattr(plant, key)]
        if not found:
            continue
        xyz = np.array([point for _, point in found])
        traces.append(go.Scatter3d(
            x=_round(xyz[:, 0]), y=_round(xyz[:, 1]), z=_round(xyz[:, 2]),
            text=[f"counted {label} fruit of plant {plant}" for plant, _ in found],
            mode="markers", marker=dict(size=7, color=color, symbol="diamond-open", line=dict(width=2, color=color)),
            name=f"counted {label} fruit", hovertemplate="%{text}<extra></extra>"))
    once = [(plant.id, point) for plant in counts.plants for point in plant.seen_once]
    if once:
        credit = counts.settings.get("lone_credit", 0.0)
        xyz = np.array([point for _, point in once])
        traces.append(go.Scatter3d(
            x=_round(xyz[:, 0]), y=_round(xyz[:, 1]), z=_round(xyz[:, 2]),
            text=[f"ripe fruit of plant {plant} seen once (the estimate credits {credit:g} of a fruit each)"
                  for plant, _ in once],
            mode="markers", marker=dict(size=6, color=RIPE, symbol="circle-open", line=dict(width=1, color=RIPE)),
            name="ripe fruit seen once", hovertemplate="%{text}<extra></extra>"))
    for ripe, color in ((True, RIPE), (False, UNRIPE)):
        fruit = [p for p in scene.peppers if p.ripe == ripe]
        if not fruit:
            continue
        xyz = np.array([p.center for p in fruit])
        traces.append(go.Scatter3d(
            x=_round(xyz[:, 0]), y=_round(xyz[:, 1]), z=_round(xyz[:, 2]),
            text=[f"true {'ripe' if ripe else 'unripe'} fruit {p.id} of plant {p.plant}, {p.color}, "
                  f"{200 * p.radius:.0f} cm across" for p in fruit],
            mode="markers", marker=dict(size=[max(4.0, 120 * p.radius) for p in fruit], color=color, opacity=0.45),
            name=f"true {'ripe' if ripe else 'unripe'} fruit", hovertemplate="%{text}<extra></extra>"))

    figure = go.Figure(traces)
    plants = np.array([[p.bounds.min, p.bounds.max] for p in scene.plants], dtype=float).reshape(-1, 3)
    figure.update_layout(
        height=HEIGHT, margin=dict(l=0, r=0, t=0, b=0), paper_bgcolor="white",
        # Left of the scene, top-aligned: plotly's toolbar sits at the top right, over the scene.
        legend=dict(x=0, xanchor="left", y=1, yanchor="top", bgcolor="rgba(255,255,255,0.85)", bordercolor="#ccc",
                    borderwidth=1, font=dict(size=12), itemsizing="constant"),
        scene=_scene_layout(traces, (plants.min(axis=0), plants.max(axis=0)) if len(plants) else None),
    )
    return figure


def _scene_layout(traces: list, focus: tuple[np.ndarray, np.ndarray] | None) -> dict:
    """Axes to the extent of everything drawn, at true scale, right of the legend, and a camera looking at `focus`
    (the box around the plants) from the front left and above, near enough that the plants fill the view."""
    low, high = np.full(3, np.inf), np.full(3, -np.inf)
    for trace in traces:
        for index, axis in enumerate("xyz"):
            values = [v for v in (getattr(trace, axis) or ()) if v is not None]
            if values:
                low[index], high[index] = min(low[index], min(values)), max(high[index], max(values))
    if not np.all(np.isfinite(low)):  # nothing drawn
        low, high = np.zeros(3), np.ones(3)
    low[2] = min(low[2], 0.0)  # down to the floor
    pad = 0.03 * (high - low).max()
    low, high = low - pad, high + pad
    ratio = (high - low) / (high - low).max()

    def scaled(point: np.ndarray) -> np.ndarray:
        """A point of the world in the camera's coordinates: the axes' box is `ratio` long on each axis, centred on 0."""
        return (point - (low + high) / 2) / (high - low) * ratio

    if focus is None:
        centre, reach = np.zeros(3), 1.0
    else:
        centre = scaled((focus[0] + focus[1]) / 2)
        reach = float(np.linalg.norm(scaled(focus[1]) - scaled(focus[0])) / 2)  # the plants' half diagonal
    # plotly draws 45 degrees high: a sphere of radius r fits its height from 2.6 r away, the plants' long, low box
    # from nearer
    eye = centre + EYE_DIRECTION / np.linalg.norm(EYE_DIRECTION) * max(EYE_REACH * reach, 0.2)
    axis = dict(showbackground=True, backgroundcolor="#f4f6f8", gridcolor="#d0d4da")
    return dict(
        domain=dict(x=[LEGEND_SHARE, 1], y=[0, 1]),
        aspectmode="manual", aspectratio=dict(zip("xyz", _round(ratio))),
        xaxis=dict(axis, title="x, m", range=_round(low[[0]]) + _round(high[[0]])),
        yaxis=dict(axis, title="y, m", range=_round(low[[1]]) + _round(high[[1]])),
        zaxis=dict(axis, title="z, m", range=_round(low[[2]]) + _round(high[[2]])),
        camera=dict(center=dict(zip("xyz", _round(centre))), eye=dict(zip("xyz", _round(eye))), up=dict(x=0, y=0, z=1)),
    )


@functools.cache
def bundle_base64() -> str:
    """The gl3d bundle, gzip-compressed (level 9, no time stamp: the same bytes every time) and base64-encoded."""
    return base64.b64encode(gzip.compress(BUNDLE.read_bytes(), compresslevel=9, mtime=0)).decode("ascii")


# Unpacks plotly.js, runs it, then draws the figure; a browser without DecompressionStream gets a line saying so.
LOADER = """(async () => {
  const view = document.getElementById("%(div)s");
  try {
    if (!window.Plotly) {
      const packed = Uint8Array.from(atob(document.getElementById("%(div)s-plotly").textContent), c => c.charCodeAt(0));
      const unpacked = new Blob([packed]).stream().pipeThrough(new DecompressionStream("gzip"));
      const script = document.createElement("script");
      script.textContent = await new Response(unpacked).text();
      document.head.appendChild(script);
    }
    const figure = JSON.parse(document.getElementById("%(div)s-figure").textContent);
    await Plotly.newPlot(view, figure.data, figure.layout, %(config)s);
  } catch (error) {
    view.textContent = "The 3D view could not be drawn in this browser: " + error;
    console.error(error);
  }
})();"""


def greenhouse_html(figure: go.Figure) -> str:
    """The figure as a <div>, its data as JSON and plotly.js inlined compressed: the page needs no network."""
    data = pio.to_json(figure, validate=False, pretty=False, engine="json").replace("</", "<\\/")
    loader = LOADER % {"div": DIV_ID, "config": json.dumps(CONFIG, sort_keys=True)}
    return (f'<div id="{DIV_ID}" class="plotly-graph-div" style="height:{HEIGHT}px; width:100%;"></div>'
            f'<script type="application/json" id="{DIV_ID}-figure">{data}</script>'
            f'<script type="application/gzip;base64" id="{DIV_ID}-plotly">{bundle_base64()}</script>'
            f"<script>{loader}</script>")
