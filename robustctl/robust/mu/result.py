"""The result of ``rc.mu``: bounds of the structured singular value over frequency."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ...checks import integer
from ...errors import SynthesisError
from ...plots import single_axes
from ...table import Table, result_html
from ..uncertainty.blocks import BlockStructure

__all__ = ["MuResult"]


@dataclass(frozen=True)
class MuResult:
    """Bounds of the structured singular value over frequency.

    Attributes
    ----------
    f_hz : ndarray, (nf,)
        Frequencies in Hz (NaN when ``M`` was given without frequencies).
    upper, lower : ndarray, (nf,)
        Upper and lower bounds of mu (``lower <= mu <= upper``).
    peak : float
        ``max(upper)``: robust stability against ``||Delta|| < 1 / peak`` is guaranteed.
    f_peak_hz : float
        Frequency of ``peak`` (Hz).
    d_scales : ndarray, (nf, n_blocks)
        Positive scalar D-scale of every block, last block normalised to 1; applied as
        ``M -> D_L M D_R^{-1}`` with block ``i`` scaled by ``d_i`` on its rows and columns.
        For a repeated scalar block with a full ``D_i`` it is ``|det D_i|^(1/r)``.
    d_matrices : tuple of ndarray
        Per block, the D-scale matrices (nf, m, m) (``m = r`` for a repeated scalar block of
        multiplicity ``r > 1``, else 1), same normalisation.
    g_scales : ndarray (nf, n_blocks) or None
        G-scales of the LMI ``M^H X_L M + j(G M - M^H G^H) - upper^2 X_R <= 0`` (``X = D^H D``)
        on the real blocks (mean eigenvalue of ``G_i``; 0 on complex blocks); None without real
        blocks.
    g_matrices : tuple of ndarray or None
        Per block the Hermitian ``G_i`` (nf, r, r) (zero on complex blocks).
    worst_perturbation : ndarray, (n_in, n_out)
        A structured ``Delta`` with ``det(I - M Delta) = 0`` and ``||Delta|| = 1 / lower`` at
        ``f_worst_hz`` (the frequency of the largest lower bound); zeros if no lower bound was
        found.
    f_worst_hz : float
        Frequency of ``worst_perturbation``.
    blocks : BlockStructure
    method : str
        ``"auto"`` (batched D/G-scaling) or ``"lmi"``.
    info : dict
        Timings (s), iteration counts.
    """

    f_hz: np.ndarray
    upper: np.ndarray
    lower: np.ndarray
    peak: float
    f_peak_hz: float
    d_scales: np.ndarray
    d_matrices: tuple[np.ndarray, ...]
    g_scales: np.ndarray | None
    g_matrices: tuple[np.ndarray, ...] | None
    worst_perturbation: np.ndarray
    f_worst_hz: float
    blocks: BlockStructure
    method: str = "auto"
    info: dict = field(default_factory=dict)

    # ------------------------------------------------------------------ derived numbers
    @property
    def lower_peak(self) -> float:
        """``max(lower)``: some ``Delta`` with ``||Delta|| = 1 / lower_peak`` destabilises."""
        return float(np.max(self.lower))

    @property
    def stability_margin(self) -> float:
        """``1 / peak``: the guaranteed robust stability margin when ``blocks`` are the
        (normalised) uncertainty blocks: stable for all ``||Delta|| < 1 / peak``."""
        return float(np.inf) if self.peak == 0 else 1.0 / self.peak

    @property
    def stability_margin_bounds(self) -> tuple[float, float]:
        """(guaranteed margin ``1/peak``, margin that is certainly exceeded ``1/lower_peak``)."""
        lp = self.lower_peak
        return self.stability_margin, (float(np.inf) if lp == 0 else 1.0 / lp)

    @property
    def gap(self) -> np.ndarray:
        """Relative gap ``upper / lower - 1`` per frequency (inf where ``lower == 0``)."""
        with np.errstate(divide="ignore", invalid="ignore"):
            return np.where(self.lower > 0, self.upper / np.where(self.lower > 0, self.lower, 1) - 1, np.inf)

    # ------------------------------------------------------------------ presentation
    def _peaks(self, count: int) -> list[int]:
        u = self.upper
        if u.size < 3:
            return list(np.argsort(-u)[:count])
        inner = np.flatnonzero((u[1:-1] >= u[:-2]) & (u[1:-1] >= u[2:])) + 1
        ends = [i for i in (0, u.size - 1) if u[i] == u.max()]
        cand = np.unique(np.concatenate([inner, ends]).astype(int))
        return list(cand[np.argsort(-u[cand])][:count])

    def table(self, count: int = 8) -> Table:
        """The largest local peaks of the upper bound: frequency, bounds, gap and D-scales."""
        count = integer(count, "count", SynthesisError, lo=1)
        names = [b.name or f"{b.kind} {b.rows}x{b.cols}" for b in self.blocks]
        cols = ("f (Hz)", "mu upper", "mu lower", "gap (%)") + tuple(f"d [{n}]" for n in names)
        rows = []
        for k in self._peaks(count):
            gap = 100 * self.gap[k] if np.isfinite(self.gap[k]) else float("inf")
            rows.append((float(self.f_hz[k]), float(self.upper[k]), float(self.lower[k]), gap)
                        + tuple(float(d) for d in self.d_scales[k]))
        return Table(cols, rows, title=f"mu peaks, blocks {self.blocks.mussv().tolist()}")

    def summary(self) -> str:
        """A few sentences in plain words."""
        nf = self.f_hz.size
        where = f" at {self.f_peak_hz:.4g} Hz" if np.isfinite(self.f_peak_hz) else ""
        lines = [
            f"mu over {nf} frequenc{'y' if nf == 1 else 'ies'}, blocks {self.blocks.mussv().tolist()} "
            f"({self.method}): peak upper bound {self.peak:.4g}{where}, "
            f"peak lower bound {self.lower_peak:.4g}.",
        ]
        lo, hi = self.stability_margin_bounds
        lines.append(
            f"As an uncertainty structure: stable for every ||Delta|| < {lo:.4g}; a perturbation of size "
            f"{hi:.4g} destabilises."
            + (" Robust stability holds for the unit ball (peak < 1)." if self.peak < 1 else
               " Robust stability for the unit ball is not guaranteed (peak >= 1).")
        )
        finite = np.isfinite(self.gap)
        if finite.any():
            lines.append(f"Largest gap between the bounds: {100 * np.max(self.gap[finite]):.3g} %.")
        return "\n".join(lines)

    def _repr_html_(self) -> str:
        return result_html(self.summary(), self.table())

    def __repr__(self) -> str:
        return (f"MuResult(peak={self.peak:.4g}, f_peak_hz={self.f_peak_hz:.4g}, "
                f"lower_peak={self.lower_peak:.4g}, n_freq={self.f_hz.size}, "
                f"blocks={self.blocks.mussv().tolist()})")

    def plot(self, fig: Any = None, *, title: str = "") -> Any:
        """Upper and lower bound against frequency (log axis); returns the matplotlib Figure."""
        fig, ax = single_axes(fig, 7.0, 4.0)
        f = self.f_hz
        x = f if np.all(np.isfinite(f)) else np.arange(f.size)
        ax.plot(x, self.upper, "C0-", lw=1.5, label="mu upper bound")
        ax.plot(x, self.lower, "C1--", lw=1.2, label="mu lower bound")
        if np.all(np.isfinite(f)) and np.all(f > 0) and f.size > 1:
            ax.set_xscale("log")
            ax.set_xlabel("frequency (Hz)")
        else:
            ax.set_xlabel("frequency (Hz)" if np.all(np.isfinite(f)) else "frequency index")
        if self.peak > 0:
            ax.axhline(1.0, color="0.5", lw=0.8, ls=":")
        ax.plot([x[int(np.argmax(self.upper))]], [self.peak], "C0o", ms=5)
        ax.set_ylabel("mu")
        ax.set_title(title or f"mu, peak {self.peak:.4g}" + (f" at {self.f_peak_hz:.4g} Hz"
                                                               if np.isfinite(self.f_peak_hz) else ""))
        ax.grid(True, which="both", alpha=0.3)
        ax.legend()
        return fig
