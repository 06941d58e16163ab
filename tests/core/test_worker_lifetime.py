"""Worker processes end with their caller: a killed or interrupted diagnose-like pool leaves no process.

Each case runs the pool in a fresh Python process whose workers sit in endless tasks, so only
the pool's own clean-up (or the workers' watch on their parent) can end them."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import pytest

pytestmark = pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc")

ROOT = Path(__file__).resolve().parents[2]

_CHILD = textwrap.dedent(
    """
    import faulthandler, os, signal, sys, time
    from robustctl.executors import parallel_map_shared, process_pool

    faulthandler.register(signal.SIGUSR1, all_threads=True)  # where it hangs, if it ever does
    # Ctrl-C as in a user's interpreter: Python installs this handler only when the SIGINT it
    # inherits is not ignored, and a pytest worker's may be (the caller then never sees the signal)
    signal.signal(signal.SIGINT, signal.default_int_handler)

    def task(shared, item):  # a candidate's fit that never ends
        while True:
            time.sleep(0.05)

    try:
        with process_pool(2, 8, 1) as pool:
            pool.submit(os.getpid).result()  # the workers are up
            print(" ".join(str(p) for p in pool._processes), flush=True)
            parallel_map_shared(task, None, range(8), pool)
    except KeyboardInterrupt:
        print("interrupted", flush=True)
    """
)


def _running(pid: int) -> bool:
    """True while ``pid`` exists and is not a zombie (an orphan's zombie waits for init to reap it)."""
    try:
        stat = Path(f"/proc/{pid}/stat").read_text()
    except (FileNotFoundError, ProcessLookupError):
        return False
    return stat.rsplit(")", 1)[1].split()[0] not in ("Z", "X")


def _start():
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    proc = subprocess.Popen([sys.executable, "-c", _CHILD], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True, env=env, cwd=ROOT)
    line = proc.stdout.readline()
    pids = [int(p) for p in line.split()]
    assert len(pids) == 2 and all(_running(p) for p in pids), line
    return proc, pids


def _wait_until_gone(pids, limit_s=60.0):
    """The pids still running after up to ``limit_s`` (a liveness bound, not a timing assertion)."""
    end = time.monotonic() + limit_s
    while time.monotonic() < end and any(_running(p) for p in pids):
        time.sleep(0.1)
    return [p for p in pids if _running(p)]


def test_workers_end_when_their_caller_is_killed():
    proc, pids = _start()
    try:
        proc.kill()  # SIGKILL: the caller runs no clean-up at all
        proc.wait(30)
        assert _wait_until_gone(pids) == []
    finally:
        for p in pids:
            if _running(p):
                os.kill(p, signal.SIGKILL)


def test_an_interrupted_caller_stops_its_workers_before_returning():
    proc, pids = _start()
    try:
        proc.send_signal(signal.SIGINT)  # KeyboardInterrupt in the caller, inside parallel_map_shared
        try:
            out, _ = proc.communicate(timeout=60)  # a pool waiting for its endless tasks would hang here
        except subprocess.TimeoutExpired:
            proc.send_signal(signal.SIGUSR1)  # every thread's stack, to say where
            time.sleep(2.0)
            proc.kill()
            _, err = proc.communicate()
            pytest.fail(f"the interrupted caller did not return in 60 s; its threads:\n{err}")
        assert "interrupted" in out and proc.returncode == 0
        assert _wait_until_gone(pids, 10.0) == []
    finally:
        proc.kill()
        for p in pids:
            if _running(p):
                os.kill(p, signal.SIGKILL)


def _children(pid: int) -> list[int]:
    """The running processes whose parent is ``pid`` (read from /proc)."""
    kids = []
    for entry in Path("/proc").iterdir():
        if entry.name.isdigit():
            try:
                fields = (entry / "stat").read_text().rsplit(")", 1)[1].split()
            except (FileNotFoundError, ProcessLookupError):
                continue
            if int(fields[1]) == pid and fields[0] not in ("Z", "X"):
                kids.append(int(entry.name))
    return kids


@pytest.mark.slow
def test_a_killed_command_line_run_leaves_no_worker_behind(tmp_path):
    """`robustctl demo` killed with SIGKILL as soon as it has started workers: none is alive 5 s later."""
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    proc = subprocess.Popen([sys.executable, "-m", "robustctl", "demo", "--out", str(tmp_path / "out")],
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, env=env, cwd=ROOT)
    kids: list[int] = []
    try:
        end = time.monotonic() + 900.0  # a liveness bound: the demo starts workers in its diagnosis
        while not kids and proc.poll() is None and time.monotonic() < end:
            kids = _children(proc.pid)
            time.sleep(0.05)
        assert kids, "the demo ended or ran 900 s without starting a worker process"
        proc.kill()
        proc.wait(30)
        time.sleep(5.0)
        assert [p for p in kids if _running(p)] == []
    finally:
        proc.kill()
        for p in kids:
            if _running(p):
                os.kill(p, signal.SIGKILL)


def test_every_process_pool_is_the_one_that_ends_with_its_caller():
    """No module starts a ProcessPoolExecutor of its own: pools come from executors.process_pool,
    whose workers end with their caller (the test above and the first one in this file)."""
    owners = [p.relative_to(ROOT).as_posix() for p in (ROOT / "robustctl").rglob("*.py")
              if "ProcessPoolExecutor(" in p.read_text()]
    assert owners == ["robustctl/executors.py"]
