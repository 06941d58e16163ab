"""A design sweep: one D-K run per weight choice, spread over any executor.

A designer rarely trusts one set of weights: the performance level, the multiplicative
uncertainty or the cover order is varied and the mu-controllers compared. Each design is an
independent :func:`~robustctl.robust.dk.iteration.dksyn` run, so the sweep goes through
:func:`robustctl.executors.parallel_map` — a ``ProcessPoolExecutor`` or a dask.distributed
``Client.get_executor()`` runs the designs side by side.
"""

from __future__ import annotations

import html
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

from ...checks import flag
from ...errors import SynthesisError
from ...executors import check_executor, parallel_map
from ...interconnect import PartitionedPlant
from ...plots import new_figure
from ...table import Table
from .iteration import DKResult, check_dk_options, dksyn

__all__ = ["design_sweep", "DesignSweep"]


@dataclass(frozen=True, eq=False)
class DesignSweep:
    """Result of :func:`design_sweep`.

    Attributes
    ----------
    labels : tuple of str
        The designs, in the order given.
    results : dict
        label -> :class:`~robustctl.robust.dk.iteration.DKResult`.
    """

    labels: tuple[str, ...]
    results: dict[str, DKResult] = field(repr=False)

    @property
    def best(self) -> str:
        """Label of the design with the lowest peak mu."""
        return min(self.labels, key=lambda k: self.results[k].mu_peak)

    def table(self) -> Table:
        """One row per design: peak mu, controller order, iterations, time, stop reason."""
        rows = []
        for k in self.labels:
            r = self.results[k]
            rows.append((k, r.mu_peak, r.K.nstates, len(r.history), sum(it.time_s for it in r.history),
                         r.stop_reason))
        return Table(("design", "peak mu", "K order", "iterations", "time (s)", "stopped"), rows,
                     title=f"Design sweep: {len(self.labels)} D-K runs, best {self.best!r}")

    def summary(self) -> str:
        best = self.results[self.best]
        return (f"{len(self.labels)} designs; the lowest peak mu is {best.mu_peak:.4g} ({self.best!r}, "
                f"{best.K.nstates}-state controller).")

    def plot(self):
        """Peak mu of each design (bar chart)."""
        fig = new_figure(6.0, 3.5)
        ax = fig.add_subplot()
        ax.bar(range(len(self.labels)), [self.results[k].mu_peak for k in self.labels])
        ax.axhline(1.0, color="k", lw=0.8, ls="--")
        ax.set_xticks(range(len(self.labels)), self.labels, rotation=30, ha="right")
        ax.set_ylabel("peak mu (upper bound)")
        ax.set_title("Design sweep")
        return fig

    def _repr_html_(self) -> str:
        return f"<p>{html.escape(self.summary())}</p>" + self.table()._repr_html_()

    def __repr__(self) -> str:
        return f"DesignSweep({len(self.labels)} designs, best {self.best!r})"


def _is_plant(recipe: Any) -> bool:
    return isinstance(recipe, (tuple, PartitionedPlant))


def _design(item: tuple[Any, dict]) -> DKResult:
    plant, options = item
    label, plant = plant
    if not _is_plant(plant):
        plant = plant()
    try:
        return dksyn(plant, **options)
    except SynthesisError as exc:
        raise SynthesisError(f"recipes[{label!r}]: {exc}") from exc


def design_sweep(
    recipes: Mapping[str, Any],
    *,
    executor: Any = None,
    progress: bool = True,
    **dk_options: Any,
) -> DesignSweep:
    """Run one D-K iteration per design and collect the controllers.

    Parameters
    ----------
    recipes : mapping of str to plant
        label -> a GeneralizedPlant, a ``(P, nmeas, ncon, blocks)`` tuple, or a callable with
        no arguments returning one (built on the worker: cheap to ship).
    executor : concurrent.futures.Executor, optional
        Runs the designs side by side (threads, processes, dask); None runs them in turn.
    progress : bool
        Progress bar over the designs in a terminal.
    **dk_options
        Passed to every :func:`~robustctl.robust.dk.iteration.dksyn` call (``max_iter``, ``order_d``,
        ``time_budget_s``, ...); each design's own progress display is off.

    Returns
    -------
    DesignSweep
    """
    import control

    check_executor(executor)
    progress = flag(progress, "progress", SynthesisError)
    if not isinstance(recipes, Mapping) or not recipes:
        raise SynthesisError(
            "recipes must be a non-empty mapping label -> plant (GeneralizedPlant, (P, nmeas, ncon, blocks) "
            f"or a callable returning one); got {type(recipes).__name__}."
        )
    for label, recipe in recipes.items():
        if not (_is_plant(recipe) or callable(recipe)) or isinstance(recipe, control.LTI):
            raise SynthesisError(
                f"recipes[{label!r}] must be a GeneralizedPlant, a (P, nmeas, ncon, blocks) tuple or a "
                f"callable returning one; got {type(recipe).__name__}."
            )
    check_dk_options(dk_options, "design_sweep")
    labels = tuple(str(k) for k in recipes)
    options = {**dk_options, "progress": False}
    items = [((str(k), recipes[k]), options) for k in recipes]
    results = parallel_map(_design, items, executor, desc="designs", progress=progress)
    return DesignSweep(labels, dict(zip(labels, results)))

