"""Failure behaviour of a whole run: SIGKILL at moments across the stages, an unwritable directory, a full disk.

Each case runs the real `renderloop run` as a child process on a fast config (raster
renderer, a frame every 4 s), so the kill lands wherever the operating system stops
it, as it would for a user's Ctrl-\\ or an out-of-memory killer.
"""

from __future__ import annotations

import hashlib
import os
import shutil
import signal
import subprocess
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest
import yaml

from renderloop.io.ownership import read_ledger

FAST = {"renderer": {"backend": "raster"}, "camera": {"rate_hz": 0.25}}
# Seconds of each stage, and the list of files renderloop wrote (a killed write may leave a name listed whose file
# never appeared): the files that may differ between two runs.
VOLATILE = {"timings.json", ".renderloop-files", "report.html"}  # the report shows the seconds and the folder's name
Trigger = Callable[[Path], bool]


def _exists(name: str) -> Trigger:
    return lambda run_dir: (run_dir / name).exists()


# Each a moment inside one stage: the first file that stage writes has appeared and it is still working.
KILL_POINTS: dict[str, Trigger] = {
    "scene": _exists("config.yaml"),
    "plan": _exists("waypoints.csv"),
    "fly": _exists("trajectory.csv"),
    "render": _exists("masks/000004.png"),
    "detect": _exists(".detections.cache.jsonl"),
    "count": _exists("detections.png"),
}


def _command(config: Path, out: Path) -> list[str]:
    return [sys.executable, "-m", "renderloop", "run", "--config", str(config), "--out", str(out)]


def _files(run_dir: Path) -> dict[str, str]:
    return {str(path.relative_to(run_dir)): hashlib.sha256(path.read_bytes()).hexdigest()
            for path in sorted(run_dir.rglob("*")) if path.is_file() and path.name not in VOLATILE}


@pytest.fixture(scope="module")
def config(tmp_path_factory) -> Path:
    path = tmp_path_factory.mktemp("faults") / "fast.yaml"
    path.write_text(yaml.safe_dump(FAST))
    return path


@dataclass(frozen=True)
class Reference:
    run_dir: Path  # an uninterrupted run of the config: copy it before changing it
    files: dict[str, str]


@pytest.fixture(scope="module")
def reference(config: Path, tmp_path_factory) -> Reference:
    out = tmp_path_factory.mktemp("faults") / "reference"
    subprocess.run(_command(config, out), check=True, capture_output=True)
    return Reference(out, _files(out))


def test_a_run_killed_in_each_stage_in_turn_resumes_to_the_same_files(config: Path, reference: Reference, tmp_path: Path):
    """Killed in the first stage, started again and killed in the next, and so on: each start takes over what the
    kill left (one run through the stages, where a fresh run killed in each would fly and render six times)."""
    out = tmp_path / "run"
    for stage, reached in KILL_POINTS.items():
        delay = np.random.default_rng(list(KILL_POINTS).index(stage)).uniform(0.0, 0.05)  # a moment past the trigger
        child = subprocess.Popen(_command(config, out), stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        try:
            while child.poll() is None and not reached(out):
                time.sleep(0.002)
            time.sleep(delay)
            child.send_signal(signal.SIGKILL)
        finally:
            child.wait()
        assert child.returncode == -signal.SIGKILL, f"the run ended before the kill point in {stage}"
        assert _files(out) != reference.files, f"killed in {stage}, it had written every file"

    subprocess.run(_command(config, out), check=True, capture_output=True)
    assert _files(out) == reference.files
    assert not [p for p in out.rglob("*") if p.name.endswith(".partial") or p.name.startswith(".detections.cache")]
    assert set(_files(out)) - {".renderloop.json"} <= set(read_ledger(out))  # every file is one renderloop knows it wrote


def _restricted(command: list[str]) -> list[str]:
    """Root writes anywhere; without CAP_DAC_OVERRIDE it meets the permission bits like any user."""
    if os.geteuid() != 0:
        return command
    if not shutil.which("setpriv"):
        pytest.skip("running as root without util-linux's setpriv to drop the override capability")
    return ["setpriv", "--bounding-set=-dac_override,-dac_read_search", *command]


def test_an_unwritable_run_directory_is_one_clear_line_and_keeps_its_files(config: Path, reference: Reference, tmp_path: Path):
    out = tmp_path / "run"
    shutil.copytree(reference.run_dir, out)
    (out / "counts.json").unlink()  # the count stage must write again, into a directory it may not write
    before = _files(out)
    out.chmod(0o555)
    try:
        ended = subprocess.run(_restricted(_command(config, out)), capture_output=True, text=True)
    finally:
        out.chmod(0o755)
    last = ended.stderr.strip().splitlines()[-1]
    assert ended.returncode == 1 and "Traceback" not in ended.stderr
    assert last.startswith("renderloop: error: ") and "Permission denied" in last and str(out) in last
    assert _files(out) == before


def test_a_full_disk_is_one_clear_line_and_every_file_left_is_complete(config: Path, reference: Reference, tmp_path: Path):
    """RLIMIT_FSIZE makes every write past the limit fail as ENOSPC would, with no root and no loop device."""
    import resource

    out = tmp_path / "run"
    limit = 300_000  # bytes: room for the scene's files, not for the 100 Hz trajectory that follows
    ended = subprocess.run(_command(config, out), capture_output=True, text=True,
                           preexec_fn=lambda: resource.setrlimit(resource.RLIMIT_FSIZE, (limit, limit)))
    last = ended.stderr.strip().splitlines()[-1]
    assert ended.returncode == 1 and "Traceback" not in ended.stderr
    assert last.startswith(f"renderloop: error: {out}/") and last.endswith("File too large")
    left = _files(out)
    assert left and all(reference.files[name] == digest for name, digest in left.items())  # complete, or not there at all
    subprocess.run(_command(config, out), check=True, capture_output=True)  # room again: the run finishes
    assert _files(out) == reference.files
