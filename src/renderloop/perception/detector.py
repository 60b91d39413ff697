"""The pepper detector at inference time: ONNX Runtime and numpy, no torch.

Post-processing mirrors torchvision's SSD (`postprocess_detections`): per class,
scores above a floor, the top 300 candidates, class-wise NMS at IoU 0.55, at most
300 detections; then the caller's score threshold. Frames of any size are resized
to the network input with PIL's antialiased bilinear filter (a 640x480 frame then
looks like the renders the network was trained on at that input) and boxes are scaled back.
The input is square, 320 px unless the network trained at a larger one or was exported for
another (`training.ssd`); the detector reads it from the model file.
With window `layouts` the frame's overlapping windows are searched as well (`tiling`), with
`mirror` the frame mirrored left to right (a second look at the same pixels that errs
elsewhere: the network is not exactly symmetric), and what the passes found is merged
(`fusion`). The windows are not mirrored: that costs a pass a window and finds no more fruit at the
same rate of false detections (docs/stages/perception.md).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from importlib import resources
from pathlib import Path

import numpy as np
from PIL import Image

from renderloop.config.perception import MAX_ENLARGEMENT, DetectorConfig
from renderloop.config.training import INPUT_SIZE, INPUT_SIZES
from renderloop.errors import UserError
from renderloop.perception.boxes import nms, shorter_side
from renderloop.perception.fusion import fuse
from renderloop.perception.tiling import Layout, all_windows, cut_by_window

CLASSES = ("ripe", "unripe")
NMS_IOU = 0.55
TOPK_CANDIDATES = 300
MAX_DETECTIONS = 300
SCORE_FLOOR = 0.01  # torchvision's score_thresh: candidates below it never reach NMS
PASS_FLOOR = 0.1  # with windows, each pass's boxes down to this score are merged: weak ones that agree add up
SHIPPED_MODEL = "pepper_ssdlite.onnx"


@dataclass(frozen=True)
class Detection:
    bbox: tuple[float, float, float, float]  # x0, y0, x1, y1 in pixels of the frame
    score: float
    label: str

    def to_json(self) -> dict:
        return {"bbox": [round(v, 2) for v in self.bbox], "score": round(self.score, 5), "label": self.label}


def shipped_model() -> Path:
    return Path(str(resources.files("renderloop.perception").joinpath("model", SHIPPED_MODEL)))


def postprocess(boxes: np.ndarray, scores: np.ndarray, width: int, height: int, score_threshold: float,
                input_size: int = INPUT_SIZE) -> list[Detection]:
    """Network outputs (boxes in pixels of its `input_size` square input, (A, 4); class probabilities,
    (A, 1 + classes)) to detections in pixels of a `width` x `height` frame. NMS runs in float32 in the
    input's pixels, as torchvision's does, so that borderline overlaps are decided the same way.

    Boxes under `score_threshold` are dropped before NMS, not after: a box is only ever
    suppressed by a higher-scoring one, so the detections above the threshold are the
    same, and NMS then runs over tens of boxes instead of hundreds."""
    boxes, scores = boxes.astype(np.float32), scores.astype(np.float32)
    candidates = []
    for label in range(1, scores.shape[1]):
        index = np.nonzero((scores[:, label] > SCORE_FLOOR) & (scores[:, label] >= score_threshold))[0]
        index = index[np.argsort(-scores[index, label], kind="stable")[:TOPK_CANDIDATES]]
        candidates.append((index, np.full(len(index), label)))
    index = np.concatenate([c[0] for c in candidates])
    labels = np.concatenate([c[1] for c in candidates])
    if len(index) == 0:
        return []
    cand_boxes, cand_scores = boxes[index], scores[index, labels]
    # class-wise NMS in one pass: boxes of different classes are moved apart so they never overlap (torchvision's trick)
    offsets = (labels[:, None] * (cand_boxes.max() + 1.0)).astype(np.float32)
    keep = nms(cand_boxes + offsets, cand_scores, NMS_IOU)[:MAX_DETECTIONS]
    scale = np.array([width, height, width, height], dtype=np.float64) / input_size
    return [Detection(tuple(float(v) for v in cand_boxes[k] * scale), float(cand_scores[k]), CLASSES[labels[k] - 1])
            for k in keep]


def contract_breach(boxes: np.ndarray, scores: np.ndarray) -> str | None:
    """What is wrong with a network's outputs on a frame, None when they keep the contract: boxes (A, 4) and scores
    (A, 1 + classes) probabilities, background first, both float32 and finite."""
    classes = 1 + len(CLASSES)
    if boxes.dtype != np.float32 or scores.dtype != np.float32:
        return f"outputs are {boxes.dtype} (boxes) and {scores.dtype} (scores), not float32"
    if boxes.ndim != 2 or boxes.shape[1] != 4:
        return f"output boxes has shape {list(boxes.shape)}, not [A, 4]"
    if scores.ndim != 2:
        return f"output scores has shape {list(scores.shape)}, not [A, {classes}]"
    if scores.shape[1] != classes:
        return f"output scores has {scores.shape[1]} columns, not {classes} (background, {', '.join(CLASSES)})"
    if len(boxes) != len(scores) or len(boxes) == 0:
        return f"outputs boxes and scores have {len(boxes)} and {len(scores)} rows, not one per anchor"
    if not np.isfinite(boxes).all() or not np.isfinite(scores).all():
        return "outputs hold NaN or infinite values on a grey frame"
    if scores.min() < 0.0 or scores.max() > 1.0 + 1e-5:
        return f"output scores range {scores.min():g} to {scores.max():g}, not probabilities in [0, 1]"
    return None


def to_input(rgb: np.ndarray, size: int = INPUT_SIZE) -> np.ndarray:
    """(H, W, 3) uint8 to the network's (1, 3, size, size) float32 in [0, 1]."""
    image = Image.fromarray(rgb)
    if image.size != (size, size):
        image = image.resize((size, size), Image.BILINEAR)
    return (np.asarray(image, dtype=np.float32) / 255.0).transpose(2, 0, 1)[None]


class Detector:
    """An ONNX pepper detector; a file that is not one, or whose outputs break the contract on a probe frame, is a
    one-line UserError naming it. The one loader: every stage and `renderloop run`'s check of its inputs build this."""

    def __init__(self, model: Path | None = None, threads: int = 0) -> None:
        import onnxruntime as ort

        self.path = Path(model) if model is not None else shipped_model()
        options = ort.SessionOptions()
        options.intra_op_num_threads = threads
        # Idle pool threads sleep rather than spin: a pass alone is as fast, and beside other busy processes (an eval's
        # workers, a renderer) spinning threads take the cores the others wait for.
        options.add_session_config_entry("session.intra_op.allow_spinning", "0")
        options.log_severity_level = 3
        try:
            self.session = ort.InferenceSession(str(self.path), options, providers=["CPUExecutionProvider"])
        except Exception as error:  # ORT raises its own exception types for unreadable files
            if not self.path.is_file():
                raise UserError(f"{self.path}: no such model file") from None
            raise UserError(f"{self.path}: not an ONNX model ({str(error).splitlines()[0][:120]})") from None
        inputs = [(i.name, i.shape) for i in self.session.get_inputs()]
        outputs = [o.name for o in self.session.get_outputs()]
        size = inputs[0][1][-1] if len(inputs) == 1 and len(inputs[0][1]) == 4 else None
        if inputs != [("images", [1, 3, size, size])] or size not in INPUT_SIZES or outputs != ["boxes", "scores"]:
            raise UserError(f"{self.path}: not a renderloop pepper detector (inputs {inputs}, outputs {outputs})")
        self.input_size: int = size
        if self.session.get_inputs()[0].type != "tensor(float)":
            raise UserError(f"{self.path}: not a renderloop pepper detector (input images is "
                            f"{self.session.get_inputs()[0].type}, not float32)")
        self._probe()

    def _probe(self) -> None:
        """One pass on a grey frame, its outputs held to the contract (perception/training/ssd.py): a model that
        breaks it is refused here, at load, not by an IndexError or a NaN in detections.json hours into a run."""
        grey = np.full((1, 3, self.input_size, self.input_size), 0.5, dtype=np.float32)
        try:
            boxes, scores = self.session.run(None, {"images": grey})
        except Exception as error:  # ORT's own exception types: a graph that cannot run on its declared input
            raise UserError(f"{self.path}: the model fails on a grey frame ({str(error).splitlines()[0][:120]})") from None
        wrong = contract_breach(np.asarray(boxes), np.asarray(scores))
        if wrong:
            raise UserError(f"{self.path}: not a renderloop pepper detector ({wrong})")

    def raw(self, rgb: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        boxes, scores = self.session.run(None, {"images": to_input(rgb, self.input_size)})
        return boxes, scores

    def search(self, rgb: np.ndarray, settings: DetectorConfig, score_threshold: float | None = None) -> list[Detection]:
        """`detect` with the windows, mirror and smallest box of `settings`, at its threshold unless one is given."""
        threshold = settings.score_threshold if score_threshold is None else score_threshold
        return self.detect(rgb, threshold, settings.layouts, settings.mirror, settings.min_box_px,
                           settings.max_window_enlargement)

    def detect(self, rgb: np.ndarray, score_threshold: float, layouts: Sequence[Layout] = (), mirror: bool = False,
               min_side: float = 0.0, max_enlargement: float = MAX_ENLARGEMENT) -> list[Detection]:
        """Detections in the whole frame, with `mirror` in the frame mirrored left to right too, and in the
        overlapping windows of each (columns, rows) layout the input enlarges at most `max_enlargement` times; the
        passes merged; boxes whose shorter side is under `min_side` px dropped."""
        if rgb.ndim != 3 or rgb.shape[2] != 3 or rgb.dtype != np.uint8:
            raise ValueError(f"expected an (H, W, 3) uint8 RGB image, got {rgb.shape} {rgb.dtype}")
        height, width = rgb.shape[:2]
        whole = (0, 0, width, height)
        passes = [(whole, False), *([(whole, True)] if mirror else []),
                  *((window, False) for window in all_windows(width, height, layouts, self.input_size, max_enlargement))]
        found = self._detect_once(rgb, score_threshold) if len(passes) == 1 else self._fused(rgb, passes, score_threshold)
        return [detection for detection in found if shorter_side(detection.bbox) >= min_side][:MAX_DETECTIONS]

    def _fused(self, rgb: np.ndarray, passes: list[tuple[tuple[int, int, int, int], bool]], score_threshold: float
               ) -> list[Detection]:
        """What the passes (a region of the frame, mirrored or not) found, merged, at `score_threshold`."""
        height, width = rgb.shape[:2]
        floor = min(PASS_FLOOR, score_threshold)
        found = []
        for number, ((x0, y0, x1, y1), mirrored) in enumerate(passes):
            view = rgb[y0:y1, x0:x1, :]
            for detection in self._detect_once(np.ascontiguousarray(view[:, ::-1] if mirrored else view), floor):
                a, b, c, d = detection.bbox
                if mirrored:
                    a, c = (x1 - x0) - c, (x1 - x0) - a
                box = (a + x0, b + y0, c + x0, d + y0)
                if not cut_by_window(box, (x0, y0, x1, y1), width, height):  # never true of the whole frame
                    found.append((number, Detection(box, detection.score, detection.label)))
        if not found:
            return []
        leaders, scores = fuse(np.array([d.bbox for _, d in found]), np.array([d.score for _, d in found]),
                               np.array([number for number, _ in found]))
        return [Detection(found[k][1].bbox, float(score), found[k][1].label)
                for k, score in zip(leaders, scores, strict=True) if score >= score_threshold]

    def _detect_once(self, rgb: np.ndarray, score_threshold: float) -> list[Detection]:
        boxes, scores = self.raw(rgb)
        return postprocess(boxes, scores, rgb.shape[1], rgb.shape[0], score_threshold, self.input_size)
