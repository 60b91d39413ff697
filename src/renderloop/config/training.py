"""The settings of a detector training run (`renderloop train`): the schedule and the backbone.

They are not part of a run's `Config` (a training run has no greenhouse), but are bounded the same way and live here
so that `renderloop train` reads its defaults and ranges without importing torch. A checkpoint records them, less
`max_steps`, and resumes only a run of the same ones.
"""

from __future__ import annotations

from typing import Literal

from pydantic import Field, field_validator, model_validator

from renderloop.config.fields import Count, Fraction, Real, Strict

EFFICIENTNET_LITE0, MOBILENET_V3 = "efficientnet-lite0", "mobilenet-v3"
# EfficientNet-Lite0 with a third tap at stride 8 (`perception/training/backbones.py`), whose default boxes start there
EFFICIENTNET_LITE0_S8 = "efficientnet-lite0-s8"
PRETRAINED = (EFFICIENTNET_LITE0, EFFICIENTNET_LITE0_S8)  # the backbones that start from ImageNet's weights
LITE0_LAYERS = 18  # EfficientNet-Lite0's stem, 16 blocks and head: the layers `--frozen-layers` can hold
CACHE_FROM = 13  # frozen layers that hold SSDlite's first part, the network down to its stride-16 tap (`feature_cache`)
BACKBONES = (EFFICIENTNET_LITE0, MOBILENET_V3, EFFICIENTNET_LITE0_S8)
# the stride-8 tap lifted every figure over the plain network at one budget (the model card's step 37)
DEFAULT_BACKBONE = EFFICIENTNET_LITE0_S8
INPUT_SIZE = 320  # px a side: the square input a network trains at unless told, and torchvision's SSDlite's
INPUT_SIZES = range(160, 1281, 32)  # the square inputs a network trains at or is exported with (its stride is 32)
SIZE_RULE = f"a multiple of {INPUT_SIZES.step} from {INPUT_SIZES[0]} to {INPUT_SIZES[-1]} px"  # what a bad size is told
MATCH_IOU = 0.4  # the IoU from which a default box learns a labelled box, the default of match_iou
# What a checkpoint that predates a setting trained with, where that is not the setting's default now: the
# random-weights MobileNetV3 until there was a choice of backbone, every layer learning until frozen_layers existed,
# torchvision SSD's match IoU of 0.5 until match_iou did
PREDATED = {"backbone": MOBILENET_V3, "frozen_layers": 0, "match_iou": 0.5}
DEVICES = ("auto", "cpu", "cuda")  # where `renderloop train` runs; auto: cuda when torch finds one


class TrainSettings(Strict):
    epochs: Count(1, 100_000) = Field(30, description="Passes over the training images; the cosine decay spans them all.")
    batch_size: Count(1, 4096) = Field(32, description="Images a step.")
    # above 0 rather than a floor: a rate too small to move the weights checks that a fine-tune starts from its --init
    learning_rate: Real(0.0, 1.0, low_open=True) = Field(
        3e-3, description="AdamW's rate after the warm-up, of the layers the backbone did not learn on ImageNet.")
    weight_decay: Real(0.0, 1.0) = Field(1e-4, description="AdamW's weight decay.")
    warmup_steps: Count(0, 10_000_000) = Field(200, description="Steps of linear learning-rate warm-up before the cosine "
                                               "decay; fewer for a short fine-tune, or it never decays.")
    seed: Count(0, 2**63 - 1) = Field(0, description="Seed of the weights of new layers, the augmentation and the order "
                                      "of the images.")
    backbone: Literal[EFFICIENTNET_LITE0, MOBILENET_V3, EFFICIENTNET_LITE0_S8] = Field(
        DEFAULT_BACKBONE, description="efficientnet-lite0-s8 (ImageNet weights, features from stride 8 on: boxes from 13 px on a "
        "grid of 8), efficientnet-lite0 (the same from stride 16 on) or mobilenet-v3 (random weights).")
    backbone_lr_factor: Fraction = Field(
        0.1, description="The pretrained layers' learning rate, as a fraction of learning_rate: at the full rate AdamW "
        "wipes out what they learned on ImageNet within a few hundred steps.")
    frozen_layers: Count(0, LITE0_LAYERS) = Field(
        6, description="The pretrained backbone's first layers (stem, 16 blocks, head) that keep their ImageNet weights "
        "and batch-norm statistics: 6 holds the layers down to stride 8, which trains faster on a CPU and keeps the "
        f"low-level features learned on real photos; {LITE0_LAYERS} holds the whole backbone. 0 trains every layer.")
    cached_copies: Count(0, 64) = Field(
        0, description=f"With --frozen-layers {CACHE_FROM} or more: augment every training image this many times once, "
        "keep what the frozen layers make of each copy (0.54 MB a copy at 320 px, 0.67 with the stride-8 tap) and "
        "train the rest on those, epoch e on copy e mod K: several times faster a step on a CPU, K augmentation draws "
        "instead of one an epoch. 0 augments anew every epoch and runs the whole network.")
    train_size: Count(INPUT_SIZES[0], INPUT_SIZES[-1]) = Field(
        INPUT_SIZE, description="Square input the network trains at, px, a multiple of 32: larger shows small fruit "
        "larger, at about the square of the cost a step and a pass. Its default boxes keep their sizes in pixels.")
    match_iou: Real(0.1, 0.9) = Field(
        MATCH_IOU, description="IoU with a labelled box from which a default box learns that fruit, its class and its "
        "box; the others learn background, and each fruit's best default box learns it at any IoU. Lower: more default "
        "boxes learn each fruit, among them those over the visible part of a fruit a leaf hides in part. torchvision's "
        "SSD: 0.5.")
    max_steps: Count(1, 10**9) | None = Field(None, description="Stop after this many steps in all (tests); the schedule "
                                              "still spans the epochs. null: train every epoch.")

    @model_validator(mode="after")
    def _cache_after_frozen_layers(self) -> TrainSettings:
        if self.cached_copies and (self.backbone not in PRETRAINED or self.frozen_layers < CACHE_FROM):
            raise ValueError(f"cached_copies needs an {' or '.join(PRETRAINED)} backbone with frozen_layers of at "
                             f"least {CACHE_FROM} (frozen down to its stride-16 tap)")
        return self

    @field_validator("train_size")
    @classmethod
    def _multiple_of_stride(cls, size: int) -> int:
        if size not in INPUT_SIZES:
            raise ValueError(f"{SIZE_RULE}, not {size}")
        return size
