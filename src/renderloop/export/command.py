"""`renderloop export`: check both targets before writing either, then export what the run holds."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

from renderloop.errors import UserError
from renderloop.export.contents import read_run
from renderloop.io import ownership


def _check_target(path: Path, force: bool, suffix: str | None = None) -> None:
    if suffix and path.suffix != suffix:
        raise UserError(f"{path}: a Rerun recording must end in {suffix}")
    if path.exists() and not force:
        raise UserError(f"{path}: exists; use --force to replace it")
    if not path.parent.is_dir():
        raise UserError(f"{path.parent}: no such directory")
    if suffix is None:  # a bag folder is replaced whole: only one renderloop wrote
        ownership.check_replaceable(path, ownership.BAG)


def export_run(run_dir: Path, rosbag: Path | None, rerun: Path | None, every: int, force: bool,
               echo: Callable[[str], None]) -> list[str]:
    """Write the asked-for exports; returns what the run directory lacked (exported without it)."""
    if rosbag is None and rerun is None:
        raise UserError("nothing to export: give --rosbag OUT and/or --rerun OUT.rrd")
    for target, suffix in ((rosbag, None), (rerun, ".rrd")):
        if target is not None:
            _check_target(Path(target), force, suffix)
    contents = read_run(Path(run_dir))
    if rosbag is not None:
        from renderloop.export.rosbag import write_rosbag

        counts = write_rosbag(contents, Path(rosbag), every)
        echo(f"export: wrote {rosbag} ({sum(counts.values())} messages on {len(counts)} topics)")
    if rerun is not None:
        from renderloop.export.rerun_recording import write_rerun

        logged = write_rerun(contents, Path(rerun), every)
        echo(f"export: wrote {rerun} ({', '.join(f'{count} {name}' for name, count in logged.items())})")
    return contents.missing
