"""Two detectors of one network blended weight by weight (`renderloop blend`): every float weight the share's mix, the
ends of the share the models themselves, and two networks that differ refused in one line."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import onnx
import onnx.numpy_helper
import pytest

from conftest import cli, jittered_model
from renderloop.perception.detector import Detector
from renderloop.perception.training.from_onnx import onnx_metadata
from renderloop.perception.training.ssd import export_onnx


@pytest.fixture(scope="module")
def pair(tmp_path_factory) -> tuple[Path, Path]:
    """Two models of one network with different weights, as a fine-tune and the model it started from are."""
    folder = tmp_path_factory.mktemp("pair")
    first, second = folder / "first.onnx", folder / "second.onnx"
    export_onnx(jittered_model(1), first)
    export_onnx(jittered_model(2), second)
    return first, second


def weights(path: Path) -> dict[str, np.ndarray]:
    return {tensor.name: onnx.numpy_helper.to_array(tensor) for tensor in onnx.load(str(path)).graph.initializer}


def test_every_float_weight_of_a_blend_is_the_shares_mix_of_the_two_models(pair, tmp_path: Path, monkeypatch, capsys):
    first, second = pair
    out = tmp_path / "blend.onnx"
    code, stdout, _ = cli(monkeypatch, capsys, "blend", str(first), str(second), "--share", "0.25", "--out", str(out))
    assert code == 0 and stdout.strip() == f"blend: wrote {out}"
    ours, theirs, mixed = weights(first), weights(second), weights(out)
    assert ours.keys() == mixed.keys()
    moved = 0
    for name, value in mixed.items():
        if np.issubdtype(value.dtype, np.floating):
            np.testing.assert_allclose(value, 0.75 * ours[name] + 0.25 * theirs[name], rtol=1e-6, atol=1e-7)
            moved += not np.array_equal(value, ours[name])
        else:
            np.testing.assert_array_equal(value, ours[name])
    assert moved > 100  # the weights, not a few constants
    assert onnx_metadata(out) == {**onnx_metadata(first), "blend": "0.75 x first.onnx + 0.25 x second.onnx"}


def test_a_blend_at_either_end_of_the_share_detects_as_that_model_does(pair, tmp_path: Path):
    from renderloop.perception.training.blend import blend_detectors

    rgb = np.random.default_rng(0).integers(0, 256, (120, 160, 3), dtype=np.uint8)
    for share, model in ((0.0, pair[0]), (1.0, pair[1])):
        made = blend_detectors(*pair, share, tmp_path / f"end_{share}.onnx")
        for got, want in zip(Detector(made).raw(rgb), Detector(model).raw(rgb)):
            np.testing.assert_allclose(got, want, rtol=1e-5, atol=1e-6)


def test_blending_two_networks_that_differ_refuses_in_one_line_and_touches_nothing(pair, tmp_path: Path, monkeypatch,
                                                                                   capsys):
    first, _ = pair
    other = tmp_path / "other.onnx"
    export_onnx(jittered_model(3, "mobilenet-v3"), other)
    mine = tmp_path / "mine.onnx"
    mine.write_bytes(b"a user's file")
    nodes = (len(onnx.load(str(first)).graph.node), len(onnx.load(str(other)).graph.node))
    cases = [(["blend", str(first), str(other), "--out", str(tmp_path / "b.onnx")],
              f"{other}: not the network of {first} ({nodes[0]} nodes against {nodes[1]}); blend a model with one "
              "trained on from it"),
             (["blend", str(first), str(first), "--out", str(mine)],
              f"--out {mine}: exists; give another --out, or --force to replace it"),
             (["blend", str(first), str(mine), "--out", str(tmp_path / "b.onnx")], None)]
    for args, message in cases:
        code, _, stderr = cli(monkeypatch, capsys, *args)
        lines = stderr.strip().splitlines()
        assert code == 2 and len(lines) == 1 and lines[0].startswith(f"renderloop: error: {message or mine}")
    assert mine.read_bytes() == b"a user's file"
    assert sorted(item.name for item in tmp_path.iterdir()) == ["mine.onnx", "other.onnx"]
