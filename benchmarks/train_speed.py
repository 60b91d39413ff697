"""Training speed of the detector: images a second of each backbone's training step at the default batch, in the
memory layout `renderloop train` uses (`train.MEMORY_FORMAT`, NHWC) and in torch's default NCHW, side by side in one
run, on the CPU (and the GPU where there is one). A step is what `train_detector` does for a batch: the forward pass
with the SSD loss, the backward pass and AdamW, with the backbone's early layers frozen as training freezes them;
random weights and a fixed batch of 320x240 images with six boxes each (speed does not depend on either). Then
EfficientNet-Lite0 with more of it frozen, the whole network run each step or trained from cached stride-16 maps
(`--cached-copies`, `perception/training/feature_cache.py`): the cost a step of each.

    .venv/bin/python benchmarks/train_speed.py [--steps 3] [--rounds 2] [--no-save]

Writes `benchmarks/results/training_speed.json` unless --no-save.
"""

from __future__ import annotations

import argparse
import statistics
import time

from common import as_table, save_result


def batch(size: int, device) -> tuple[list, list]:
    import torch

    generator = torch.Generator().manual_seed(0)
    images = [torch.rand(3, 240, 320, generator=generator).to(device) for _ in range(size)]
    targets = []
    for _ in range(size):
        corner = torch.rand(6, 2, generator=generator) * torch.tensor([280.0, 200.0])
        boxes = torch.cat([corner, corner + 10 + 30 * torch.rand(6, 2, generator=generator)], dim=1)
        targets.append({"boxes": boxes.to(device), "labels": torch.randint(1, 3, (6,), generator=generator).to(device)})
    return images, targets


def images_per_second(backbone: str, memory_format, device: str, size: int, steps: int, frozen_count: int | None = None,
                      cached: bool = False) -> float:
    """Median images a second over `steps` training steps, after one step of warm-up; `frozen_count` layers frozen
    (None: the default), `cached`: from the stride-16 maps of the batch (`feature_cache`), made before the timing."""
    import torch

    from renderloop.config.training import TrainSettings
    from renderloop.perception.training.backbones import frozen_layers
    from renderloop.perception.training.feature_cache import frozen_maps, loss_from_maps
    from renderloop.perception.training.ssd import build_model

    torch.manual_seed(0)
    model = build_model(backbone, pretrained=False)
    frozen = frozen_layers(model, TrainSettings().frozen_layers if frozen_count is None else frozen_count)
    model = model.to(device, memory_format=memory_format).train()
    for layer in frozen:
        layer.eval()
    optimizer = torch.optim.AdamW([p for p in model.parameters() if p.requires_grad], lr=1e-4)
    images, targets = batch(size, device)
    if cached:
        maps, targets, input_size = frozen_maps(model, images, targets, memory_format)
    rates = []
    for step in range(steps + 1):
        start = time.perf_counter()
        if cached:
            loss = sum(loss_from_maps(model, maps, targets, input_size).values())
        else:
            loss = sum(model(images, targets).values())
        optimizer.zero_grad(set_to_none=True)
        loss.backward()
        optimizer.step()
        if device == "cuda":
            torch.cuda.synchronize()
        if step:
            rates.append(size / (time.perf_counter() - start))
    return statistics.median(rates)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=3, help="timed training steps a case and round")
    parser.add_argument("--rounds", type=int, default=2, help="rounds over every case, interleaved (median taken)")
    parser.add_argument("--no-save", action="store_true", help="print only; do not write benchmarks/results/")
    args = parser.parse_args()
    import torch

    from renderloop.config.training import BACKBONES, TrainSettings
    from renderloop.perception.training.train import MEMORY_FORMAT

    layouts = (MEMORY_FORMAT, torch.contiguous_format)  # the training's, then torch's default
    size = TrainSettings().batch_size
    devices = ["cpu"] + (["cuda"] if torch.cuda.is_available() else [])
    cases = [(device, backbone, layout) for device in devices for backbone in BACKBONES for layout in layouts]
    rates: dict[tuple, list[float]] = {case: [] for case in cases}
    for _ in range(args.rounds):  # interleaved, so that the machine's drift touches every case alike
        for case in cases:
            rates[case].append(images_per_second(case[1], case[2], case[0], size, args.steps))
    records = []
    for device, backbone in dict.fromkeys((device, backbone) for device, backbone, _ in cases):
        nhwc, nchw = (statistics.median(rates[(device, backbone, layout)]) for layout in layouts)
        records.append({"case": f"{backbone}, {device}", "nhwc": round(nhwc, 1), "nchw": round(nchw, 1),
                        "ratio": round(nhwc / nchw, 2)})
        print(f"{backbone:<20} {device:<5} NHWC {nhwc:6.1f}  NCHW {nchw:6.1f} images/s  ({nhwc / nchw:.2f}x)")
    # EfficientNet-Lite0 in the training's layout with more of it frozen, and from cached stride-16 maps
    from renderloop.config.training import CACHE_FROM, EFFICIENTNET_LITE0, LITE0_LAYERS

    frozen_cases = [(TrainSettings().frozen_layers, False), (CACHE_FROM, False), (LITE0_LAYERS, False), (CACHE_FROM, True),
                    (LITE0_LAYERS, True)]
    frozen_rates: dict[tuple, list[float]] = {case: [] for case in frozen_cases}
    for _ in range(args.rounds):
        for case in frozen_cases:
            frozen_rates[case].append(images_per_second(EFFICIENTNET_LITE0, MEMORY_FORMAT, "cpu", size, args.steps, *case))
    frozen_records = []
    for count, cached in frozen_cases:
        rate = statistics.median(frozen_rates[(count, cached)])
        frozen_records.append({"frozen": count, "cached": "cached maps" if cached else "whole network", "rate": round(rate, 1)})
        print(f"{EFFICIENTNET_LITE0} frozen {count:>2} {frozen_records[-1]['cached']:<14} {rate:6.1f} images/s")
    if not args.no_save:
        table = as_table(records, {"case": f"backbone, device (batch {size})",
                                   "nhwc": "images/s, NHWC (training's layout)", "nchw": "images/s, NCHW", "ratio": "ratio"})
        frozen_table = as_table(frozen_records, {"frozen": "frozen layers", "cached": "a step runs",
                                                 "rate": "images/s, cpu"})
        print(save_result("training_speed", {"table": table, "frozen_table": frozen_table, "threads": torch.get_num_threads()}))


if __name__ == "__main__":
    main()
