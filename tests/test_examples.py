"""The Python a user is shown runs as shown: every ```python block of the documentation, and examples/.

A block is run as a script of its own in an empty folder (its relative paths, `runs/api` say, land there), the
way a reader pastes it. The docs' blocks fly the demo for 20 s and its whole scan with the raster camera, and
make one Gymnasium step: about 20 s together; the example policy flies one short episode.
"""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PAGES = [ROOT / "README.md", *sorted((ROOT / "docs").rglob("*.md"))]
BLOCK = re.compile(r"^```python\n(.*?)^```", re.S | re.M)


def python_blocks() -> list:
    """Each block as a pytest parameter (name, code), its id the page and the block's number there."""
    return [pytest.param(f"{page.relative_to(ROOT)}#{number}", code, id=f"{page.relative_to(ROOT)}#{number}")
            for page in PAGES for number, code in enumerate(BLOCK.findall(page.read_text(encoding="utf-8")), start=1)]


def run_python(arguments: list[str], folder: Path) -> subprocess.CompletedProcess:
    environment = {**os.environ, "MUJOCO_GL": os.environ.get("MUJOCO_GL", "egl")}
    return subprocess.run([sys.executable, *arguments], cwd=folder, env=environment, capture_output=True, text=True,
                          timeout=300)


def test_the_docs_show_python_to_run():
    """Guards the test below against a changed fence or page layout that would leave it nothing to check."""
    assert any(block.values[0].startswith("docs/stages/loop.md") for block in python_blocks())


@pytest.mark.parametrize(("name", "code"), python_blocks())
def test_every_python_block_of_the_docs_runs_as_shown(name, code, tmp_path):
    (tmp_path / "block.py").write_text(code, encoding="utf-8")
    result = run_python(["block.py"], tmp_path)
    assert result.returncode == 0, f"{name}:\n{code}\n{result.stderr[-3000:]}"


def test_the_example_policy_flies_its_episodes_and_prints_a_row_each(tmp_path):
    result = run_python([str(ROOT / "examples" / "random_policy.py"), "--episodes", "1", "--max-views", "2"], tmp_path)
    assert result.returncode == 0, result.stderr[-3000:]
    header, *rows = [line.split() for line in result.stdout.splitlines() if line.strip()]
    assert header[:3] == ["episode", "plant", "return"]
    assert len(rows) == 1 and rows[0][0] == "0" and int(rows[0][3]) <= 2  # one episode, at most the views asked for


UNGUARDED = """
from renderloop import Simulation, load_config

config = load_config("demo").override({"camera": {"width": 64, "height": 48, "rate_hz": 0.04},  # four frames of the 86 s scan
                                       "renderer": {"backend": "cycles", "samples": 1}})
with Simulation(config, "run") as sim:
    sim.follow(sim.scan_trajectory())
    camera = sim.add_camera(workers=2)
    sim.run()
    print(len([frame for frame in camera.frames_until(sim.end)]))
"""


def test_a_script_without_a_main_guard_renders_with_cycles_workers(tmp_path):
    """Spawned workers run the main script again unless `if __name__ == "__main__":` guards it; a reader's script
    has none, and its Cycles workers must start without it (they hung, and the script with them)."""
    (tmp_path / "script.py").write_text(UNGUARDED, encoding="utf-8")
    result = run_python(["script.py"], tmp_path)
    assert result.returncode == 0, result.stderr[-3000:]
    assert int(result.stdout) >= 3  # the script's one line: its workers print to stderr
