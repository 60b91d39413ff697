"""The detector network and its ONNX form.

torchvision's SSDlite (320x320, or the `train_size` of the run) over one of the backbones of
`renderloop.perception.training.backbones`, classes background, ripe, unripe. The ONNX graph holds the network
and the box decoding, not the per-class filtering and NMS: those run in numpy
after ONNX Runtime (`renderloop.perception.detector`), the same code for every
backend, so the exported file has no data-dependent shapes and its outputs can be
compared with torch's number for number.

ONNX contract: input `images` float32 (1, 3, S, S) RGB in [0, 1] (the frame
resized to the input, aspect not kept, as torchvision's SSD transform does; S is the size
the network trained at, unless the model was exported with another);
outputs `boxes` (A, 4) x0 y0 x1 y1 in pixels of the input, and `scores`
(A, 3) softmax class probabilities, background first.
"""

from __future__ import annotations

from pathlib import Path

import torch
from torch import nn

from renderloop.config.training import INPUT_SIZE
from renderloop.perception.detector import CLASSES
from renderloop.perception.training.torch_support import import_torchvision

torchvision = import_torchvision()
from torchvision.models.detection import _utils as det_utils
from torchvision.models.detection import ssdlite320_mobilenet_v3_large
from torchvision.models.detection.anchor_utils import DefaultBoxGenerator
from torchvision.models.detection.image_list import ImageList
from torchvision.models.detection.ssd import SSD
from torchvision.models.detection.ssdlite import SSDLiteHead
from torchvision.models.detection.transform import GeneralizedRCNNTransform

from renderloop.config.training import BACKBONES, DEFAULT_BACKBONE, EFFICIENTNET_LITE0_S8, MATCH_IOU, MOBILENET_V3
from renderloop.perception.training.backbones import NORM, lite0_extractor

OPSET = 17
# Default-box scales (fraction of the input) of the six feature maps, and the extra one
# the last map's second square box uses. torchvision's SSDlite starts at 0.2 (64 px), but
# half of our training fruit are under 22 px at the input: with boxes that large no
# anchor overlaps them by IoU 0.5 and small fruit were learned from one anchor each.
# Two boxes per map and four ratios each, as torchvision's, so the head keeps its shape.
# With a stride-8 tap (`efficientnet-lite0-s8`) the same boxes start there, each size on a grid half as coarse, and the
# last of its seven maps holds boxes of the whole input.
ANCHOR_SCALES = [0.04, 0.08, 0.16, 0.32, 0.52, 0.76, 1.0]


# What torchvision's SSDlite sets besides the network; the inputs go from [0, 1] to [-1, 1], which is also
# EfficientNet-Lite's (x - 127) / 128 on 8-bit values.
SSD_SETTINGS = {"score_thresh": 0.001, "nms_thresh": 0.55, "detections_per_img": 300, "topk_candidates": 300,
                "image_mean": [0.5, 0.5, 0.5], "image_std": [0.5, 0.5, 0.5]}


def default_boxes(input_size: int, backbone: str = DEFAULT_BACKBONE) -> DefaultBoxGenerator:
    """The default boxes over an `input_size` square input: the same sizes in pixels at any input (ANCHOR_SCALES of a
    320 px one) on a grid that grows with it, so that a network fine-tuned or run at another size than it trained
    at regresses from boxes of the sizes it learned from, on features of fruit of so many pixels; boxes that grew
    with the input would come out scaled by its growth. Run at another size, a network still loses much of its
    recall (the model card's steps 18 and 20): train at the size it will run at."""
    scales = ANCHOR_SCALES + [1.0] if backbone == EFFICIENTNET_LITE0_S8 else ANCHOR_SCALES
    return DefaultBoxGenerator([[2, 3] for _ in scales[1:]], scales=[s * INPUT_SIZE / input_size for s in scales])


def build_model(backbone: str = DEFAULT_BACKBONE, pretrained: bool = True, train_size: int = INPUT_SIZE,
                match_iou: float = MATCH_IOU) -> nn.Module:
    """The detector over `backbone`, training at a `train_size` square input; `pretrained` loads the backbone's
    ImageNet weights where it has them (weights loaded afterwards, from a checkpoint or an ONNX model, make it moot).
    Its weights are those of any size: only the input transform and the grid of default boxes depend on it.
    `match_iou` is the IoU with a labelled box from which a default box trains on it (training only)."""
    anchors, size = default_boxes(train_size, backbone), (train_size, train_size)
    if backbone == MOBILENET_V3:
        model = ssdlite320_mobilenet_v3_large(weights=None, weights_backbone=None, num_classes=len(CLASSES) + 1)
        model.anchor_generator = anchors
        model.transform = GeneralizedRCNNTransform(train_size, train_size, SSD_SETTINGS["image_mean"],
                                                   SSD_SETTINGS["image_std"], size_divisible=1, fixed_size=size)
    else:
        extractor = lite0_extractor(pretrained, stride_8=backbone == EFFICIENTNET_LITE0_S8)
        channels = det_utils.retrieve_out_channels(extractor, size)
        head = SSDLiteHead(channels, anchors.num_anchors_per_location(), len(CLASSES) + 1, NORM)
        model = SSD(extractor, anchors, size, len(CLASSES) + 1, head=head, **SSD_SETTINGS)
    model.proposal_matcher = det_utils.SSDMatcher(match_iou)
    model.renderloop_backbone = backbone  # what the exported model's metadata names
    return model


def detector_name(backbone: str) -> str:
    """The name an exported model carries in its metadata (`renderloop_detector`)."""
    return "ssdlite320_mobilenet_v3_large" if backbone == MOBILENET_V3 else f"ssdlite320_{backbone.replace('-', '_')}"


def backbone_of(name: str) -> str | None:
    """The backbone a `renderloop_detector` name was built on; None for a name renderloop does not write."""
    return next((backbone for backbone in BACKBONES if detector_name(backbone) == name), None)


class DecodedSSD(nn.Module):
    """Network plus box decoding for one image already at the `input_size` square input (the ONNX graph), whatever
    size it trained at: its default boxes keep their sizes in pixels (`default_boxes`)."""

    def __init__(self, model: nn.Module, input_size: int = INPUT_SIZE) -> None:
        super().__init__()
        self.model, self.input_size = model, input_size
        transform = model.transform
        self.register_buffer("mean", torch.tensor(transform.image_mean).view(1, 3, 1, 1))
        self.register_buffer("std", torch.tensor(transform.image_std).view(1, 3, 1, 1))
        generator = default_boxes(input_size, model.renderloop_backbone)
        with torch.no_grad():
            dummy = torch.zeros(1, 3, input_size, input_size)
            features = list(model.backbone(dummy).values())
            anchors = generator(ImageList(dummy, [(input_size, input_size)]), features)[0]
        self.register_buffer("anchors", anchors)

    def forward(self, images: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        features = list(self.model.backbone((images - self.mean) / self.std).values())
        head = self.model.head(features)
        boxes = self.model.box_coder.decode_single(head["bbox_regression"][0], self.anchors)
        return boxes.clamp(0.0, float(self.input_size)), torch.softmax(head["cls_logits"][0], dim=-1)


def export_onnx(model: nn.Module, path: Path, metadata: dict[str, str] | None = None, input_size: int = INPUT_SIZE) -> None:
    """Write the ONNX graph (classic TorchScript exporter, opset 17, zero padding folded into the convolutions) for an
    `input_size` square input, with the backbone and the classes in its metadata."""
    import onnx

    from renderloop.io.atomic import atomic_path
    from renderloop.perception.training.graph import fold_pads

    model = model.eval()
    wrapper = DecodedSSD(model, input_size).eval()
    with atomic_path(Path(path)) as tmp:
        torch.onnx.export(wrapper, (torch.zeros(1, 3, input_size, input_size),), str(tmp), input_names=["images"],
                          output_names=["boxes", "scores"], opset_version=OPSET, dynamo=False)
        graph = onnx.load(str(tmp))
        fold_pads(graph)  # the same function, a fifth faster on ONNX Runtime's CPU kernels (`graph`)
        entries = {"renderloop_detector": detector_name(model.renderloop_backbone), "classes": ",".join(CLASSES), **(metadata or {})}
        for key, value in entries.items():
            graph.metadata_props.add(key=key, value=str(value))
        onnx.save(graph, str(tmp))
