"""The torch weights of a renderloop ONNX detector, so that a shipped model can be fine-tuned without its checkpoint.

The exporter folds each batch norm into the convolution before it, so the ONNX file holds
W' = W * g / sqrt(v + eps) and a bias b' where torch has W, no bias and a batch norm
(g, b, mean m, variance v). The network is rebuilt with each convolution's W' and its batch
norm made the identity plus b' (g = 1, b = b', m = 0, v = 1 - eps): the same function
in eval mode. Batch statistics would undo that in train mode, so a model made this way is
fine-tuned with its batch norms frozen (`freeze_batch_norms`), as detection fine-tunes
usually are. Each ONNX Conv node is matched to its torch module by the node's name, which
the exporter writes as the module's path.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import torch
from torch import nn

from renderloop.errors import UserError

__all__ = ["weights_from_onnx", "freeze_batch_norms", "onnx_metadata", "check_model_out", "set_metadata"]


def _module_name(node_name: str) -> str:
    """'/backbone/features.0/features.0.1/block/block.0/block.0.0/Conv' -> 'backbone.features.0.1.block.0.0'."""
    name, previous = "", ""
    for part in node_name.strip("/").split("/")[:-1]:
        if previous and part.startswith(previous + "."):
            name += part[len(previous):]
        else:
            name = f"{name}.{part}" if name else part
        previous = part
    return name.removeprefix("model.")


def onnx_metadata(path: Path) -> dict[str, str]:
    """The metadata properties of a renderloop ONNX model (which detector, classes, training figures)."""
    import onnx

    try:
        model = onnx.load(str(path), load_external_data=False)
    except Exception as error:  # onnx raises its own decode errors, of several types
        raise UserError(f"--init {path}: not an ONNX model ({type(error).__name__})") from None
    return {entry.key: entry.value for entry in model.metadata_props}


def check_model_out(out: Path, force: bool) -> None:
    """Refuse, in one line, an `--out` for a model made from another (quantized, blended) that is no .onnx file or
    that exists without `force`."""
    if out.suffix != ".onnx":
        raise UserError(f"--out {out}: the model file must end in .onnx")
    if out.exists() and not force:
        raise UserError(f"--out {out}: exists; give another --out, or --force to replace it")


def set_metadata(model, entries: dict[str, str]) -> None:
    """Make `entries` the metadata properties of the loaded ONNX `model`, in place of those it has."""
    del model.metadata_props[:]
    for key, value in entries.items():
        model.metadata_props.add(key=key, value=value)


def weights_from_onnx(path: Path, model: nn.Module) -> dict[str, torch.Tensor]:
    """The state dict of `model` (built by `build_model`) that computes what the ONNX file at `path` computes."""
    import onnx
    from onnx import numpy_helper

    try:
        graph = onnx.load(str(path)).graph
    except Exception as error:  # onnx raises its own decode errors, of several types
        raise UserError(f"--init {path}: not an ONNX model ({type(error).__name__})") from None
    values = {item.name: numpy_helper.to_array(item) for item in graph.initializer}
    modules = dict(model.named_modules())
    state = {key: value.clone() for key, value in model.state_dict().items()}
    convs = [node for node in graph.node if node.op_type == "Conv"]
    torch_convs = [name for name, module in modules.items() if isinstance(module, nn.Conv2d)]
    if len(convs) != len(torch_convs):
        raise UserError(f"--init {path}: {len(convs)} convolutions where the detector has {len(torch_convs)}; "
                        "not a renderloop detector")
    for node in convs:
        name = _module_name(node.name)
        conv = modules.get(name)
        weight = values.get(node.input[1])
        if not isinstance(conv, nn.Conv2d) or weight is None or tuple(weight.shape) != tuple(conv.weight.shape):
            raise UserError(f"--init {path}: its convolution {node.name!r} has no match in the detector")
        bias = values[node.input[2]] if len(node.input) > 2 else np.zeros(weight.shape[0], dtype=np.float32)
        state[f"{name}.weight"] = torch.from_numpy(weight.copy())
        if conv.bias is not None:
            state[f"{name}.bias"] = torch.from_numpy(bias.copy())
            continue
        parent, index = name.rsplit(".", 1)
        norm_name = f"{parent}.{int(index) + 1}"
        norm = modules.get(norm_name)
        if not isinstance(norm, nn.BatchNorm2d):
            raise UserError(f"--init {path}: {name} has neither a bias nor a batch norm after it")
        state[f"{norm_name}.weight"] = torch.ones_like(norm.weight)
        state[f"{norm_name}.bias"] = torch.from_numpy(bias.copy())
        state[f"{norm_name}.running_mean"] = torch.zeros_like(norm.running_mean)
        state[f"{norm_name}.running_var"] = torch.full_like(norm.running_var, 1.0 - norm.eps)
    return state


def freeze_batch_norms(model: nn.Module) -> None:
    """Batch norms keep their running statistics (eval mode) while the rest trains; their scale and shift still learn."""
    for module in model.modules():
        if isinstance(module, nn.BatchNorm2d):
            module.eval()
