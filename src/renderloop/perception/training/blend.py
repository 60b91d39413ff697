"""Two detectors of one network blended weight by weight: (1 - share) x first + share x second.

A fine-tune that trains the ImageNet backbone on renders learns the renders and forgets some
of what made it find real fruit. Averaging its weights with those of the model it was trained
on from (Wortsman et al. 2022, "Robust fine-tuning of zero-shot models", WiSE-FT) keeps much
of both: on the model card's steps 49 and 51 the half-way blend keeps nearly all of step 49's
score on real photos and more than half of step 51's gain on the renders, at no cost in
training or at run time (one network, as before). It is meaningful only where one model was
trained on from the other, so that both lie in one basin of the loss; the graphs must match
node for node and tensor for tensor, which two models of one training lineage exported by
`renderloop train` do. A quantized model has no float weights to average: blend the float
models, then quantize.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from renderloop.errors import UserError
from renderloop.io.atomic import atomic_path
from renderloop.perception.detector import Detector
from renderloop.perception.training.from_onnx import check_model_out, onnx_metadata, set_metadata
from renderloop.perception.training.quantize import is_quantized

__all__ = ["BLEND", "blend_detectors"]

BLEND = "blend"  # the metadata key a blended model carries: what it was made of


def _different(first, second) -> str | None:
    """Where two ONNX graphs differ as networks (their nodes or their tensors' names, shapes and types), or None."""
    if len(first.node) != len(second.node):
        return f"{len(first.node)} nodes against {len(second.node)}"
    for number, (a, b) in enumerate(zip(first.node, second.node)):
        if (a.op_type, list(a.input), list(a.output)) != (b.op_type, list(b.input), list(b.output)):
            return f"node {number} is {a.op_type} against {b.op_type}" if a.op_type != b.op_type else f"node {number} ({a.op_type}) is wired differently"
    ours = {tensor.name: (tuple(tensor.dims), tensor.data_type) for tensor in first.initializer}
    theirs = {tensor.name: (tuple(tensor.dims), tensor.data_type) for tensor in second.initializer}
    for name in sorted(ours.keys() | theirs.keys()):
        if ours.get(name) != theirs.get(name):
            return f"tensor {name} differs in shape or type" if name in ours and name in theirs else f"tensor {name} is in one only"
    return None


def blend_detectors(first: Path, second: Path, share: float, out: Path, force: bool = False) -> Path:
    """Write at `out` the detector whose every float weight is (1 - share) x `first`'s + share x `second`'s, with
    `first`'s metadata and a `blend` entry saying what it was made of (replacing a file at `out` only with `force`)."""
    import onnx
    from onnx import numpy_helper

    first, second, out = Path(first), Path(second), Path(out)
    if not 0.0 <= share <= 1.0:
        raise UserError(f"--share {share}: must lie in [0, 1]")
    check_model_out(out, force)
    for path in (first, second):
        Detector(path)  # a file that is not a renderloop detector is refused here, in one line
        if is_quantized(path):
            raise UserError(f"{path}: quantized, its float weights are gone; blend the float models, then quantize")
    model, other = onnx.load(str(first)), onnx.load(str(second))
    wrong = _different(model.graph, other.graph)
    if wrong is None and onnx_metadata(first).get("renderloop_detector") != onnx_metadata(second).get("renderloop_detector"):
        wrong = "other detector names"
    if wrong:
        raise UserError(f"{second}: not the network of {first} ({wrong}); blend a model with one trained on from it")
    theirs = {tensor.name: numpy_helper.to_array(tensor) for tensor in other.graph.initializer}
    for tensor in model.graph.initializer:
        ours = numpy_helper.to_array(tensor)
        if np.issubdtype(ours.dtype, np.floating):  # integer tensors (shapes, indices) are the network's, not weights
            mixed = (1.0 - share) * ours.astype(np.float64) + share * theirs[tensor.name].astype(np.float64)
            tensor.CopyFrom(numpy_helper.from_array(mixed.astype(ours.dtype), tensor.name))
    set_metadata(model, {**onnx_metadata(first), BLEND: f"{1.0 - share:g} x {first.name} + {share:g} x {second.name}"})
    with atomic_path(out) as tmp:
        onnx.save(model, str(tmp))
        Detector(tmp)  # the contract holds on the blend too (a grey frame's outputs are probabilities)
    return out
