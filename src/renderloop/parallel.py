"""Work spread over local processes or a Ray cluster, the same way for every caller.

Where the work runs is one value, `Executor` (local or Ray, how many workers, the cluster's
address), validated once; the CLI's `--executor/--workers/--address` build it. The work
takes one of two shapes:

- `map_tasks`: one function over independent calls (the dataset's scenes, the evaluation's
  runs), the results in order or as they finish; Ray runs them as tasks, on every CPU of
  the cluster;
- `Workers`: long-lived workers, each holding an object built once (a renderer holding its
  scene) and asked to run its methods (the batch render's chunks, the online camera's
  frames); Ray runs them as actors, one per worker.

One local worker works in this process, unless it must leave this process free (the online
camera's Cycles frames, while the physics keeps stepping); more are spawned processes, which
stop once the process that started them is gone, however it ended. A worker's `UserError`,
in its work or in building its object, comes back to the caller as the one line it is,
whichever the executor.

A low-level module: render, loop, dataset and evaluation use it, it uses none of them.
"""

from __future__ import annotations

import os
import socket
import sys
import threading
import time
from collections.abc import Callable, Iterable, Iterator
from concurrent.futures import Future, ProcessPoolExecutor, as_completed
from contextlib import ExitStack, contextmanager
from dataclasses import dataclass
from multiprocessing import get_context
from typing import Any, Literal

from pydantic import Field, ValidationError

from renderloop.config import Config
from renderloop.config.fields import Count, Strict
from renderloop.errors import UserError, problem


class Executor(Strict):
    """Where work runs: local processes, or tasks and actors on a Ray cluster."""

    kind: Literal["local", "ray"] = Field(
        "local", description="'local': spawned processes on this machine; 'ray': tasks and actors on a Ray cluster.")
    workers: Count(1, 1024) = Field(1, description="Processes (or Ray actors, and the CPUs of a Ray cluster started "
                                    "here) working at once; one local worker works in this process.")
    address: str | None = Field(None, description="The Ray cluster to join (HOST:PORT, ray://HOST:PORT or auto); "
                                "None starts a local one. Only with kind 'ray'.")

    @classmethod
    def of(cls, kind: str = "local", workers: int = 1, address: str | None = None) -> Executor:
        """The executor the CLI's --executor, --workers and --address name, or their one-line UserError."""
        try:
            return cls(kind=kind, workers=workers, address=address)
        except ValidationError as error:
            raise UserError(f"executor: {problem(error)}") from None

    @property
    def threads(self) -> int:
        """Render threads each worker takes: the cores shared out among the workers (0, all of them, for one)."""
        return 0 if self.workers <= 1 else max(1, (os.cpu_count() or 1) // self.workers)

    def check_answers(self) -> None:
        """Refuse, in one line, a Ray address no cluster answers at: for a caller that must know before it works."""
        if self.kind == "ray" and self.address:
            _check_answers(self.address)

    def share_cores(self, config: Config) -> Config:
        """`config` rendering on one worker's share of the cores, unless the config sets its own thread count."""
        if config.renderer.threads or not self.threads:
            return config
        return config.override({"renderer": {"threads": self.threads}})


LOCAL = Executor()  # one worker, in this process

# A worker's UserError -----------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class _Refused:
    """A worker's UserError on its way back: its one line, not the exception, which Ray would wrap in a traceback."""

    message: str


def _trapped(call: Callable[..., Any], *args: Any) -> Any:
    try:
        return call(*args)
    except UserError as error:
        return _Refused(str(error))


def _unwrap(result: Any) -> Any:
    if isinstance(result, _Refused):
        raise UserError(result.message)
    return result


class Pending:
    """A call's result to come: `done()` says whether it is there without waiting, `result()` waits for it and raises
    a worker's UserError in its one line. The two methods of `concurrent.futures.Future`, so a caller may hold either."""

    def __init__(self, done: Callable[[], bool], result: Callable[[], Any]) -> None:
        self._done, self._result = done, result

    @classmethod
    def of(cls, value: Any) -> Pending:
        """A result that is there already."""
        return cls(lambda: True, lambda: value)

    def done(self) -> bool:
        return self._done()

    def result(self) -> Any:
        return _unwrap(self._result())


# Local processes ----------------------------------------------------------------------------------------------------


@contextmanager
def spawn_safely() -> Iterator[None]:
    """What spawned workers take from the parent while they start, held back for the time they start:

    - sys.path: once bpy is imported it holds Blender's scripts/modules, whose inner `bpy` package shadows the real
      one and makes `import bpy` fail in the child;
    - the main script: a spawned child runs it again unless `if __name__ == "__main__":` guards it, so a user's script
      that flies a Cycles camera would start itself in every worker (and hang, the parent writing the worker's scene
      into a pipe nobody reads). The workers run renderloop's own functions and need nothing of it."""
    saved = list(sys.path)
    main = sys.modules.get("__main__")
    held = {name: vars(main)[name] for name in ("__file__", "__spec__") if main is not None and name in vars(main)}
    sys.path[:] = [p for p in saved if not ("scripts" in p and ("bpy" in p or "blender" in p))]
    if held:  # multiprocessing.spawn finds the script by __spec__'s name (python -m) or else by __file__
        vars(main).pop("__file__", None)
        main.__spec__ = None
    try:
        yield
    finally:
        sys.path[:] = saved
        if held:
            vars(main).update(held)


@contextmanager
def _processes(workers: int, initializer: Callable[..., None] | None = None,
               initargs: tuple = ()) -> Iterator[ProcessPoolExecutor]:
    # spawn, not fork: neither Blender nor an OpenGL context survives a fork
    pool = ProcessPoolExecutor(workers, mp_context=get_context("spawn"), initializer=_started,
                               initargs=(os.getpid(), initializer, initargs))
    try:
        yield pool
    finally:
        pool.shutdown(cancel_futures=True)  # a caller that stops early drops the work not started


PARENT_POLL_S = 0.5  # how often a spawned worker looks whether the process that started it still lives


def _started(parent: int, initializer: Callable[..., None] | None, initargs: tuple) -> None:
    """A spawned worker's standard output points at its standard error: its results come back through the pool,
    and what a library prints from native code (Cycles' CUDA-loader warning when it loads) must not land in the
    output a caller reads from the program's stdout. And it watches `parent`, the process that started it
    (`_leave_with`): its pid as the parent knew it, for a parent killed while the worker started."""
    sys.stdout.flush()
    os.dup2(2, 1)
    threading.Thread(target=_leave_with, args=(parent,), daemon=True).start()
    if initializer is not None:
        initializer(*initargs)


def _leave_with(parent: int) -> None:
    """Stop this worker once `parent` is gone. A parent killed outright (SIGKILL, or a SIGTERM, which runs no
    `finally` and so no pool shutdown) leaves its workers to the init process, which would let them render on for
    nobody, holding the cores, until their task ended."""
    while os.getppid() == parent:
        time.sleep(PARENT_POLL_S)
    os._exit(1)


def _finished(futures: list[Future], ordered: bool) -> Iterator[Any]:
    for future in futures if ordered else as_completed(futures):
        yield _unwrap(future.result())


# Ray ----------------------------------------------------------------------------------------------------------------


def _check_answers(address: str, timeout: float = 3.0) -> None:
    """Ray retries an unanswered address for minutes; a plain TCP connect says no in seconds."""
    if address == "auto":
        return
    host, _, port = address.removeprefix("ray://").rpartition(":")
    try:
        socket.create_connection((host or "127.0.0.1", int(port)), timeout=timeout).close()
    except (OSError, ValueError):
        raise UserError(f"--address {address}: no Ray cluster answers there") from None


@contextmanager
def ray_session(executor: Executor) -> Iterator[None]:
    """Join the cluster at the executor's address, or start a local one with a CPU per worker; a session started here
    is shut down on leaving, one the caller started is left running."""
    import ray

    address = executor.address
    started_here = not ray.is_initialized()
    if started_here:
        try:
            if address:
                _check_answers(address)
                ray.init(address=address, log_to_driver=False)
            else:
                ray.init(num_cpus=executor.workers, include_dashboard=False, log_to_driver=False)
        except UserError:
            raise
        except (ConnectionError, RuntimeError, ValueError) as error:
            raise UserError(f"--address {address}: no Ray cluster answers there ({str(error).splitlines()[0]})") from None
    try:
        yield
    finally:
        if started_here:
            ray.shutdown()


def _ray_finished(refs: list, ordered: bool) -> Iterator[Any]:
    import ray

    if ordered:
        for ref in refs:
            yield _unwrap(ray.get(ref))
        return
    while refs:
        [done], refs = ray.wait(refs, num_returns=1)
        yield _unwrap(ray.get(done))


# Stateless tasks ----------------------------------------------------------------------------------------------------


def map_tasks(executor: Executor, task: Callable[..., Any], calls: Iterable[tuple], ordered: bool = False) -> Iterator[Any]:
    """`task(*args)` for every `args` of `calls`: the results in the order of `calls`, or (`ordered` False) each as
    it finishes. `task` and its arguments travel to the workers, so they must pickle (a module-level function)."""
    calls = list(calls)
    if executor.kind == "ray":
        import ray

        with ray_session(executor):
            remote = ray.remote(num_cpus=1)(_trapped)
            yield from _ray_finished([remote.remote(task, *args) for args in calls], ordered)
    elif executor.workers <= 1:
        for args in calls:
            yield task(*args)
    else:
        with _processes(executor.workers) as pool:
            with spawn_safely():  # the workers start on the first submissions
                futures = [pool.submit(_trapped, task, *args) for args in calls]
            yield from _finished(futures, ordered)


# Long-lived workers -------------------------------------------------------------------------------------------------


class _Held:
    """One worker's object, built once. A build that fails is raised by every call instead, so the caller hears it
    from its first (a failing initializer tells it only "BrokenProcessPool", a failing actor only that it died)."""

    def __init__(self, factory: Callable[..., Any], args: tuple) -> None:
        self.held, self.error = None, None
        try:
            self.held = factory(*args)
        except Exception as error:
            self.error = error

    def call(self, method: str, *args: Any) -> Any:
        return _trapped(self._call, method, args)

    def _call(self, method: str, args: tuple) -> Any:
        if self.error is not None:
            raise self.error
        return getattr(self.held, method)(*args)


_held: _Held | None = None  # a local worker process's object


def _hold(factory: Callable[..., Any], args: tuple) -> None:
    global _held
    _held = _Held(factory, args)


def _call_held(method: str, *args: Any) -> Any:
    assert _held is not None
    return _held.call(method, *args)


class Workers:
    """The executor's workers, each holding `factory(*args)`, built once where it works; `submit` a call of one of
    its methods and read it when it is `done`, or map a method over items with `as_completed`. With one local worker
    the object is built and works in this process, unless `background`: then in a process of its own, so this one
    keeps going while it works. Leave it (`close`, or `with`) to stop the workers and the Ray session started for
    them."""

    def __init__(self, executor: Executor, factory: Callable[..., Any], *args: Any, background: bool = False) -> None:
        self._stack = ExitStack()
        self.actors: list = []
        self.pool: ProcessPoolExecutor | None = None
        self.here: Any = None
        self._turn = 0  # the actor the next call goes to
        try:
            if executor.kind == "ray":
                import ray

                self._stack.enter_context(ray_session(executor))
                actor = ray.remote(num_cpus=1)(_Held)
                self.actors = [actor.remote(factory, args) for _ in range(executor.workers)]
                self._stack.callback(self.actors.clear)  # in a session the caller keeps, dropped actors end
            elif executor.workers > 1 or background:
                self.pool = self._stack.enter_context(_processes(executor.workers, _hold, (factory, args)))
            else:
                self.here = factory(*args)
                if hasattr(self.here, "close"):
                    self._stack.callback(self.here.close)
        except BaseException:
            self._stack.close()
            raise

    def submit(self, method: str, *args: Any) -> Pending:
        """`method(*args)` of a worker's object: at once in this process, else on the next worker in turn."""
        if self.actors:
            import ray

            ref = self.actors[self._turn % len(self.actors)].call.remote(method, *args)
            self._turn += 1
            return Pending(lambda: bool(ray.wait([ref], timeout=0)[0]), lambda: ray.get(ref))
        if self.pool is not None:
            with spawn_safely():  # a worker process starts on a submission
                future = self.pool.submit(_call_held, method, *args)
            return Pending(future.done, future.result)
        return Pending.of(getattr(self.here, method)(*args))

    def as_completed(self, method: str, items: Iterable[Any]) -> Iterator[Any]:
        """`method(item)` for every item, each on whichever worker is free, the results as they finish."""
        items = list(items)
        if self.pool is not None:
            with spawn_safely():  # the workers start on the first submissions
                futures = [self.pool.submit(_call_held, method, item) for item in items]
            yield from _finished(futures, ordered=False)
        elif not self.actors:
            for item in items:
                yield getattr(self.here, method)(item)
        else:
            import ray

            pending: dict = {}

            def give(actor: Any) -> None:  # one call in flight per actor; the next goes to whichever finishes first
                if items:
                    pending[actor.call.remote(method, items.pop(0))] = actor

            for actor in self.actors:
                give(actor)
            while pending:
                [done], _ = ray.wait(list(pending), num_returns=1)
                give(pending.pop(done))
                yield _unwrap(ray.get(done))

    def close(self) -> None:
        self._stack.close()

    def __enter__(self) -> Workers:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
