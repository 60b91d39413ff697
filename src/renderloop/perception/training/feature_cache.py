"""Training on cached maps: the frozen first part of the backbone runs once per augmented copy of an image.

With EfficientNet-Lite0 frozen down to SSDlite's stride-16 tap (`frozen_layers` at least
`config.training.CACHE_FROM`), what that part makes of an augmented image never changes while the rest learns, and on
a CPU its forward pass is most of a training step. `cached_copies` K > 0 augments every training image K times (the
same augmentation as always, `training.data`), runs each copy through the frozen part once, keeps its maps in memory
(float16; the stride-16 map, 672 channels at a sixteenth of the input, 0.54 MB a copy at 320 px, and with a stride-8
tap the 40-channel map it is made from, 0.13 MB more: `Lite0Extractor.frozen`), and trains the rest (the stride-32
blocks unless frozen too, SSDlite's extra blocks and its heads) on those maps: epoch e uses copy e mod K of every
image, so an epoch is still one pass over the images. What it gives up is a new augmentation draw every epoch: K of
them instead.

The copies come from their own seeded stream (`CACHE_STREAM`), drawn before anything of a resumed run is restored, so
a resumed run builds the same maps again.
"""

from __future__ import annotations

from collections.abc import Iterator

import torch
from torch import nn

from renderloop.perception.training.data import collate
from renderloop.perception.training.torch_support import import_torchvision

import_torchvision()
from torchvision.models.detection.image_list import ImageList
from torchvision.ops import boxes as box_ops

CACHE_STREAM = 0x636163  # "cac": the copies' augmentation draws, apart from the training order's


class FrozenMaps:
    """K augmented copies of every image of `dataset` through the model's frozen first part: `maps`, one (K * N, C, H,
    W) float16 tensor for each map it keeps, and each copy's targets in the network's input pixels, copy k of image i
    at k * N + i."""

    def __init__(self, model: nn.Module, dataset: torch.utils.data.Dataset, copies: int, seed: int,
                 device: torch.device, workers: int, memory_format: torch.memory_format, batch_size: int = 32) -> None:
        self.images, self.copies = len(dataset), copies
        torch.manual_seed(seed ^ CACHE_STREAM)  # the copies' own draws (workers=0 augments in this process)
        loader = torch.utils.data.DataLoader(dataset, batch_size=batch_size, shuffle=False, collate_fn=collate, num_workers=workers,
                                             generator=torch.Generator().manual_seed(seed ^ CACHE_STREAM))
        for part in model.backbone.features[:-1]:  # frozen whole (CACHE_FROM): their batch norms keep ImageNet's
            part.eval()
        self.maps, self.targets = [], []
        for _ in range(copies):
            for images, targets in loader:
                on_device = [{"boxes": t["boxes"].to(device), "labels": t["labels"].to(device)} for t in targets]
                maps, resized, self.input_size = frozen_maps(model, [image.to(device) for image in images], on_device,
                                                             memory_format)
                if not self.maps:  # filled in place: a list joined at the end would need twice the memory
                    self.maps = [torch.empty((copies * self.images, *m.shape[1:]), dtype=torch.float16) for m in maps]
                for kept, new in zip(self.maps, maps):
                    kept[len(self.targets):len(self.targets) + len(new)] = new.to(torch.float16).cpu()
                self.targets += [{"boxes": t["boxes"].cpu(), "labels": t["labels"].cpu()} for t in resized]

    @property
    def gib(self) -> float:
        """The memory the maps take, GiB."""
        return sum(m.numel() * m.element_size() for m in self.maps) / 2**30

    def epoch(self, epoch: int, order: torch.Tensor, batch_size: int,
              drop_last: bool) -> Iterator[tuple[list[torch.Tensor], list]]:
        """The batches of one epoch: copy epoch mod K of every image, in `order`."""
        offset = (epoch % self.copies) * self.images
        stop = len(order) - len(order) % batch_size if drop_last else len(order)
        for start in range(0, stop, batch_size):
            index = order[start:start + batch_size] + offset
            yield [m[index].float() for m in self.maps], [self.targets[i] for i in index.tolist()]


@torch.no_grad()
def frozen_maps(model: nn.Module, images: list[torch.Tensor], targets: list[dict],
                memory_format: torch.memory_format) -> tuple[list[torch.Tensor], list[dict], tuple[int, int]]:
    """What the network's frozen first part makes of `images` (SSD's own resize and normalisation first), with the
    targets in the input's pixels and the input's size: the maps `loss_from_maps` trains the rest on."""
    batch, resized = model.transform(images, targets)
    maps = model.backbone.frozen(batch.tensors.contiguous(memory_format=memory_format))
    return maps, resized, tuple(batch.tensors.shape[-2:])


def loss_from_maps(model: nn.Module, maps: list[torch.Tensor], targets: list[dict],
                   input_size: tuple[int, int]) -> dict:
    """SSD's training losses from the frozen part's maps: the rest of the extractor, the heads, the default boxes and
    the matching, as torchvision's `SSD.forward` does after the extractor's first part."""
    features = model.backbone.from_frozen(maps)
    head_outputs = model.head(features)
    # The default boxes depend on the input's size alone; a zero stride-0 view stands in for the images.
    images = ImageList(maps[0].new_zeros(()).expand(len(targets), 3, *input_size), [input_size] * len(targets))
    anchors = model.anchor_generator(images, features)
    matched = []
    for anchors_per_image, target in zip(anchors, targets):
        if target["boxes"].numel() == 0:
            matched.append(torch.full((anchors_per_image.size(0),), -1, dtype=torch.int64, device=maps[0].device))
        else:
            matched.append(model.proposal_matcher(box_ops.box_iou(target["boxes"], anchors_per_image)))
    return model.compute_loss(targets, head_outputs, anchors, matched)
