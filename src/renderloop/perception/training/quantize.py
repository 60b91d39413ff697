"""A detector quantized to 8-bit integers, for ONNX Runtime's integer kernels on the CPU.

Static quantization (`onnxruntime.quantization`): each convolution's weights become int8 (in 7 bits, so that no
CPU's integer kernel overflows), per output channel, and the activations between layers uint8, with each tensor's
range measured once on calibration images: renders drawn from the training splits of datasets made by `renderloop
dataset`, as the network sees them (the frame scaled to its input). The graph is written in operator form
(QLinearConv and its kin), which ONNX Runtime runs on its integer kernels. That pays for a network built as the
EfficientNet-Lite family is, for integer use (ReLU6, no squeeze-excitation): about twice as fast on one core.
MobileNetV3's hard-swish and squeeze-excitation stay in floating point between quantized convolutions, so it gains
nothing (`docs/stages/perception.md`).

The quantized file keeps the float model's metadata and adds `quantized`; it detects like any renderloop model but
cannot be fine-tuned: fine-tune the float model it was made from, then quantize again.
"""

from __future__ import annotations

import tempfile
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from renderloop.errors import UserError
from renderloop.io.atomic import atomic_path
from renderloop.io.images import open_image
from renderloop.perception.detector import Detector, to_input
from renderloop.perception.training.from_onnx import check_model_out, onnx_metadata, set_metadata

__all__ = ["QUANTIZED", "calibration_images", "is_quantized", "quantize_detector", "quantize_on_renders"]

QUANTIZED = "quantized"  # the metadata key a quantized model carries: how it was calibrated


def is_quantized(path: Path) -> bool:
    """Whether the renderloop ONNX model at `path` was made by `quantize_detector`."""
    return QUANTIZED in onnx_metadata(path)


def calibration_images(datasets: list[Path], count: int, seed: int) -> list[Path]:
    """`count` images drawn without replacement, with `seed`, from the training splits of `datasets` together, in
    the order they were drawn (fewer when the splits hold fewer)."""
    from renderloop.perception.training.data import read_coco

    files = [Path(dataset) / image["file_name"] for dataset in datasets
             for image in read_coco(Path(dataset) / "annotations" / "instances_train.json")["images"]]
    if not files:
        raise UserError(f"{', '.join(map(str, datasets))}: no training images to calibrate on")
    chosen = np.random.default_rng(seed).choice(len(files), size=min(count, len(files)), replace=False)
    return [files[index] for index in chosen]


def quantize_detector(model: Path, frames: Sequence[np.ndarray], out: Path, calibration: str, force: bool = False) -> Path:
    """Write `model` quantized to int8 at `out` (replacing a file there only with `force`), each tensor's range
    measured on `frames` ((H, W, 3) uint8 RGB, as the detector is given them), which `calibration` says in words in
    the model's metadata."""
    import onnx
    from onnxruntime.quantization import CalibrationDataReader, QuantFormat, QuantType, quantize_static
    from onnxruntime.quantization.shape_inference import quant_pre_process

    model, out = Path(model), Path(out)
    check_model_out(out, force)
    size = Detector(model).input_size  # a file that is not a renderloop detector is refused here, in one line
    if is_quantized(model):
        raise UserError(f"{model}: already quantized")

    class Inputs(CalibrationDataReader):
        def __init__(self) -> None:
            self.frames = iter(frames)

        def get_next(self) -> dict | None:
            frame = next(self.frames, None)
            return None if frame is None else {"images": to_input(frame, size)}

    with tempfile.TemporaryDirectory() as scratch, atomic_path(out) as tmp:
        prepared = Path(scratch) / "prepared.onnx"  # shapes inferred and the graph simplified, as quantizing needs
        quant_pre_process(str(model), str(prepared))
        # reduce_range: weights in 7 bits. Without AVX-512 VNNI, ONNX Runtime multiplies uint8 by int8 with an
        # instruction that sums each pair into 16 bits, which full-range weights overflow (255 x 127 x 2 > 32767): the
        # model would detect on one CPU and find nothing on another.
        quantize_static(str(prepared), str(tmp), Inputs(), quant_format=QuantFormat.QOperator, per_channel=True,
                        reduce_range=True, activation_type=QuantType.QUInt8, weight_type=QuantType.QInt8)
        graph = onnx.load(str(tmp))
        # the float model's, without what the quantizer's own passes added
        set_metadata(graph, {**onnx_metadata(model), QUANTIZED: f"int8, {calibration}"})
        onnx.save(graph, str(tmp))
        Detector(tmp)  # the contract holds on the quantized graph too (a grey frame's outputs are probabilities)
    return out


def quantize_on_renders(model: Path, datasets: list[Path], out: Path, images: int = 64, seed: int = 0,
                        force: bool = False) -> Path:
    """`quantize_detector` calibrated on `images` renders drawn with `seed` from `datasets`' training splits."""
    chosen = calibration_images(datasets, images, seed)
    frames = [np.asarray(open_image(path, "RGB")) for path in chosen]
    return quantize_detector(model, frames, out, f"{len(chosen)} calibration renders drawn with seed {seed}", force)
