"""Hostile or broken image files (issue 21): every image a verb reads is size-checked before it is decoded, and a
decompression bomb, a truncated file or a file that is not an image ends in one line naming it, exit code 2.

The bombs are a few hundred bytes: a PNG whose IHDR claims 100000 x 100000 pixels and a real JPEG whose SOF0 claims
65000 x 65000. Their pixel data is garbage, so an image decoded before the size check would fail as corrupt, not as
too large: the size message itself shows that nothing was decoded.
"""

from __future__ import annotations

import io
import json
import shutil
import struct
import time
import warnings
import zlib
from pathlib import Path

import numpy as np
import pytest
from conftest import cli
from PIL import Image, ImageFile

from renderloop.errors import UserError
from renderloop.io.images import MAX_PIXELS, check_image, open_image, read_image
from renderloop.render.frames import read_png

ERROR_PREFIX = "renderloop: error:"


def _chunk(kind: bytes, data: bytes) -> bytes:
    return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))


def png_header_claiming(width: int, height: int) -> bytes:
    """An 8-bit RGB PNG header of any size, followed by a little pixel data that does not fill it."""
    ihdr = struct.pack(">IIBBBBB", width, height, 8, 2, 0, 0, 0)
    return (b"\x89PNG\r\n\x1a\n" + _chunk(b"IHDR", ihdr) + _chunk(b"IDAT", zlib.compress(bytes(1000)))
            + _chunk(b"IEND", b""))


def jpeg_claiming(width: int, height: int) -> bytes:
    """A real 16 x 16 JPEG with its SOF0 height and width fields patched."""
    buffer = io.BytesIO()
    Image.new("RGB", (16, 16), (200, 30, 30)).save(buffer, format="JPEG")
    data = bytearray(buffer.getvalue())
    sof = data.index(b"\xff\xc0")  # marker, length (2), precision (1), then height and width
    struct.pack_into(">HH", data, sof + 5, height, width)
    return bytes(data)


def rgb_png() -> bytes:
    rgb = (np.arange(48 * 64 * 3) % 251).astype(np.uint8).reshape(48, 64, 3)
    buffer = io.BytesIO()
    Image.fromarray(rgb).save(buffer, format="PNG")
    return buffer.getvalue()


# --- the bad files: each writes itself at a path; the fragment its error line must hold --------------------------

BAD_FILES = {
    "png-bomb": (lambda path, frame: path.write_bytes(png_header_claiming(100_000, 100_000)), "10,000,000,000 pixels"),
    "jpeg-bomb": (lambda path, frame: path.write_bytes(jpeg_claiming(65_000, 65_000)), "4,225,000,000 pixels"),
    "truncated-png": (lambda path, frame: path.write_bytes(frame[: len(frame) // 2]), "truncated or corrupt data"),
    "text-not-image": (lambda path, frame: path.write_text("peppers: 12\n", encoding="utf-8"), "not a readable"),
}


def assert_one_line_naming(code: int, out: str, err: str, path: Path, fragment: str) -> None:
    assert "Traceback" not in err and "Warning" not in err, err
    lines = [line for line in err.splitlines() if line.strip()]
    errors = [line for line in lines if ERROR_PREFIX in line]
    assert len(errors) == 1 and lines[-1] == errors[0] and errors[0].startswith(ERROR_PREFIX), err
    assert code == 2, err
    assert str(path) in errors[0] and fragment in errors[0], errors[0]


@pytest.fixture
def broken_run(complete_run: Path, tmp_path: Path, request) -> tuple[Path, Path, str]:
    """A copy of the complete run with its first RGB frame replaced by the bad file; the frame, and what its error says."""
    run = tmp_path / "run"
    shutil.copytree(complete_run, run)
    frame = run / "rgb" / "000000.png"
    write, fragment = BAD_FILES[request.param]
    write(frame, frame.read_bytes())
    if request.param == "jpeg-bomb":  # a run frame must be a PNG: a JPEG is refused as such, before its size is read
        fragment = "not a readable PNG"
    return run, frame, fragment


# --- the verbs, on each bad file ---------------------------------------------------------------------------------

@pytest.mark.parametrize("kind", BAD_FILES)
def test_a_bad_photo_stops_detect_images_with_one_line_naming_it(kind: str, complete_run: Path, tmp_path: Path, monkeypatch,
                                                                 capsys):
    photos = tmp_path / "photos"
    photos.mkdir()
    bad = photos / ("photo.jpg" if kind == "jpeg-bomb" else "photo.png")
    write, fragment = BAD_FILES[kind]
    write(bad, (complete_run / "rgb" / "000000.png").read_bytes())
    out = tmp_path / "found.json"

    code, stdout, stderr = cli(monkeypatch, capsys, "detect", "--images", str(photos), "--out", str(out))

    assert_one_line_naming(code, stdout, stderr, bad, fragment)
    assert json.loads(out.read_text())["complete"] is False


@pytest.mark.parametrize("broken_run", BAD_FILES, indirect=True)
def test_a_bad_frame_stops_dataset_from_runs_with_one_line_naming_it(broken_run, tmp_path: Path, monkeypatch, capsys):
    run, frame, fragment = broken_run

    code, stdout, stderr = cli(monkeypatch, capsys, "dataset-from-runs", str(run), "--out", str(tmp_path / "dataset"),
                               "--val-runs", "0")

    assert_one_line_naming(code, stdout, stderr, frame, fragment)


@pytest.mark.parametrize("broken_run", BAD_FILES, indirect=True)
def test_a_bad_frame_stops_detect_on_a_run_with_one_line_naming_it(broken_run, monkeypatch, capsys):
    run, frame, fragment = broken_run

    code, stdout, stderr = cli(monkeypatch, capsys, "detect", str(run), "--force")

    assert_one_line_naming(code, stdout, stderr, frame, fragment)


@pytest.mark.parametrize("kind", ["png-bomb", "jpeg-bomb", "text-not-image"])
def test_a_bad_training_image_stops_train_with_one_line_before_training_starts(kind: str, tmp_path: Path, monkeypatch, capsys):
    """Checked in the trainer's process (headers only), so the default data-loading worker does not wrap the error."""
    dataset = tmp_path / "dataset"
    (dataset / "images").mkdir(parents=True)
    (dataset / "annotations").mkdir()
    bad = dataset / "images" / "000000.jpg"
    write, fragment = BAD_FILES[kind]
    write(bad, rgb_png())
    coco = {"images": [{"id": 0, "file_name": "images/000000.jpg", "width": 64, "height": 48}], "annotations": [],
            "categories": [{"id": 1, "name": "ripe"}, {"id": 2, "name": "unripe"}]}
    for split in ("train", "val"):
        (dataset / "annotations" / f"instances_{split}.json").write_text(json.dumps(coco), encoding="utf-8")

    code, stdout, stderr = cli(monkeypatch, capsys, "train", str(dataset), "--out", str(tmp_path / "model" / "model.onnx"))

    assert_one_line_naming(code, stdout, stderr, bad, fragment)


# --- io.images itself ----------------------------------------------------------------------------------------------

def test_a_png_and_a_jpeg_read_back_exactly(tmp_path: Path):
    rgb = (np.arange(48 * 64 * 3) % 251).astype(np.uint8).reshape(48, 64, 3)
    Image.fromarray(rgb).save(tmp_path / "frame.png")
    Image.fromarray(rgb).save(tmp_path / "photo.jpg", quality=90)
    depth = (np.arange(48 * 64) * 17).astype(np.uint16).reshape(48, 64)
    Image.fromarray(depth).save(tmp_path / "depth.png")

    assert np.array_equal(read_image(tmp_path / "frame.png"), rgb)
    assert np.array_equal(read_png(tmp_path / "frame.png", np.uint8), rgb)
    with Image.open(tmp_path / "photo.jpg") as pillow:  # lossy: the same pixels as Pillow decodes
        assert np.array_equal(read_image(tmp_path / "photo.jpg", "RGB"), np.asarray(pillow.convert("RGB")))
    got = read_png(tmp_path / "depth.png", np.uint16)
    assert got.dtype == np.uint16 and np.array_equal(got, depth)
    assert open_image(tmp_path / "frame.png", "L").mode == "L" and check_image(tmp_path / "photo.jpg") == (64, 48)


@pytest.mark.parametrize("side, claim", [(9000, "9000 x 9000 = 81,000,000 pixels"),  # over ours, under Pillow's limit
                                         (10_000, "100,000,000 pixels"),  # where Pillow only warns
                                         (100_000, "10,000,000,000 pixels")])  # where Pillow refuses
def test_a_header_claiming_too_many_pixels_is_refused_before_decoding(side: int, claim: str, tmp_path: Path):
    path = tmp_path / "bomb.png"
    path.write_bytes(png_header_claiming(side, side))
    began = time.perf_counter()
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # Pillow's DecompressionBombWarning must become our error, never a warning
        for read in (read_image, check_image, lambda p: read_png(p, np.uint8)):
            with pytest.raises(UserError, match=f"bomb.png: its header claims {claim}, more than the {MAX_PIXELS:,} allowed"):
                read(path)
    assert time.perf_counter() - began < 1.0


def test_a_jpeg_claiming_too_many_pixels_is_refused(tmp_path: Path):
    path = tmp_path / "bomb.jpg"
    path.write_bytes(jpeg_claiming(65_000, 65_000))
    with pytest.raises(UserError, match="bomb.jpg: its header claims 4,225,000,000 pixels"):
        read_image(path, "RGB")


def test_truncated_missing_and_foreign_files_each_give_one_line_naming_them(tmp_path: Path):
    (tmp_path / "half.png").write_bytes(rgb_png()[:300])
    (tmp_path / "notes.png").write_text("not an image", encoding="utf-8")
    Image.new("RGB", (8, 8)).save(tmp_path / "frame.gif")
    (tmp_path / "folder.png").mkdir()
    Image.fromarray(np.full((4, 4), 60000, np.uint16)).save(tmp_path / "deep.png")
    frame = lambda path: read_png(path, np.uint8)  # noqa: E731
    cases = [(read_image, "half.png", r"half.png: not a readable image \(truncated or corrupt data\)$"),
             (frame, "half.png", r"half.png: not a readable PNG \(truncated or corrupt data\)$"),
             (read_image, "notes.png", "notes.png: not a readable image$"),
             (read_image, "frame.gif", "frame.gif: not a readable image$"),  # only PNG and JPEG are identified at all
             (read_image, "missing.png", "missing.png: no such file$"),
             (read_image, "folder.png", "folder.png: a folder, not an image$"),
             (frame, "deep.png", "deep.png: holds uint16 values up to 60000, more than uint8 holds$")]
    for read, name, message in cases:
        with pytest.raises(UserError, match=message) as raised:
            read(tmp_path / name)
        assert "\n" not in str(raised.value)


def test_a_file_name_holding_a_newline_is_quoted_so_the_error_stays_one_line(tmp_path: Path):
    path = tmp_path / "two\nlines.png"
    path.write_text("not an image", encoding="utf-8")
    with pytest.raises(UserError) as raised:
        read_image(path)
    assert "\n" not in str(raised.value) and "two\\nlines.png" in str(raised.value)


def test_truncated_images_are_never_loaded_as_grey(tmp_path: Path, monkeypatch):
    """Pillow pads a truncated image with grey when LOAD_TRUNCATED_IMAGES is set; reading then is a bug, not input."""
    assert ImageFile.LOAD_TRUNCATED_IMAGES is False
    (tmp_path / "half.png").write_bytes(rgb_png()[:300])
    monkeypatch.setattr(ImageFile, "LOAD_TRUNCATED_IMAGES", True)
    with pytest.raises(RuntimeError, match="LOAD_TRUNCATED_IMAGES"):
        read_image(tmp_path / "half.png")
