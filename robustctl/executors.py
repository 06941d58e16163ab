"""One way to spread independent work: an optional ``concurrent.futures.Executor`` and a progress bar.

Every ``executor=`` argument in robustctl (diagnose's candidates, sensitivities, mu over a
large grid, D-K design sweeps) goes through :func:`parallel_map`, so any executor that
implements ``submit`` works the same everywhere: ``ThreadPoolExecutor``,
``ProcessPoolExecutor`` (tasks and results travel by cloudpickle, so systems holding lambdas
cross), or a dask.distributed ``Client.get_executor()`` / Ray executor to spread the work past
one machine.
"""

from __future__ import annotations

import contextlib
import multiprocessing
import os
import sys
import threading
import time
import uuid
import warnings
import weakref
from collections import OrderedDict
from collections.abc import Callable, Iterable, Iterator
from concurrent.futures import ProcessPoolExecutor, ThreadPoolExecutor
from typing import Any

import cloudpickle
import numpy as np

from .errors import ParallelWarning, RobustctlError

__all__ = ["parallel_map", "parallel_map_shared", "check_executor", "available_cores", "process_pool"]


def check_executor(executor: Any) -> Any:
    """Refuse anything that is not None or an executor with a callable ``submit``.

    Raises
    ------
    RobustctlError
        With the fix (e.g. ``executor="threads"`` is a string, not an executor).
    """
    if executor is None or callable(getattr(executor, "submit", None)):
        return executor
    raise RobustctlError(
        f"executor must be a concurrent.futures.Executor (anything with .submit), or None for serial "
        f"work; got {executor!r}. E.g. executor=concurrent.futures.ThreadPoolExecutor(2), or a "
        "dask.distributed Client(...).get_executor()."
    )


def parallel_map(
    fn: Callable[..., Any],
    items: Iterable[Any],
    executor: Any = None,
    *,
    desc: str = "",
    progress: bool = True,
) -> list[Any]:
    """``[fn(item) for item in items]``, on ``executor`` when one is given, results in order.

    Parameters
    ----------
    fn : callable
        Applied to each item; must be picklable for process or cluster executors.
    items : iterable
    executor : concurrent.futures.Executor, optional
        None runs serially in this process.
    desc : str
        Label of the progress bar.
    progress : bool
        Show a tqdm bar when standard error is a terminal.

    Returns
    -------
    list
        The results, in the order of ``items``. An exception raised by ``fn`` propagates.
    """
    from tqdm import tqdm

    check_executor(executor)
    items = list(items)
    show = bool(progress) and sys.stderr.isatty()
    if executor is None:
        return [fn(it) for it in tqdm(items, desc=desc, disable=not show, leave=False)]
    if isinstance(executor, ProcessPoolExecutor):  # standard pickle: no lambdas, no local classes
        futures = [executor.submit(_call_pickled, cloudpickle.dumps((fn, it))) for it in items]
        blobs = [f.result() for f in tqdm(futures, desc=desc, disable=not show, leave=False)]
        return [cloudpickle.loads(b) for b in blobs]
    futures = [executor.submit(fn, it) for it in items]
    return [f.result() for f in tqdm(futures, desc=desc, disable=not show, leave=False)]


def _call_pickled(blob: bytes) -> bytes:
    """Worker side of a ``ProcessPoolExecutor`` task: ``fn(item)`` shipped and returned by
    cloudpickle, so that systems holding lambdas (python-control's ``StateSpace``) and local
    functions cross the process boundary (dask does the same by itself)."""
    fn, item = cloudpickle.loads(blob)
    return cloudpickle.dumps(fn(item))


# ============================================================================ shared payloads
#: Chunks per worker of :func:`parallel_map_shared` (load balance against shipping the payload).
CHUNKS_PER_WORKER = 8
#: Most worker processes ``workers="auto"`` starts: the serial parts of a diagnosis (its null fit,
#: the fits of a few contenders) leave little to gain beyond, and each chunk carries the payload.
MAX_AUTO_WORKERS = 8
#: Payloads a worker process keeps unpickled (most recent last), keyed by their token.
_WORKER_SHARED: OrderedDict[str, Any] = OrderedDict()
_WORKER_KEEP = 2
_WORKER_LOCK = threading.Lock()


def parallel_map_shared(
    fn: Callable[[Any, Any], Any],
    shared: Any,
    items: Iterable[Any],
    executor: Any = None,
    *,
    desc: str = "",
    progress: bool = True,
) -> list[Any]:
    """``[fn(shared, item) for item in items]``, with ``shared`` sent to each worker once.

    :func:`parallel_map` ships its (closure) function with every task: a closure over a large
    model, its data and a residual costs megabytes of pickling per item and a cold start of
    every cache on the other side. Here the items travel in a few interleaved chunks
    (``items[i::n]``, so expensive and cheap items mix), each with ``shared`` pickled once
    for the whole call, and a worker process unpickles a payload only the first time it sees
    its token: the chunks it runs afterwards reuse the same objects (and the caches keyed on
    them). ``shared`` is taken as immutable: while the same object lives, later calls with it
    keep its token, so a worker reuses its copy across calls (a fit's successive Jacobians).

    Parameters
    ----------
    fn : callable ``(shared, item) -> result``
        A module-level function (pickled by reference).
    shared : object
        What every item needs (picklable by cloudpickle).
    items : iterable
    executor : concurrent.futures.Executor, optional
        None runs serially here; a ``ThreadPoolExecutor`` shares ``shared`` in memory; any other
        executor (process pool, dask) gets the chunks.
    desc, progress : str, bool
        As :func:`parallel_map`.

    Returns
    -------
    list
        The results, in the order of ``items`` (each item is computed as in a serial loop, so
        the results equal the serial ones).
    """
    from tqdm import tqdm

    check_executor(executor)
    items = list(items)
    show = bool(progress) and sys.stderr.isatty()
    if executor is None or getattr(executor, "_robustctl_unpicklable", False):
        return [fn(shared, it) for it in tqdm(items, desc=desc, disable=not show, leave=False)]
    if isinstance(executor, ThreadPoolExecutor):
        futures = [executor.submit(fn, shared, it) for it in items]
        return [f.result() for f in tqdm(futures, desc=desc, disable=not show, leave=False)]
    workers = int(getattr(executor, "_max_workers", 0) or available_cores())
    n_chunks = max(1, min(len(items), CHUNKS_PER_WORKER * workers))
    token = _token(fn, shared)
    try:
        payload = cloudpickle.dumps((fn, shared))
    except Exception as exc:  # pickle raises TypeError, AttributeError, PicklingError ...
        if not getattr(executor, "_robustctl_own", False):
            raise
        warnings.warn(
            f"{desc or 'parallel work'}: the model or data cannot be sent to worker processes "
            f"({type(exc).__name__}: {exc}); computing in this process instead (workers=1 avoids the try).",
            ParallelWarning,
            stacklevel=3,
        )
        executor._robustctl_unpicklable = True  # the rest of the work too, without more warnings
        return [fn(shared, it) for it in tqdm(items, desc=desc, disable=not show, leave=False)]
    chunks = [list(range(i, len(items), n_chunks)) for i in range(n_chunks)]
    blobs = [cloudpickle.dumps([items[k] for k in idx]) for idx in chunks]
    futures = [executor.submit(_run_chunk, token, payload, b) for b in blobs]
    out: list[Any] = [None] * len(items)
    with tqdm(total=len(items), desc=desc, disable=not show, leave=False) as bar:
        for idx, f in zip(chunks, futures):  # the bar counts items (not chunks) as they come back
            for k, r in zip(idx, cloudpickle.loads(f.result())):
                out[k] = r
            bar.update(len(idx))
    return out


def _token(fn: Callable, shared: Any) -> str:
    """A name for the payload ``(fn, shared)``: the same while ``shared`` is the same live object
    (one that can be weakly referenced, e.g. a Residual: a Levenberg-Marquardt fit sends it for
    every Jacobian, and the workers keep their unpickled copy with its warm caches), new
    otherwise (tuples, dicts)."""
    name = getattr(fn, "__qualname__", "") + "@" + getattr(fn, "__module__", "")
    try:
        ref = weakref.ref(shared)
    except TypeError:
        return uuid.uuid4().hex
    with _TOKEN_LOCK:
        entry = _TOKENS.get(id(shared))
        if entry is None or entry[0]() is not shared:
            entry = _TOKENS[id(shared)] = (ref, uuid.uuid4().hex)
            weakref.finalize(shared, _forget, id(shared), entry[1])
    return entry[1] + name


def _forget(key: int, token: str) -> None:
    with _TOKEN_LOCK:
        if key in _TOKENS and _TOKENS[key][1] == token:
            del _TOKENS[key]


#: ``id(shared) -> (weak reference, token)`` of live payload objects (:func:`_token`).
_TOKENS: dict[int, tuple] = {}
_TOKEN_LOCK = threading.Lock()


def _run_chunk(token: str, payload: bytes, chunk: bytes) -> bytes:
    """Worker side of :func:`parallel_map_shared`: the payload is unpickled once per token."""
    with _WORKER_LOCK:
        found = _WORKER_SHARED.get(token)
        if found is None:
            found = _WORKER_SHARED[token] = cloudpickle.loads(payload)
            while len(_WORKER_SHARED) > _WORKER_KEEP:
                _WORKER_SHARED.popitem(last=False)
    fn, shared = found
    return cloudpickle.dumps([fn(shared, it) for it in cloudpickle.loads(chunk)])


def available_cores() -> int:
    """CPU cores this process may run on (its affinity mask where the OS has one)."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except (AttributeError, OSError):
        return max(1, os.cpu_count() or 1)


@contextlib.contextmanager
def process_pool(workers: Any, n_tasks: int, min_tasks: int) -> Iterator[ProcessPoolExecutor | None]:
    """A process pool of ``workers`` for ``n_tasks`` independent tasks, or None for serial work.

    ``workers``: ``"auto"`` (the cores available, at most :data:`MAX_AUTO_WORKERS`; serial when
    that is one, when there are fewer than ``min_tasks`` tasks, when this process is itself a
    worker, or off Linux (:func:`_fork_is_safe`): starting a fresh interpreter costs seconds of
    imports), a whole number (1 is serial), or None (serial). On Linux workers are forked, so
    they start with the caller's modules and warm caches (elsewhere the platform's default,
    spawn, starts them) (a program running robustctl in several threads at
    once should pass 1: a fork copies only the calling thread). When the payload of
    :func:`parallel_map_shared` cannot be pickled, the work is done in this process with a
    RuntimeWarning. The workers end with the pool on every exit path: normally after their
    tasks, at once (terminated) on an exception or KeyboardInterrupt, and by themselves when
    the calling process is killed (:func:`_worker_start`).

    Raises
    ------
    RobustctlError
        ``workers`` neither "auto", None nor a whole number >= 1.
    """
    n = resolve_workers(workers, n_tasks, min_tasks)
    if n <= 1:
        yield None
        return
    ctx = multiprocessing.get_context("fork" if _fork_is_safe() else "spawn")  # spawn: as on macOS, Windows
    pool = ProcessPoolExecutor(max_workers=n, mp_context=ctx, initializer=_worker_start,
                               initargs=(os.getpid(),))
    pool._robustctl_own = True  # parallel_map_shared may fall back to serial work on it
    try:
        yield pool
    except BaseException:  # an error, KeyboardInterrupt, a closed generator: stop the work now
        _stop_workers(pool)
        raise
    finally:
        pool.shutdown(wait=True, cancel_futures=True)


#: Seconds between a worker's checks that the process which started it still runs.
PARENT_POLL_S = 0.5


def _worker_start(parent_pid: int) -> None:
    """Initializer of :func:`process_pool`'s workers: they end with their parent.

    A killed parent (SIGKILL, an out-of-memory kill) runs no clean-up, and a pool's worker
    blocked on its task queue would outlive it. Each worker therefore asks the kernel for
    SIGKILL when its parent ends (Linux ``prctl(PR_SET_PDEATHSIG)``) and, everywhere, polls
    its parent id from a daemon thread (an orphan is re-parented). Workers ignore SIGINT: a
    Ctrl-C reaches the whole process group, and the parent, not each worker, decides (it
    stops them, see :func:`_stop_workers`).
    """
    import signal

    with contextlib.suppress(ValueError, OSError):  # not the main thread of a worker: keep the default
        signal.signal(signal.SIGINT, signal.SIG_IGN)
    if sys.platform.startswith("linux"):
        with contextlib.suppress(Exception):  # no libc by that name: the poll below still works
            import ctypes

            pr_set_pdeathsig = 1
            ctypes.CDLL("libc.so.6", use_errno=True).prctl(pr_set_pdeathsig, int(signal.SIGKILL), 0, 0, 0)
    if os.getppid() != parent_pid:  # the parent ended before the request took effect
        os._exit(1)

    def watch() -> None:
        while True:
            time.sleep(PARENT_POLL_S)
            if os.getppid() != parent_pid:
                os._exit(1)

    threading.Thread(target=watch, name="robustctl-parent-watch", daemon=True).start()


def _stop_workers(pool: ProcessPoolExecutor) -> None:
    """End a pool's workers at once (queued tasks cancelled, running ones terminated)."""
    procs = list((getattr(pool, "_processes", None) or {}).values())
    pool.shutdown(wait=False, cancel_futures=True)
    for p in procs:
        with contextlib.suppress(Exception):
            p.terminate()
    for p in procs:
        with contextlib.suppress(Exception):
            p.join(5.0)
            if p.is_alive():
                p.kill()
                p.join()


def _fork_is_safe() -> bool:
    """Forked workers for ``workers="auto"`` only on Linux: macOS offers fork, but its system
    libraries (Accelerate, used by numpy there) are not fork-safe, which is why Python starts
    processes by spawning there; Windows has no fork."""
    return sys.platform.startswith("linux") and "fork" in multiprocessing.get_all_start_methods()


def resolve_workers(workers: Any, n_tasks: int, min_tasks: int) -> int:
    """The number of worker processes :func:`process_pool` starts (1: none)."""
    if workers is None:
        return 1
    if isinstance(workers, str) and workers == "auto":
        if (n_tasks < min_tasks or not _fork_is_safe()
                or multiprocessing.parent_process() is not None):  # already a worker: no pool in a pool
            return 1
        return min(available_cores(), n_tasks, MAX_AUTO_WORKERS)
    if isinstance(workers, bool) or not isinstance(workers, (int, np.integer)) or workers < 1:
        raise RobustctlError(
            f'workers must be "auto", None or a whole number >= 1 of worker processes (1: serial); '
            f"got {workers!r}."
        )
    return min(int(workers), max(n_tasks, 1))
