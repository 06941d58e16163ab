"""Same input, same output: a representative set of results, computed in two fresh processes (one
of them beside a CPU load), is equal bit for bit.

The set (``_reproducible_run.py``): the six-mode measurement model with and without the leakage
correction, diagnose on the Caltech truss (serially in one run, in two worker processes in the
other), D-K iteration on the distillation column and a two-model yardstick. A result that read
the clock, the load, the number of workers, the string hash seed or unseeded random numbers
would differ between the runs: the loaded one gets a fraction of the cores and its timings
change several-fold.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import time
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
SCRIPT = Path(__file__).with_name("_reproducible_run.py")
#: Longest the quiet run may take (s; a hang guard, not a timing assertion). The loaded run may
#: take LOADED_FACTOR x as long as the quiet one took, plus this: a fixed 600 s guard failed the
#: loaded run when other jobs already kept this 2-core machine at load 18.
RUN_LIMIT_S = 600
LOADED_FACTOR = 4
#: Busy-loop processes of the load generator, and how long each may live (s) at most.
LOAD_PROCESSES = 2
LOAD_LIMIT_S = 600


def _run(*args: str, limit_s: float = RUN_LIMIT_S, **env_vars: str) -> tuple[dict, float]:
    """The script's results and how long it ran (s, for the next run's hang guard)."""
    env = dict(os.environ, PYTHONPATH=str(ROOT), PYTHONHASHSEED="random", **env_vars)
    start = time.monotonic()
    out = subprocess.run([sys.executable, str(SCRIPT), *args], capture_output=True, text=True, env=env,
                         cwd=ROOT, timeout=limit_s, check=True)
    return json.loads(out.stdout.strip().splitlines()[-1]), time.monotonic() - start


def _load() -> list[subprocess.Popen]:
    """CPU hogs that end by themselves after LOAD_LIMIT_S (and are killed by the caller before)."""
    busy = f"import time\nend = time.monotonic() + {LOAD_LIMIT_S}\nwhile time.monotonic() < end:\n    pass\n"
    return [subprocess.Popen([sys.executable, "-c", busy]) for _ in range(LOAD_PROCESSES)]


@pytest.mark.slow
def test_results_are_bit_identical_in_fresh_processes_with_and_without_cpu_load():
    quiet, took = _run("--workers=1")
    hogs = _load()
    try:
        # and diagnose in two worker processes instead of serially
        loaded, _ = _run("--workers=2", limit_s=RUN_LIMIT_S + LOADED_FACTOR * took)
    finally:
        for h in hogs:
            h.kill()
            h.wait()
    assert set(quiet) == {"measurement_model_leakage_False", "measurement_model_leakage_True",
                          "diagnose_truss", "dksyn_distillation", "dksyn_caltech", "yardstick_small"}
    differ = sorted(k for k in quiet if quiet[k] != loaded[k])
    assert differ == [], f"results that changed between two runs of the same input: {differ}"


@pytest.mark.slow
def test_dk_is_bit_identical_across_processes_blas_threads_and_load():
    """D-K (dksyn runs its BLAS calls with robustctl's thread setting, whatever the process's):
    the demo's recipe and the distillation column in a fresh process with one OpenBLAS thread,
    and in another with two beside a CPU load."""
    quiet, took = _run("dk_caltech", "dk_distillation", OPENBLAS_NUM_THREADS="1")
    hogs = _load()
    try:
        loaded, _ = _run("dk_caltech", "dk_distillation", limit_s=RUN_LIMIT_S + LOADED_FACTOR * took,
                         OPENBLAS_NUM_THREADS="2")
    finally:
        for h in hogs:
            h.kill()
            h.wait()
    assert set(quiet) == {"dksyn_caltech", "dksyn_distillation"}
    assert quiet == loaded
