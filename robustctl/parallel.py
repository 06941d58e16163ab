"""One way to spread independent work: an optional ``concurrent.futures.Executor`` and a progress bar.

Every ``executor=`` argument in robustctl (diagnose's candidates, sensitivities, mu over a
large grid, D-K design sweeps) goes through :func:`parallel_map`, so any executor that
implements ``submit`` works the same everywhere: ``ThreadPoolExecutor``,
``ProcessPoolExecutor`` (tasks and results travel by cloudpickle, so systems holding lambdas
cross), or a dask.distributed ``Client.get_executor()`` / Ray executor to spread the work past
one machine.
"""

from __future__ import annotations

import sys
from collections.abc import Callable, Iterable
from concurrent.futures import ProcessPoolExecutor
from typing import Any

import cloudpickle

from .errors import RobustctlError

__all__ = ["parallel_map", "check_executor"]


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
