"""mu-synthesis by D-K iteration: H-infinity synthesis alternating with D-scale fits.

The structured singular value of the closed loop ``M = Fl(P, K)`` is bounded above by
``inf_D sigma_max(D M D^-1)`` (Packard & Doyle 1993, eq. 8.1; Zhou, Doyle & Glover 1996,
sec. 11.3). D-K iteration (Doyle 1985; Balas & Doyle's Caltech truss design, seed paper
"Identification of Flexible Structures for Robust Control", Fig. 1) minimises this bound
over ``K`` and ``D(s)`` alternately (Skogestad & Postlethwaite 2005, sec. 8.12.1):

1. **K step** -- ``K = argmin || D Fl(P, K) D^-1 ||_inf`` by H-infinity synthesis on the
   scaled plant ``diag(D, I) P diag(D^-1, I)`` (the scales act on the uncertainty and
   performance channels only, so ``K`` works unchanged on the unscaled ``P``);
2. **D step** -- the mu upper bound of ``Fl(P, K)`` on a frequency grid gives optimal
   constant scales ``d_i(f)`` per block; each ``|d_i(j 2 pi f)|`` is fitted by a stable,
   minimum-phase ``d_i(s)`` (its inverse is stable too), the last block normalised to 1;
3. repeat while the peak of mu falls.

The best controller (lowest peak of mu) is kept.

Alternating minimisation creeps on flat problems: on Skogestad & Postlethwaite's
distillation example mu is flat from DC to 0.3 Hz after three iterations and plain D-K
gains 0.1-0.3 % per iteration (1.0277, 1.0215, 1.0174, 1.0145, 1.0134, ...). From the third
iteration on, the D step is therefore a short line search along the change of the optimal
scales between the last two controllers (over-relaxation of the fixed-point iteration):
targets ``ln d_k + beta (ln d_k - ln d_{k-1})`` for ``beta`` in :data:`D_STEPS`, each fitted
with the orders chosen for ``beta = 0`` and scored by the K step's verified gamma (the D-K
objective ``inf_K ||D Fl(P, K) D^-1||_inf``, an upper bound on the next peak of mu); the
lowest gamma wins. On the distillation example this gives 1.1809, 1.0284, 1.0139, 1.0035,
0.9918 (plain D-K: 1.0145 at iteration 5).

With real scalar blocks (``real="mixed"``, the default) the iteration is D-G-K (Young 1996,
"Controller design for mixed uncertainties", Automatica 32(8)): the analysis is mixed mu,
the scales offered to the K step are the complex analysis' wherever they keep the mixed
bound and the mixed ones elsewhere, the G-scales become stable filters absorbed by a loop
transformation (:mod:`robustctl.robust.dk.dgk`), and the K step searches the level it can
certify. The G-scales are fitted as follows: at the level ``beta`` (the peak of mixed mu on the
grid) the analysis' optimal ``G_i(f)`` gives the target ``Im r_i / (1 - |r_i|^2) = -g_i /
(2 beta d_i^2)``, which a stable real-rational filter ``r_i(s)`` with ``|r_i| <= 0.95`` on the
axis fits by nonlinear least squares on real poles two per decade with a penalty above 0.95
(:func:`~robustctl.robust.dk.dgk.fit_g_filter`);
the D-scales offered to the K step are ``d_i / sqrt(1 - |r_i|^2)``. A complex-mu design is a
valid mixed-mu design, so D-G-K starts from the complex D-K design and returns the better
verified one of the two (``DKResult.complex_mu_peak``; :func:`_mixed_from_complex`). The
iteration can rise: the fitted filters only approximate the optimal multipliers, and the K
step's certified level bounds the next mixed mu, not the last; it stops when mu stops falling.

The returned controller is the best of the iterations, and its mu is verified on a denser
and wider grid with a search of its highest maxima (:func:`verification_grid`): the
iterations judge mu on a finite grid, which can miss a lightly damped resonance's peak.
An iteration whose mu rises above the best before it says so (``DKIteration.note``).
"""

from __future__ import annotations

import sys
import time
from collections.abc import Callable, Mapping, Sequence
from concurrent.futures import Executor
from dataclasses import dataclass, field, replace
from types import SimpleNamespace
from typing import Any

import numpy as np

from ...budget import Deadline, as_deadline
from ...checks import flag, integer, positive_number
from ...errors import PlantError, SynthesisError, SynthesisWarning
from ...executors import check_executor
from ...interconnect import PartitionedPlant
from ...lti import freqresp_array, is_stable
from ...plots import new_figure
from ...table import Table
from ...threads import limit_blas
from ..hinf.synthesis import gamma_feasible, hinfsyn
from ..mu.bounds import mu
from ..partitioned import as_partitioned
from ..plant import GeneralizedPlant
from ..uncertainty.blocks import Block, BlockStructure
from .design_plant import DesignReduction, check_design_order, design_on_reduced
from .dgk import blended_scales, fit_g_filter, g_transform, scaled_d_targets, transformed_norm
from .reduce import Reduction, _reduce
from .sampled_design import sampled_result, tustin_original
from .scales import (
    HINF_BACKOFF,
    _autoscaled,
    _constant_scaled,
    _DCandidate,
    _edge_response,
    _extrapolated,
    _fit_d_scales,
    _log_scales,
    _orders,
    _scale_plant,
    _Scaling,
    _unscaled_controller,
    _unscaled_mu,
)
from .scales import _dynamics_in_band as _dynamics_in_band
from .scales import _fit_one as _fit_one
from .scales import _into_band as _into_band
from .verify import closed_loop, default_grid, mu_of, verified_mu
from .verify import verification_grid as verification_grid

__all__ = ["DKIteration", "DKResult", "Reduction", "DesignReduction", "dksyn"]

#: Extrapolation steps ``beta`` of the D step's line search (module docstring); 0 is plain D-K.
D_STEPS = (0.0, 0.5, 1.0)
#: With automatic D orders, a run the iteration cap stops while it creeps is repeated with
#: fixed orders around its own (:func:`_neighbour_orders`); False turns that off.
ORDER_NEIGHBOURS = True
#: Most fixed-order runs of that repetition.
ORDER_NEIGHBOURS_RUNS = 8
#: A fixed-order run replaces the automatic one only when its peak of mu is this fraction lower.
ORDER_NEIGHBOURS_GAIN = 5e-3
#: The fall of the peak of mu in the last iteration above which such a run counts as creeping
#: (at 0.5 % per iteration more iterations could still matter; the distillation column capped
#: at six iterations falls 0.3 % in its last; mkhicn with the least-squares D fits 0.69 %, where
#: fixed order 5 reaches 0.932 against the automatic run's 0.959).
ORDER_NEIGHBOURS_CREEP = 0.005
#: A run stopped by a rise of the peak of mu (more than this fraction above its best) right after
#: a fall of more than :data:`ORDER_NEIGHBOURS_CREEP` is repeated with fixed orders too.
ORDER_NEIGHBOURS_RISE = 1e-3
#: False: only runs the iteration cap stopped are repeated with fixed orders.
ORDER_NEIGHBOURS_ON_RISE = True
#: With automatic D orders, a complex D-K run whose peak of mu stops falling repeats the D step
#: on its best closed loop with every block's order at least one higher, at most this many times
#: per run (each a further iteration within ``max_iter``), and goes on while mu falls. The fits
#: lose against the optimal scales where they stopped (on the Caltech design plant the orders
#: (2, 2, 2) bounded the best loop at 0.859 against its mu 0.776, and mu rose to 0.777; the
#: grown orders (4, 3, 4) reached 0.751 in one further iteration, where restarting D-K at the
#: neighbouring fixed orders took two further designs and reached 0.775). A run whose grown orders
#: lowered mu is not repeated at fixed orders after a later rise (:func:`_creeping`). 0: off.
ORDER_GROWTH_STEPS = 1
#: Most fixed-order runs after such a rise (the best iteration's own orders first when the run
#: changed orders on its way: on the Caltech design plant orders (4, 3, 4) fixed reached 0.748
#: where the automatic run rose after 0.787; on mkhic none of seven orders beat the rise's 0.974).
ORDER_NEIGHBOURS_RISE_RUNS = 2
#: Most fixed-order runs of that repetition when the automatic run's K steps were solved by
#: LMIs (the orders one below and one above): the interior-point solve grows like ``n^6`` in
#: the scaled plant's states, which each order adds to (eight runs of the D12 = 0 plant took
#: 35x the automatic run's CPU time).
ORDER_NEIGHBOURS_LMI_RUNS = 2
#: Most states of a scaled plant whose failed Riccati K step is retried on the LMI route.
LMI_FALLBACK_MAX_STATES = 40
#: Starts of the automatically scaled D-K (ln of a factor on all block scales but the last).
AUTOSCALE_STARTS = (0.0, -1.5, 1.5)
#: A start whose verified mu is below this ends the multi-start (robust performance certified).
AUTOSCALE_CERTIFIED = 1.0
#: H-infinity syntheses of one D-G-K K step's search for its level (:func:`_mixed_k_step`).
MIXED_K_EVALS = 5
#: ``|ln gamma|`` at which that search stops (the level is then within about 0.5 %).
MIXED_K_TOL = 5e-3
#: A verified peak of mu this fraction above the iteration grid's draws a RuntimeWarning.
VERIFY_WARN_RTOL = 0.01


# ---------------------------------------------------------------------------- plant
def _complexified(blocks: BlockStructure) -> BlockStructure:
    """Real scalar blocks treated as complex ones (D-K has no G-scales; conservative)."""
    return BlockStructure(tuple(
        Block("complex", b.rows, b.cols, b.name) if b.kind == "real" else b for b in blocks
    ))


def as_plant(gp: Any) -> GeneralizedPlant:
    """A GeneralizedPlant or ``(P, nmeas, ncon, blocks)`` as a checked plant with blocks
    (continuous, or sampled: :mod:`.sampled_design`)."""
    if isinstance(gp, tuple) and len(gp) == 4:
        P, nmeas, ncon, blocks = gp
        return as_partitioned(P, nmeas, ncon, blocks, who="dksyn", need_blocks=True)
    if isinstance(gp, PartitionedPlant):
        return as_partitioned(gp, who="dksyn", need_blocks=True)
    raise PlantError(
        f"dksyn takes a GeneralizedPlant (rc.generalized_plant) or a tuple (P, nmeas, ncon, blocks); "
        f"got a {type(gp).__name__}."
    )


# ---------------------------------------------------------------------------- state space
@dataclass(frozen=True)
class DKIteration:
    """One D-K iteration.

    Attributes
    ----------
    index : int
        1-based iteration number.
    gamma : float
        H-infinity norm of the scaled closed loop reached by the K step.
    mu_peak : float
        Peak over frequency of the mu upper bound of the unscaled closed loop.
    f_peak_hz : float
        Frequency of that peak (Hz).
    controller_order : int
        States of the controller.
    d_orders : tuple of int
        Orders of the D-scales used in this iteration's K step (empty in the first).
    time_s : float
        Wall-clock time of the iteration (s).
    mu : MuResult
        The mu analysis of this iteration's closed loop.
    fitted_bound : float
        ``max_f sigma_max(D M D^-1)`` of this closed loop with the (``beta = 0``) fitted
        D-scales offered to the next K step: an upper bound on their gamma (NaN when no fit followed).
    d_step : float
        The line search's extrapolation step ``beta`` of the D-scales used in this K step
        (0: plain D-K; see the module docstring).
    n_candidates : int
        D-scale candidates whose K step was tried in this iteration.
    note : str
        Set when this iteration's peak of mu is above the best before it (the D fits only
        approximate the optimal scales, so D-K need not descend): the two peaks, and the
        K step's gamma when it was already above that best (the fitted scales, not the K
        step, lost the ground).
    k_method : str
        The route of this iteration's H-infinity synthesis: ``"riccati"``, or ``"lmi"`` when
        the K step was solved by LMIs (asked in ``hinf_options``, or the fallback where the
        Riccati route refuses, e.g. ``D12 = 0``); empty when the first controller was given.
    grown_from : int
        When this iteration's D-scales were fitted with grown orders (:data:`ORDER_GROWTH_STEPS`):
        the iteration whose closed loop they were fitted on (the best before it); 0 otherwise
        (fitted on the previous iteration's loop).
    """

    index: int
    gamma: float
    mu_peak: float
    f_peak_hz: float
    controller_order: int
    d_orders: tuple[int, ...]
    time_s: float
    mu: Any = field(repr=False)
    fitted_bound: float = float("nan")
    d_step: float = 0.0
    n_candidates: int = 1
    note: str = ""
    k_method: str = "riccati"
    grown_from: int = 0


@dataclass(frozen=True)
class DKResult:
    """The result of :func:`dksyn`.

    Attributes
    ----------
    K : control.StateSpace
        The best controller (inputs: the plant's measurements, outputs: its controls), or
        its reduction when ``reduce`` was given and accepted.
    mu_peak : float
        Peak of the mu upper bound of ``Fl(P, K)`` on the verification grid
        (:func:`verification_grid`: DC, the iteration grid made three times denser and a
        decade wider each way, and the lightly damped closed-loop poles); < 1: robust
        stability / performance certified there for the block structure (mixed mu with
        real="mixed", else real blocks complexified).
    mu : MuResult
        mu analysis of the returned controller's closed loop on the verification grid.
    closed_loop : control.StateSpace
        ``Fl(P, K)``, ``w -> z``.
    history : tuple of DKIteration
    best_iteration : int
        The iteration whose controller was kept (1-based).
    stop_reason : str
    blocks : BlockStructure
    d_scales : tuple of control.StateSpace
        The fitted D-scales used for the best controller's K step (one per block but the last).
    reduction : Reduction or None
    grid_mu_peak : float
        The returned controller's peak of mu on the iteration grid (what the iteration saw;
        ``mu_peak`` is at least this).
    stopped_by_budget : bool
        A ``time_budget_s`` ended the iteration (or a K step's bisection) early: the result
        depends on the machine's speed (:mod:`robustctl.budget`).
    design_reduction : DesignReduction or None
        The balanced truncation of the design plant before synthesis (``design_order``):
        orders, error bound and the verified mu with the reduced and the full plant. When
        set, ``mu_peak``, ``mu`` and ``closed_loop`` are the full plant's and ``history`` the
        design plant's.
    complex_mu_peak : float
        With real blocks and ``real="mixed"``: the verified peak of complex mu (real blocks
        complexified) of the complex D-K design that D-G-K starts from (NaN otherwise). The
        returned mixed ``mu_peak`` is never above that design's mixed mu, hence never above
        this figure.
    elapsed_s : float
        Wall-clock time of the :func:`dksyn` call that returned this result (s): every
        strategy's runs (autoscaled starts, neighbouring D orders, the complex D-K before
        D-G-K), the verification and the reduction, not only the iterations in ``history``.
        NaN for a result built outside ``dksyn``.
    """

    K: Any
    mu_peak: float
    mu: Any
    closed_loop: Any
    history: tuple[DKIteration, ...]
    best_iteration: int
    stop_reason: str
    blocks: BlockStructure
    d_scales: tuple[Any, ...] = ()
    reduction: Reduction | None = None
    grid_mu_peak: float = float("nan")
    stopped_by_budget: bool = False
    design_reduction: DesignReduction | None = None
    complex_mu_peak: float = float("nan")
    elapsed_s: float = float("nan")

    @property
    def time_s(self) -> float:
        """Wall-clock time of the call (s): ``elapsed_s``, or the iterations' sum without it."""
        if np.isfinite(self.elapsed_s):
            return float(self.elapsed_s)
        return self.iterations_time_s

    @property
    def iterations_time_s(self) -> float:
        """Wall-clock time of the iterations in ``history`` (s)."""
        return float(sum(h.time_s for h in self.history))

    def table(self) -> Table:
        """One row per iteration: gamma, peak mu, controller order, D orders, line-search step, time."""
        rows = [
            (h.index, h.gamma, h.mu_peak, h.f_peak_hz, h.controller_order,
             " ".join(str(o) for o in h.d_orders) or "-", f"{h.d_step:g} of {h.n_candidates}",
             h.fitted_bound, h.time_s, "best" if h.index == self.best_iteration else "")
            for h in self.history
        ]
        cols = ("iteration", "gamma", "mu peak", "f peak (Hz)", "K order", "D orders", "D step",
                "next bound", "time (s)", "")
        return Table(cols, rows, title="D-K iteration")

    def summary(self) -> str:
        """A short account of the iteration."""
        verdict = "certified (< 1)" if self.mu_peak < 1 else "not certified (>= 1)"
        text = (
            f"D-K iteration: peak mu {self.mu_peak:.4f} {verdict} at {self.mu.f_peak_hz:.3g} Hz with a "
            f"{self.K.nstates}-state controller (iteration {self.best_iteration} of {len(self.history)}; "
            f"stopped: {self.stop_reason}). The call took {self.time_s:.2f} s"
        )
        if np.isfinite(self.elapsed_s):
            text += f", {self.iterations_time_s:.2f} s of it in the iterations listed"
        text += "."
        if self.mu_peak > self.grid_mu_peak * (1 + 1e-3):
            text += (f" Between and beyond the iteration grid's points mu reaches {self.mu_peak:.4f} "
                     f"(the grid saw {self.grid_mu_peak:.4f}).")
        if self.stopped_by_budget:
            text += (" The time budget stopped the iteration early: the result depends on the "
                     "machine's speed (time_budget_s=None for one that does not).")
        rises = [h for h in self.history if h.note]
        if rises:
            text += " " + " ".join(f"Iteration {h.index}: {h.note}." for h in rises)
        if np.isfinite(self.complex_mu_peak):
            text += (f" Complex D-K (real blocks as complex) reached mu {self.complex_mu_peak:.4f}; mixed mu "
                     f"{self.mu_peak:.4f} is the better of that design's and D-G-K's from it.")
        if self.design_reduction is not None:
            text += " " + self.design_reduction.summary()
        if self.reduction is not None:
            r = self.reduction
            text += (
                f" Reduction {r.order_before} -> {r.order_after} states: mu {r.mu_peak_before:.4f} -> "
                f"{r.mu_peak_after:.4f} ({'accepted' if r.accepted else 'rejected: ' + r.reason})."
            )
        return text

    def plot(self):
        """mu upper bound over frequency per iteration, and the peak of mu per iteration."""
        fig = new_figure(10.0, 4.5)
        ax1, ax2 = fig.subplots(1, 2, width_ratios=(2, 1))
        for h in self.history:
            ax1.semilogx(h.mu.f_hz, h.mu.upper, lw=2.0 if h.index == self.best_iteration else 1.0,
                         label=f"iteration {h.index}: {h.mu_peak:.3f}")
        ax1.axhline(1.0, color="k", ls=":", lw=0.8)
        ax1.set(xlabel="frequency (Hz)", ylabel="mu upper bound", title="mu of Fl(P, K) per iteration")
        ax1.legend(fontsize=8)
        it = [h.index for h in self.history]
        ax2.plot(it, [h.mu_peak for h in self.history], "o-", label="peak mu")
        ax2.plot(it, [h.gamma for h in self.history], "s--", label="gamma (scaled)")
        ax2.axhline(1.0, color="k", ls=":", lw=0.8)
        ax2.set(xlabel="iteration", title="D-K history")
        ax2.set_xticks(it)
        ax2.legend(fontsize=8)
        return fig

    def _repr_html_(self) -> str:
        import html

        return f"<p>{html.escape(self.summary())}</p>" + self.table()._repr_html_()

    def __repr__(self) -> str:
        return (f"DKResult(mu_peak={self.mu_peak:.4f}, K order={self.K.nstates}, "
                f"iterations={len(self.history)})")


# ---------------------------------------------------------------------------- the loop
def _check_args(max_iter: Any, time_budget_s: Any, f_hz: Any) -> np.ndarray | None:
    integer(max_iter, "max_iter", SynthesisError, lo=1, hi=100)
    as_deadline(time_budget_s, SynthesisError)  # None, seconds >= 0 or a caller's Deadline
    if f_hz is None:
        return None
    try:
        f = np.asarray(f_hz, dtype=float).ravel()
    except (TypeError, ValueError):
        f = np.full(1, np.nan)
    if f.size < 3 or not np.all(np.isfinite(f)) or np.any(f <= 0) or np.any(np.diff(f) <= 0):
        raise SynthesisError(
            "f_hz must be at least 3 positive, finite, increasing frequencies in Hz, e.g. "
            f"np.logspace(-3, 2, 200); got {f_hz!r}."
        )
    return f


def _check_options(progress: Any, rtol: Any, patience: Any, hinf_options: Any, callback: Any) -> dict:
    """The keyword options of :func:`dksyn`, checked before any work (SynthesisError naming each)."""
    if progress is not None:
        flag(progress, "progress", SynthesisError)
    positive_number(rtol, "rtol", SynthesisError)
    integer(patience, "patience", SynthesisError, lo=1)
    if callback is not None and not callable(callback):
        raise SynthesisError(f"callback must be a function of one DKIteration (or None); got {callback!r}.")
    if hinf_options is None:
        return {}
    allowed = ("method", "gamma_tol", "backoff", "time_budget_s")
    if not isinstance(hinf_options, Mapping) or not set(hinf_options) <= set(allowed):
        raise SynthesisError(
            f"hinf_options must be a dict with keys among {allowed} (rc.hinfsyn's options); "
            f"got {hinf_options!r}."
        )
    if "time_budget_s" in hinf_options:
        Deadline(hinf_options["time_budget_s"], error=SynthesisError)
    for key in ("gamma_tol", "backoff"):
        if key in hinf_options:
            positive_number(hinf_options[key], f"hinf_options[{key!r}]", SynthesisError,
                            allow_zero=key == "backoff")
    if hinf_options.get("method", "riccati") not in ("riccati", "lmi"):
        raise SynthesisError(
            f"hinf_options['method'] must be 'riccati' or 'lmi'; got {hinf_options['method']!r}."
        )
    return dict(hinf_options)


_DK_OPTIONS = ("max_iter", "order_d", "f_hz", "executor", "time_budget_s", "reduce", "rtol", "patience",
               "hinf_options", "callback", "real", "autoscale", "gamma", "design_order")


def check_dk_options(options: Any, where: str) -> None:
    """Refuse, before any design, keyword options that :func:`dksyn` would refuse (all but
    ``order_d`` and ``reduce``, which need the plant): unknown names and bad values."""
    unknown = sorted(set(options) - set(_DK_OPTIONS))
    if unknown:
        raise SynthesisError(
            f"{where} got unknown D-K option(s) {unknown}; the options are {list(_DK_OPTIONS)}."
        )
    _check_args(options.get("max_iter", 10), options.get("time_budget_s"), options.get("f_hz"))
    _check_options(None, options.get("rtol", 1e-3), options.get("patience", 1), options.get("hinf_options"),
                   options.get("callback"))
    check_executor(options.get("executor"))
    check_design_order(options.get("design_order", "auto"))
    if options.get("order_d") is not None:
        _orders(options["order_d"], 1 if np.ndim(options["order_d"]) == 0 else len(options["order_d"]))


@limit_blas
def dksyn(
    gp: Any,
    max_iter: int = 10,
    order_d: int | Sequence[int] | None = None,
    f_hz: Any = None,
    executor: Executor | None = None,
    time_budget_s: float | None = None,
    reduce: int | str | tuple | None = None,
    progress: bool | None = None,
    *,
    rtol: float = 1e-3,
    patience: int = 1,
    hinf_options: dict[str, Any] | None = None,
    callback: Callable[[DKIteration], None] | None = None,
    real: str = "mixed",
    autoscale: bool = True,
    gamma: float | None = None,
    design_order: int | str | None = "auto",
) -> DKResult:
    """mu-synthesis by D-K iteration (Skogestad & Postlethwaite 2005, sec. 8.12.1; module docstring).

    Parameters
    ----------
    gp : GeneralizedPlant or tuple (P, nmeas, ncon, blocks)
        The plant ``[w; u] -> [z; y]``, the uncertainty and performance channels first in block
        order; ``blocks`` in any form ``as_block_structure`` takes (mussv rows ``[[1, 1], [2,
        2]]``; ``[-r, 0]`` a real parameter, see ``real``). A sampled plant (``dt > 0`` s) is
        designed through the Tustin map, which keeps stability and mu (:mod:`.sampled_design`).
    max_iter : int
        Iteration cap (each iteration is one K step and one mu analysis).
    order_d : int, sequence of int or None
        Order of each D-scale fit (one per block but the last). None: per block the lowest
        order in 0..8 within 5 % of the best bound (:func:`~.scales._fit_d_scales`); where mu stops
        falling the best loop's D step is repeated once with higher orders (:data:`ORDER_GROWTH_STEPS`);
        a run the cap stops while mu still falls is repeated at neighbouring orders
        (:func:`_neighbour_orders`).
    f_hz : array_like, optional
        Analysis grid (Hz). Default: :func:`default_grid`, refined at lightly damped closed-loop poles.
    executor : concurrent.futures.Executor, optional
        Runs the D-scale fits in parallel.
    time_budget_s : float or None
        Optional wall-clock budget (s) by :mod:`robustctl.budget`'s policy; None (default): the
        result depends only on the inputs. A budget that stops the iteration keeps the best
        controller and sets ``stopped_by_budget``.
    reduce : int, "auto" or (method, order), optional
        Reduce the final controller and re-check mu (kept if it stabilises and raises mu by at
        most 2 %; :mod:`robustctl.robust.dk.reduce`, :mod:`robustctl.robust.reduction.controller`).
    progress : bool, optional
        tqdm bar over iterations (default: when stderr is a terminal).
    rtol : float
        The fraction by which the peak of mu must fall to count as an improvement.
    patience : int
        Non-improving iterations tolerated before stopping (1: "repeat while mu falls").
    hinf_options : dict, optional
        Extra keyword arguments of :func:`~robustctl.robust.hinf.synthesis.hinfsyn`
        (``method``, ``gamma_tol``, ``backoff``, ``time_budget_s``); see :func:`_k_step`.
    callback : callable, optional
        Called with each :class:`DKIteration`.
    real : {"mixed", "complex"}
        With real blocks, ``"mixed"`` runs D-G-K (Young 1996; :mod:`robustctl.robust.dk.dgk`)
        from the complex D-K design and returns the better (:func:`_mixed_from_complex`);
        ``mu_peak`` is then mixed mu. ``"complex"``: real blocks treated as complex.
    autoscale : bool
        Scale the plant's channels first and start from several block scalings
        (:func:`_autoscaled_dksyn`), so the result does not depend on the plant's units.
    gamma : float, optional
        A fixed design level for the K steps when above their optimum (better conditioned
        controllers; not used by D-G-K's K step, which searches its level).
    design_order : "auto", int or None
        States of the design plant the K steps see (:mod:`robustctl.robust.dk.design_plant`):
        ``"auto"`` reduces plants above 200 states by balanced truncation with the error as an
        added block and verifies mu on the full plant; an integer: that many; None: the full plant.

    Returns
    -------
    DKResult
        With ``elapsed_s``, the call's own wall-clock time (s).

    Raises
    ------
    SynthesisError
        A malformed plant, blocks or option; no stabilising controller; a design-plant
        controller that does not stabilise the full plant (raise ``design_order``); a
        sampled plant with a pole at ``z = -1``.

    Examples
    --------
    >>> dk = rc.dksyn((P, 2, 2, [[1, 1], [1, 1], [2, 2]]))   # doctest: +SKIP
    >>> dk.mu_peak, dk.table()                                # doctest: +SKIP
    """
    t0 = time.perf_counter()
    run = _settings(max_iter, f_hz, executor, time_budget_s, reduce, progress, rtol, patience, hinf_options,
                    callback, real, gamma)
    plant = as_plant(gp)
    sampled = plant if plant.P.isdtime(strict=True) else None
    if sampled is not None:
        plant = tustin_original(sampled)
    autoscale = flag(autoscale, "autoscale", SynthesisError)
    _orders(order_d, len(plant.blocks) - 1)  # refuse a bad order_d now, not at the first D step

    def design(p: GeneralizedPlant, error_block: bool) -> DKResult:
        od = order_d
        if error_block and od is not None and np.ndim(od) == 1:  # a constant D-scale for the error block
            k = len(plant.blocks) - 1
            od = [*list(od)[:k], 0, *list(od)[k:]]
        return _solve(p, od, autoscale, run)

    result = design_on_reduced(plant, design_order, _design_blocks(plant, real), design)
    if run.deadline.hit and not isinstance(time_budget_s, Deadline):  # a caller's Deadline: it reports
        run.deadline.warn("dksyn (D-K iteration from the autoscaled starts)" if autoscale
                          else "dksyn (D-K iteration)")
    if sampled is not None:
        result = sampled_result(result, sampled)
    return replace(result, elapsed_s=time.perf_counter() - t0)


def _settings(max_iter: Any, f_hz: Any, executor: Any, time_budget_s: Any, reduce: Any, progress: Any,
              rtol: Any, patience: Any, hinf_options: Any, callback: Any, real: Any, gamma: Any) -> _Settings:
    """:func:`dksyn`'s options checked before any work (SynthesisError naming each), as one record."""
    grid = _check_args(max_iter, time_budget_s, f_hz)
    hinf_options = _check_options(progress, rtol, patience, hinf_options, callback)
    if gamma is not None:
        gamma = positive_number(gamma, "gamma", SynthesisError)
    check_executor(executor)
    if not isinstance(real, str) or real not in ("mixed", "complex"):
        raise SynthesisError(f"real must be 'mixed' (D-G-K with G-scales on the real blocks) or 'complex' "
                             f"(real blocks treated as complex); got {real!r}.")
    return _Settings(max_iter=max_iter, grid=grid, executor=executor, rtol=rtol, patience=patience,
                     hinf_options=hinf_options, callback=callback, real=real, gamma=gamma, progress=progress,
                     reduce=reduce, deadline=as_deadline(time_budget_s, SynthesisError))


# ---------------------------------------------------------------------------- strategies
@dataclass(frozen=True)
class _Settings:
    """The checked options of one :func:`dksyn` call, shared by its strategies and the core."""

    max_iter: int
    grid: np.ndarray | None
    executor: Executor | None
    rtol: float
    patience: int
    hinf_options: dict
    callback: Callable[[DKIteration], None] | None
    real: str
    gamma: float | None
    progress: bool | None
    reduce: Any
    deadline: Deadline


def _design_blocks(plant: GeneralizedPlant, real: str) -> BlockStructure:
    """The blocks D-K designs for: the plant's, real ones complexified unless ``real="mixed"``."""
    mixed = real == "mixed" and plant.blocks.has_real
    return plant.blocks if mixed else _complexified(plant.blocks)


def _solve(plant: GeneralizedPlant, order_d: Any, autoscale: bool, run: _Settings) -> DKResult:
    """D-K on ``plant``: the autoscaled starts, or one run of the core from the user's scaling,
    each followed by the neighbouring D orders when the automatic orders crept (strategies 2, 3)."""
    blocks = _design_blocks(plant, run.real)
    if blocks.has_real:
        return _mixed_from_complex(plant, blocks, order_d, autoscale, run)
    if autoscale:
        return _autoscaled_dksyn(plant, blocks, order_d, run)
    result = _iterate(plant, blocks, order_d, run, run.reduce)
    if order_d is not None or not ORDER_NEIGHBOURS:
        return result
    return _neighbour_orders(result, blocks, lambda o: _iterate(plant, blocks, list(o), run, run.reduce),
                             run.deadline)


def _mixed_from_complex(plant: GeneralizedPlant, blocks: BlockStructure, order_d: Any, autoscale: bool,
                        run: _Settings) -> DKResult:
    """D-G-K that never loses to complex D-K (strategy 4).

    A complex-mu design is a valid mixed-mu design (complex mu bounds mixed mu from above), so
    complex D-K runs first (real blocks complexified, with the autoscaled starts and order
    neighbours as asked). D-G-K then starts from that controller: its first iteration is the
    complex design's closed loop, whose mixed analysis gives the first D- and G-scales, and it
    runs while its mixed mu falls (``patience``). The D-G-K iteration is not monotone -- the
    fitted G filters and D-scales only approximate the analysis' optimal multipliers, and the
    K step's certified level is a bound on the *next* mixed mu, not the last -- so an
    iteration can rise, and the run stops there. The core keeps the best iterate, so when no
    D-G-K step beats the complex design its verified mixed mu is the complex design's own (no
    separate analysis). Only when the D-G-K design verifies above the complex design's
    complex mu (a different verification grid) is the complex design's mixed mu verified on
    its iteration grid, and the lower of the two is returned. ``complex_mu_peak`` is the
    complex design's complex mu; when that design is kept and its mixed mu verified above it
    (a finer grid at a peak), its complex mu on the mixed grid too, which also bounds the mixed
    mu reported.
    """
    cx = _solve(plant, order_d, autoscale, replace(run, real="complex"))
    mx = _iterate(plant, blocks, order_d, run, run.reduce, first=cx.K)
    done = {"stopped_by_budget": cx.stopped_by_budget or mx.stopped_by_budget,
            "complex_mu_peak": float(cx.mu_peak)}
    if mx.best_iteration == 1:
        mixed_peak = float(mx.mu_peak)
        if mixed_peak > cx.mu_peak:
            # one controller, two verification grids: its mixed mu cannot exceed its complex mu,
            # so the complex mu is also taken on the mixed analysis' grid, where it bounds the
            # mixed mu too (a complex bound is a mixed bound)
            f = np.asarray(mx.mu.f_hz, dtype=float)
            mc = mu(freqresp_array(mx.closed_loop, f), _complexified(blocks), f_hz=f, lower=False)
            done["complex_mu_peak"] = max(float(cx.mu_peak), float(mc.peak))
            mixed_peak = min(mixed_peak, done["complex_mu_peak"])
        why = (f"the complex D-K design (mixed mu {mixed_peak:.4f}) is kept: D-G-K from it did not "
               "reach lower")
        return replace(cx, mu=mx.mu, mu_peak=mixed_peak, grid_mu_peak=mx.grid_mu_peak,
                       closed_loop=mx.closed_loop, stop_reason=f"{cx.stop_reason}; {why}", **done)
    if mx.mu_peak > cx.mu_peak:
        m_cx = verified_mu(cx.closed_loop, blocks, cx.history[cx.best_iteration - 1].mu.f_hz)
        if m_cx.peak <= mx.mu_peak:
            why = (f"the complex D-K design (mixed mu {m_cx.peak:.4f}) is kept: D-G-K from it reached "
                   f"{mx.mu_peak:.4f}")
            return replace(cx, mu=m_cx, mu_peak=float(m_cx.peak), stop_reason=f"{cx.stop_reason}; {why}",
                           **done)
    why = (f"D-G-K from the complex D-K design reached mixed mu {mx.mu_peak:.4f} (from "
           f"{mx.history[0].mu_peak:.4f} on the iteration grid)")
    return replace(mx, stop_reason=f"{mx.stop_reason}; {why}", **done)


# ---------------------------------------------------------------------------- the core
def _iterate(plant: GeneralizedPlant, blocks: BlockStructure, order_d: Any, run: _Settings,
             reduce: Any, first: Any = None) -> DKResult:
    """The D-K iteration on ``plant`` as it is (module docstring): K steps and D (and G) steps
    until the peak of mu stops falling, then the best controller reduced (``reduce``) and its mu
    verified (:func:`verification_grid`). The one loop every strategy of :func:`dksyn` calls.
    ``first``: a controller that replaces the first K step (its ``gamma`` is NaN)."""
    from tqdm import tqdm

    mixed = blocks.has_real
    grid, max_iter, rtol, deadline = run.grid, run.max_iter, run.rtol, run.deadline
    base = default_grid(plant.P) if grid is None else grid
    show = sys.stderr.isatty() and (run.progress is None or bool(run.progress))
    history: list[DKIteration] = []
    best: dict[str, Any] | None = None
    candidates = [_DCandidate((), ())]
    previous: tuple[np.ndarray, np.ndarray] | None = None
    stop, stale = f"max_iter={max_iter} reached", 0
    # automatic D orders: a run that stops falling is retried from its best loop with every
    # block's order one higher (complex D-K; D-G-K's level search is not repeated)
    grow_left = ORDER_GROWTH_STEPS if order_d is None and not mixed else 0
    grown_from = 0
    bar = tqdm(total=max_iter, desc="D-K", disable=not show, leave=False)
    try:
        for index in range(1, max_iter + 1):
            t0 = time.perf_counter()
            opts = {"time_budget_s": deadline, "backoff": HINF_BACKOFF, **(run.hinf_options or {})}
            try:
                if index == 1 and first is not None:
                    hres, cand = SimpleNamespace(K=first, gamma=float("nan"), info={}), candidates[0]
                else:
                    hres, cand = _k_step_search(hinfsyn, plant, candidates, opts, index, deadline, run.gamma)
            except SynthesisError as exc:
                if best is None:
                    raise
                stop = f"K step failed at iteration {index} ({exc})"
                break
            K = hres.K
            cl = closed_loop(plant.P, K, plant.nmeas, plant.ncon)
            m, H = mu_of(cl, blocks, base, refine=grid is None)
            entry = DKIteration(index, float(hres.gamma), float(m.peak), float(m.f_peak_hz), K.nstates,
                                cand.orders, 0.0, m, d_step=cand.beta, n_candidates=len(candidates),
                                k_method=hres.info.get("method", ""), grown_from=grown_from)
            improved = best is None or entry.mu_peak < best["it"].mu_peak * (1 - rtol)
            if best is not None and entry.mu_peak > best["it"].mu_peak:
                prev = best["it"]
                why = (f"the K step's gamma {entry.gamma:.4f} on the fitted D-scales was already above "
                       f"it; their bound on the previous loop was {history[-1].fitted_bound:.4f}"
                       if entry.gamma > prev.mu_peak and not mixed else "")
                entry = DKIteration(**{**entry.__dict__, "note": (
                    f"peak mu {entry.mu_peak:.4f} rose above iteration {prev.index}'s {prev.mu_peak:.4f}"
                    + (f" ({why})" if why else ""))})
            if best is None or entry.mu_peak < best["it"].mu_peak:
                best = {"it": entry, "K": K, "cl": cl, "d": cand.fits}
            if grown_from:
                extra = (f"D-scales of orders {cand.orders} fitted on iteration {grown_from}'s loop "
                         "(the orders grown where mu stopped falling)")
                entry = DKIteration(**{**entry.__dict__,
                                       "note": f"{entry.note}; {extra}" if entry.note else extra})
            if hres.info.get("stopped_by_budget"):
                extra = "the K step's gamma bisection was stopped by the time budget"
                entry = DKIteration(**{**entry.__dict__,
                                       "note": f"{entry.note}; {extra}" if entry.note else extra})
            stale = 0 if improved else stale + 1
            # the next iteration needs at least this one's K step and mu analysis: a K step
            # started with too little time left stops its gamma bisection early (gamma 7.3
            # where 1.2 was reachable, on a 28-state plant with five scaled blocks)
            k_time = time.perf_counter() - t0
            out_of_time = deadline.expired() or deadline.remaining() < k_time
            done = stale >= run.patience or index == max_iter or out_of_time
            bound = float("nan")
            if stale >= run.patience and grow_left > 0 and index < max_iter and not out_of_time \
                    and "step" in best:
                grown = _grown_d_step(best["step"], blocks, run, deadline)
                if grown is not None:
                    # the best loop's D step again with every block's order one higher
                    candidates, previous, stale, done = [grown], best["step"][5], 0, False
                    grow_left, grown_from = grow_left - 1, best["it"].index
            elif not done:
                g_fits, level, md, zb = (), float("nan"), m, None
                H_edges = _edge_response(cl)
                if mixed:
                    g_fits, level, md, zb = _g_step(m, H, H_edges, blocks)
                fits, orders, bound = _fit_d_scales(H, md, blocks, order_d, run.executor, cand.orders,
                                                    H_edges, deadline, zb)
                candidates = [_DCandidate(tuple(fits), orders, 0.0, bound, g_fits, level)]
                if previous is not None and fits:
                    candidates += [replace(c, g_fits=g_fits, level=level) for c in
                                   _extrapolated(md, previous, orders, D_STEPS, run.executor, deadline)]
                previous = _log_scales(md)
                if best["it"].index == index and grow_left > 0:
                    best["step"] = (H, md, H_edges, zb, orders, previous)
                grown_from = 0
            elapsed = time.perf_counter() - t0
            entry = DKIteration(**{**entry.__dict__, "time_s": elapsed, "fitted_bound": bound})
            history.append(entry)
            if best["it"].index == index:
                best["it"] = entry
            if run.callback is not None:
                run.callback(entry)
            bar.update(1)
            bar.set_postfix(mu=f"{entry.mu_peak:.4f}")
            if stale >= run.patience:
                stop = f"peak mu did not fall by {rtol:g} for {stale} iteration(s)"
                if entry.mu_peak > best["it"].mu_peak:
                    kept = best["it"]
                    stop += f"; iteration {kept.index}'s controller (mu {kept.mu_peak:.4f}) is kept"
                break
            if (out_of_time or deadline.expired() or deadline.remaining() < k_time) and index < max_iter:
                deadline.hit = True
                stop = (f"time budget {deadline.budget_s:g} s: too little left for another iteration "
                        f"(this one's K step and mu analysis took {k_time:.1f} s)")
                break
    finally:
        bar.close()
    assert best is not None
    K, cl, m = best["K"], best["cl"], best["it"].mu
    reduction = None
    if reduce is not None and (first is None or best["it"].index > 1):  # ``first`` came reduced
        K, cl, m, reduction = _reduce(plant, blocks, K, cl, m, reduce, base, grid is None)
    grid_peak = float(m.peak)
    m = verified_mu(cl, blocks, m.f_hz)
    d_fits = best["d"]
    if m.peak > grid_peak * (1 + VERIFY_WARN_RTOL):
        import warnings

        warnings.warn(
            f"dksyn: the returned controller's peak of mu is {m.peak:.4g} at {m.f_peak_hz:.3g} Hz on the "
            f"verification grid, but {grid_peak:.4g} on the iteration grid, which misses the peak: the "
            "iterations were judged on too coarse a grid (pass a denser f_hz, or leave it to the default).",
            SynthesisWarning, stacklevel=2,
        )
    return DKResult(K=K, mu_peak=float(m.peak), mu=m, closed_loop=cl, history=tuple(history),
                    best_iteration=best["it"].index, stop_reason=stop, blocks=plant.blocks,
                    d_scales=d_fits, reduction=reduction, grid_mu_peak=grid_peak,
                    stopped_by_budget=deadline.hit)


def _creeping(res: DKResult) -> bool:
    """The iteration cap ended a run whose last iteration still lowered the peak of mu (by more
    than :data:`ORDER_NEIGHBOURS_CREEP`), or a rise of the peak ended a run whose best iteration
    had lowered it by more than that (the fitted D-scales lost the ground, not a converged run)
    and whose grown D orders (:data:`ORDER_GROWTH_STEPS`) did not lower it."""
    h, b = res.history, res.best_iteration
    if len(h) < 2 or res.stopped_by_budget or b < 2:
        return False
    fell = h[b - 1].mu_peak < h[b - 2].mu_peak * (1 - ORDER_NEIGHBOURS_CREEP)
    if res.stop_reason.startswith("max_iter="):
        return b == len(h) and fell
    rose = b < len(h) and h[-1].mu_peak > h[b - 1].mu_peak * (1 + ORDER_NEIGHBOURS_RISE)
    # the rise was answered within the run: a grown D step lowered mu below the loop it was fitted on
    grew = any(x.grown_from and x.mu_peak < h[x.grown_from - 1].mu_peak for x in h)
    return (ORDER_NEIGHBOURS_ON_RISE and res.stop_reason.startswith("peak mu did not fall") and rose and fell
            and not grew)


def _grown_d_step(step: tuple, blocks: BlockStructure, run: _Settings, deadline: Deadline) -> Any:
    """The D step of a run's best closed loop again with every block's order at least one above
    the orders it chose there (automatic above that floor; :data:`ORDER_GROWTH_STEPS`): the
    candidate for the next K step, or None when no block's order can grow (the caps of
    :func:`~robustctl.robust.dk.scales._fit_d_scales`)."""
    H, md, H_edges, zb, orders, _ = step
    floor = tuple(o + 1 for o in orders)
    fits, grown, bound = _fit_d_scales(H, md, blocks, None, run.executor, floor, H_edges, deadline, zb)
    if grown == tuple(orders):
        return None
    return _DCandidate(tuple(fits), grown, 0.0, bound)


def _neighbour_orders(res: DKResult, blocks: BlockStructure, run: Callable[[tuple[int, ...]], Any],
                      deadline: Deadline, result_of: Callable[[Any], DKResult] = lambda r: r) -> Any:
    """The automatic D orders' result, or a fixed-order run beside it that ends lower.

    A D-K run the iteration cap stops while its peak of mu still falls by more than
    :data:`ORDER_NEIGHBOURS_CREEP` per iteration has not converged: on flat problems it creeps
    (1-4 % per iteration), and where it ends within ``max_iter`` depends on the path, which
    the orders of the D fits change. On mu-tools' HIMAT with sensor noise (``mkhicn``) the
    automatic choice (orders 3, then 4) crept to 0.980 in ten iterations while a fixed order
    3 reached 0.954 and 5 reached 0.965; on ``mkhic`` it reached 0.970 where order 5 (from the
    second start) reached 0.943 and orders 2 and 4 1.002 and 0.987: which order ends lowest
    is not predictable from its neighbours. Such a run is therefore repeated with fixed
    orders, every block's order of its best iteration shifted by -1, +1, -2, +2, ... (within
    :data:`~robustctl.robust.dk.scales.MAX_AUTO_ORDER_D` and
    :data:`~robustctl.robust.dk.scales.MAX_D_STATES_PER_BLOCK`, at most
    :data:`ORDER_NEIGHBOURS_RUNS` runs, each as ``dksyn`` runs that fixed order: with the
    autoscaled starts when ``autoscale``), and the lowest verified peak of mu is kept when it
    is :data:`ORDER_NEIGHBOURS_GAIN` below the automatic one; ``stop_reason`` says which. A
    run whose peak rose (by more than :data:`ORDER_NEIGHBOURS_RISE`) right after its best
    iteration lowered it by more than :data:`ORDER_NEIGHBOURS_CREEP` is treated alike with at
    most :data:`ORDER_NEIGHBOURS_RISE_RUNS` orders, unless the run's own grown D orders
    (:data:`ORDER_GROWTH_STEPS`) lowered mu after a rise, which answers it at the cost of one
    iteration (on the Caltech design plant restarts at fixed orders reached 0.775 in two more
    designs where the grown orders reached 0.751 within the run); one that stopped because
    mu stopped falling is returned as it is. When the automatic run changed its orders on the
    way to its best iteration, that iteration's orders are the first fixed run. When the
    automatic run's K steps were solved by LMIs (the Riccati route's fallback, or
    ``hinf_options``), at most :data:`ORDER_NEIGHBOURS_LMI_RUNS` orders are tried.
    ``run(orders)`` returns what ``result_of`` maps to a DKResult; ``res`` is the automatic
    run's and ``run``'s results are returned as they are.
    """
    from .scales import MAX_AUTO_ORDER_D, MAX_D_STATES_PER_BLOCK

    first = result_of(res)
    if not _creeping(first):
        return res
    lmi = any(h.k_method == "lmi" for h in first.history)
    max_runs = ORDER_NEIGHBOURS_LMI_RUNS if lmi else ORDER_NEIGHBOURS_RUNS
    capped = first.stop_reason.startswith("max_iter=")
    if not capped:
        max_runs = min(max_runs, ORDER_NEIGHBOURS_RISE_RUNS)
    how = (f"crept to {first.mu_peak:.4f} at max_iter={len(first.history)}" if capped else
           f"reached {first.mu_peak:.4f} and rose at iteration {len(first.history)}")
    base = first.history[first.best_iteration - 1].d_orders
    scaled = list(blocks)[:len(base)]
    if not base or len(scaled) != len(base):
        return res
    cap = [min(MAX_AUTO_ORDER_D, MAX_D_STATES_PER_BLOCK // (b.rows + b.cols)) for b in scaled]
    tried: list[tuple[tuple[int, ...], Any]] = []
    # every block's order shifted by the same step, nearest first: -1, +1, -2, +2, ...
    steps = sorted(range(-max(base), max(cap) + 1), key=lambda k: (abs(k), k))
    # the best iteration's own orders as a fixed run too when the automatic run changed orders
    # on its way (a different path to them)
    same = all(h.d_orders == base for h in first.history[1:first.best_iteration])
    for step in steps:
        orders = tuple(int(min(max(o + step, 0), c)) for o, c in zip(base, cap))
        if (orders == base and same) or orders in [t[0] for t in tried]:
            continue
        if len(tried) >= max_runs or deadline.expired():
            break
        tried.append((orders, run(orders)))
    if not tried:
        return res
    orders, best = min(tried, key=lambda t: result_of(t[1]).mu_peak)
    rb = result_of(best)
    listed = ", ".join(f"orders {o} {result_of(r).mu_peak:.4f}" for o, r in tried)
    if rb.mu_peak >= first.mu_peak * (1 - ORDER_NEIGHBOURS_GAIN):
        why = f"the automatic D orders {how} and were kept (fixed {listed})"
        return _with_reason(res, result_of, replace(first, stop_reason=f"{first.stop_reason}; {why}"))
    why = f"the automatic D orders {how}; the fixed orders {orders} reached {rb.mu_peak:.4f} (fixed {listed})"
    return _with_reason(best, result_of, replace(rb, stop_reason=f"{rb.stop_reason}; {why}",
                                                 stopped_by_budget=rb.stopped_by_budget
                                                 or first.stopped_by_budget))


def _with_reason(item: Any, result_of: Callable[[Any], DKResult], new: DKResult) -> Any:
    """``item`` with its DKResult (``result_of(item)``) replaced by ``new``."""
    if isinstance(item, DKResult):
        return new
    return (new, *item[1:])


def _autoscaled_dksyn(plant: GeneralizedPlant, blocks: BlockStructure, order_d: Any,
                      run: _Settings) -> DKResult:
    """D-K on the automatically scaled plant (:func:`_autoscaled`) from :data:`AUTOSCALE_STARTS`
    (factors ``e^s`` on all block scales but the last; a further start only while the best
    verified peak of mu is not below :data:`AUTOSCALE_CERTIFIED`): the run with the lowest
    verified peak is kept (then reduced, when asked), and its controller, closed loop, mu and
    D-scales are returned for the user's plant. With automatic D orders, a run that crept is
    followed by the neighbouring orders over all starts (:func:`_neighbour_orders`).

    D-K is a local method: on the distillation column the final mu depends on the constant
    block scale it starts from (0.97 from 0.3 times the book's, 1.00 from the book's own, 1.10
    from 1.3 times, the scale whose first K step is best), so starting from several covariant
    points makes the result both independent of the user's units and less a matter of luck.
    """
    import control

    _, sc = _autoscaled(plant, run.hinf_options)
    deadline = run.deadline  # shared by the starts

    def starts(od: Any) -> tuple[DKResult, _Scaling, GeneralizedPlant]:
        best = None
        for s in AUTOSCALE_STARTS:
            if best is not None and (deadline.expired() or best[0].mu_peak < AUTOSCALE_CERTIFIED):
                break
            factor = np.exp(np.append(np.full(len(sc.d) - 1, s), 0.0))
            sc_k = _Scaling(sc.su, sc.sy, sc.d * factor)
            p_k = GeneralizedPlant(_constant_scaled(plant, sc.su, sc.sy, sc_k.d), plant.nmeas, plant.ncon,
                                   blocks=plant.blocks)
            res = _iterate(p_k, blocks, od, run, None)
            if best is None or res.mu_peak < best[0].mu_peak:
                best = (res, sc_k, p_k)
        assert best is not None
        return best

    best = starts(order_d)
    if order_d is None and ORDER_NEIGHBOURS:
        best = _neighbour_orders(best, blocks, lambda o: starts(list(o)), deadline, lambda t: t[0])
    res, sc_k, p_k = best
    K, cl, m, reduction = res.K, res.closed_loop, res.mu, None
    if run.reduce is not None:
        refine = run.grid is None
        base = default_grid(p_k.P) if refine else run.grid
        K, cl, m, reduction = _reduce(p_k, blocks, K, cl, m, run.reduce, base, refine)
        if reduction.accepted:
            m = verified_mu(cl, blocks, m.f_hz)
    K = _unscaled_controller(K, sc_k)
    cl = closed_loop(plant.P, K, plant.nmeas, plant.ncon)
    d_fits = tuple(control.ss(f.A, f.B, f.C * float(di), f.D * float(di))
                   for f, di in zip(res.d_scales, sc_k.d))
    return replace(res, K=K, closed_loop=cl, mu=_unscaled_mu(m, sc_k), mu_peak=float(m.peak),
                   d_scales=d_fits, reduction=reduction, stopped_by_budget=deadline.hit)


def _g_step(m: Any, H: np.ndarray, H_edges: np.ndarray,
            blocks: BlockStructure) -> tuple[tuple[Any, ...], float, Any, Callable]:
    """The G part of a D-G-K step (:mod:`robustctl.robust.dk.dgk`).

    At the level ``beta`` = the peak of mu on the grid: the scales closest to the complex
    analysis' that keep the mixed bound (:func:`~robustctl.robust.dk.dgk.blended_scales`), one
    stable filter ``r_i(s)`` per real block fitted to their G-scales, the MuResult with the
    D-scales ``d_i / sqrt(1 - |r_i|^2)`` that keep their ``X`` (what the D fits follow), and
    the bound the D fits are judged by: ``beta sigma_max(Z)`` with the fitted filters
    (:func:`~robustctl.robust.dk.dgk.transformed_norm`), on the grid and at ``w = 0, inf``.
    """
    level = float(m.peak)
    f = np.asarray(m.f_hz, dtype=float)
    mc = mu(H, _complexified(blocks), f_hz=f, lower=False)
    d, gam = blended_scales(H, m, mc, blocks, level)
    fits = tuple(fit_g_filter(f, gam[:, k], np.ones(f.size)) for k in range(gam.shape[1]))
    r_grid = np.stack([freqresp_array(r, f)[:, 0, 0] for r in fits], axis=1)
    r_edges = np.stack([np.array([freqresp_array(r, np.zeros(1))[0, 0, 0], complex(np.asarray(r.D)[0, 0])])
                        for r in fits], axis=1)
    md = replace(m, d_scales=scaled_d_targets(d, blocks, np.abs(r_grid)))

    def zbound(scales: np.ndarray, edges: bool) -> float:
        Hx, rx = (H_edges, r_edges) if edges else (H, r_grid)
        return level * float(np.max(transformed_norm(Hx, blocks, scales, rx, level)))

    return fits, level, md, zbound


def _k_step_search(hinfsyn: Callable, plant: GeneralizedPlant, candidates: Sequence[_DCandidate], opts: dict,
                   index: int, deadline: Deadline | None = None,
                   gamma: float | None = None) -> tuple[Any, _DCandidate]:
    """The K step for each D-scale candidate; the lowest verified gamma wins (the line search).

    Once a candidate has a verified gamma, each further one (Riccati route, no fixed ``gamma``)
    is first tested at that level (:func:`~robustctl.robust.hinf.synthesis.gamma_feasible`, one
    gamma test): infeasible there, its optimum is above it and it cannot win, so its synthesis
    is skipped. A candidate whose K step fails is skipped; when all fail, the first failure is raised.
    Past ``deadline`` no further candidate is tried once one has succeeded.
    """

    best, first_error = None, None
    screen = gamma is None and opts.get("method", "riccati") == "riccati"
    for cand in candidates:
        if best is not None and deadline is not None and deadline.expired():
            break
        P_scaled = _scale_plant(plant, cand.fits)
        try:
            if cand.g_fits:
                hres = _mixed_k_step(hinfsyn, P_scaled, plant, cand, opts, index)
            else:
                scaled = PartitionedPlant(P_scaled, plant.nmeas, plant.ncon)
                if screen and best is not None and not gamma_feasible(scaled, gamma=best[0].gamma):
                    # no controller beats the verified gamma so far here: the candidate cannot win
                    continue
                hres = _k_step(hinfsyn, scaled, plant, opts, index, gamma)
        except SynthesisError as exc:
            first_error = first_error or exc
            continue
        if best is None or hres.gamma < best[0].gamma:
            best = (hres, cand)
    if best is None and candidates and not candidates[0].g_fits:
        # every candidate failed on the Riccati route: the first (unextrapolated) on the LMI route
        cand = candidates[0]
        scaled = PartitionedPlant(_scale_plant(plant, cand.fits), plant.nmeas, plant.ncon)
        try:
            best = (_k_step(hinfsyn, scaled, plant, opts, index, gamma, lmi_fallback=True), cand)
        except SynthesisError as exc:
            first_error = exc  # the Riccati failure, and the LMI route's when it was tried
    if best is None:
        assert first_error is not None
        raise first_error
    return best


def _mixed_k_step(hinfsyn: Callable, P_scaled: Any, plant: GeneralizedPlant, cand: _DCandidate, opts: dict,
                  index: int) -> Any:
    """The D-G-K K step: the smallest level ``beta`` at which ``min_K ||Z_beta||_inf <= 1``.

    ``Z_beta = Fl(Theta * (D P D^-1 / beta), K)`` (:func:`~robustctl.robust.dk.dgk.g_transform`)
    with the fitted D-scales and G filters kept: every stable ``|r| < 1`` gives a valid
    multiplier at every level, so ``||Z_beta|| <= 1`` certifies ``mu <= beta`` whatever the
    level the filters were fitted at. ``beta`` is not a factor of ``Z`` (the transformation is
    not homogeneous), so the H-infinity synthesis is repeated: from the analysis' level
    ``beta_0``, the next guess is ``beta_0 gamma_0`` (as if it were), then secant steps on
    ``ln gamma`` against ``ln beta`` (:data:`MIXED_K_EVALS` syntheses at most). Returns the
    design at the smallest level with ``gamma <= 1``, its ``gamma`` replaced by that level (an
    upper bound on the new peak of mixed mu), or the one with the smallest ``beta gamma``.
    """
    from dataclasses import replace as _replace

    def solve(level: float) -> Any:
        scaled = PartitionedPlant(g_transform(P_scaled, plant.blocks, cand.g_fits, level), plant.nmeas,
                                  plant.ncon)
        return _k_step(hinfsyn, scaled, plant, opts, index)

    pts: list[tuple[float, Any]] = []
    x = float(np.log(cand.level))
    for _ in range(MIXED_K_EVALS):
        try:
            h = solve(float(np.exp(x)))
        except SynthesisError:
            if not pts:
                raise
            break
        pts.append((x, h))
        ys = [(px, float(np.log(ph.gamma))) for px, ph in pts]
        if abs(ys[-1][1]) < MIXED_K_TOL:
            break
        feas = [px for px, y in ys if y <= 0]
        infeas = [px for px, y in ys if y > 0]
        if len(ys) == 1:
            x = ys[0][0] + ys[0][1]
        else:
            (x0, y0), (x1, y1) = ys[-2], ys[-1]
            x = x1 - y1 * (x1 - x0) / (y1 - y0) if y1 != y0 else x1 + y1
        if feas and infeas:  # keep the guess inside the bracket
            lo, hi = max(infeas), min(feas)
            if not lo < x < hi:
                x = 0.5 * (lo + hi)
    feasible = [(px, ph) for px, ph in pts if ph.gamma <= 1.0 + 1e-9]
    if feasible:
        px, ph = min(feasible, key=lambda t: t[0])
        level = float(np.exp(px))
    else:
        px, ph = min(pts, key=lambda t: t[0] + np.log(t[1].gamma))
        level = float(np.exp(px)) * ph.gamma
    return _replace(ph, gamma=level, info={**ph.info, "mixed_level": float(np.exp(px)),
                                           "scaled_gamma": ph.gamma, "level_evals": len(pts)})


def _k_step(hinfsyn: Callable, scaled: Any, plant: GeneralizedPlant, opts: dict, index: int,
            gamma: float | None = None, lmi_fallback: bool = False) -> Any:
    """One H-infinity synthesis on the scaled plant; refuses a controller that does not stabilise P.

    With ``lmi_fallback``, when the Riccati route fails and advises ``method='lmi'`` (a
    violated rank or axis-zero assumption, no feasible gamma found, or no controller that
    passed its closed-loop check), the LMI route is tried once, unless the caller chose the
    method or the scaled plant has more than :data:`LMI_FALLBACK_MAX_STATES` states (the
    interior-point solve grows like ``n^6``: 20-40 s per solve at 50 states).
    """
    try:
        hres = hinfsyn(scaled, **opts)
    except SynthesisError as exc:
        if not lmi_fallback or "method" in opts or "method='lmi'" not in str(exc) \
                or scaled.P.nstates > LMI_FALLBACK_MAX_STATES:
            raise
        try:
            hres = hinfsyn(scaled, **{**opts, "method": "lmi"})
        except SynthesisError as exc_lmi:
            raise SynthesisError(f"{exc} The LMI route failed too: {exc_lmi}") from exc_lmi
        hres = replace(hres, info={**hres.info, "fallback": f"Riccati route failed: {exc}"})
    if gamma is not None and gamma > hres.info.get("gamma_design", hres.gamma):
        # a fixed design level above the optimum: the central controller at that gamma
        hres = hinfsyn(scaled, **{**opts, "method": hres.info.get("method", "riccati"),
                                  "backoff": gamma / hres.gamma_opt - 1.0})
    if not is_stable(closed_loop(plant.P, hres.K, plant.nmeas, plant.ncon), margin=0.0):
        raise SynthesisError(
            f"the K step of iteration {index} returned a controller that does not stabilise the plant; "
            "check that (A, B2) is stabilisable and (C2, A) detectable."
        )
    return hres


