"""Time budgets: one helper, :class:`Deadline`, and one policy for every routine that takes one.

The policy (every ``time_budget_s=`` argument in robustctl follows it)
--------------------------------------------------------------------------
1. **Counts bound the work.** A result depends only on its inputs and its explicit options:
   iteration caps (numbers of iterations, evaluations, gamma tests, orders) bound every loop,
   so the same call gives the same numbers on a fast, a slow or a loaded machine.
2. **The wall clock is opt-in.** ``time_budget_s=None`` (the default everywhere) means no
   clock. A number of seconds (``>= 0``) caps the wall time: the budget is checked between
   steps (a step in progress is never cut), and when it ends the computation early the
   computation returns the best result it has, with ``stopped_by_budget=True`` (a field of
   the result, or ``info["stopped_by_budget"]``), says so in its ``summary()``, and issues a
   :class:`BudgetWarning`. Such a result depends on the machine's speed and load.
3. **No result, an error.** Only when the budget ends before anything usable exists (e.g. no
   feasible gamma yet, no candidate screened) does the routine raise its stage's
   :class:`~robustctl.errors.RobustctlError` subclass, naming the budget and the fix.

A budget of ``0`` s stops at the first check: every routine then returns (or raises) at once,
which is how the policy itself is tested. Routines that pass work on share one ``Deadline``
(a nested call gets the caller's, so the budget covers the whole call). A ``Deadline`` crosses
process boundaries by what is left of it.

See Also
--------
robustctl.dksyn, robustctl.hinfsyn, robustctl.diagnose, robustctl.update, robustctl.mu
"""

from __future__ import annotations

import math
import time
import warnings
from typing import Any

from .checks import positive_number
from .errors import RobustctlError, RobustctlWarning

__all__ = ["Deadline", "BudgetWarning", "as_deadline"]


class BudgetWarning(RobustctlWarning, RuntimeWarning):
    """A wall-clock ``time_budget_s`` ended a computation early: its result depends on the clock
    (also a RuntimeWarning, the class such notices had before)."""


class Deadline:
    """A wall-clock budget that may be absent: ``Deadline(None)`` never expires.

    Parameters
    ----------
    time_budget_s : float or None
        Seconds from now (``>= 0``), or None for no clock (the default of every routine).
    error : type of RobustctlError
        The error class for a bad ``time_budget_s`` (the calling stage's).

    Attributes
    ----------
    budget_s : float or None
        The budget as given.
    hit : bool
        True once :meth:`expired` has returned True (the budget stopped something).
    """

    __slots__ = ("budget_s", "hit", "_end")

    def __init__(self, time_budget_s: float | None = None, *, error: type[RobustctlError] = RobustctlError):
        if time_budget_s is None:
            self.budget_s, self._end = None, math.inf
        else:
            self.budget_s = positive_number(time_budget_s, "time_budget_s", error, allow_zero=True, unit="s")
            self._end = time.monotonic() + self.budget_s
        self.hit = False

    @property
    def active(self) -> bool:
        """True when there is a clock (``time_budget_s`` was a number)."""
        return self.budget_s is not None

    def remaining(self) -> float:
        """Seconds left (``inf`` without a clock, never below 0)."""
        if self.budget_s is None:
            return math.inf
        return max(0.0, self._end - time.monotonic())

    def expired(self) -> bool:
        """True when the budget is used up (never without a clock); marks :attr:`hit`."""
        if self.budget_s is None:
            return False
        if time.monotonic() >= self._end:
            self.hit = True
        return self.hit

    def budget_or_none(self) -> float | None:
        """What is left as a ``time_budget_s`` for a nested call (None without a clock)."""
        return None if self.budget_s is None else self.remaining()

    def warn(self, what: str, stacklevel: int = 3) -> None:
        """Issue the policy's :class:`BudgetWarning`: ``what`` was stopped by the budget."""
        warnings.warn(
            f"{what} was stopped by time_budget_s={self.budget_s:g} s: the result is the best found "
            "so far and depends on the machine's speed and load (stopped_by_budget=True). Leave "
            "time_budget_s=None for a result that depends only on the inputs.",
            BudgetWarning,
            stacklevel=stacklevel,
        )

    def __reduce__(self):  # what is left travels to a worker process
        return (_resume, (self.budget_s, self.remaining(), self.hit))

    def __repr__(self) -> str:
        if self.budget_s is None:
            return "Deadline(None)"
        return f"Deadline({self.budget_s:g} s, {self.remaining():.3g} s left)"


def _resume(budget_s: float | None, left: float, hit: bool) -> Deadline:
    d = Deadline(None)
    if budget_s is not None:
        d.budget_s, d._end = budget_s, time.monotonic() + left
    d.hit = hit
    return d


def as_deadline(value: Any, error: type[RobustctlError] = RobustctlError) -> Deadline:
    """``value`` as a :class:`Deadline`: a Deadline passes through (a nested call shares its
    caller's budget), None or seconds make a new one."""
    if isinstance(value, Deadline):
        return value
    return Deadline(value, error=error)
