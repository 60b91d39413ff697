"""The camera and how its frames are rendered (`camera`, `renderer`)."""

from __future__ import annotations

import math
from typing import Literal

from pydantic import Field, model_validator

from renderloop.config.fields import MAX_CAMERA_RATE_HZ, MAX_PIXELS, Count, Fraction, Range, Real, Strict

# px: the width of the frames the colour sensor's noise and defocus are stated in, the D435's 1280x720 colour stream
# that the real greenhouse photos come from; the noise defaults give their flat-region noise (benchmarks/sensor_noise.py)
SENSOR_STREAM_WIDTH = 1280


class SensorConfig(Strict):
    """The colour stream of a RealSense D435-class camera (render/sensor.py); each frame draws every value from its
    range. Off: the ideal stream only. On: `rgb_sensor/` beside `rgb/`, and perception reads the sensor's frames."""

    enabled: bool = Field(False, description="Render the sensor stream rgb_sensor/ beside the ideal rgb/.")
    exposure_time: Range(0.0, 0.2) = Field(
        (0.008, 0.025), description="Shutter time, s (a D435's indoor auto exposure): Cycles blurs rgb_sensor/ with the "
        "camera's flown motion over it (render/motion.py); raster frames are not blurred; 0: no blur.")
    exposure_target: Range(0.01, 1.0) = Field(
        (0.12, 0.22), description="Centre-weighted mean linear luminance auto exposure aims for (0.18: mid grey).")
    gain: Range(0.01, 100.0) = Field((0.5, 16.0), description="Smallest and largest gain auto exposure may set.")
    white_balance_error: Range(0.0, 0.5) = Field((0.0, 0.04), description="Sigma of each channel's white-balance gain error.")
    white_balance_warmth: Range(-1.0, 1.0) = Field(
        (-0.25, 0.25), description="Auto white balance misjudging the light's colour temperature: log of the red gain "
        "over the blue gain (red times e^(w/2), blue times e^(-w/2)); > 0 warm, < 0 cool.")
    vignetting: Range(0.0, 1.0) = Field((0.05, 0.3), description="Share of light lost in the image corners.")
    focus_distance: Range(0.05, 100.0) = Field((0.6, 1.2), description="Distance the fixed-focus lens is sharp at, m.")
    # The D435's colour lens (1.9 mm at f/2 over the OV2740's 1.4 um pixels, 1920 across) images a point 1/m away from
    # focus as a disc 1.9 mm x 0.95 mm / 1.4 um = 1.29 px wide at 1920 px, 0.86 px at 1280: a Gaussian sigma of 0.21 px
    # (a disc's sigma is a quarter of its width). The range adds the spread of fixed-focus units.
    defocus: Range(0.0, 20.0) = Field(
        (0.15, 0.35), description=f"Gaussian sigma of the blur per 1/m away from focus, px m, of a {SENSOR_STREAM_WIDTH} "
        "px wide frame (a narrower one blurs as many pixels fewer, render/sensor.py).")
    shot_noise: Range(0.0, 0.1) = Field(
        (0.00025, 0.0015), description=f"Shot-noise variance per unit of linear signal and gain, of a "
        f"{SENSOR_STREAM_WIDTH} px wide frame (a narrower one averages it down, render/sensor.py).")
    read_noise: Range(0.0, 0.1) = Field(
        (0.0005, 0.002), description=f"Read-noise sigma in linear units before the gain, of a {SENSOR_STREAM_WIDTH} px "
        "wide frame.")
    sharpen: Range(0.0, 3.0) = Field((0.2, 0.8), description="ISP unsharp-mask amount (1 = 100 %).")
    jpeg_quality: Range(10.0, 100.0) = Field((80.0, 100.0), description="JPEG quality of the stream; 100: not compressed.")


class CameraConfig(Strict):
    width: Count(16, 8192) = Field(640, description=f"Image width, px; width x height at most {MAX_PIXELS} px.")
    height: Count(16, 8192) = Field(480, description="Image height, px.")
    hfov_deg: Real(1.0, 179.0, low_open=True, high_open=True) = Field(57.0, description="Horizontal field of view, deg.")
    clip: tuple[Real(0.01, 100.0), Real(0.01, 100.0)] = Field(
        (0.2, 5.0), description="Near and far clipping distance (the depth range), m.")
    rate_hz: Real(0.001, MAX_CAMERA_RATE_HZ) = Field(
        5.0, description="Camera frame rate along the trajectory, Hz; at most controller.rate_hz.")
    sensor: SensorConfig = Field(SensorConfig(), description="The real camera's colour stream.")

    @model_validator(mode="after")
    def _clip(self) -> CameraConfig:
        if self.clip[0] >= self.clip[1]:
            raise ValueError("clip: near must be smaller than far")
        if self.width * self.height > MAX_PIXELS:
            raise ValueError(f"width: a {self.width} x {self.height} px image is more than {MAX_PIXELS} px")
        return self

    @property
    def fx(self) -> float:
        return self.width / (2.0 * math.tan(math.radians(self.hfov_deg) / 2.0))


class DepthNoiseConfig(Strict):
    enabled: bool = Field(True, description="Add depth noise and edge dropout to the rendered depth.")
    sigma_at_1m: Real(0.0, 0.5) = Field(0.002, description="Depth noise sigma at 1 m, m; grows with z^2.")
    edge_dropout: Fraction = Field(0.5, description="Probability that a depth pixel on an object's edge reads no depth.")


# Cycles caps every light-path bounce count at 1024.
Bounces = Count(0, 1024)


class BouncesConfig(Strict):
    """Cycles' light-path limits, for a user trading light transport against time. Samples, not
    bounces, are what a frame costs: shorter light paths save little time (docs/stages/render.md)."""

    total: Bounces = Field(6, description="Most bounces of a light path.")
    diffuse: Bounces = Field(3, description="Most diffuse bounces.")
    glossy: Bounces = Field(3, description="Most glossy bounces.")
    transmission: Bounces = Field(4, description="Most transmission bounces.")
    transparent: Bounces = Field(4, description="Most transparent bounces.")


class RasterConfig(Strict):
    """MuJoCo's OpenGL look, for a user trading it against speed: on 2 cores through llvmpipe the sun's shadows
    double a frame's cost or more, the multisampling adds half (docs/stages/render.md)."""

    shadows: bool = Field(False, description="The sun casts shadows (a 2048 x 2048 shadow map over the view).")
    antialias: Count(0, 16) = Field(4, description="Multisamples per pixel of the colour image; 0 turns antialiasing off.")


class RendererConfig(Strict):
    backend: Literal["cycles", "raster"] = Field("cycles", description="'cycles': Blender's path tracer; 'raster': MuJoCo's OpenGL renderer, milliseconds a frame, for tests and previews.")
    # Denoised, one sample is all the detector needs, at a small fraction of the cost of many (docs/stages/render.md).
    samples: Count(1, 65536) = Field(1, description="Cycles path-tracing samples per pixel.")
    adaptive_threshold: Fraction = Field(0.05, description="Cycles adaptive sampling noise threshold; 0 turns adaptive sampling off.")
    denoise: bool = Field(True, description="Denoise each frame with OpenImageDenoise.")
    denoise_quality: Literal["fast", "balanced", "high"] = Field(
        "fast", description="OpenImageDenoise effort; 'high' (accurate prefilter) costs seconds more per frame on a CPU."
    )
    bounces: BouncesConfig = Field(BouncesConfig(), description="Cycles' light-path bounce limits.")
    persistent_data: bool = Field(True, description="Keep Blender's scene data between frames.")
    threads: Count(0, 1024) = Field(0, description="Render threads; 0 means all cores.")
    device: Literal["cpu", "gpu", "auto"] = Field(
        "cpu", description="Where Cycles path-traces: 'cpu'; 'gpu': an NVIDIA GPU through OptiX or CUDA, refused when none "
        "answers; 'auto': the GPU when one answers, else the CPU. Speed only: render.json does not record it.")
    depth_noise: DepthNoiseConfig = Field(DepthNoiseConfig(), description="Noise model of the depth image.")
    raster: RasterConfig = Field(RasterConfig(), description="The raster backend's shadows and antialiasing.")
