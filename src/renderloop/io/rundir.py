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


def complete(run_dir: Path, outputs: tuple[str, ...], inputs: tuple[str, ...] = ()) -> bool:
    """All outputs exist and none is older than an input (as make decides), so redoing
    an early stage with --force makes the later ones run again."""
    paths = [run_dir / name for name in outputs]
    if not all(path.is_file() for path in paths):
        return False
    sources = [run_dir / name for name in inputs if (run_dir / name).is_file()]
    if not sources:
        return True
    return min(path.stat().st_mtime_ns for path in paths) >= max(path.stat().st_mtime_ns for path in sources)


def require(run_dir: Path, names: tuple[str, ...], stage: str) -> None:
    """Refuse to run a stage whose inputs an earlier stage has not written yet."""
    missing = [name for name in names if not (run_dir / name).is_file()]
    if missing:
        raise UserError(f"{run_dir}: missing {', '.join(missing)} (run `renderloop {stage}` first)")


def _what_it_computes(config: Config) -> Config:
    """The config less the renderer's thread count, which decides how fast frames come, not what they hold."""
    return config.model_copy(update={"renderer": config.renderer.model_copy(update={"threads": 0})})


def check_config(run_dir: Path, config: Config) -> None:
    """Refuse to add files of one config to a run directory made with another."""
    path = run_dir / CONFIG_FILE
    if path.is_file() and _what_it_computes(load_resolved(path)) != _what_it_computes(config):
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
