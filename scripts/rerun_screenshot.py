"""Screenshot of the Rerun viewer on a recording, headless: the README's picture of `renderloop export --rerun`.

    python scripts/rerun_screenshot.py runs/demo.rrd --time 13 --out docs/rerun_demo.png

Needs a virtual X display and a software Vulkan driver (Debian: xvfb mesa-vulkan-drivers).
The 3D view shows the greenhouse, plan, flight and counts; the camera and depth views show
the frame at --time through a blueprint, because the viewer's time cursor cannot be set
from outside.
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

# rerun 0.23.1 builds time ranges with np.asarray(..., copy=...), a numpy 2 argument; bpy pins numpy 1.
_asarray = np.asarray
np.asarray = lambda a, dtype=None, order=None, copy=None, **kw: _asarray(a, dtype=dtype, order=order, **kw)

import rerun.blueprint as rrb


def blueprint(seconds: float) -> rrb.Blueprint:
    instant = [rrb.VisibleTimeRange("sim_time", start=rrb.TimeRangeBoundary.absolute(seconds=seconds),
                                    end=rrb.TimeRangeBoundary.absolute(seconds=seconds))]
    scene = ["world/greenhouse/**", "world/plan/**", "world/flight/**", "world/counts/**"]
    return rrb.Blueprint(
        rrb.Horizontal(
            rrb.Spatial3DView(origin="world", name="greenhouse, plan (blue), flight (orange), counted fruit", contents=scene),
            rrb.Vertical(
                rrb.Spatial2DView(origin="world/camera/image", name=f"camera at {seconds:g} s, detections",
                                  contents=["world/camera/image/rgb", "world/camera/image/detections"], time_ranges=instant),
                rrb.Spatial2DView(origin="world/camera/image", name="depth (sensor)", contents=["world/camera/image/depth"],
                                  time_ranges=instant),
            ),
            column_shares=[3, 2],
        ),
        rrb.BlueprintPanel(state="collapsed"), rrb.SelectionPanel(state="collapsed"), rrb.TimePanel(state="collapsed"),
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("recording", type=Path)
    parser.add_argument("--time", type=float, required=True, help="sim_time of the frame to show, seconds")
    parser.add_argument("--out", type=Path, required=True)
    parser.add_argument("--size", default="1600x900")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as folder:
        layout = Path(folder) / "layout.rbl"
        blueprint(args.time).save("renderloop", str(layout))
        viewer = Path(sys.executable).with_name("rerun")
        subprocess.run(["xvfb-run", "-a", "-s", f"-screen 0 {args.size}x24", str(viewer), str(args.recording), str(layout),
                        "--window-size", args.size, "--screenshot-to", str(args.out)],
                       check=False, capture_output=True, timeout=300)  # the viewer exits non-zero after its screenshot
    if not args.out.is_file():
        sys.exit(f"rerun_screenshot: the viewer wrote no {args.out}")
    print(f"rerun_screenshot: wrote {args.out}")


if __name__ == "__main__":
    main()
