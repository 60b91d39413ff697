"""A pipeline stage: what it needs, what it makes, and the one check that decides whether it runs.

Every stage runs the same way (`Stage.run`): the run directory must be ours
(`ownership.claim`), its inputs must exist (naming the verb that writes a missing
one), and a stage whose outputs all exist, are newer than its inputs (as make
decides, so redoing an early stage makes the later ones run again) and are current
for the config is skipped, so a killed run resumes. `--force` redoes it.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from renderloop.config import Config
from renderloop.io import ownership
from renderloop.parallel import LOCAL, Executor
from renderloop.rundir import files, names

Progress = Callable[[int, int], None]


@dataclass(frozen=True)
class Job:
    """How a stage is asked to run; none of it changes what the stage computes."""

    force: bool = False
    progress: Progress | None = None
    executor: Executor = LOCAL  # where the stages that spread work run it


@dataclass(frozen=True)
class Stage:
    name: str
    needs: tuple[str, ...]
    work: Callable[[Path, Config, Job], None]
    # Are the existing outputs made from this config? False redoes the stage; a stage may refuse (UserError) instead.
    current: Callable[[Path, Config], bool] | None = None
    covers: tuple[str, ...] = ()  # the stages whose outputs this one makes, when not just its own (the online loop)

    @property
    def makes(self) -> tuple[str, ...]:
        return tuple(name for stage in (self.covers or (self.name,)) for name in names.OUTPUTS[stage])

    def complete(self, run_dir: Path) -> bool:
        outputs = [run_dir / name for name in self.makes]
        if not all(path.is_file() for path in outputs):
            return False
        sources = [run_dir / name for name in self.needs if (run_dir / name).is_file()]
        if not sources:
            return True
        return min(path.stat().st_mtime_ns for path in outputs) >= max(path.stat().st_mtime_ns for path in sources)

    def run(self, run_dir: Path, config: Config, force: bool = False, progress: Progress | None = None,
            executor: Executor = LOCAL) -> bool:
        """Run the stage, or skip it when its outputs are complete and current; True when it ran."""
        run_dir = Path(run_dir)
        files.require(run_dir, self.needs)
        claim(run_dir, write=bool(self.needs))  # the first stage makes the directory once its input proved good
        if not force and (self.current is None or self.current(run_dir, config)) and self.complete(run_dir):
            return False
        self.work(run_dir, config, Job(force, progress, executor))
        return True


def claim(run_dir: Path, write: bool = True) -> Path:
    """Make `run_dir` a renderloop run directory, or refuse it in one line (see `ownership.claim`)."""
    return ownership.claim(run_dir, ownership.RUN, write=write)
