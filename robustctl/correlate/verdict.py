"""Is a misfit within the noise? One chi-square test per channel and frequency section.

The complex-log residual ``e = ln(G_data / G_model)`` divided by the noise model's standard
deviation (:class:`robustctl.measure.noise.NoiseModel`) has unit variance in its real and imaginary
parts when the model is right. Over a channel and a contiguous section of ``n`` points,
``S = sum |e / sigma|^2`` is then about ``c chi2_nu`` with ``nu = 2n / c`` and ``c`` the
Satterthwaite factor of the window's bin-to-bin correlation (``NoiseModel.chi2_factor``, the
bound over output noise and leakage, raised per cell by an impact test's band-wide correlated
force noise: :func:`robustctl.measure.noise.cell_chi2_factor`;
:func:`robustctl.measure.noise.chi2_verdict`). With a coherence noise model the sum is of the exact
scores of the plug-in sigma (:func:`robustctl.measure.noise.plug_in_scores`). A cell fails when
its upper-tail probability is below ``alpha / n_tests`` (Bonferroni: the family of all
channel-section cells holds the false-alarm rate at ``alpha``), so a true model passes
everywhere with probability ``>= 1 - alpha``.
The same test serves compare's verdicts, update's warnings and diagnose's statements.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from ..measure.noise import NO_NOISE_SENTENCE, NoiseModel, cell_chi2_factor, chi2_verdict, format_p
from ..table import Table

__all__ = ["Cell", "NoiseTest", "noise_test", "sections"]

#: default family-wise false-alarm rate of a noise test
ALPHA = 0.01


@dataclass(frozen=True)
class Cell:
    """One channel over one frequency section: ``ratio = S / 2n`` (1 for pure noise), dof, p."""

    output: str
    input: str
    lo_hz: float
    hi_hz: float
    n_points: int
    ratio: float
    dof: float
    p_value: float
    within: bool

    @property
    def channel(self) -> str:
        return f"{self.output} <- {self.input}"


@dataclass(frozen=True, eq=False)
class NoiseTest:
    """Chi-square verdicts of a residual against the noise, per channel and section.

    Attributes
    ----------
    cells : tuple of Cell
        One per channel (not dropped) and section.
    alpha : float
        Family-wise false-alarm rate; a cell fails when ``p < alpha / len(cells)``.
    source : str
        Where the noise estimate came from (``NoiseModel.source``).
    n_untested : int
        Points left out as noise-dominated (coherence not significantly above zero, or sigma
        above ``SIGMA_TESTABLE``: the log-normal error model fails there).
    """

    cells: tuple[Cell, ...]
    alpha: float
    source: str
    n_untested: int = 0

    @property
    def threshold(self) -> float:
        """The per-cell p-value threshold ``alpha / n_cells`` (Bonferroni)."""
        return self.alpha / max(len(self.cells), 1)

    @property
    def failing(self) -> tuple[Cell, ...]:
        """Cells beyond the noise, worst (smallest p, then largest ratio) first."""
        bad = [c for c in self.cells if not c.within]
        return tuple(sorted(bad, key=lambda c: (c.p_value, -c.ratio)))

    @property
    def within(self) -> bool:
        """True when every cell is within the noise."""
        return not self.failing

    @property
    def overall_ratio(self) -> float:
        """``S / 2n`` over every cell (1 for a residual that is pure noise)."""
        n = sum(c.n_points for c in self.cells)
        return float(sum(c.ratio * c.n_points for c in self.cells) / max(n, 1))

    def fails_at(self, lo_hz: float, hi_hz: float) -> bool:
        """Whether a failing cell overlaps ``[lo_hz, hi_hz]``."""
        return any(c.lo_hz <= hi_hz and c.hi_hz >= lo_hz for c in self.failing)

    def sentence(self) -> str:
        """The verdict in words; numbers equal those of :meth:`table`."""
        n = len(self.cells)
        head = f"Noise model: {self.source}."
        test = f"chi-square per channel and section, family-wise alpha {self.alpha:g} over {n} cells"
        if self.n_untested:
            test += f"; {self.n_untested} noise-dominated points left out"
        if self.within:
            worst = min(self.cells, key=lambda c: c.p_value) if self.cells else None
            tail = f"; smallest {format_p(worst.p_value)}" if worst else ""
            return (
                f"{head} The misfit is within the noise in every channel and band ({test}; mean "
                f"normalised squared error {self.overall_ratio:.3g}{tail})."
            )
        bad = self.failing
        parts = [
            f"{c.channel} at {c.lo_hz:.3g}-{c.hi_hz:.3g} Hz ({c.ratio:.3g} x the noise variance, "
            f"{format_p(c.p_value)})"
            for c in bad[:3]
        ]
        more = f" and {len(bad) - 3} more" if len(bad) > 3 else ""
        return (
            f"{head} Beyond the noise in {len(bad)} of {n} channel-bands ({test}): "
            + "; ".join(parts) + more + "."
        )

    def table(self) -> Table:
        """One row per cell: channel, section, points, ratio, dof, p, within the noise."""
        rows = [
            (c.output, c.input, c.lo_hz, c.hi_hz, c.n_points, c.ratio, c.dof, format_p(c.p_value), c.within)
            for c in self.cells
        ]
        return Table(
            ("output", "input", "lo (Hz)", "hi (Hz)", "points", "S / 2n", "dof", "p", "within noise"),
            rows,
            title=f"misfit against the noise (fails when p < {self.threshold:.2g})",
            digits=3,
        )


def sections(n_points: int, n_sections: int) -> list[slice]:
    """``n_sections`` contiguous slices of (about) equal point count over ``n_points``."""
    k = int(max(1, min(n_sections, n_points)))
    edges = np.linspace(0, n_points, k + 1).round().astype(int)
    return [slice(a, b) for a, b in zip(edges[:-1], edges[1:]) if b > a]


def noise_test(
    error: np.ndarray,
    noise: NoiseModel | None,
    f_hz: np.ndarray,
    outputs: tuple[str, ...],
    inputs: tuple[str, ...],
    keep: np.ndarray | None = None,
    n_sections: int = 6,
    alpha: float = ALPHA,
) -> NoiseTest | None:
    """Chi-square test of ``error`` (n_freq, n_out, n_in) against ``noise``; None without noise.

    ``keep`` (n_out, n_in) bool leaves channels out (e.g. negligible ones). Points whose
    sigma exceeds :data:`robustctl.measure.noise.SIGMA_TESTABLE` are noise-dominated and left out
    (counted in ``n_untested``). A coherence noise model's cells are tested on the exact scores
    of its plug-in sigma (:func:`robustctl.measure.noise.plug_in_scores`, with the column's
    averages): at few averages (an impact test's hits) ``|z|^2`` is F-distributed, not chi-square.
    Each cell's Satterthwaite factor counts an impact test's force noise, correlated across the
    band (:func:`robustctl.measure.noise.cell_chi2_factor`).
    """
    if noise is None:
        return None
    z = noise.normalised(error)
    testable = noise.testable
    f = np.asarray(f_hz, dtype=float)
    no, ni = z.shape[1:]
    keep = np.ones((no, ni), dtype=bool) if keep is None else np.asarray(keep, dtype=bool)
    averages = [None] * ni
    if noise.kind == "coherence" and noise.averages is not None:
        nd = np.asarray(noise.averages, dtype=float).reshape(-1)
        averages = [float(v) for v in np.broadcast_to(nd, (ni,))]
    raw: list[tuple[Any, ...]] = []
    untested = 0
    for sl in sections(f.size, n_sections):
        for o in range(no):
            for i in range(ni):
                if not keep[o, i]:
                    continue
                ok = testable[sl, o, i]
                untested += int(ok.size - ok.sum())
                if not ok.any():
                    continue
                factor = cell_chi2_factor(noise, np.arange(f.size)[sl][ok], o, i)
                ratio, dof, p = chi2_verdict(z[sl, o, i][ok], factor, averages[i])
                raw.append((outputs[o], inputs[i], float(f[sl][0]), float(f[sl][-1]), int(ok.sum()),
                            ratio, dof, p))
    limit = alpha / max(len(raw), 1)
    cells = tuple(Cell(*r, within=bool(r[-1] >= limit)) for r in raw)
    return NoiseTest(cells, float(alpha), noise.source, untested)


def no_noise_sentence() -> str:
    """What a result says without a noise model."""
    return NO_NOISE_SENTENCE[:1].upper() + NO_NOISE_SENTENCE[1:] + "."
