"""The run directory: where stages find each other's files.

A stage is complete when all of its outputs exist; outputs are written atomically,
so existing means complete. A run directory belongs to one resolved config: asking
it to run another config is refused unless the user says --force, because mixing
two seeds' files in one directory would make every later figure a lie.
"""

from __future__ import annotations

from pathlib import Path

from renderloop.config import Config, load_resolved
from renderloop.errors import UserError
from renderloop.io.atomic import write_text

CONFIG_FILE = "config.yaml"


def check_target(run_dir: Path) -> Path:
    """Refuse an output path that is a file; the directory itself is made only when there is something to write."""
    run_dir = Path(run_dir)
    if run_dir.exists() and not run_dir.is_dir():
        raise UserError(f"--out {run_dir}: is a file, not a directory")
    return run_dir


def complete(run_dir: Path, outputs: tuple[str, ...]) -> bool:
    return all((run_dir / name).is_file() for name in outputs)


def check_config(run_dir: Path, config: Config) -> None:
    """Refuse to add files of one config to a run directory made with another."""
    path = run_dir / CONFIG_FILE
    if path.is_file() and load_resolved(path) != config:
        raise UserError(
            f"{path}: this run directory was made with another config; "
            "use --force to start it again, or another --out"
        )


def write_config(run_dir: Path, config: Config) -> None:
    run_dir.mkdir(parents=True, exist_ok=True)
    write_text(run_dir / CONFIG_FILE, config.to_yaml())


def read_config(run_dir: Path) -> Config:
    path = Path(run_dir) / CONFIG_FILE
    if not path.is_file():
        raise UserError(f"{run_dir}: not a run directory (no {CONFIG_FILE}; run `renderloop scene` first)")
    return load_resolved(path)
