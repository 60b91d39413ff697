"""The README's picture: a frame of a run with the detector's boxes, beside the report's 3D view of the greenhouse.

    python scripts/readme_picture.py RUN_DIR --out docs/images/readme_demo.jpg [--plant ID] [--height 480]

Left: the frame that shows a plant best (the report's plant cards choose it the same way; by default the plant
with the most detections), drawn with every detection and the plant's true fruit. Right: the report's 3D view
(tables, plants, flown path, camera frusta, detections' 3D points, counted and true fruit) as Debian's chromium
draws it, captured with Playwright. Both at the same height, side by side, one JPEG.
"""

from __future__ import annotations

import argparse
import tempfile
from pathlib import Path

from PIL import Image

from renderloop.render.camera import Intrinsics, read_camera_info
from renderloop.report.plants import best_views, drawn_view
from renderloop.report.view3d import greenhouse_figure, greenhouse_html
from renderloop.rundir import files
from renderloop.scene.model import read_scene

CHROMIUM = "/usr/bin/chromium"
VIEW_WIDTH = 1.25  # the 3D view's width, in heights
ZOOM = 0.55  # the report's camera moved this much of the way towards the plants: the picture has no legend to read


def frame_picture(run_dir: Path, plant: int | None, height: int) -> Image.Image:
    _, poses = files.read_poses(run_dir)
    views = best_views(run_dir, read_scene(run_dir), files.read_detections(run_dir, len(poses)))
    view = views[plant] if plant is not None else max(views.values(), key=lambda v: v.rank)
    intrinsics: Intrinsics = read_camera_info(run_dir)
    return drawn_view(run_dir, view, width=round(height * intrinsics.width / intrinsics.height))


def view_picture(run_dir: Path, height: int) -> Image.Image:
    from playwright.sync_api import sync_playwright

    scene = read_scene(run_dir)
    times, poses = files.read_poses(run_dir)
    figure = greenhouse_figure(scene, files.read_counts(run_dir), files.read_detections(run_dir, len(poses)),
                               files.read_flight(run_dir), times, poses, read_camera_info(run_dir))
    width = round(VIEW_WIDTH * height)
    camera = figure.layout.scene.camera
    centre = [getattr(camera.center, axis) for axis in "xyz"]
    eye = {axis: c + ZOOM * (getattr(camera.eye, axis) - c) for axis, c in zip("xyz", centre)}
    figure.update_layout(width=width, height=height, margin=dict(l=0, r=0, t=0, b=0), showlegend=False,
                         scene_camera_eye=eye)
    with tempfile.TemporaryDirectory() as tmp:
        page_file, shot = Path(tmp) / "view.html", Path(tmp) / "view.png"
        page_file.write_text(f"<!DOCTYPE html><html><body style='margin:0'>{greenhouse_html(figure)}</body></html>")
        with sync_playwright() as playwright:
            browser = playwright.chromium.launch(executable_path=CHROMIUM, args=["--no-sandbox"])
            page = browser.new_page(viewport={"width": width, "height": height})
            page.goto(page_file.as_uri())
            page.wait_for_selector("canvas")
            page.wait_for_timeout(1500)  # WebGL draws on the next frames
            page.screenshot(path=str(shot))
            browser.close()
        return Image.open(shot).convert("RGB")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("run_dir", type=Path)
    parser.add_argument("--out", type=Path, required=True)
    parser.add_argument("--plant", type=int, help="the plant whose best frame is drawn (default: the best shown)")
    parser.add_argument("--height", type=int, default=480, help="px")
    args = parser.parse_args()
    left, right = frame_picture(args.run_dir, args.plant, args.height), view_picture(args.run_dir, args.height)
    picture = Image.new("RGB", (left.width + 8 + right.width, args.height), "white")
    picture.paste(left, (0, 0))
    picture.paste(right, (left.width + 8, 0))
    picture.save(args.out, quality=88, optimize=True)
    print(f"wrote {args.out} ({picture.width}x{picture.height})")


if __name__ == "__main__":
    main()
