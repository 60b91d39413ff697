"""Work spread over local processes or Ray: the same results as in this process, and a worker's bad input in one line.

The tasks are functions of the standard library and renderloop (`parse_seeds` refuses "x" with a UserError), so a
spawned process or a Ray worker imports them without this test module."""

from __future__ import annotations

import os
import re
import subprocess
import sys
import time
from pathlib import Path

import pytest

from renderloop.config import load_config
from renderloop.errors import UserError
from renderloop.evaluation.seeds import parse_seeds
from renderloop.parallel import LOCAL, Executor, Workers, map_tasks, ray_session

TWO = Executor(workers=2)
REFUSED = r"^--seeds 'x': 'x' is not a seed or a range like 0-19$"  # parse_seeds("x")'s one line


def test_an_ordered_map_on_two_processes_is_the_serial_map_and_unordered_the_same_results():
    calls = [(2, i) for i in range(7)]
    serial = list(map_tasks(LOCAL, pow, calls))
    assert serial == [2**i for i in range(7)]
    assert list(map_tasks(TWO, pow, calls, ordered=True)) == serial
    assert sorted(map_tasks(TWO, pow, calls)) == serial


def test_what_a_spawned_worker_prints_from_native_code_goes_to_stderr_not_into_the_callers_stdout(capfd):
    assert list(map_tasks(TWO, os.write, [(1, b"worker line\n")] * 3)) == [12] * 3  # os.write: bytes written to fd 1
    out, err = capfd.readouterr()
    assert "worker line" not in out and err.count("worker line") == 3


def test_a_task_user_error_on_a_process_comes_back_as_its_one_line():
    with pytest.raises(UserError, match=REFUSED):
        list(map_tasks(TWO, parse_seeds, [("1",), ("x",)]))


@pytest.mark.parametrize("executor", [LOCAL, TWO], ids=["here", "two processes"])
def test_workers_hold_their_object_and_a_failed_start_is_its_one_line_at_the_first_call(executor: Executor):
    with Workers(executor, str, "renderloop") as workers:
        assert sorted(workers.as_completed("count", ["r", "o", "x"])) == [0, 2, 2]
        pending = workers.submit("upper")
        assert pending.result() == "RENDERLOOP" and pending.done()
    if executor is LOCAL:  # in this process the start itself refuses
        with pytest.raises(UserError, match=REFUSED):
            Workers(executor, parse_seeds, "x")
        return
    with Workers(executor, parse_seeds, "x") as workers:  # a process pool's initializer would only say it broke
        with pytest.raises(UserError, match=REFUSED):
            workers.submit("index", 1).result()


# A parent that starts two workers on a minute's sleep each, prints their pids and waits for them.
SLEEPING_PARENT = """
import multiprocessing, threading, time
from renderloop.parallel import Executor, map_tasks
threading.Thread(target=list, args=(map_tasks(Executor(workers=2), time.sleep, [(60,), (60,)]),), daemon=True).start()
while len(multiprocessing.active_children()) < 2:
    time.sleep(0.05)
print(*[p.pid for p in multiprocessing.active_children()], flush=True)
time.sleep(60)
"""


def _running(pid: int) -> bool:
    """Whether `pid` still runs: neither gone nor a zombie (the init process of a container may never reap it)."""
    try:
        return Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0] != "Z"
    except FileNotFoundError:
        return False


@pytest.mark.skipif(not Path("/proc/self/stat").exists(), reason="reads process states from /proc")
def test_workers_stop_when_the_process_that_started_them_is_killed_outright():
    parent = subprocess.Popen([sys.executable, "-c", SLEEPING_PARENT], stdout=subprocess.PIPE, text=True)
    try:
        workers = [int(pid) for pid in parent.stdout.readline().split()]
        assert len(workers) == 2 and all(_running(pid) for pid in workers)
    finally:
        parent.kill()  # SIGKILL: no pool shutdown runs, the workers are orphaned mid-task
        parent.wait()
    deadline = time.monotonic() + 30  # s: a loaded machine may take seconds to start a worker; its task sleeps 60
    while any(_running(pid) for pid in workers) and time.monotonic() < deadline:
        time.sleep(0.05)
    assert not any(_running(pid) for pid in workers), "a worker sleeps on for nobody"


def test_one_worker_in_the_background_works_in_a_process_of_its_own():
    import os

    with Workers(LOCAL, os.getpid, background=True) as workers:  # the pid of the process that built it
        assert workers.submit("__int__").result() != os.getpid()


def test_ray_gives_the_results_of_local_processes_and_a_workers_user_error_in_its_one_line():
    ray = Executor(kind="ray", workers=2)
    with ray_session(ray):  # started once: the calls below join it
        calls = [(3, i) for i in range(5)]
        assert list(map_tasks(ray, pow, calls, ordered=True)) == list(map_tasks(TWO, pow, calls, ordered=True))
        with Workers(ray, str, "renderloop") as workers:
            assert sorted(workers.as_completed("count", ["r", "o", "x"])) == [0, 2, 2]
            assert [workers.submit("upper").result() for _ in range(3)] == ["RENDERLOOP"] * 3
        with pytest.raises(UserError, match=REFUSED) as task:
            list(map_tasks(ray, parse_seeds, [("x",)]))
        with Workers(ray, parse_seeds, "x") as workers, pytest.raises(UserError, match=REFUSED) as actor:
            workers.submit("index", 1).result()
    assert "\n" not in str(task.value) and "\n" not in str(actor.value)


def test_an_executor_is_checked_once_and_shares_the_cores_among_its_workers():
    config = load_config("demo")
    with pytest.raises(UserError, match=re.escape("executor: kind: Input should be 'local' or 'ray'")):
        Executor.of("dask")
    with pytest.raises(UserError, match=re.escape("executor: workers: Input should be greater than or equal to 1")):
        Executor.of("local", 0)
    assert LOCAL.threads == 0 and LOCAL.share_cores(config) is config  # one worker takes every core
    assert 1 <= TWO.threads and TWO.share_cores(config).renderer.threads == TWO.threads
    own = config.override({"renderer": {"threads": 3}})
    assert TWO.share_cores(own) is own  # a config that sets its threads keeps them
