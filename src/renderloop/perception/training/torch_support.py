"""Import torchvision on a CPU-only torch.

PyPI's torchvision wheels are CUDA builds: next to the CPU build of torch (the one
this project's machines install) their compiled ops fail to load, and torchvision
0.28 then fails at import, because it registers a fake kernel for `torchvision::nms`
that was never defined. The detector needs only one of those ops, non-maximum
suppression (in SSD's post-processing), so when the compiled ops are missing this
module defines `torchvision::nms` with a plain torch implementation before the
import. Where the compiled ops load (a CUDA machine, a matching CPU build) nothing
is replaced.
"""

from __future__ import annotations

import importlib.util
from pathlib import Path
from types import ModuleType

import torch

_shim: torch.library.Library | None = None


def _compiled_ops_load() -> bool:
    spec = importlib.util.find_spec("torchvision")
    if spec is None or spec.origin is None:
        raise ImportError("torchvision is not installed (pip install 'renderloop[train]')")
    library = next(Path(spec.origin).parent.glob("_C*.so"), None)
    if library is None:
        return False
    try:
        torch.ops.load_library(str(library))
        return True
    except (OSError, RuntimeError):
        return False


def nms_reference(boxes: torch.Tensor, scores: torch.Tensor, iou_threshold: float) -> torch.Tensor:
    """Greedy NMS, torchvision's contract: indices of kept boxes by decreasing score."""
    order = scores.argsort(descending=True, stable=True)
    ordered = boxes[order]
    area = (ordered[:, 2] - ordered[:, 0]).clamp(min=0) * (ordered[:, 3] - ordered[:, 1]).clamp(min=0)
    top_left = torch.maximum(ordered[:, None, :2], ordered[None, :, :2])
    bottom_right = torch.minimum(ordered[:, None, 2:], ordered[None, :, 2:])
    inter = (bottom_right - top_left).clamp(min=0).prod(-1)
    iou = inter / (area[:, None] + area[None, :] - inter).clamp(min=1e-12)
    keep = torch.ones(len(ordered), dtype=torch.bool)
    for i in range(len(ordered)):
        if keep[i]:
            keep[i + 1 :] &= iou[i, i + 1 :] <= iou_threshold
    return order[keep]


def import_torchvision() -> ModuleType:
    global _shim
    if _shim is None and not _compiled_ops_load():
        _shim = torch.library.Library("torchvision", "DEF")
        _shim.define("nms(Tensor dets, Tensor scores, float iou_threshold) -> Tensor")
        _shim.define("qnms(Tensor dets, Tensor scores, float iou_threshold) -> Tensor")  # declared only: torchvision registers a fake kernel for it
        _shim.impl("nms", nms_reference, "CPU")
    import torchvision
    import torchvision.extension

    if _shim is not None:
        torchvision.extension._has_ops = lambda: True  # nms now exists; the other ops are never called by SSD
    return torchvision
