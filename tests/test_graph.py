"""The exported graph's zero padding folded into its convolutions: the same outputs to the bit, no Pad left."""

from __future__ import annotations

import numpy as np
import onnx
import onnxruntime as ort
from onnx import TensorProto, helper, numpy_helper

from renderloop.perception.training.graph import fold_pads


def _run(model: onnx.ModelProto, x: np.ndarray) -> list[np.ndarray]:
    session = ort.InferenceSession(model.SerializeToString(), providers=["CPUExecutionProvider"])
    return session.run(None, {"x": x})


def _padded_graph() -> onnx.ModelProto:
    """x -> Pad (zeros, 0 before and 1 after in height and width, its pads computed from constants as torch's exporter
    writes them) -> strided Conv -> a; x -> Pad of ones -> Conv -> b; x -> Pad of zeros -> Relu -> c."""
    rng = np.random.default_rng(0)
    weight = numpy_helper.from_array(rng.standard_normal((4, 2, 3, 3)).astype(np.float32), "w")
    nodes = [
        helper.make_node("Constant", [], ["raw"], value=numpy_helper.from_array(np.array([0, 0, 0, 0, 0, 0, 1, 1], np.int32))),
        helper.make_node("Cast", ["raw"], ["pads"], to=TensorProto.INT64),
        helper.make_node("Pad", ["x", "pads"], ["padded"], mode="constant"),
        helper.make_node("Conv", ["padded", "w"], ["a"], strides=[2, 2], pads=[1, 0, 1, 0]),
        helper.make_node("Constant", [], ["one"], value=numpy_helper.from_array(np.array(1.0, np.float32))),
        helper.make_node("Pad", ["x", "pads", "one"], ["padded_ones"], mode="constant"),
        helper.make_node("Conv", ["padded_ones", "w"], ["b"], strides=[2, 2]),
        helper.make_node("Pad", ["x", "pads"], ["padded_again"], mode="constant"),
        helper.make_node("Relu", ["padded_again"], ["c"]),
    ]
    outputs = [helper.make_tensor_value_info(name, TensorProto.FLOAT, None) for name in "abc"]
    graph = helper.make_graph(nodes, "padded", [helper.make_tensor_value_info("x", TensorProto.FLOAT, [1, 2, 8, 8])],
                              outputs, [weight])
    return helper.make_model(graph, opset_imports=[helper.make_opsetid("", 17)])


def test_a_pad_of_zeros_read_by_a_convolution_becomes_its_padding_and_nothing_else_changes():
    model = _padded_graph()
    x = np.random.default_rng(1).standard_normal((1, 2, 8, 8)).astype(np.float32)
    before = _run(model, x)
    assert fold_pads(model) == 1
    after = _run(model, x)
    assert all(np.array_equal(got, want) for got, want in zip(after, before, strict=True))  # to the bit
    convs = [node for node in model.graph.node if node.op_type == "Conv"]
    assert [list(next(a.ints for a in conv.attribute if a.name == "pads")) for conv in convs[:1]] == [[1, 0, 2, 1]]
    # the Pad of ones and the Pad a Relu reads stay; the constants only the folded Pad read stay for the others
    assert [node.op_type for node in model.graph.node].count("Pad") == 2

