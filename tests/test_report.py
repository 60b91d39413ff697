"""report.html in a real browser, and the summary `renderloop run` ends with.

The page is opened from a file:// URL in Debian's chromium through Playwright (never a
browser Playwright downloads) with every request but the page itself refused, so a
page that reached for the network, threw a JavaScript error or drew no 3D view fails
here. Only a machine without chromium skips (scripts/setup.sh installs it).
"""

from __future__ import annotations

import base64
import io
import json
import math
import re
import shutil
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest
import yaml
from PIL import Image

from conftest import cli
from renderloop.render.camera import read_camera_info
from renderloop.render import contact_sheet
from renderloop.render.contact_sheet import DepthScale
from renderloop.render.frames import decode_depth, read_png
from renderloop.report.html import build_report, write_report
from renderloop.report.view3d import greenhouse_figure
from renderloop.report.words import recall_sentence, signed_pct
from renderloop.rundir import names
from renderloop.rundir import files
from renderloop.scene.model import read_scene

CHROMIUM = Path("/usr/bin/chromium")
LAUNCH_ARGS = ["--no-sandbox", "--disable-gpu", "--disable-background-networking", "--disable-component-update",
               "--no-first-run"]
FAST = {"renderer": {"backend": "raster"}, "camera": {"rate_hz": 0.25}}
PATH_COLOR = (0x1F, 0x3B, 0x73)  # the flown path in the 3D view (report/view3d.py)
MAX_BYTES = 2_000_000  # the demo run's report.html


def _near(image: Image.Image, color: tuple[int, int, int], tolerance: int = 12) -> int:
    pixels = np.asarray(image.convert("RGB"), dtype=int)
    return int((np.abs(pixels - np.array(color)).sum(axis=2) < tolerance).sum())


@pytest.fixture(scope="module")
def browser():
    if not CHROMIUM.is_file():
        pytest.skip(f"no chromium at {CHROMIUM}: scripts/setup.sh installs Debian's chromium")
    from playwright.sync_api import sync_playwright

    with sync_playwright() as playwright:
        launched = playwright.chromium.launch(executable_path=str(CHROMIUM), args=LAUNCH_ARGS)
        yield launched
        launched.close()


@pytest.fixture(scope="module")
def report(complete_run: Path, tmp_path_factory) -> Path:
    return write_report(complete_run, tmp_path_factory.mktemp("report") / "report.html")


@dataclass
class Opened:
    page: object  # playwright's Page
    errors: list[str]  # page errors and console errors
    outside: list[str]  # requests that left the page's own file


@pytest.fixture(scope="module")
def opened(browser, report: Path):
    """The report loaded once, from its file:// URL, every other request refused, the 3D view drawn."""
    context = browser.new_context(viewport={"width": 1280, "height": 900})
    seen = Opened(None, [], [])

    def only_the_page(route):
        if route.request.url.startswith(("file:", "data:", "blob:")):
            route.continue_()
        else:
            seen.outside.append(route.request.url)
            route.abort()

    context.route("**/*", only_the_page)
    page = context.new_page()
    page.on("pageerror", lambda error: seen.errors.append(f"page error: {error}"))
    page.on("console", lambda message: seen.errors.append(f"console: {message.text}") if message.type == "error" else None)
    page.goto(report.as_uri())
    page.wait_for_selector("#greenhouse-3d .main-svg")
    page.wait_for_selector("#greenhouse-3d canvas")
    page.wait_for_timeout(1000)  # WebGL draws on the next frames
    seen.page = page
    yield seen
    context.close()


def test_the_report_opens_offline_without_errors_and_draws_the_3d_view(opened: Opened, complete_run: Path, tmp_path: Path):
    page = opened.page
    assert page.locator("#greenhouse-3d .plotly").count() >= 1
    for selector in ("#greenhouse-3d canvas", "#greenhouse-3d svg.main-svg"):
        box = page.locator(selector).first.bounding_box()
        assert box and box["width"] > 300 and box["height"] > 300, selector
    view = tmp_path / "report_3d.png"
    page.locator("#greenhouse-3d").scroll_into_view_if_needed()
    page.locator("#greenhouse-3d").screenshot(path=str(view))
    # the path's colour covers ~100 px in the legend (SVG) and more than a thousand where WebGL draws the path
    assert _near(Image.open(view), PATH_COLOR) > 500, "the flown path (WebGL) was not drawn"
    top = tmp_path / "report_top.png"
    page.evaluate("window.scrollTo(0, 0)")
    page.screenshot(path=str(top))
    assert Image.open(top).size == (1280, 900)

    assert page.evaluate("[...document.images].every(image => image.complete && image.naturalWidth > 0)")
    scene = json.loads((complete_run / "scene.json").read_text())
    assert page.locator(".card").count() == len(scene["plants"])
    assert page.locator(".card img").count() >= 1
    assert not opened.errors, opened.errors
    assert not opened.outside, f"the page reached for the network: {opened.outside}"


def test_the_3d_view_draws_the_ripe_fruit_seen_once_that_the_estimate_credits(complete_run: Path):
    scene = read_scene(complete_run)
    times, poses = files.read_poses(complete_run)
    counts = files.read_counts(complete_run)
    once = (0.1, -0.2, 0.5)
    plants = [plant.model_copy(update={"seen_once": [once] if index == 0 else []}) for index, plant in enumerate(counts.plants)]

    def names_and_points(counted) -> dict:
        figure = greenhouse_figure(scene, counted, files.read_detections(complete_run, len(poses)),
                                   files.read_flight(complete_run), times, poses, read_camera_info(complete_run))
        return {trace.name: list(zip(trace.x, trace.y, trace.z)) for trace in figure.data if trace.name}

    drawn = names_and_points(counts.model_copy(update={"plants": plants}))
    assert drawn["ripe fruit seen once"] == [once]
    without = names_and_points(counts.model_copy(update={"plants": [p.model_copy(update={"seen_once": []}) for p in plants]}))
    assert "ripe fruit seen once" not in without


def test_the_yield_table_comes_first_with_the_numbers_of_counts_json(opened: Opened, complete_run: Path):
    counts = json.loads((complete_run / "counts.json").read_text())
    page = opened.page
    assert page.evaluate("document.querySelector('main section').id") == "yield"
    assert page.evaluate("document.querySelector('table').className") == "yield"
    cells = page.evaluate("[...document.querySelector('table.yield').rows].map(row => [...row.cells].map(c => c.innerText.trim()))")
    header, *rows, total = cells
    assert header[:5] == ["Row", "Ripe fruit estimated", "Ripe fruit true", "Error, % of true", "Plants counted exactly"]
    t = counts["total"]
    exact = sum(p["estimate"] == p["truth"] for p in counts["plants"])
    assert total == ["all rows", str(t["estimate"]), str(t["truth"]), signed_pct(t["error_pct"]),
                     f"{exact} of {len(counts['plants'])} ({100 * exact / len(counts['plants']):.0f} %)",
                     str(t["unseen"]), str(t["too_small"]), str(t["unripe_estimate"]), str(t["unripe_truth"]),
                     str(t["interval"]["low"]) if t["interval"]["low"] == t["interval"]["high"]
                     else f"{t['interval']['low']}-{t['interval']['high']}"]
    assert [row[:3] for row in rows] == [[f"row {r['id']}", str(r["estimate"]), str(r["truth"])] for r in counts["rows"]]


def test_the_same_files_give_the_same_page(complete_run: Path):
    page = build_report(complete_run)
    assert page == build_report(complete_run)
    plotly_js = max(re.findall(r"<script[^>]*>(.*?)</script>", page, flags=re.S), key=len)
    assert len(page) - len(plotly_js) < 1_200_000, "the report's own content (images, 3D data) grew past 1.2 MB"


def test_the_demo_report_with_plotly_inlined_is_at_most_2_mb(report: Path):
    page = report.read_text(encoding="utf-8")
    assert report.stat().st_size <= MAX_BYTES, f"report.html is {report.stat().st_size / 1e6:.2f} MB"
    assert "cdn.plot.ly" not in page and "<script src=" not in page  # all of plotly.js is inside the page


def test_every_depth_image_is_coloured_on_the_one_scale_the_page_states(opened: Opened, complete_run: Path):
    page = opened.page
    assert page.locator(".depthscale").count() == 1
    near, far = (float(page.locator(".depthscale").get_attribute(key)) for key in ("data-near", "data-far"))
    assert f"{near:.1f} m to {far:.1f} m" in page.locator("#frames").inner_text()
    scale = DepthScale(near, far)
    images = page.evaluate("[...document.querySelectorAll('#frames img.depth')].map(i => [i.dataset.frame, i.src])")
    assert len(images) >= 2
    fruit_depth = []
    for frame, uri in images:
        depth = decode_depth(read_png(complete_run / names.frame_file(names.DEPTH, int(frame)), np.uint16))
        drawn = np.asarray(Image.open(io.BytesIO(base64.b64decode(uri.split(",", 1)[1]))).convert("RGB"))
        assert np.array_equal(drawn, scale.colour(depth)), f"frame {frame} is not drawn on the page's scale"
        mask = read_png(complete_run / names.frame_file(names.MASKS, int(frame)), np.uint16)
        fruit_depth.append(depth[(mask > 0) & (depth > 0)])
    # the scale spans the fruit the frames show: most of them get a colour of their own, not the far grey
    fruit = np.concatenate(fruit_depth)
    assert np.mean((fruit >= near) & (fruit <= far)) > 0.95


def test_the_contact_sheet_shows_the_reports_frames_on_the_reports_depth_scale(report: Path, complete_run: Path,
                                                                               tmp_path: Path):
    page = report.read_text(encoding="utf-8")
    near, far = (float(v) for v in re.search(r'data-near="([\d.]+)" data-far="([\d.]+)"', page).groups())
    shown = [int(frame) for frame in re.findall(r'class="depth" data-frame="(\d+)"', page)]
    count = len(files.read_poses(complete_run)[0])
    assert contact_sheet.pick_frames(complete_run, count) == shown
    contact_sheet.draw_contact_sheet(complete_run, count, tmp_path / "sheet.png")
    sheet = np.asarray(Image.open(tmp_path / "sheet.png").convert("RGB"))
    width = contact_sheet.TILE_WIDTH
    for row, frame in enumerate(shown):
        depth = decode_depth(read_png(complete_run / names.frame_file(names.DEPTH, frame), np.uint16))
        tile = Image.fromarray(DepthScale(near, far).colour(depth))
        tile = np.asarray(tile.resize((width, round(tile.height * width / tile.width)), Image.Resampling.NEAREST))
        left, top = contact_sheet.tile_origin(row, 1, tile.shape[0])
        assert np.array_equal(sheet[top:top + tile.shape[0], left:left + width], tile), f"frame {frame}"


def test_the_recall_sentence_uses_the_run_s_numbers(complete_run: Path):
    scores = files.read_detection_scores(complete_run)
    counts = files.read_counts(complete_run)
    page = build_report(complete_run)
    sentence = recall_sentence(scores, counts)
    assert sentence in page.replace("&#x27;", "'")
    t = counts.total
    assert (f"found the fruit in {scores.ripe_found} of those {scores.ripe_findable} views "
            f"({100 * scores.ripe_found / scores.ripe_findable:.0f} %)") in sentence
    assert f"here {t.estimate} estimated against {t.truth} true" in sentence
    assert f"found in {counts.settings['min_views']} or more of its views" in sentence
    other = recall_sentence(scores.model_copy(update={"ripe_found": 412, "ripe_findable": 543}),
                            counts.model_copy(update={"total": t.model_copy(update={"estimate": 14})}))
    assert "found the fruit in 412 of those 543 views (76 %)" in other and f"here 14 estimated against {t.truth} true" in other


def test_the_3d_view_opens_on_the_plants_with_the_legend_clear_of_the_toolbar(opened: Opened, complete_run: Path):
    page = opened.page
    page.locator("#greenhouse-3d").hover()  # the toolbar shows on hover
    legend = page.locator("#greenhouse-3d g.legend").bounding_box()
    toolbar = page.locator("#greenhouse-3d .modebar").bounding_box()
    assert legend and toolbar and toolbar["width"] > 0
    apart = (legend["x"] + legend["width"] <= toolbar["x"] or toolbar["x"] + toolbar["width"] <= legend["x"]
             or legend["y"] + legend["height"] <= toolbar["y"] or toolbar["y"] + toolbar["height"] <= legend["y"])
    assert apart, (legend, toolbar)

    scene = read_scene(complete_run)
    times, poses = files.read_poses(complete_run)
    figure = greenhouse_figure(scene, files.read_counts(complete_run), files.read_detections(complete_run, len(poses)),
                               files.read_flight(complete_run), times, poses, read_camera_info(complete_run))
    layout = figure.layout.scene
    low = np.array([axis.range[0] for axis in (layout.xaxis, layout.yaxis, layout.zaxis)])
    high = np.array([axis.range[1] for axis in (layout.xaxis, layout.yaxis, layout.zaxis)])
    ratio = np.array([layout.aspectratio[a] for a in "xyz"])
    plants = np.array([[p.bounds.min, p.bounds.max] for p in scene.plants]).reshape(-1, 3)
    box = [(point - (low + high) / 2) / (high - low) * ratio for point in (plants.min(axis=0), plants.max(axis=0))]
    centre = np.array([layout.camera.center[a] for a in "xyz"])
    eye = np.array([layout.camera.eye[a] for a in "xyz"])
    assert np.allclose(centre, (box[0] + box[1]) / 2, atol=2e-3), "the view does not look at the plants"
    # plotly draws 45 degrees high: the plants' bounding sphere fills between a half and all of it
    half_angle = math.degrees(math.asin(min(1.0, np.linalg.norm(box[1] - box[0]) / 2 / np.linalg.norm(eye - centre))))
    assert 11 < half_angle < 30, half_angle


def test_a_run_without_masks_still_gets_its_cards_and_says_what_it_cannot_know(complete_run: Path, tmp_path: Path):
    run = tmp_path / "run"
    shutil.copytree(complete_run, run)
    shutil.rmtree(run / "masks")
    counts = json.loads((run / "counts.json").read_text())
    for part in (counts["total"], *counts["plants"]):
        part.update({key: None for key in ("unseen", "too_small", "seen_error_pct") if key in part})
    (run / "counts.json").write_text(json.dumps(counts))
    page = build_report(run)
    assert "has no instance masks" in page
    assert page.count('class="card ') == len(counts["plants"]) and "data:image/jpeg;base64," in page


@pytest.mark.parametrize("remove, stage", [(("counts.json", "harvest.json"), "count"), (("camera_info.yaml",), "render"),
                                           (("detections.json",), "detect")])
def test_a_run_missing_a_stage_s_files_names_the_stage_to_run(remove: tuple[str, ...], stage: str, complete_run: Path,
                                                              tmp_path: Path, monkeypatch, capsys):
    run = tmp_path / "run"
    shutil.copytree(complete_run, run)
    for name in remove:
        (run / name).unlink()
    code, out, err = cli(monkeypatch, capsys, "report", str(run))
    assert code == 2 and out == "" and err.count("\n") == 1
    assert f"(run `renderloop {stage}` first)" in err and remove[0] in err
    assert not (run / "report.html").exists()


def test_run_ends_with_the_yield_summary_and_the_report(monkeypatch, capsys, tmp_path: Path):
    fast = tmp_path / "fast.yaml"
    fast.write_text(yaml.safe_dump(FAST))
    out = tmp_path / "demo"
    code, stdout, stderr = cli(monkeypatch, capsys, "run", "--config", str(fast), "--out", str(out))
    assert code == 0, stderr
    counts = json.loads((out / "counts.json").read_text())
    t = counts["total"]
    exact = sum(p["estimate"] == p["truth"] for p in counts["plants"])
    assert stdout.splitlines()[-3:] == [
        f"ripe yield: {t['estimate']} estimated, {t['truth']} true ({signed_pct(t['error_pct'])})",
        f"plants counted exactly: {exact} of {len(counts['plants'])} ({100 * exact / len(counts['plants']):.0f} %)",
        f"report: {out / 'report.html'}",
    ]
    page = (out / "report.html").read_text()
    assert "Stage times" in page and " in all; most of it went to " in page  # timings.json, in words
    stamp = (out / "report.html").stat().st_mtime_ns

    code, again, stderr = cli(monkeypatch, capsys, "run", "--config", str(fast), "--out", str(out))
    assert code == 0 and stderr.count("complete, skipped") == 6
    assert again.splitlines()[-3:] == stdout.splitlines()[-3:]
    assert (out / "report.html").stat().st_mtime_ns == stamp  # nothing changed: the report is kept as it is
