"""BLAS thread control for robustctl's small dense kernels.

OpenBLAS's default thread pool oversubscribes small machines on the small dense problems
that control design is made of (a python-control ``hinfsyn`` call took 25 ms with one
BLAS thread and up to 10 s with the default pool on 2 cores). robustctl therefore runs
its dense kernels with a limited number of BLAS threads:

* :func:`set_blas_threads` sets the global setting (default 1, or the environment
  variable ``ROBUSTCTL_BLAS_THREADS``; ``0`` or ``"none"`` means "leave BLAS alone");
* :func:`blas_threads` is a context manager / decorator for an explicit limit;
* :func:`limit_blas` is the decorator robustctl's own kernels use: it applies the global
  setting at call time.

Limits are applied with ``threadpoolctl`` and restored on exit; nested calls with the
same limit do not touch the thread pools again.
"""

from __future__ import annotations

import contextlib
import functools
import operator
import os
import sys
import threading
import warnings
from collections.abc import Callable, Iterator
from typing import Any, TypeVar

from .errors import RobustctlError, SetupWarning

__all__ = ["blas_threads", "set_blas_threads", "get_blas_threads", "limit_blas"]

F = TypeVar("F", bound=Callable[..., Any])
ENV_VAR = "ROBUSTCTL_BLAS_THREADS"


def _parse(value: Any, source: str) -> int | None:
    """``None`` (no limit) or a positive int from a user value or env string."""
    if value is None:
        return None
    if isinstance(value, str):
        text = value.strip().lower()
        if text in ("", "none", "0", "off", "default"):
            return None
        try:
            value = int(text)
        except ValueError:
            raise RobustctlError(
                f"{source} must be a positive integer number of BLAS threads or 'none'; got {value!r}."
            ) from None
    if isinstance(value, bool):
        raise RobustctlError(f"{source} must be a positive integer or None; got {value!r}.")
    try:
        value = operator.index(value)
    except TypeError:
        raise RobustctlError(f"{source} must be a positive integer or None; got {value!r}.") from None
    if value < 0:
        raise RobustctlError(f"{source} must be a positive integer or None; got {value}.")
    return None if value == 0 else value


def _initial_setting() -> int | None:
    try:
        return _parse(os.environ.get(ENV_VAR, "1"), f"environment variable {ENV_VAR}")
    except RobustctlError as exc:  # a bad environment must not break `import robustctl`
        warnings.warn(f"{exc} Using 1 BLAS thread.", SetupWarning, stacklevel=2)
        return 1


_setting: int | None = _initial_setting()
_state = threading.local()
_controller_cache: dict[str, Any] = {"ctrl": None, "n_modules": -1}


def _controller():
    """A cached ``ThreadpoolController``, refreshed when new modules were imported."""
    from threadpoolctl import ThreadpoolController

    n_modules = len(sys.modules)
    if _controller_cache["ctrl"] is None or _controller_cache["n_modules"] != n_modules:
        _controller_cache["ctrl"] = ThreadpoolController()
        _controller_cache["n_modules"] = n_modules
    return _controller_cache["ctrl"]


def get_blas_threads() -> int | None:
    """The global BLAS thread setting of robustctl's kernels (``None``: no limit)."""
    return _setting


def set_blas_threads(n: int | str | None) -> int | None:
    """Set the number of BLAS threads robustctl's dense kernels use; returns the old setting.

    Parameters
    ----------
    n : int or None
        A positive number of threads, or ``None`` / ``0`` to leave the BLAS pools alone.
        The default is 1 (or the environment variable ``ROBUSTCTL_BLAS_THREADS``).
    """
    global _setting
    old = _setting
    _setting = _parse(n, "set_blas_threads(n)")
    return old


@contextlib.contextmanager
def _limited(n: int | None) -> Iterator[None]:
    current = getattr(_state, "active", None)
    if n is None or current == n:
        yield
        return
    limiter = _controller().limit(limits=n, user_api="blas")
    _state.active = n
    try:
        yield
    finally:
        _state.active = current
        limiter.restore_original_limits()


class blas_threads(contextlib.ContextDecorator):  # noqa: N801 - used like a function
    """Context manager and decorator running its body with ``n`` BLAS threads.

    Parameters
    ----------
    n : int or None
        Number of BLAS threads inside; ``None`` uses the global setting
        (:func:`set_blas_threads`).

    Examples
    --------
    >>> import robustctl as rc
    >>> with rc.blas_threads(1):
    ...     pass
    """

    def __init__(self, n: int | None = None):
        self._explicit = n is not None
        self.n = _parse(n, "blas_threads(n)") if n is not None else None
        self._stack: list[contextlib.AbstractContextManager] = []

    def __enter__(self) -> blas_threads:
        n = self.n if self._explicit else _setting
        cm = _limited(n)
        cm.__enter__()
        self._stack.append(cm)
        return self

    def __exit__(self, *exc: Any) -> None:
        self._stack.pop().__exit__(*exc)


def limit_blas(func: F) -> F:
    """Decorator: run ``func`` under the global BLAS thread setting (see :func:`set_blas_threads`)."""

    @functools.wraps(func)
    def wrapper(*args: Any, **kwargs: Any) -> Any:
        with _limited(_setting):
            return func(*args, **kwargs)

    return wrapper  # type: ignore[return-value]
