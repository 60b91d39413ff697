"""The colour-sensor model: each effect does what a real camera does, zero settings change nothing, and a run with
the sensor on renders rgb_sensor/ beside rgb/ and detects on what the camera delivers."""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np

from renderloop.config import SensorConfig
from renderloop.config.camera import SENSOR_STREAM_WIDTH
from renderloop.perception.stage import run_detect
from renderloop.render.sensor import metered, sensor_rgb
from renderloop.render.srgb import decode_u8, encode_u8
from renderloop.render.stage import run_render
from renderloop.rundir import files, names

IDEAL = SensorConfig(enabled=True, exposure_target=(0.18, 0.18), gain=(1.0, 1.0), white_balance_error=(0.0, 0.0),
                     white_balance_warmth=(0.0, 0.0),
                     vignetting=(0.0, 0.0), defocus=(0.0, 0.0), shot_noise=(0.0, 0.0), read_noise=(0.0, 0.0),
                     sharpen=(0.0, 0.0), jpeg_quality=(100.0, 100.0))


def _flat(linear: float, shape=(60, 80)) -> np.ndarray:
    return np.full((*shape, 3), encode_u8(np.array(linear))[()], dtype=np.uint8)


def _depth(shape=(60, 80)) -> np.ndarray:
    return np.full(shape, 0.8, dtype=np.float32)


def test_a_sensor_with_every_effect_at_zero_delivers_the_ideal_frame():
    rgb = (np.random.default_rng(0).random((60, 80, 3)) * 255).astype(np.uint8)
    assert np.array_equal(sensor_rgb(rgb, _depth(), IDEAL, np.random.default_rng(1)), rgb)


def test_auto_exposure_brings_a_dark_frame_up_to_its_target_within_its_gain():
    dark = _flat(0.02)
    exposed = sensor_rgb(dark, _depth(), IDEAL.model_copy(update={"gain": (0.5, 16.0)}), np.random.default_rng(0))
    assert abs(metered(decode_u8(exposed)) - 0.18) < 0.01
    capped = sensor_rgb(dark, _depth(), IDEAL.model_copy(update={"gain": (0.5, 2.0)}), np.random.default_rng(0))
    assert metered(decode_u8(capped)) < 0.05  # the gain it may not exceed leaves it dark


def test_a_misjudged_colour_temperature_turns_a_grey_frame_warm_or_cool_and_leaves_green_alone():
    grey = _flat(0.18)
    warm, cool = (decode_u8(sensor_rgb(grey, _depth(), IDEAL.model_copy(update={"white_balance_warmth": (w, w)}),
                                            np.random.default_rng(0))).mean(axis=(0, 1)) for w in (0.4, -0.4))
    assert warm[0] > 1.15 * warm[1] > 1.15 * warm[2]
    assert cool[2] > 1.15 * cool[1] > 1.15 * cool[0]
    assert abs(warm[1] - cool[1]) < 0.01


FULL_WIDTH = (20, SENSOR_STREAM_WIDTH)  # a strip of the stream the noise is stated for


def test_the_gain_makes_dark_regions_noisier_than_bright_ones():
    noisy = IDEAL.model_copy(update={"gain": (0.5, 16.0), "shot_noise": (0.002, 0.002), "read_noise": (0.002, 0.002)})
    dark = decode_u8(sensor_rgb(_flat(0.015, FULL_WIDTH), _depth(FULL_WIDTH), noisy, np.random.default_rng(0)))
    bright = decode_u8(sensor_rgb(_flat(0.18, FULL_WIDTH), _depth(FULL_WIDTH), noisy, np.random.default_rng(0)))
    assert abs(dark.mean() - bright.mean()) < 0.02  # both exposed to the same level
    assert dark.std() > 2 * bright.std()


def test_a_frame_a_quarter_as_wide_as_the_stream_has_a_quarter_of_its_noise():
    noisy = IDEAL.model_copy(update={"shot_noise": (0.002, 0.002), "read_noise": (0.004, 0.004)})

    def noise(width: int) -> float:
        shape = (width * 3 // 4, width)  # as many pixels as it takes for the figure to settle, at either width
        return float(decode_u8(sensor_rgb(_flat(0.18, shape), _depth(shape), noisy, np.random.default_rng(0))).std())

    full, quarter = noise(SENSOR_STREAM_WIDTH), noise(SENSOR_STREAM_WIDTH // 4)
    assert 0.01 < full < 0.05  # linear units: the stated noise, well above a grey level's step
    assert abs(quarter / full - 0.25) < 0.03  # 16 of the stream's pixels binned into one average their noise down


def test_defocus_blurs_what_lies_off_focus_by_a_circle_that_shrinks_with_the_frames_width():
    lens = IDEAL.model_copy(update={"focus_distance": (1.0, 1.0), "defocus": (1.5, 1.5)})

    def edge_spread(width: int, depth_m: float) -> float:
        """The sigma of a black-white edge across the frame, in the stream's pixels: its profile's derivative is the
        blur's kernel, whose second moment is its variance."""
        rgb = np.zeros((4, width, 3), dtype=np.uint8)
        rgb[:, width // 2:] = 255
        depth = np.full((4, width), depth_m, dtype=np.float32)
        profile = decode_u8(sensor_rgb(rgb, depth, lens, np.random.default_rng(0)))[2, :, 1]
        kernel = np.diff(profile) / np.diff(profile).sum()
        x = np.arange(kernel.size)
        mean = (kernel * x).sum()
        return float(np.sqrt((kernel * (x - mean) ** 2).sum())) * SENSOR_STREAM_WIDTH / width

    assert edge_spread(SENSOR_STREAM_WIDTH, 1.0) < 0.01  # in focus: sharp
    near = edge_spread(SENSOR_STREAM_WIDTH, 0.25)  # 3 /m off focus: sigma 1.5 px m x 3 /m = 4.5 px
    assert abs(near - 4.5) < 0.2
    assert abs(edge_spread(SENSOR_STREAM_WIDTH // 2, 0.25) - near) < 0.3  # the same blur in the stream's pixels


def test_vignetting_darkens_the_corners_and_the_draws_repeat_with_the_seed():
    vignetted = IDEAL.model_copy(update={"vignetting": (0.3, 0.3)})
    out = decode_u8(sensor_rgb(_flat(0.18), _depth(), vignetted, np.random.default_rng(0)))
    assert out[0, 0].mean() < 0.8 * out[30, 40].mean()
    settings = SensorConfig(enabled=True)
    rgb = (np.random.default_rng(3).random((60, 80, 3)) * 255).astype(np.uint8)
    one, two = (sensor_rgb(rgb, _depth(), settings, np.random.default_rng(9)) for _ in range(2))
    assert np.array_equal(one, two) and not np.array_equal(one, rgb)


def test_a_run_with_the_sensor_on_renders_rgb_sensor_and_detects_on_it(complete_run: Path, tmp_path: Path):
    run = tmp_path / "run"
    shutil.copytree(complete_run, run)
    config = files.read_config(run)
    config = config.override({"camera": {"sensor": SensorConfig(enabled=True)}})
    files.write_config(run, config)
    assert run_render(run, config)  # another camera: the render starts over
    rendered = sorted(p.name for p in (run / names.RGB_SENSOR).iterdir())
    assert rendered == sorted(p.name for p in (run / names.RGB).iterdir()) and (run / names.frames_index(names.RGB_SENSOR)).is_file()
    assert (run / names.frame_file(names.RGB, 0)).read_bytes() == (complete_run / names.frame_file(names.RGB, 0)).read_bytes()
    assert (run / names.frame_file(names.RGB_SENSOR, 0)).read_bytes() != (run / names.frame_file(names.RGB, 0)).read_bytes()
    run_detect(run, config, force=True)
    detections = files.read_detections(run, len(files.read_poses(run)[0]))
    assert all(frame.image.startswith(f"{names.RGB_SENSOR}/") for frame in detections.frames)
