"""The usual mu analyses of a closed loop: robust stability, robust performance, worst-case gain.

The closed loop ``N`` (system, FrequencyData or array) has its uncertainty channels first and
its performance channels last: inputs ``[w_Delta..., w_perf...]``, outputs
``[z_Delta..., z_perf...]``, and ``Delta = diag(Delta_1, ...)`` (the uncertainty blocks,
normalised so that ``||Delta_i|| <= 1``) closes ``z_Delta -> w_Delta``
(Skogestad & Postlethwaite 2005, sec. 8.8-8.10; Zhou, Doyle & Glover 1996, sec. 10.3):

* robust stability: ``mu_Delta(N11) < 1`` at every frequency; the margin is ``1 / peak``;
* robust performance: ``mu_{diag(Delta, Delta_P)}(N) < 1`` with a full performance block
  ``Delta_P`` (the main loop theorem, S&P Thm 8.7);
* worst-case gain: ``max_{||Delta|| <= 1} sigma_max(F_u(N, Delta))`` at each frequency, the
  ``gamma`` at which the skewed mu ``mu(diag(I, I / gamma) N) = 1`` (bisection on ``gamma``;
  the upper bound of mu gives an upper bound of the gain, the lower bound a lower one).
"""

from __future__ import annotations

import html
from dataclasses import dataclass
from typing import Any

import numpy as np

from ...checks import integer, positive_number
from ...errors import SynthesisError
from ...plots import single_axes
from ...table import Table
from ..uncertainty.blocks import Block, BlockStructure, as_block_structure
from .bounds import MuResult, as_frequency_array, mu, validate_mu_input

__all__ = ["robust_stability", "robust_performance", "worst_case_gain", "WorstCaseGain"]


def _uncertainty_structure(blocks: Any, n_out: int, n_in: int) -> BlockStructure:
    """The uncertainty blocks: ``blocks`` itself, a GeneralizedPlant's blocks, or either without
    a trailing full block named ``"performance"`` that covers the last channels."""
    bs = as_block_structure(getattr(blocks, "blocks", blocks) if hasattr(blocks, "n_perf_w") else blocks)
    last = bs.blocks[-1]
    if (len(bs) > 1 and last.kind == "full" and last.name == "performance"
            and (bs.n_out, bs.n_in) == (n_out, n_in)):
        bs = BlockStructure(bs.blocks[:-1])
    return bs


_MU_OPTIONS = ("lower", "method", "executor", "chunk", "seed", "time_budget_s")


def _check_mu_options(options: dict) -> None:
    unknown = sorted(set(options) - set(_MU_OPTIONS))
    if unknown:
        raise SynthesisError(f"unknown mu option(s) {unknown}; rc.mu takes {list(_MU_OPTIONS)}.")


def _split(closed_loop: Any, blocks: Any, f_hz: Any):
    N, f = as_frequency_array(closed_loop, f_hz, what="closed_loop")
    n_out, n_in = N.shape[1], N.shape[2]
    bs = _uncertainty_structure(blocks, n_out, n_in)
    if bs.n_out > n_out or bs.n_in > n_in:
        raise SynthesisError(
            f"the uncertainty blocks {bs.mussv().tolist()} need {bs.n_out} outputs x {bs.n_in} inputs; "
            f"the closed loop has only {n_out} x {n_in}. Its first outputs/inputs must be the "
            "uncertainty channels."
        )
    return N, f, bs


def robust_stability(closed_loop: Any, blocks: Any, f_hz: Any = None, **mu_options: Any) -> MuResult:
    """mu of the uncertainty channels ``N11`` (the first ``sum(cols)`` outputs and ``sum(rows)``
    inputs of the closed loop): robustly stable for ``||Delta|| < 1 / peak``
    (``result.stability_margin``).

    Parameters
    ----------
    closed_loop : system, FrequencyData or array (nf, n_out, n_in)
        Uncertainty channels first; any further (performance) channels are ignored.
    blocks : anything :func:`as_block_structure` accepts, or a GeneralizedPlant
        The uncertainty blocks (a trailing full block named ``"performance"`` covering the
        last channels, as in ``GeneralizedPlant.blocks``, is left out).
    f_hz : array_like, optional
        Frequencies (Hz); required for a system.
    **mu_options
        Passed to :func:`robustctl.robust.mu.bounds.mu` (``lower``, ``method``, ``executor`` ...).
    """
    _check_mu_options(mu_options)
    N, f, bs = _split(closed_loop, blocks, f_hz)
    sub = N[:, : bs.n_out, : bs.n_in]
    return mu(sub, bs, None if np.isnan(f).all() else f, **mu_options)


def _with_performance(bs: BlockStructure, n_out: int, n_in: int) -> tuple[BlockStructure, int, int]:
    """The structure extended by a full performance block covering the remaining channels."""
    pw, pz = n_in - bs.n_in, n_out - bs.n_out
    if pw == 0 and pz == 0:
        last = bs.blocks[-1]
        if last.kind != "full":
            raise SynthesisError("the blocks cover every channel but the last block is not a full "
                                 "performance block; give the uncertainty blocks only.")
        return bs, last.rows, last.cols
    if pw <= 0 or pz <= 0:
        raise SynthesisError(
            f"the closed loop has {n_out} outputs x {n_in} inputs and the uncertainty blocks use "
            f"{bs.n_out} x {bs.n_in}; the performance channels (the rest) need at least one input and "
            "one output."
        )
    return BlockStructure(bs.blocks + (Block("full", pw, pz, "performance"),)), pw, pz


def robust_performance(closed_loop: Any, blocks: Any, f_hz: Any = None, **mu_options: Any) -> MuResult:
    """mu of the whole closed loop with a full performance block appended (S&P Thm 8.7).

    Robust performance (``||F_u(N, Delta)|| < 1`` for every ``||Delta|| <= 1``) holds iff
    ``peak < 1``. ``blocks`` are the uncertainty blocks (or a GeneralizedPlant, or its
    ``.blocks``); a full ``"performance"`` block from the remaining outputs to the remaining
    inputs is added (if ``blocks`` already cover all channels, its last block is taken as the
    performance block).

    Parameters
    ----------
    closed_loop : system or ndarray (nf, n_out, n_in)
        The closed loop ``N`` (uncertainty and performance channels), or its response on
        ``f_hz``.
    blocks : BlockStructure, sequence of Block, mussv rows or GeneralizedPlant
        The uncertainty blocks (:func:`robustctl.robust.uncertainty.blocks.as_block_structure`).
    f_hz : array_like, optional
        Frequencies (Hz) at which a system is evaluated, or those of a response array (as for
        :func:`robustctl.robust.mu.bounds.mu`).
    **mu_options
        Passed to :func:`robustctl.robust.mu.bounds.mu` (``lower``, ``method``, ``executor`` ...).

    Returns
    -------
    MuResult
        Bounds of mu over the augmented structure; robust performance iff ``peak < 1``.
    """
    _check_mu_options(mu_options)
    N, f, bs = _split(closed_loop, blocks, f_hz)
    full, _, _ = _with_performance(bs, N.shape[1], N.shape[2])
    return mu(N, full, None if np.isnan(f).all() else f, **mu_options)


@dataclass(frozen=True)
class WorstCaseGain:
    """Worst-case gain of the performance channels over the unit uncertainty ball.

    Attributes
    ----------
    f_hz : ndarray (nf,)
    upper, lower : ndarray (nf,)
        Bounds on ``max_{||Delta|| <= 1} sigma_max(F_u(N, Delta))`` (inf where robust stability
        is not guaranteed / certainly lost).
    nominal : ndarray (nf,)
        ``sigma_max(N22)``, the gain without uncertainty.
    peak, f_peak_hz : float
        ``max(upper)`` and its frequency.
    blocks : BlockStructure
        Uncertainty blocks and the performance block.
    """

    f_hz: np.ndarray
    upper: np.ndarray
    lower: np.ndarray
    nominal: np.ndarray
    peak: float
    f_peak_hz: float
    blocks: BlockStructure

    @property
    def lower_peak(self) -> float:
        return float(np.max(self.lower))

    def table(self, count: int = 8) -> Table:
        """The frequencies of the largest worst-case gains."""
        count = integer(count, "count", SynthesisError, lo=1)
        order = np.argsort(-np.where(np.isfinite(self.upper), self.upper, np.inf))[:count]
        rows = [(float(self.f_hz[k]), float(self.nominal[k]), float(self.lower[k]), float(self.upper[k]))
                for k in order]
        return Table(("f (Hz)", "nominal gain", "worst-case gain >=", "worst-case gain <="), rows,
                     title="worst-case gain")

    def summary(self) -> str:
        where = f" at {self.f_peak_hz:.4g} Hz" if np.isfinite(self.f_peak_hz) else ""
        k = int(np.argmax(self.upper))
        return (f"Worst-case gain over the unit uncertainty ball: at most {self.peak:.4g}{where} "
                f"(at least {self.lower[k]:.4g} there; nominal {self.nominal[k]:.4g}); "
                f"largest certified worst-case gain {self.lower_peak:.4g}.")

    def _repr_html_(self) -> str:
        return f"<p>{html.escape(self.summary())}</p>" + self.table()._repr_html_()

    def __repr__(self) -> str:
        return (f"WorstCaseGain(peak={self.peak:.4g}, f_peak_hz={self.f_peak_hz:.4g}, "
                f"lower_peak={self.lower_peak:.4g})")

    def plot(self, fig: Any = None) -> Any:
        """Nominal and worst-case gain bounds against frequency (log axes)."""
        fig, ax = single_axes(fig, 7.0, 4.0)
        x = self.f_hz if np.all(np.isfinite(self.f_hz)) else np.arange(self.f_hz.size)
        ax.plot(x, self.nominal, "k:", lw=1, label="nominal")
        ax.plot(x, self.upper, "C0-", lw=1.5, label="worst case (upper bound)")
        ax.plot(x, self.lower, "C1--", lw=1.2, label="worst case (lower bound)")
        if np.all(np.isfinite(self.f_hz)) and np.all(self.f_hz > 0) and x.size > 1:
            ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel("frequency (Hz)")
        ax.set_ylabel("gain")
        ax.set_title(f"worst-case gain, peak {self.peak:.4g}")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend()
        return fig


def _skew(N: np.ndarray, n_unc_out: int, gamma: np.ndarray) -> np.ndarray:
    out = N.copy()
    out[:, n_unc_out:, :] /= gamma[:, None, None]
    return out


def _bisect(N, bs, n_unc_out, lo, hi, above, rel_tol, max_iter):
    """Per-frequency bisection in log(gamma) of the predicate ``above(M_gamma) -> mu >= 1``."""
    for _ in range(max_iter):
        act = np.isfinite(hi) & (hi > lo * (1 + rel_tol))
        if not act.any():
            break
        mid = np.sqrt(lo[act] * hi[act])
        up = above(_skew(N[act], n_unc_out, mid), bs)
        lo[act] = np.where(up, mid, lo[act])
        hi[act] = np.where(up, hi[act], mid)
    return lo, hi


def worst_case_gain(closed_loop: Any, blocks: Any, f_hz: Any = None, *, rel_tol: float = 1e-3,
                    max_iter: int = 60, gamma_max: float = 1e8) -> WorstCaseGain:
    """Worst-case gain of the performance channels over ``||Delta|| <= 1`` by skewed mu.

    At each frequency ``gamma`` solves ``mu(diag(I, I / gamma) N) = 1`` (the performance
    outputs scaled by ``1 / gamma``, structure ``diag(Delta, Delta_P)``), by bisection on
    ``log gamma`` from the nominal gain. The gain is infinite where ``mu_Delta(N11) >= 1``.

    Parameters
    ----------
    closed_loop : system, FrequencyData or array (nf, n_out, n_in)
        Uncertainty channels first, performance channels last.
    blocks : anything :func:`as_block_structure` accepts
        The uncertainty blocks (a full performance block is appended).
    f_hz : array_like, optional
        Frequencies (Hz); required for a system.
    rel_tol : float
        Relative accuracy of ``gamma``.
    max_iter : int
        Bisection cap per bound.
    gamma_max : float
        Gains above this count as infinite (relative to the nominal gain).
    """
    rel_tol = positive_number(rel_tol, "rel_tol", SynthesisError)
    if rel_tol >= 1:
        raise SynthesisError(f"rel_tol must be a relative accuracy in (0, 1); got {rel_tol!r}.")
    max_iter = integer(max_iter, "max_iter", SynthesisError, lo=1)
    gamma_max = positive_number(gamma_max, "gamma_max", SynthesisError)
    if gamma_max <= 1:
        raise SynthesisError(f"gamma_max must be > 1 (a factor on the nominal gain); got {gamma_max!r}.")
    N, f, bs = _split(closed_loop, blocks, f_hz)
    full, _, _ = _with_performance(bs, N.shape[1], N.shape[2])
    validate_mu_input(N, full)
    n_unc_out = bs.n_out
    nominal = np.linalg.norm(N[:, n_unc_out:, bs.n_in:], ord=2, axis=(1, 2))
    rs = mu(N[:, :n_unc_out, : bs.n_in], bs)
    floor = np.maximum(nominal, 1e-12 * np.maximum(np.abs(N).max(axis=(1, 2)), 1e-300))

    def above_upper(M, b):
        return mu(M, b, lower=False).upper >= 1.0

    def above_lower(M, b):
        return mu(M, b).lower >= 1.0

    bounds = []
    for stable, above in ((rs.upper < 1.0, above_upper), (rs.lower < 1.0, above_lower)):  # upper, then lower
        lo = floor * (1 - 1e-9)
        hi = np.where(stable, floor, np.inf)
        grow = stable.copy()
        while grow.any():  # bracket: double gamma until mu < 1
            hi[grow] *= 2.0
            still = above(_skew(N[grow], n_unc_out, hi[grow]), full)
            idx = np.flatnonzero(grow)
            lo[idx[still]] = hi[idx[still]]
            grow[idx[~still]] = False
            grow &= hi < gamma_max * floor
        hi = np.where(hi >= gamma_max * floor, np.inf, hi)
        lo, hi = _bisect(N, full, n_unc_out, lo, hi, above, rel_tol, max_iter)
        bounds.append((lo, hi, stable))
    upper = bounds[0][1]  # mu_upper < 1 at hi: the gain is certainly below hi
    lo, hi, stable = bounds[1]  # mu_lower >= 1 at lo: a perturbation achieves gain lo
    lower = np.minimum(np.where(stable, lo, np.inf), upper)
    k = int(np.argmax(upper))
    return WorstCaseGain(f, upper, lower, nominal, float(upper[k]), float(f[k]), full)
