"""``RationalFit``: the pole-residue model every fitting route returns (VF, Chebyshev/SK, the
Caltech SIMO combination and SVD grouping, the modal refinement), and ``IdentifyWarning``.

Kept apart from :mod:`.rational` (the fitting) so that :mod:`.grouping` and the refinements
import the type without importing the fitting routes (which use :func:`.grouping.combine_simo`).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..errors import FitError, RobustctlWarning
from ..frd import FrequencyData
from ..lti import pole_frequency_damping
from ..plots import bode_grid
from ..table import Table
from .cost import LogCost, channel_cost
from .poles import evaluate, n_states
from .realization import modal_statespace

__all__ = ["RationalFit", "IdentifyWarning"]


class IdentifyWarning(RobustctlWarning):
    """A fit succeeded but something deserves a look (pole outside the band, no convergence)."""


@dataclass(frozen=True, eq=False)
class RationalFit:
    """A pole-residue model ``G(s) = D + sum_k R_k/(s-p_k) (+ conjugates)``.

    Attributes
    ----------
    poles : ndarray, complex, shape (n_p,)
        One pole of each complex-conjugate pair (``Im p > 0``) and the real poles, rad/s.
    residues : ndarray, complex, shape (n_p, n_out, n_in)
        Residue matrix of each pole.
    d : ndarray, shape (n_out, n_in)
        Feedthrough.
    ranks : ndarray of int, shape (n_p,)
        Modes each pole stands for: the rank kept of its residue in the state space
        (1 for SIMO fits and physical modes; up to min(n_out, n_in) for raw MIMO fits).
    inputs, outputs : tuple of str
        Signal names.
    band_hz : tuple of float
        Fitted band (Hz).
    method : str
        ``"chebyshev"``, ``"vf"``, ``"combined"``, ``"grouped"``.
    iterations : int
        Pole-relocation iterations used.
    converged : bool
        Whether the pole iteration met its tolerance before the cap.
    data : FrequencyData or None
        The fitted data (band only), kept for scoring and plots.
    """

    poles: np.ndarray
    residues: np.ndarray
    d: np.ndarray
    ranks: np.ndarray
    inputs: tuple[str, ...]
    outputs: tuple[str, ...]
    band_hz: tuple[float, float]
    method: str
    iterations: int = 0
    converged: bool = True
    data: FrequencyData | None = field(default=None, repr=False)

    # ----------------------------------------------------------------- properties
    @property
    def order(self) -> int:
        """Number of poles counting conjugates (states of a SISO realisation)."""
        return n_states(self.poles)

    @property
    def n_modes(self) -> int:
        """Modes in the state-space realisation: sum of the ranks of the complex poles."""
        return int(np.sum(self.ranks[self.poles.imag != 0]))

    @property
    def n_states(self) -> int:
        """States of :meth:`statespace` (2 per complex pole and rank, 1 per real pole and rank)."""
        return int(np.sum(np.where(self.poles.imag != 0, 2, 1) * self.ranks))

    @property
    def f_hz(self) -> np.ndarray:
        """Natural frequency ``|p|/(2 pi)`` of each pole, Hz."""
        return pole_frequency_damping(self.poles)[0]

    @property
    def zeta(self) -> np.ndarray:
        """Damping ratio ``-Re p / |p|`` of each pole."""
        return pole_frequency_damping(self.poles)[1]

    # ----------------------------------------------------------------- evaluation
    def response(self, f_hz: Any) -> np.ndarray:
        """Complex response at ``f_hz`` (Hz), shape (n_freq, n_out, n_in)."""
        s = 2j * np.pi * np.asarray(f_hz, dtype=float).reshape(-1)
        return evaluate(s, self.poles, self.residues, self.d)

    def freqresp(self, f_hz: Any) -> FrequencyData:
        """The response at ``f_hz`` (Hz) as FrequencyData with the model's signal names."""
        return FrequencyData(f_hz, self.response(f_hz), inputs=self.inputs, outputs=self.outputs)

    def statespace(self, name: str | None = None):
        """Real modal ``control.StateSpace`` (2x2 block per complex pole and kept rank)."""
        return modal_statespace(
            self.poles, self.residues, self.d, self.ranks, self.inputs, self.outputs, name=name
        )

    @property
    def sys(self):
        """Shorthand for :meth:`statespace`."""
        return self.statespace()

    def cost(self, data: FrequencyData | None = None) -> LogCost:
        """MACE eq. 5 against ``data`` (default: the fitted band data)."""
        data = self.data if data is None else data
        if data is None:
            raise FitError("this fit keeps no data; pass data=FrequencyData to score it.")
        return channel_cost(data.response, self.response(data.f_hz), self.outputs, self.inputs)

    # ----------------------------------------------------------------- presentation
    def summary(self) -> str:
        """One sentence: method, poles, modes, band, convergence and (with data) the cost."""
        text = (
            f"{self.method} fit of {len(self.outputs)} outputs x {len(self.inputs)} inputs on "
            f"{self.band_hz[0]:.4g}-{self.band_hz[1]:.4g} Hz: {self.order} poles, {self.n_modes} modes, "
            f"{self.iterations} iterations ({'converged' if self.converged else 'not converged'})."
        )
        if self.data is not None:
            cost = self.cost()
            text += f" J = {cost.total:.4g} (MACE eq. 5), rms log-magnitude error {cost.rms_db_total:.3g} dB."
        return text

    def table(self):
        """One row per pole: frequency (Hz), damping (%), rank, largest residue entry."""
        rows = [
            (k, float(f), 100 * float(z), int(r), float(np.max(np.abs(res))))
            for k, (f, z, r, res) in enumerate(zip(self.f_hz, self.zeta, self.ranks, self.residues), start=1)
        ]
        return Table(("pole", "f (Hz)", "damping (%)", "rank", "max |residue|"), rows, title=self.summary())

    def plot(self, max_channels: int = 9):
        """The fitted data and the fit per channel, magnitude and phase (needs the fitted data)."""
        if self.data is None:
            raise FitError("this fit keeps no data to plot against; use rc.freqresp(fit, f_hz) instead.")
        model = self.freqresp(self.data.f_hz)
        return bode_grid([self.data, model], ["data", f"fit ({self.order} poles)"], max_channels=max_channels,
                         phase=True, title=self.summary().split(":")[0])

    def _repr_html_(self) -> str:
        return self.table()._repr_html_()

    def __repr__(self) -> str:
        return (
            f"RationalFit({self.method}, {self.order} poles, {self.n_modes} modes, {len(self.outputs)}x"
            f"{len(self.inputs)}, band {self.band_hz[0]:.4g}-{self.band_hz[1]:.4g} Hz)"
        )
