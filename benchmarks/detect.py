"""Speed of perception on one core: ONNX detector ms per 640x480 frame of peppers (the whole frame alone, with 2x2
windows, and the default windows and the mirrored frame), one pass of each backbone's network at each
export size in float32 and quantized to int8, the shipped network's pass with its zero padding folded into the
convolutions and as Pad nodes, organised point cloud ms per 640x480 frame (side by side with
Open3D's `create_from_depth_image` when Open3D is installed); saved to benchmarks/results/NAME.json. Training speed: benchmarks/train_speed.py.

    .venv/bin/python benchmarks/detect.py [--repeats 30] [--name perception_speed]
"""

from __future__ import annotations

import argparse
import time

import numpy as np
from common import save_result, scan_poses, summary

from renderloop.config import DetectorConfig
from renderloop.perception.detector import Detector
from renderloop.perception.pointcloud import organised_cloud
from renderloop.perception.tiling import all_windows
from renderloop.render.camera import Intrinsics


def timed(function, repeats: int) -> list[float]:
    function()  # warm-up
    out = []
    for _ in range(repeats):
        start = time.perf_counter()
        function()
        out.append((time.perf_counter() - start) * 1000)
    return out


def pepper_frame() -> np.ndarray:
    """A 640x480 raster frame of the demo greenhouse from a scan pose: real boxes go through NMS."""
    from renderloop.config import load_config
    from renderloop.render.raster import RasterRenderer
    from renderloop.scene.generate import generate_scene

    config = load_config("paper")
    data = load_config("demo").model_dump(mode="json")
    data["camera"] = config.camera.model_dump(mode="json")
    config = type(config).model_validate(data)
    scene = generate_scene(config)
    with RasterRenderer(scene, config, Intrinsics.from_config(config.camera)) as renderer:
        return renderer.render(scan_poses(scene, 1)[0]).rgb


def synthetic_depth(intrinsics: Intrinsics, rng: np.random.Generator) -> np.ndarray:
    depth = rng.uniform(0.3, 3.0, (intrinsics.height, intrinsics.width)).astype(np.float32)
    depth[rng.random(depth.shape) < 0.1] = 0.0
    return depth


def open3d_cloud_ms(depth: np.ndarray, intrinsics: Intrinsics, repeats: int) -> list[float] | None:
    try:
        import open3d as o3d
    except ImportError:
        return None
    image = o3d.geometry.Image(depth)
    camera = o3d.camera.PinholeCameraIntrinsic(intrinsics.width, intrinsics.height, intrinsics.fx, intrinsics.fy, intrinsics.cx, intrinsics.cy)
    return timed(lambda: o3d.geometry.PointCloud.create_from_depth_image(image, camera, depth_scale=1.0, depth_trunc=100.0,
                                                                       project_valid_depth_only=False), repeats)


def torch_and_onnx_ms(frame: np.ndarray, repeats: int) -> tuple[list[float], list[float]]:
    """The same network (random weights: the shipped ONNX file carries no torch weights) through torch and through
    ONNX Runtime, each with its own post-processing (torchvision's, ours in numpy), at the same thread count."""
    import tempfile
    from pathlib import Path

    import torch

    from renderloop.perception.detector import to_input
    from renderloop.perception.training.ssd import build_model, export_onnx

    torch.manual_seed(0)
    model = build_model().eval()
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "same.onnx"
        export_onnx(model, path)
        onnx = Detector(path, threads=2)
    torch.set_num_threads(2)
    image = torch.from_numpy(to_input(frame))[0]
    with torch.no_grad():
        torch_ms = timed(lambda: model([image]), repeats)
    return torch_ms, timed(lambda: onnx.detect(frame, 0.5), repeats)


DEFAULT_GOAL_MS = 50  # the default detector setting's cost goal, ms a 640x480 frame on one core (issue 48)
EXPORT_SIZES = (320, 384, 448, 512)  # square inputs each backbone's detector is timed at


def backbone_pass_ms(frame: np.ndarray, repeats: int) -> dict[tuple[str, int, str], list[float]]:
    """One pass of the whole frame through each backbone's detector at each of EXPORT_SIZES, in float32 and quantized to
    int8 (`renderloop quantize`; random weights, calibrated on the frame: speed does not depend on them), with ONNX
    Runtime on one core, side by side."""
    import tempfile
    from pathlib import Path

    from renderloop.config.training import BACKBONES
    from renderloop.perception.training.quantize import quantize_detector
    from renderloop.perception.training.ssd import build_model, export_onnx

    figures = {}
    for backbone in BACKBONES:
        model = build_model(backbone, pretrained=False).eval()
        for size in EXPORT_SIZES:
            with tempfile.TemporaryDirectory() as folder:
                path = Path(folder) / f"{backbone}.onnx"
                export_onnx(model, path, input_size=size)
                detectors = {"float32": Detector(path, threads=1),
                             "int8": Detector(quantize_detector(path, [frame], path.with_suffix(".int8.onnx"), "the frame"),
                                              threads=1)}
            for kind, detector in detectors.items():
                figures[backbone, size, kind] = timed(lambda: detector.detect(frame, 0.5), repeats)
    return figures


def pad_fold_ms(frame: np.ndarray, repeats: int) -> dict[str, list[float]]:
    """One pass of the shipped network (`efficientnet-lite0-s8` at 384 px, random weights) as exported, its zero
    padding folded into the convolutions (`perception/training/graph.py`), and with the padding left as the Pad nodes
    torch writes; on one core, the two timed in turn."""
    import tempfile
    from pathlib import Path
    from unittest import mock

    from renderloop.perception.training.ssd import build_model, export_onnx

    model = build_model("efficientnet-lite0-s8", pretrained=False).eval()
    detectors = {}
    with tempfile.TemporaryDirectory() as folder:
        for kind in ("folded", "Pad nodes"):
            path = Path(folder) / f"{len(detectors)}.onnx"
            if kind == "folded":
                export_onnx(model, path, input_size=384)
            else:
                with mock.patch("renderloop.perception.training.graph.fold_pads", lambda graph: 0):
                    export_onnx(model, path, input_size=384)
            detectors[kind] = Detector(path, threads=1)
    times: dict[str, list[float]] = {kind: [] for kind in detectors}
    for _ in range(repeats):
        for kind, detector in detectors.items():
            times[kind] += timed(lambda: detector.detect(frame, 0.5), 1)
    return times


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=30)
    parser.add_argument("--name", default="perception_speed", help="Results file: benchmarks/results/NAME.json.")
    args = parser.parse_args()
    rng = np.random.default_rng(0)
    intrinsics = Intrinsics(640, 480, 589.4, 589.4, 319.5, 239.5)
    frame = pepper_frame()
    detector, defaults = Detector(threads=1), DetectorConfig()  # one core: the cost goal's setting
    depth = synthetic_depth(intrinsics, rng)
    passes = 1 + defaults.mirror + len(all_windows(640, 480, defaults.layouts, detector.input_size))
    rows = [("detector, the whole frame alone (one pass)", timed(lambda: detector.detect(frame, 0.5), args.repeats), ""),
            ("detector, 2x2 windows fused", timed(lambda: detector.detect(frame, 0.5, [(2, 2)]), args.repeats), ""),
            (f"detector, the default: {', '.join(defaults.windows)} windows and the mirrored frame "
             f"({passes} passes)", timed(lambda: detector.search(frame, defaults, 0.5), args.repeats),
             f"≤ {DEFAULT_GOAL_MS}")]
    rows += [(f"one pass, {backbone} at {size} px, {kind}", values, "")
             for (backbone, size, kind), values in backbone_pass_ms(frame, args.repeats).items()]
    fold = pad_fold_ms(frame, args.repeats)
    rows += [(f"one pass, efficientnet-lite0-s8 at 384 px, float32, zero padding {kind}", values, "")
             for kind, values in fold.items()]
    cloud = timed(lambda: organised_cloud(depth, intrinsics), args.repeats)
    rows.append(("organised point cloud", cloud, "≤ 5"))
    reference = open3d_cloud_ms(depth, intrinsics, args.repeats)
    if reference is not None:
        rows.append(("Open3D `create_from_depth_image`, for reference", reference, ""))
    torch_ms, onnx_ms = torch_and_onnx_ms(frame, args.repeats)
    medians = [summary(values)["median"] for _, values, _ in rows]
    figures = {
        "table": {"columns": ["figure (one core)", "ms per 640x480 frame, median", "min-max", "goal"],
                  "rows": [[name, round(median, 1), f"{min(values):.1f}-{max(values):.1f}", goal]
                           for (name, values, goal), median in zip(rows, medians, strict=True)]},
        "whole_frame_ms": round(medians[0], 1), "windows_2x2_ms": round(medians[1], 1),
        "default_ms": round(medians[2], 1), "cloud_ms": round(summary(cloud)["median"], 2),
        "pad_fold_speedup": round(summary(fold["Pad nodes"])["median"] / summary(fold["folded"])["median"], 2),
        "onnx_speed_vs_torch_2_threads": round(summary(torch_ms)["median"] / summary(onnx_ms)["median"], 2),
    }
    if reference is not None:
        figures["open3d_cloud_ms"] = round(summary(reference)["median"], 2)
    for row in figures["table"]["rows"]:
        print(f"{row[0]:<96} {row[1]:>8} {row[2]:>14} {row[3]:>6}")
    print(save_result(args.name, figures))


if __name__ == "__main__":
    main()
