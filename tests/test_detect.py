"""`renderloop detect`: detections.json of a rendered run (resumable, geometric), and photo folders;
`renderloop threshold` on rendered runs."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest
from conftest import cli, fly_demo_raster, jittered_model

from renderloop.errors import UserError
from renderloop.perception.detector import Detector
from renderloop.perception.fruit_points import CENTRE_BEHIND_SKIN, MAX_RADIUS
from renderloop.perception.stage import run_detect
from renderloop.perception.threshold import THRESHOLDS, ThresholdScore, choose, format_scores, score_thresholds, search_run
from renderloop.perception.training.ssd import export_onnx
from renderloop.render.camera import read_camera_info
from renderloop.render.frames import decode_depth, read_png
from renderloop.render.stage import run_render
from renderloop.rundir.files import read_config, read_poses
from renderloop.rundir.names import DETECT_CACHE as CACHE


@pytest.fixture(scope="module")
def model(tmp_path_factory) -> Path:
    """A random detector whose scores vary enough to give boxes at threshold 0.3."""
    path = tmp_path_factory.mktemp("model") / "random.onnx"
    export_onnx(jittered_model(0), path)
    return path


@pytest.fixture(scope="module")
def rendered(tmp_path_factory) -> Path:
    run_dir = fly_demo_raster(tmp_path_factory.mktemp("detect") / "run", rate_hz=0.2)
    (run_dir / "config.yaml").write_text(read_config(run_dir).override({"detector": {"score_threshold": 0.3}}).to_yaml())
    run_render(run_dir, read_config(run_dir))
    return run_dir


def test_detections_hold_every_frame_and_points_lie_in_their_boxes(rendered: Path, model: Path, tmp_path: Path):
    run_dir = tmp_path / "run"
    shutil.copytree(rendered, run_dir)
    assert run_detect(run_dir, read_config(run_dir).override({"detector": {"model": model}}))
    document = json.loads((run_dir / "detections.json").read_text())
    times, poses = read_poses(run_dir)
    assert [f["index"] for f in document["frames"]] == list(range(len(poses)))
    assert [f["timestamp"] for f in document["frames"]] == pytest.approx(times, abs=1e-6)
    assert document["depth"] == "depth_sensor" and document["score_threshold"] == 0.3
    intrinsics = read_camera_info(run_dir)
    placed = 0
    for frame, pose in zip(document["frames"], poses):
        depth = decode_depth(read_png(run_dir / "depth_sensor" / Path(frame["image"]).name, np.uint16))
        for detection in frame["detections"]:
            x0, y0, x1, y1 = detection["bbox"]
            assert 0 <= x0 <= x1 <= intrinsics.width and 0 <= y0 <= y1 <= intrinsics.height
            assert detection["label"] in ("ripe", "unripe") and detection["score"] >= 0.3
            if detection["position"] is None:
                continue
            local = (np.asarray(detection["position"]) - pose[:3, 3]) @ pose[:3, :3]
            u, v = intrinsics.project(local)[0]
            assert x0 - 1 <= u <= x1 + 1 and y0 - 1 <= v <= y1 + 1  # the centroid of points inside the box
            box_depth = depth[int(y0):int(np.ceil(y1)), int(x0):int(np.ceil(x1))]
            behind = CENTRE_BEHIND_SKIN * MAX_RADIUS  # the point is the fruit's centre, behind the skin the box shows
            assert box_depth[box_depth > 0].min() - 0.01 <= local[2] <= box_depth.max() + 0.01 + behind
            placed += 1
    assert placed > 20
    scores = json.loads((run_dir / "detection_scores.json").read_text())
    assert {"ripe_recall", "false_rate", "position_error_median_m"} <= set(scores)
    assert (run_dir / "detections.png").is_file() and not (run_dir / CACHE).exists()
    assert not run_detect(run_dir, read_config(run_dir))  # complete: skipped (the model came from --model)


def test_a_bad_frame_stops_detection_and_the_rerun_finishes_the_same(rendered: Path, model: Path, tmp_path: Path):
    clean, broken = tmp_path / "clean", tmp_path / "broken"
    shutil.copytree(rendered, clean)
    shutil.copytree(rendered, broken)
    run_detect(clean, read_config(clean).override({"detector": {"model": model}}))
    frame = broken / "rgb" / "000002.png"
    good = frame.read_bytes()
    frame.write_bytes(good[:100])
    with pytest.raises(UserError, match="000002.png: not a readable PNG"):
        run_detect(broken, read_config(broken).override({"detector": {"model": model}}))
    assert len((broken / CACHE).read_text().splitlines()) == 2 and not (broken / "detections.json").exists()
    frame.write_bytes(good)
    run_detect(broken, read_config(broken).override({"detector": {"model": model}}))
    assert (broken / "detections.json").read_bytes() == (clean / "detections.json").read_bytes()


def test_depth_of_another_size_is_refused(rendered: Path, model: Path, tmp_path: Path):
    run_dir = tmp_path / "run"
    shutil.copytree(rendered, run_dir)
    from PIL import Image

    Image.fromarray(np.zeros((10, 12), np.uint16)).save(run_dir / "depth_sensor" / "000000.png")
    with pytest.raises(UserError, match="000000.png: depth is 12x10 but the RGB frame is 320x240"):
        run_detect(run_dir, read_config(run_dir).override({"detector": {"model": model}}))


def test_photo_folders(rendered: Path, model: Path, tmp_path: Path, monkeypatch, capsys):
    photos = tmp_path / "photos"
    photos.mkdir()
    for name in ("a.png", "b.png", "c.png"):
        shutil.copy(rendered / "rgb" / "000001.png", photos / name)
    from PIL import Image

    Image.open(photos / "a.png").convert("RGB").resize((500, 333)).save(photos / "d.jpg")
    out = tmp_path / "found.json"
    code, stdout, _ = cli(monkeypatch, capsys, "detect", "--images", str(photos), "--out", str(out), "--model", str(model), "--threshold", "0.3",
                                  "--mirror")
    assert code == 0 and "4 photos" in stdout
    found = json.loads(out.read_text())
    assert found["complete"] and found["mirror"] is True and sorted(found["images"]) == ["a.png", "b.png", "c.png", "d.jpg"]
    assert found["images"]["a.png"] == found["images"]["b.png"] and found["images"]["a.png"]["detections"]
    assert found["images"]["d.jpg"]["width"] == 500
    assert all(d["bbox"][2] <= 500 and d["bbox"][3] <= 333 for d in found["images"]["d.jpg"]["detections"])

    (photos / "b.png").write_bytes(b"not a png at all")
    code, _, stderr = cli(monkeypatch, capsys, "detect", "--images", str(photos), "--out", str(out), "--model", str(model))
    assert code == 2 and "found.json: exists; use --force to replace it" in stderr  # the user's file, or an earlier result
    code, _, stderr = cli(monkeypatch, capsys, "detect", "--images", str(photos), "--out", str(out), "--model", str(model), "--force")
    errors = [line for line in stderr.splitlines() if line.startswith("renderloop: error")]
    assert code == 2 and len(errors) == 1 and errors[0].endswith("b.png: not a readable image") and "Traceback" not in stderr
    partial = json.loads(out.read_text())
    assert not partial["complete"] and list(partial["images"]) == ["a.png"]

    empty = tmp_path / "empty"
    empty.mkdir()
    code, _, stderr = cli(monkeypatch, capsys, "detect", "--images", str(empty), "--out", str(out))
    assert code == 2 and "no PNG or JPEG files" in stderr
    junk = tmp_path / "junk.onnx"
    junk.write_bytes(b"\x00" * 64)
    code, _, stderr = cli(monkeypatch, capsys, "detect", "--images", str(photos), "--out", str(tmp_path / "new.json"),
                          "--model", str(junk))
    assert code == 2 and "junk.onnx: not an ONNX model" in stderr


def test_a_threshold_scored_from_one_search_is_what_detect_gives_at_it(rendered: Path, model: Path, tmp_path: Path):
    run_dir = tmp_path / "run"
    shutil.copytree(rendered, run_dir)
    settings = read_config(run_dir).detector
    searched = search_run(run_dir, Detector(model), settings)
    for threshold in (0.3, 0.5):
        config = read_config(run_dir).override({"detector": {"score_threshold": threshold}})
        run_detect(run_dir, config.override({"detector": {"model": model}}), force=True)
        truth = json.loads((run_dir / "detection_scores.json").read_text())
        (score,) = score_thresholds([searched], [threshold])
        assert score.detections > 0
        assert (score.found, score.findable, score.false, score.detections) == (
            truth["ripe_found"], truth["ripe_findable"], truth["false_detections"], truth["detections_scored"])


def test_the_search_scores_thresholds_above_0_99_and_prints_them_as_they_are_set():
    assert THRESHOLDS[-1] == 0.999 and 0.992 in THRESHOLDS and list(THRESHOLDS) == sorted(set(THRESHOLDS))
    scores = [ThresholdScore(t, 50, 100, 10 if t < 0.992 else 2, 60) for t in THRESHOLDS]  # false under 5 % from 0.992
    chosen = choose(scores, 0.05)
    table = format_scores(scores, chosen)
    assert chosen.threshold == 0.992 and "0.992" in table and "<- chosen" in table and "1.00" not in table


def test_the_chosen_threshold_is_the_lowest_within_the_false_share(rendered: Path, model: Path, monkeypatch, capsys):
    scores = [ThresholdScore(0.5, 90, 100, 12, 102), ThresholdScore(0.6, 88, 100, 5, 93), ThresholdScore(0.7, 80, 100, 2, 82),
              ThresholdScore(0.8, 0, 100, 0, 0)]  # nothing left to be false: not a choice
    assert choose(scores, 0.06).threshold == 0.6 and choose(scores, 0.03).threshold == 0.7 and choose(scores, 0.01) is None
    code, stdout, _ = cli(monkeypatch, capsys, "threshold", str(rendered), "--model", str(model), "--max-false", "1")
    assert code == 0 and "threshold: 0.10" in stdout and "<- chosen" in stdout
    code, _, stderr = cli(monkeypatch, capsys, "threshold", str(rendered), "--model", str(model), "--max-false", "0")
    assert code == 2 and "no threshold up to 0.999 keeps false detections at or under 0.0%" in stderr
    code, _, stderr = cli(monkeypatch, capsys, "threshold", str(rendered / "rgb"))
    assert code == 2 and "missing" in stderr and "Traceback" not in stderr
