"""The detector quantized to int8: it finds what its float model finds, keeps what the float model says of itself, and
refuses what it cannot do in one line."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import onnx
import onnx.numpy_helper
import pytest

from conftest import cli
from renderloop.perception.boxes import box_iou
from renderloop.perception.detector import Detector, shipped_model
from renderloop.perception.training.from_onnx import onnx_metadata
from renderloop.perception.training.quantize import calibration_images, is_quantized, quantize_detector
from renderloop.render.frames import read_frame
from renderloop.rundir.files import read_poses


@pytest.fixture(scope="module")
def quantized(complete_run: Path, tmp_path_factory) -> tuple[Path, list[np.ndarray]]:
    """The shipped detector quantized on the even frames of a flown run (raster frames of the demo greenhouse); the
    odd frames are the ones it is compared on."""
    frames = [read_frame(complete_run, index).rgb for index in range(len(read_poses(complete_run)[0]))]
    out = tmp_path_factory.mktemp("int8") / "int8.onnx"
    return quantize_detector(shipped_model(), frames[::2], out, "the test's frames"), frames[1::2]


def test_a_quantized_detector_finds_the_fruit_its_float_model_finds(quantized):
    path, frames = quantized
    model = onnx.load(str(path))
    assert any(node.op_type == "QLinearConv" for node in model.graph.node)
    assert not any(node.op_type == "Conv" for node in model.graph.node)
    float_model, int8_model = Detector(), Detector(path)
    assert int8_model.input_size == float_model.input_size
    found = kept = 0
    for frame in frames:
        before, after = (np.array([d.bbox for d in model.detect(frame, 0.5)]).reshape(-1, 4)
                         for model in (float_model, int8_model))
        found += len(before)
        if len(before) and len(after):
            kept += int((box_iou(before, after).max(axis=1) >= 0.5).sum())
        assert abs(len(after) - len(before)) <= max(1, len(before) // 5)
    assert found >= 10 and kept >= 0.9 * found


def test_a_quantized_detectors_weights_fit_in_seven_bits_so_no_cpus_integer_kernel_overflows(quantized):
    # Without AVX-512 VNNI, ONNX Runtime sums each pair of uint8 x int8 products in 16 bits: full-range weights overflow
    # it, and the same model found other fruit (or none) on such a CPU than on this one.
    path, _ = quantized
    model = onnx.load(str(path))
    weights = {node.input[3] for node in model.graph.node if node.op_type == "QLinearConv"}
    tensors = [onnx.numpy_helper.to_array(tensor) for tensor in model.graph.initializer if tensor.name in weights]
    assert len(tensors) == len(weights) > 10
    assert all(tensor.dtype == np.int8 and np.abs(tensor).max() <= 64 for tensor in tensors)  # 255 x 64 x 2 < 32767
    assert max(int(np.abs(tensor).max()) for tensor in tensors) == 64  # the 7 bits are used, not squeezed further


def test_a_quantized_detector_says_what_it_was_made_from(quantized):
    path, _ = quantized
    before, after = onnx_metadata(shipped_model()), onnx_metadata(path)
    assert is_quantized(path) and not is_quantized(shipped_model())
    assert {key: value for key, value in after.items() if key != "quantized"} == before
    assert after["quantized"] == "int8, the test's frames"


def test_the_calibration_renders_are_drawn_from_the_seed(tiny_dataset: Path):
    first, again = calibration_images([tiny_dataset], 4, seed=3), calibration_images([tiny_dataset], 4, seed=3)
    assert first == again and len(set(first)) == 4
    assert calibration_images([tiny_dataset], 4, seed=4) != first
    every = calibration_images([tiny_dataset], 100, seed=3)
    assert sorted(every) == sorted((tiny_dataset / "images").glob("train*.jpg"))


def test_quantizing_refuses_in_one_line_and_touches_nothing(quantized, tiny_dataset: Path, tmp_path: Path, monkeypatch,
                                                           capsys):
    path, _ = quantized
    mine = tmp_path / "mine.onnx"
    mine.write_bytes(b"a user's file")
    cases = [(["quantize", "shipped", str(tiny_dataset), "--out", str(mine)],
              f"--out {mine}: exists; give another --out, or --force to replace it"),
             (["quantize", str(path), str(tiny_dataset), "--out", str(tmp_path / "twice.onnx")],
              f"{path}: already quantized"),
             (["train", str(tiny_dataset), "--init", str(path), "--out", str(tmp_path / "tuned.onnx")],
              f"--init {path}: quantized (int8, the test's frames), its float weights are gone; fine-tune the float "
              "model it was made from")]
    for args, message in cases:
        code, _, stderr = cli(monkeypatch, capsys, *args)
        assert code == 2 and stderr.strip().splitlines() == [f"renderloop: error: {message}"]
    assert mine.read_bytes() == b"a user's file"
    assert sorted(item.name for item in tmp_path.iterdir()) == ["mine.onnx"]


def test_quantize_force_replaces_the_file_at_out_with_the_int8_model(tiny_dataset: Path, tmp_path: Path, monkeypatch,
                                                                      capsys):
    out = tmp_path / "int8.onnx"
    out.write_bytes(b"an older model")
    code, stdout, _ = cli(monkeypatch, capsys, "quantize", "shipped", str(tiny_dataset), "--out", str(out), "--images", "4",
                          "--force")
    assert code == 0 and stdout.strip() == f"quantize: wrote {out}"
    assert onnx_metadata(out)["quantized"] == "int8, 4 calibration renders drawn with seed 0"
    assert Detector(out).input_size == Detector().input_size
