"""`renderloop score-photos FOLDER --coco labels.json --out DIR`: how well the detector knows the user's own labelled photos.

Every photo the COCO file lists is searched once, through the photo path of `detect --images`
(`read_image`, then `Detector.detect` with the given windows and mirror), keeping fused boxes
down to PASS_FLOOR. Matching is one-to-one and greedy, highest score first, at IoU >= 0.5
(the rule of COCOeval): a higher threshold only drops the lowest-scoring boxes, and the boxes
above it meet the labelled boxes in the same order as before, so each detection's match at the
floor is its match at every threshold above it, and the whole recall/precision curve
(THRESHOLDS, PASS_FLOOR..0.999) is scored from the one search.

Scores are class-agnostic (any detection on any labelled box); when every category of the
labels names a ripeness (ripe/unripe, or red/yellow/orange for ripe and green for unripe) they
are also given per class, a detection then counting only on a box of its own label. AP@0.5 is
pycocotools' COCOeval (101-point interpolated precision, at most 100 detections an image) over
the detections the search kept: none scores under the floor, so the curve's tail below it is not
in the AP.

DIR holds score.json (PhotoScore), pr_curve.png and sheet.png; it must be new, empty or one
`score-photos` wrote (an existing score is replaced only with `force`). Bad labels, a missing
photo or one of another size than the labels say are refused in one line before the search,
and nothing is written until every photo was searched.
"""

from __future__ import annotations

import contextlib
import io
import json
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path, PurePosixPath

import numpy as np
from PIL import Image
from pydantic import BaseModel, ConfigDict, Field, FiniteFloat, PositiveInt, ValidationError

from renderloop.config import DetectorConfig
from renderloop.errors import UserError, problem
from renderloop.io import ownership
from renderloop.io.atomic import write_json
from renderloop.io.images import check_image, read_image
from renderloop.perception.boxes import box_iou
from renderloop.perception.detector import CLASSES, PASS_FLOOR, Detection, Detector
from renderloop.perception.threshold import THRESHOLDS, threshold_text
from renderloop.perception.tiling import layout_names

MATCH_IOU = 0.5
EDGE_TOLERANCE = 0.5  # px: a labelled box may pass its image's edge by this much (rounding); it is clipped to the image
# Category names that say a pepper's ripeness (lower case): the detector's own labels and the colours of a bell pepper.
RIPENESS = {"ripe": "ripe", "red": "ripe", "yellow": "ripe", "orange": "ripe", "unripe": "unripe", "green": "unripe"}
SCORE, PR_CURVE, SHEET = "score.json", "pr_curve.png", "sheet.png"
OUTPUTS = (PR_CURVE, SHEET, SCORE)  # in the order written: a score.json means the figures beside it are its own
SHEET_IMAGES = 12

Progress = Callable[[int, int], None]


def _shown(text: object) -> str:
    """A path or name as it goes into a one-line message: quoted when it is not one printable line."""
    text = str(text)
    return text if text.isprintable() else repr(text)


# --- the COCO subset read -------------------------------------------------------------------------------------------

class _Coco(BaseModel):
    model_config = ConfigDict(extra="ignore", frozen=True)  # COCO files carry area, iscrowd, info, licenses, ...


class CocoImage(_Coco):
    id: int
    file_name: str = Field(min_length=1)
    width: PositiveInt
    height: PositiveInt


class CocoAnnotation(_Coco):
    image_id: int
    bbox: tuple[FiniteFloat, FiniteFloat, FiniteFloat, FiniteFloat]  # x, y, width, height in pixels
    category_id: int


class CocoCategory(_Coco):
    id: int
    name: str


class CocoLabels(_Coco):
    images: list[CocoImage] = Field(min_length=1)
    annotations: list[CocoAnnotation] = Field(min_length=1)
    categories: list[CocoCategory] = Field(min_length=1)


@dataclass(frozen=True)
class LabelledImage:
    id: int
    path: Path
    width: int
    height: int
    boxes: np.ndarray  # (N, 4) x0, y0, x1, y1 in pixels
    classes: tuple[str | None, ...]  # each box's ripeness, None when its category names none


@dataclass(frozen=True)
class Labels:
    images: list[LabelledImage]
    by_class: bool  # every category names a ripeness

    @property
    def boxes(self) -> int:
        return sum(len(image.boxes) for image in self.images)


def _parse(coco: Path) -> CocoLabels:
    where = f"--coco {_shown(coco)}"
    if coco.is_dir():
        raise UserError(f"{where}: a folder, not a COCO file")
    try:
        data = json.loads(coco.read_bytes().decode("utf-8"))
    except FileNotFoundError:
        raise UserError(f"{where}: no such file") from None
    except UnicodeDecodeError:
        raise UserError(f"{where}: not JSON (not UTF-8 text)") from None
    except json.JSONDecodeError as error:
        raise UserError(f"{where}: not JSON ({error.msg} at line {error.lineno} column {error.colno})") from None
    except RecursionError:
        raise UserError(f"{where}: not JSON we can read (nested too deeply)") from None
    try:
        return CocoLabels.model_validate(data)
    except ValidationError as error:
        raise UserError(f"{where}: not a COCO file ({problem(error)})") from None


def _photo_path(folder: Path, image: CocoImage, where: str) -> Path:
    name = PurePosixPath(image.file_name.replace("\\", "/"))
    if name.is_absolute() or ".." in name.parts or not image.file_name.isprintable():
        raise UserError(f"{where}: image {image.id} has file_name {image.file_name!r}; give a name inside the photo folder")
    return folder / name


def read_labels(coco: Path, folder: Path) -> Labels:
    """The labelled boxes of every image `coco` lists, each image checked (from its header only) to lie in
    `folder` at the size the labels say; anything wrong is a one-line UserError."""
    coco, folder = Path(coco), Path(folder)
    where = f"--coco {_shown(coco)}"
    parsed = _parse(coco)
    if not folder.is_dir():
        raise UserError(f"{_shown(folder)}: not a folder")
    images: dict[int, CocoImage] = {}
    names: dict[str, int] = {}
    for image in parsed.images:
        if image.id in images:
            raise UserError(f"{where}: image id {image.id} is listed twice")
        if image.file_name in names:
            raise UserError(f"{where}: images {names[image.file_name]} and {image.id} are both {image.file_name!r}")
        images[image.id], names[image.file_name] = image, image.id
    categories: dict[int, str] = {}
    for category in parsed.categories:
        if category.id in categories:
            raise UserError(f"{where}: category id {category.id} is listed twice")
        categories[category.id] = category.name
    ripeness = {cid: RIPENESS.get(name.strip().lower()) for cid, name in categories.items()}
    by_class = all(value is not None for value in ripeness.values())
    boxes: dict[int, list[tuple[float, float, float, float]]] = {image_id: [] for image_id in images}
    classes: dict[int, list[str | None]] = {image_id: [] for image_id in images}
    for number, annotation in enumerate(parsed.annotations):
        image = images.get(annotation.image_id)
        if image is None:
            raise UserError(f"{where}: annotations.{number} is on image id {annotation.image_id}, which images does not list")
        if annotation.category_id not in categories:
            raise UserError(f"{where}: annotations.{number} has category id {annotation.category_id}, "
                            "which categories does not list")
        x, y, w, h = annotation.bbox
        box = f"annotations.{number}: box [x, y, w, h] = {list(annotation.bbox)}"
        if w <= 0 or h <= 0:
            raise UserError(f"{where}: {box} has no area (width and height must be positive)")
        if min(x, y) < -EDGE_TOLERANCE or x + w > image.width + EDGE_TOLERANCE or y + h > image.height + EDGE_TOLERANCE:
            raise UserError(f"{where}: {box} lies outside its image {image.file_name!r} ({image.width}x{image.height})")
        boxes[image.id].append((max(x, 0.0), max(y, 0.0), min(x + w, image.width), min(y + h, image.height)))
        classes[image.id].append(ripeness[annotation.category_id])
    labelled = []
    for image in parsed.images:
        path = _photo_path(folder, image, where)
        width, height = check_image(path)  # missing, not PNG/JPEG, or too large: its own one line
        if (width, height) != (image.width, image.height):
            raise UserError(f"{_shown(path)}: {width}x{height} pixels, but {where} says {image.width}x{image.height}")
        labelled.append(LabelledImage(image.id, path, image.width, image.height,
                                      np.array(boxes[image.id], dtype=float).reshape(-1, 4), tuple(classes[image.id])))
    return Labels(labelled, by_class)


# --- matching and figures -------------------------------------------------------------------------------------------

def match(boxes: np.ndarray, scores: np.ndarray, truth: np.ndarray, iou: float = MATCH_IOU) -> np.ndarray:
    """The labelled box each detection found, -1 for none: greedy by decreasing score, each detection (boxes (N, 4),
    scores (N,)) taking the free labelled box (truth (M, 4)) it overlaps most, at IoU >= `iou`; each box is taken once."""
    taken = np.full(len(boxes), -1, dtype=int)
    if len(boxes) == 0 or len(truth) == 0:
        return taken
    overlap = box_iou(np.asarray(boxes, dtype=float).reshape(-1, 4), np.asarray(truth, dtype=float).reshape(-1, 4))
    free = np.ones(len(truth), dtype=bool)
    for d in np.argsort(-np.asarray(scores), kind="stable"):
        candidates = np.where(free, overlap[d], -1.0)
        best = int(np.argmax(candidates))
        if candidates[best] >= iou:
            taken[d] = best
            free[best] = False
    return taken


class Figures(BaseModel):
    """Recall, precision and F1 at one score threshold; recall is None without labelled boxes, precision without detections."""

    model_config = ConfigDict(extra="forbid", frozen=True)
    threshold: float
    recall: float | None
    precision: float | None
    f1: float
    true_positives: int  # detections on a labelled box
    false_positives: int  # detections on none (or a second one on a box already found)
    misses: int  # labelled boxes no detection found


@dataclass(frozen=True)
class Tally:
    """Every detection kept at the floor: its score and whether it matched; and how many boxes were labelled."""
    scores: np.ndarray
    hits: np.ndarray
    truth: int

    def at(self, threshold: float) -> Figures:
        kept = self.scores >= threshold
        found = int(self.hits[kept].sum())
        detections = int(kept.sum())
        recall = found / self.truth if self.truth else None
        precision = found / detections if detections else None
        f1 = 2 * found / (self.truth + detections) if found else 0.0
        return Figures(threshold=round(float(threshold), 4), recall=None if recall is None else round(recall, 5),
                       precision=None if precision is None else round(precision, 5), f1=round(f1, 5),
                       true_positives=found, false_positives=detections - found, misses=self.truth - found)


@dataclass(frozen=True)
class Searched:
    """One photo's detections at the search floor."""
    image: LabelledImage
    detections: list[Detection]


def _truth_of(image: LabelledImage, label: str | None) -> np.ndarray:
    if label is None:
        return image.boxes
    return image.boxes[[c == label for c in image.classes]].reshape(-1, 4)


def _detections_of(searched: Searched, label: str | None) -> list[Detection]:
    return [d for d in searched.detections if label is None or d.label == label]


def tally(photos: Sequence[Searched], label: str | None = None) -> Tally:
    """Scores and matches over all photos: every detection on every box (`label` None), or one class's on its own."""
    scores, hits, truth = [], [], 0
    for photo in photos:
        found = _detections_of(photo, label)
        boxes = _truth_of(photo.image, label)
        scores += [d.score for d in found]
        found_boxes = np.array([d.bbox for d in found], dtype=float).reshape(-1, 4)
        hits.append(match(found_boxes, np.array([d.score for d in found]), boxes) >= 0)
        truth += len(boxes)
    return Tally(np.array(scores, dtype=float), np.concatenate(hits) if hits else np.zeros(0, dtype=bool), truth)


def ap50(photos: Sequence[Searched], label: str | None = None) -> float | None:
    """AP at IoU 0.5 by pycocotools' COCOeval (useCats=0: one kind of box, the class's or all); None without labelled boxes."""
    from pycocotools.coco import COCO
    from pycocotools.cocoeval import COCOeval

    truth, results = [], []
    for photo in photos:
        for x0, y0, x1, y1 in _truth_of(photo.image, label).tolist():
            truth.append({"id": len(truth) + 1, "image_id": photo.image.id, "category_id": 1, "iscrowd": 0,
                          "bbox": [x0, y0, x1 - x0, y1 - y0], "area": (x1 - x0) * (y1 - y0)})
        for d in _detections_of(photo, label):
            x0, y0, x1, y1 = d.bbox
            results.append({"image_id": photo.image.id, "category_id": 1, "bbox": [x0, y0, x1 - x0, y1 - y0], "score": d.score})
    if not truth:
        return None
    if not results:
        return 0.0
    with contextlib.redirect_stdout(io.StringIO()):  # pycocotools prints its progress
        ground = COCO()
        ground.dataset = {"images": [{"id": p.image.id, "width": p.image.width, "height": p.image.height} for p in photos],
                          "annotations": truth, "categories": [{"id": 1, "name": label or "pepper"}]}
        ground.createIndex()
        evaluation = COCOeval(ground, ground.loadRes(results), "bbox")
        evaluation.params.iouThrs = np.array([MATCH_IOU])
        evaluation.params.useCats = 0
        evaluation.evaluate()
        evaluation.accumulate()
    precision = evaluation.eval["precision"][0, :, 0, 0, -1]  # IoU 0.5, every recall step, all areas, 100 detections
    precision = precision[precision > -1]
    return round(float(precision.mean()), 5) if precision.size else 0.0


# --- the record -----------------------------------------------------------------------------------------------------

class ClassScore(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)
    boxes: int  # labelled
    at_threshold: Figures
    best_f1: Figures  # the point of the curve with the highest F1 (the lowest threshold among equals)
    ap50: float | None
    curve: list[Figures]  # thresholds PASS_FLOOR..0.95 step 0.01


class PhotoScore(BaseModel):
    """score.json: the detector on the user's labelled photos."""

    model_config = ConfigDict(extra="forbid", frozen=True)
    model: str
    folder: str
    coco: str
    threshold: float
    windows: list[str]
    mirror: bool
    match_iou: float
    search_floor: float
    images: int
    boxes: int  # labelled
    class_agnostic: ClassScore
    by_class: dict[str, ClassScore] | None  # ripe, unripe: only when every category names a ripeness


def class_score(photos: Sequence[Searched], threshold: float, label: str | None = None) -> ClassScore:
    counted = tally(photos, label)
    curve = [counted.at(t) for t in THRESHOLDS]
    best = max(curve, key=lambda f: f.f1)  # max keeps the first (lowest threshold) of equals
    return ClassScore(boxes=counted.truth, at_threshold=counted.at(threshold), best_f1=best, ap50=ap50(photos, label),
                      curve=curve)


def score(photos: Sequence[Searched], by_class: bool, model: Path, folder: Path, coco: Path,
          settings: DetectorConfig) -> PhotoScore:
    threshold = settings.score_threshold
    return PhotoScore(
        model=str(model), folder=str(folder), coco=str(coco), threshold=threshold, windows=layout_names(settings.layouts),
        mirror=settings.mirror, match_iou=MATCH_IOU, search_floor=min(PASS_FLOOR, threshold), images=len(photos),
        boxes=sum(len(p.image.boxes) for p in photos), class_agnostic=class_score(photos, threshold),
        by_class={label: class_score(photos, threshold, label) for label in CLASSES} if by_class else None)


# --- the verb -------------------------------------------------------------------------------------------------------

def sheet_picks(count: int, most: int = SHEET_IMAGES) -> list[int]:
    """Indices of up to `most` photos spread evenly over `count`, the first and the last among them."""
    return sorted({int(round(i)) for i in np.linspace(0, count - 1, min(count, most))}) if count else []


def check_out(out: Path, force: bool) -> None:
    """`out` may take a score: new, empty or one `score-photos` wrote; its old score is replaced only with `force`."""
    out = Path(out)
    ownership.claim(out, ownership.PHOTO_SCORE, write=False)
    if not out.is_dir():
        return
    listed = set(ownership.read_ledger(out))
    present = [name for name in OUTPUTS if (out / name).exists()]
    for name in present:
        if name not in listed:
            raise UserError(f"{_shown(out / name)}: exists and renderloop did not write it; "
                            "move it away or choose another directory")
    if present and not force:
        raise UserError(f"{_shown(out)}: exists; use --force to replace its score")


def search(labels: Labels, detector: Detector, floor: float, settings: DetectorConfig, picks: Sequence[int] = (),
           progress: Progress | None = None) -> tuple[list[Searched], dict[int, Image.Image]]:
    """Every photo's detections down to `floor` with the windows and mirror of `settings`, and the photos at `picks`
    (for the sheet)."""
    photos, kept = [], {}
    for index, image in enumerate(labels.images):
        if progress:
            progress(index, len(labels.images))
        rgb = read_image(image.path, "RGB")
        if rgb.shape[:2] != (image.height, image.width):  # the header said otherwise: a file that changed since
            raise UserError(f"{_shown(image.path)}: {rgb.shape[1]}x{rgb.shape[0]} pixels, "
                            f"but the labels say {image.width}x{image.height}")
        photos.append(Searched(image, detector.search(rgb, settings, floor)))
        if index in picks:
            kept[index] = Image.fromarray(rgb)
    if progress:
        progress(len(labels.images), len(labels.images))
    return photos, kept


def score_photos(folder: Path, coco: Path, out: Path, settings: DetectorConfig, force: bool = False,
                 progress: Progress | None = None) -> PhotoScore:
    """Search with the model, windows and mirror of `settings`, score at its threshold (and the curve around it), and
    write score.json, pr_curve.png and sheet.png into `out`; the record written."""
    from renderloop.perception.photo_plots import draw_photo_sheet, draw_pr_curve

    out = Path(out)
    check_out(out, force)
    labels = read_labels(coco, folder)
    detector = Detector(settings.model)
    picks = sheet_picks(len(labels.images))
    photos, shown = search(labels, detector, min(PASS_FLOOR, settings.score_threshold), settings, picks, progress)
    record = score(photos, labels.by_class, detector.path, Path(folder), Path(coco), settings)
    ownership.claim(out, ownership.PHOTO_SCORE)
    ownership.remove_recorded(out, OUTPUTS)  # the old score goes whole: never half of it beside the new one
    draw_pr_curve(record, out / PR_CURVE)
    draw_photo_sheet([(photos[i], shown[i]) for i in picks], settings.score_threshold, labels.by_class, out / SHEET)
    write_json(out / SCORE, record.model_dump(mode="json"))
    return record


def _ratio(value: float | None) -> str:
    return "n/a" if value is None else f"{value:.3f}"


def summary(record: PhotoScore) -> list[str]:
    """The lines the verb prints: the set, the figures at the threshold, AP@0.5 and the best F1 of the curve."""
    lines = [f"{record.images} photos, {record.boxes} labelled boxes"]
    scores = [("", record.class_agnostic), *((f"{label} ", s) for label, s in (record.by_class or {}).items())]
    for name, s in scores:
        f, best = s.at_threshold, s.best_f1
        lines.append(f"{name}at threshold {threshold_text(f.threshold)}: recall {_ratio(f.recall)} ({f.true_positives}/{s.boxes}), "
                     f"precision {_ratio(f.precision)} ({f.true_positives}/{f.true_positives + f.false_positives}), "
                     f"F1 {f.f1:.3f}; AP@0.5 {_ratio(s.ap50)}; best F1 {best.f1:.3f} at {threshold_text(best.threshold)} "
                     f"(recall {_ratio(best.recall)}, precision {_ratio(best.precision)})")
    return lines
