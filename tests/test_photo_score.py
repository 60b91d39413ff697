"""`renderloop score-photos`: the detector scored on a user's labelled photos (COCO), from one search at the floor."""

from __future__ import annotations

import json
import struct
import zlib
from pathlib import Path

import numpy as np
import pytest
from conftest import cli
from PIL import Image

from renderloop.perception.detector import PASS_FLOOR, Detection, Detector, shipped_model
from renderloop.perception.photo_score import (
    LabelledImage, PhotoScore, Searched, ap50, match, sheet_picks, tally,
)

WIDTH, HEIGHT = 64, 48
# The hand-made case. Labelled boxes (COCO x, y, w, h): photo 1 has A1 and A2, photo 2 has B1, photo 3 none.
TRUTH = {1: [[0, 0, 20, 20], [30, 10, 20, 20]], 2: [[10, 10, 20, 20]], 3: []}
# What the fake network finds on each photo (x0, y0, x1, y1), best first overall: d4 false, d1 on A1, d2 a second box
# on A1 (false), d5 on nothing (false), d3 on A2 (true only from 0.3 down). B1 is never found.
FOUND = {
    1: [Detection((1.0, 1.0, 21.0, 21.0), 0.9, "ripe"), Detection((0.0, 0.0, 20.0, 20.0), 0.8, "unripe"),
        Detection((30.0, 10.0, 50.0, 30.0), 0.3, "unripe")],
    2: [Detection((40.0, 20.0, 60.0, 40.0), 0.95, "ripe")],
    3: [Detection((5.0, 5.0, 15.0, 15.0), 0.5, "unripe")],
}


@pytest.fixture
def fake_network(monkeypatch) -> list[tuple[float, list, bool, float]]:
    """Detector.detect answers FOUND for the photo whose first pixel holds its id; the calls are recorded."""
    calls = []

    def detect(self, rgb, score_threshold, layouts=(), mirror=False, min_side=0.0, max_enlargement=1.5):
        calls.append((score_threshold, list(layouts), mirror, min_side))
        return [d for d in FOUND[int(rgb[0, 0, 0])]
                if d.score >= score_threshold and min(d.bbox[2] - d.bbox[0], d.bbox[3] - d.bbox[1]) >= min_side]

    monkeypatch.setattr(Detector, "detect", detect)
    return calls


def coco(categories: list[str] | None = None, classes: dict[int, list[int]] | None = None) -> dict:
    categories = categories or ["pepper"]
    annotations = []
    for image_id, boxes in TRUTH.items():
        for number, box in enumerate(boxes):
            category = classes[image_id][number] if classes else 1
            annotations.append({"id": len(annotations) + 1, "image_id": image_id, "bbox": box, "category_id": category,
                                "area": box[2] * box[3], "iscrowd": 0})
    return {"info": {"description": "hand-made"},
            "images": [{"id": i, "file_name": f"{'abc'[i - 1]}.png", "width": WIDTH, "height": HEIGHT} for i in TRUTH],
            "annotations": annotations,
            "categories": [{"id": number + 1, "name": name} for number, name in enumerate(categories)]}


@pytest.fixture
def photos(tmp_path: Path) -> tuple[Path, Path]:
    """Three tiny PNG photos, each filled with its image id, and their COCO labels (one category: pepper)."""
    folder = tmp_path / "photos"
    folder.mkdir()
    for image_id in TRUTH:
        Image.fromarray(np.full((HEIGHT, WIDTH, 3), image_id, dtype=np.uint8)).save(folder / f"{'abc'[image_id - 1]}.png")
    labels = tmp_path / "labels.json"
    labels.write_text(json.dumps(coco()))
    return folder, labels


def searched() -> list[Searched]:
    return [Searched(LabelledImage(i, Path(f"{i}.png"), WIDTH, HEIGHT,
                                   np.array([[x, y, x + w, y + h] for x, y, w, h in TRUTH[i]], dtype=float).reshape(-1, 4),
                                   (None,) * len(TRUTH[i])), FOUND[i]) for i in TRUTH]


def _tree(folder: Path) -> dict[str, bytes]:
    return {p.relative_to(folder).as_posix(): p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()}


def test_each_labelled_box_goes_to_one_detection_the_highest_scoring_first_at_iou_one_half() -> None:
    truth = np.array([[0, 0, 20, 20], [30, 10, 50, 30]], dtype=float)
    boxes = np.array([[0, 0, 20, 20], [1, 1, 21, 21], [30, 10, 50, 30], [30, 20, 50, 40]], dtype=float)
    # the 0.9 box takes the first box although the 0.8 one fits it exactly; the half-covering box (IoU 1/3) finds nothing
    assert match(boxes, np.array([0.8, 0.9, 0.3, 0.99]), truth).tolist() == [-1, 0, 1, -1]
    assert match(boxes[:0], np.zeros(0), truth).tolist() == []
    assert match(boxes, np.ones(4), truth[:0]).tolist() == [-1] * 4


def test_figures_at_a_threshold_and_over_the_curve_are_the_ones_counted_by_hand() -> None:
    counted = tally(searched())
    at_default = counted.at(0.68)  # d4 false, d1 true, d2 false
    assert (at_default.true_positives, at_default.false_positives, at_default.misses) == (1, 2, 2)
    assert (at_default.recall, at_default.precision, at_default.f1) == pytest.approx((1 / 3, 1 / 3, 1 / 3), abs=1e-5)
    low = counted.at(0.3)  # every detection: d1 and d3 true
    assert (low.true_positives, low.false_positives, low.misses) == (2, 3, 1)
    assert (low.recall, low.precision, low.f1) == pytest.approx((2 / 3, 2 / 5, 1 / 2), abs=1e-5)
    assert counted.at(0.85).f1 == pytest.approx(0.4, abs=1e-5)  # d4 and d1
    top = counted.at(0.96)
    assert top.precision is None and top.recall == 0.0 and top.f1 == 0.0  # nothing passes: precision is undefined


def test_ap_at_one_half_is_pycocotools_101_point_interpolation() -> None:
    # by score: d4 F, d1 T, d2 F, d5 F, d3 T over 3 boxes: precision 0.5 up to recall 1/3, 0.4 up to 2/3, then nothing
    assert ap50(searched()) == pytest.approx((34 * 0.5 + 33 * 0.4) / 101, abs=1e-5)
    perfect = [Searched(s.image, [Detection(tuple(box), 0.9, "ripe") for box in s.image.boxes.tolist()]) for s in searched()]
    assert ap50(perfect) == pytest.approx(1.0)
    assert ap50([Searched(s.image, []) for s in searched()]) == 0.0
    assert ap50(searched(), "ripe") is None  # no box names a ripeness


def test_the_sheet_spreads_its_photos_over_the_whole_set() -> None:
    assert sheet_picks(3) == [0, 1, 2]
    picks = sheet_picks(804)
    assert len(picks) == 12 and picks[0] == 0 and picks[-1] == 803
    assert max(np.diff(picks)) - min(np.diff(picks)) <= 1


def test_the_verb_scores_the_photos_from_one_search_at_the_floor_and_writes_its_files(
        photos, fake_network, tmp_path: Path, monkeypatch, capsys) -> None:
    folder, labels = photos
    out = tmp_path / "score"
    code, stdout, stderr = cli(monkeypatch, capsys, "score-photos", str(folder), "--coco", str(labels), "--out", str(out))
    assert code == 0, stderr
    assert [call[0] for call in fake_network] == [PASS_FLOOR] * 3  # each photo searched once, with the config's passes
    assert all(call[1] == [(2, 2)] and call[2] for call in fake_network)
    assert "3 photos, 3 labelled boxes" in stdout
    assert "at threshold 0.88: recall 0.333 (1/3), precision 0.500 (1/2), F1 0.400" in stdout
    assert "best F1 0.500 at 0.10" in stdout and str(out) in stdout
    record = PhotoScore.model_validate_json((out / "score.json").read_text())
    assert (record.images, record.boxes, record.threshold, record.windows, record.mirror) == (3, 3, 0.88, ["2x2"], True)
    assert record.class_agnostic.ap50 == pytest.approx(30.2 / 101, abs=1e-5)
    assert record.by_class is None  # one category, "pepper": no ripeness to score
    curve = record.class_agnostic.curve
    assert curve[0].threshold == PASS_FLOOR and curve[-1].threshold == 0.999 and len(curve) == 99
    assert [f.f1 for f in curve if f.threshold in (0.1, 0.3, 0.31, 0.5, 0.51, 0.8, 0.81, 0.9, 0.91)] == pytest.approx(
        [0.5, 0.5, 2 / 7, 2 / 7, 1 / 3, 1 / 3, 0.4, 0.4, 0.0], abs=1e-5)
    for name in ("pr_curve.png", "sheet.png"):
        with Image.open(out / name) as image:
            assert image.format == "PNG" and image.width > 100
    assert not list(out.glob(".*partial"))


def test_the_name_shipped_scores_the_model_in_the_package(photos, fake_network, tmp_path: Path, monkeypatch, capsys) -> None:
    folder, labels = photos
    out = tmp_path / "score"
    code, _, stderr = cli(monkeypatch, capsys, "score-photos", str(folder), "--coco", str(labels), "--out", str(out),
                          "--model", "shipped")
    assert code == 0, stderr
    assert PhotoScore.model_validate_json((out / "score.json").read_text()).model == str(shipped_model())


def test_ripeness_categories_give_per_class_scores_and_the_options_reach_the_search(
        photos, fake_network, tmp_path: Path, monkeypatch, capsys) -> None:
    folder, labels = photos
    labels.write_text(json.dumps(coco(["Red", "green"], {1: [1, 2], 2: [2], 3: []})))  # A1 ripe, A2 and B1 unripe
    out = tmp_path / "score"
    code, stdout, stderr = cli(monkeypatch, capsys, "score-photos", str(folder), "--coco", str(labels), "--out", str(out),
                               "--threshold", "0.05", "--windows", "none", "--no-mirror", "--min-box", "4")
    assert code == 0, stderr
    assert fake_network == [(0.05, [], False, 4.0)] * 3  # a threshold under the floor is searched down to itself
    record = PhotoScore.model_validate_json((out / "score.json").read_text())
    assert record.search_floor == 0.05 and record.windows == [] and not record.mirror
    ripe, unripe = record.by_class["ripe"], record.by_class["unripe"]
    assert (ripe.boxes, ripe.at_threshold.true_positives, ripe.at_threshold.false_positives) == (1, 1, 1)  # d1; d4
    assert (unripe.boxes, unripe.at_threshold.true_positives, unripe.at_threshold.false_positives) == (2, 1, 2)  # d3; d2, d5
    assert ripe.curve[60].threshold == 0.7 and ripe.curve[60].recall == 1.0 and unripe.curve[60].recall == 0.0
    assert "ripe at threshold 0.05" in stdout and "unripe at threshold 0.05" in stdout


def _truncate(folder: Path, labels: Path) -> None:
    data = (folder / "b.png").read_bytes()
    (folder / "b.png").write_bytes(data[: len(data) - 30])


def _bomb(folder: Path, labels: Path) -> None:
    """b.png's header claims 10000 x 10000 pixels (its CRC fixed), the rest of the file unchanged."""
    data = bytearray((folder / "b.png").read_bytes())
    header = b"IHDR" + struct.pack(">II", 10_000, 10_000) + bytes(data[24:29])
    data[12:29] = header
    data[29:33] = struct.pack(">I", zlib.crc32(header))
    (folder / "b.png").write_bytes(bytes(data))


def _edit(change):
    def apply(folder: Path, labels: Path) -> None:
        data = json.loads(labels.read_text())
        change(data)
        labels.write_text(json.dumps(data))
    return apply


BAD_INPUT = {
    "labels missing": (lambda folder, labels: labels.unlink(), "no such file"),
    "labels not JSON": (lambda folder, labels: labels.write_text('{"images": ['), "not JSON"),
    "labels not COCO": (_edit(lambda d: d.pop("categories")), "not a COCO file (categories: Field required)"),
    "a box of three numbers": (_edit(lambda d: d["annotations"][0].update(bbox=[1, 2, 3])), "not a COCO file (annotations.0.bbox"),
    "a box on an image not listed": (_edit(lambda d: d["annotations"][1].update(image_id=9)), "image id 9, which images does not list"),
    "a category not listed": (_edit(lambda d: d["annotations"][0].update(category_id=4)), "category id 4"),
    "an image id twice": (_edit(lambda d: d["images"][2].update(id=1)), "image id 1 is listed twice"),
    "a name outside the folder": (_edit(lambda d: d["images"][0].update(file_name="../a.png")), "inside the photo folder"),
    "a box outside its image": (_edit(lambda d: d["annotations"][1].update(bbox=[50, 10, 20, 20])), "lies outside its image"),
    "a box of no width": (_edit(lambda d: d["annotations"][2].update(bbox=[10, 10, 0, 5])), "no area"),
    "a listed photo missing": (lambda folder, labels: (folder / "c.png").unlink(), "c.png: no such file"),
    "a photo of another size": (_edit(lambda d: d["images"][1].update(width=65)), "64x48 pixels, but --coco"),
    "a photo that is not one": (lambda folder, labels: (folder / "b.png").write_text("hello"), "b.png: not a readable image"),
    "a truncated photo": (_truncate, "b.png: not a readable image (truncated or corrupt data)"),
    "a decompression bomb": (_bomb, "b.png: its header claims"),
}


@pytest.mark.parametrize("case", BAD_INPUT)
def test_bad_labels_or_photos_end_in_one_line_and_exit_two_with_nothing_written(
        case: str, photos, fake_network, tmp_path: Path, monkeypatch, capsys) -> None:
    folder, labels = photos
    spoil, expected = BAD_INPUT[case]
    spoil(folder, labels)
    out = tmp_path / "score"
    code, stdout, stderr = cli(monkeypatch, capsys, "score-photos", str(folder), "--coco", str(labels), "--out", str(out))
    assert code == 2 and stderr.count("renderloop: error") == 1 and "Traceback" not in stderr, stderr
    assert expected in stderr.splitlines()[-1]
    if case != "a truncated photo":  # found only on decoding, with the progress bar up; the rest before the search
        assert stderr.count("\n") == 1 and not fake_network
    assert not out.exists()


def test_a_folder_of_the_users_is_refused_and_left_byte_identical(photos, fake_network, tmp_path: Path, monkeypatch, capsys):
    folder, labels = photos
    out = tmp_path / "mine"
    out.mkdir()
    (out / "notes.txt").write_text("my notes\n")
    (out / "score.json").write_text("{}")
    before = _tree(out)
    code, _, stderr = cli(monkeypatch, capsys, "score-photos", str(folder), "--coco", str(labels), "--out", str(out), "--force")
    assert code == 2 and stderr.count("\n") == 1 and "not made by renderloop" in stderr, stderr
    assert _tree(out) == before and not fake_network  # refused before any photo was searched
    assert not list(tmp_path.glob(".*partial"))


def test_a_second_score_needs_force_and_a_users_file_beside_it_stays(photos, fake_network, tmp_path: Path, monkeypatch, capsys):
    folder, labels = photos
    out = tmp_path / "score"
    arguments = ("score-photos", str(folder), "--coco", str(labels), "--out", str(out))
    assert cli(monkeypatch, capsys, *arguments)[0] == 0
    (out / "notes.txt").write_text("my notes\n")
    before = _tree(out)
    code, _, stderr = cli(monkeypatch, capsys, *arguments)
    assert code == 2 and stderr.strip().endswith("exists; use --force to replace its score"), stderr
    assert _tree(out) == before
    code, _, stderr = cli(monkeypatch, capsys, *arguments, "--threshold", "0.3", "--force")
    assert code == 0, stderr
    assert PhotoScore.model_validate_json((out / "score.json").read_text()).threshold == 0.3
    assert (out / "notes.txt").read_text() == "my notes\n"
    code, _, stderr = cli(monkeypatch, capsys, "eval", "--out", str(out), "--seeds", "0")
    assert code == 2 and "photo score directory" in stderr  # and no other verb writes into it
