"""The exported ONNX graph made faster to run, its function unchanged: zero padding folded into the convolutions.

EfficientNet-Lite's strided convolutions pad TensorFlow's way, one pixel fewer before than
after (`backbones.SamePadConv2d`). torch's Conv2d pads both sides alike, so the exporter
writes an explicit Pad node before each of them. ONNX Runtime runs convolutions on the CPU
in a blocked channel layout, and a Pad node is not one of the operators that keeps it: the
feature map goes back to plain layout, is padded, and goes blocked again, five times a
pass, on the largest maps of the network. ONNX's Conv takes its pads before and after
apart, so a Pad of zeros in height and width that only a convolution reads is that
convolution's own padding: folded in, the same sums are added in the same order, the
outputs are the same to the bit, and a pass of the shipped detector is about a fifth
faster on one core (`benchmarks/detect.py`).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np


def _constant_value(model, name: str, producers: dict, initializers: dict) -> np.ndarray | None:
    """The value of tensor `name` when it is computed from constants alone (the exporter's pads are a chain of
    Constant, Concat, Reshape, Slice, Transpose and Cast nodes), else None."""
    from onnx import helper, numpy_helper
    from onnx.reference import ReferenceEvaluator

    if name in initializers:
        return numpy_helper.to_array(initializers[name])
    nodes, todo, seen = [], [name], set()
    while todo:
        tensor = todo.pop()
        if tensor in seen or tensor == "":
            continue
        seen.add(tensor)
        node = producers.get(tensor)
        if node is None:
            if tensor not in initializers:
                return None  # a graph input: not a constant
            continue
        nodes.append(node)
        todo.extend(node.input)
    used = [initializers[t] for t in seen if t in initializers]
    chosen = {id(node) for node in nodes}
    nodes = [node for node in model.graph.node if id(node) in chosen]  # in the graph's order
    sub = helper.make_model(helper.make_graph(nodes, "constant", [], [helper.make_tensor_value_info(name, 0, None)], used),
                            opset_imports=model.opset_import)
    return np.asarray(ReferenceEvaluator(sub).run(None, {})[0])


def fold_pads(model) -> int:
    """Fold each Pad of zeros in height and width whose only reader is a Conv into that Conv's pads, in place; the
    nodes that computed the pads and nothing else go too. Returns how many Pads were folded."""
    from onnx import helper

    graph = model.graph
    producers = {output: node for node in graph.node for output in node.output}
    initializers = {item.name: item for item in graph.initializer}
    readers: dict[str, list] = {}
    for node in graph.node:
        for tensor in node.input:
            readers.setdefault(tensor, []).append(node)
    graph_outputs = {output.name for output in graph.output}
    folded = []
    for node in graph.node:
        if node.op_type != "Pad" or node.output[0] in graph_outputs:
            continue
        users = readers.get(node.output[0], [])
        mode = next((a.s for a in node.attribute if a.name == "mode"), b"constant")
        if len(users) != 1 or users[0].op_type != "Conv" or mode != b"constant" or len(node.input) < 2:
            continue
        pads = _constant_value(model, node.input[1], producers, initializers)
        value = (_constant_value(model, node.input[2], producers, initializers)
                 if len(node.input) > 2 and node.input[2] else np.zeros(1))
        conv = users[0]
        auto_pad = next((a.s for a in conv.attribute if a.name == "auto_pad"), b"NOTSET")
        if pads is None or value is None or np.any(value != 0) or pads.size != 8 or auto_pad != b"NOTSET":
            continue
        pads = [int(v) for v in pads]  # begin of N, C, H, W, then their ends
        if pads[0] or pads[1] or pads[4] or pads[5] or min(pads) < 0:
            continue  # padding of the batch or the channels, or cropping: no convolution's own
        own = next((a for a in conv.attribute if a.name == "pads"), None)
        before = list(own.ints) if own is not None else [0, 0, 0, 0]  # H begin, W begin, H end, W end
        if own is not None:
            conv.attribute.remove(own)
        conv.attribute.append(helper.make_attribute("pads", [before[0] + pads[2], before[1] + pads[3],
                                                             before[2] + pads[6], before[3] + pads[7]]))
        conv.input[0] = node.input[0]
        folded.append(node)
    for node in folded:
        graph.node.remove(node)
    _drop_unread(model)
    return len(folded)


def _drop_unread(model) -> None:
    """Remove nodes none of whose outputs is read (by a node or as a graph output), until none is left, and the
    initializers no node reads."""
    graph = model.graph
    while True:
        read = {tensor for node in graph.node for tensor in node.input} | {output.name for output in graph.output}
        unread = [node for node in graph.node if not any(output in read for output in node.output)]
        if not unread:
            break
        for node in unread:
            graph.node.remove(node)
    read = {tensor for node in graph.node for tensor in node.input}
    for item in [item for item in graph.initializer if item.name not in read]:
        graph.initializer.remove(item)


def fold_pads_in_file(path: Path) -> int:
    """`fold_pads` on the ONNX file at `path`, rewritten in place atomically; its metadata kept."""
    import onnx

    from renderloop.io.atomic import atomic_path

    model = onnx.load(str(path))
    count = fold_pads(model)
    if count:
        with atomic_path(Path(path)) as tmp:
            onnx.save(model, str(tmp))
    return count
