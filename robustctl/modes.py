"""The one ``Mode`` type: a structural mode seen by a model or in measured data.

Used by ``rc.compare`` (model, measured and peak-picked modes), ``rc.fit_measurement_model``
(identified modes) and everything that pairs or tabulates modes.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["Mode"]


@dataclass(frozen=True, eq=False)
class Mode:
    """One mode (or a group of ``rank`` modes sharing a pole).

    Attributes
    ----------
    f_hz : float
        Natural frequency ``|p| / 2 pi``, Hz.
    zeta : float
        Damping ratio ``-Re p / |p|`` (ratio, not %); NaN when unknown.
    residue : ndarray, complex, shape (n_out, n_in), optional
        Residue matrix of the pole (``C v w B`` for a state space), or the response at the peak
        for a peak-picked mode: the mode's shape over the channels.
    pole : complex, optional
        Pole with ``Im p > 0``, rad/s (None for a peak-picked mode).
    rank : int
        Number of modes at this pole (1 for an isolated physical mode).
    output_shape : ndarray, complex, shape (n_out, rank), optional
        ``C = U sqrt(S)`` of the residue's SVD (Caltech eq. 10).
    input_shape : ndarray, complex, shape (rank, n_in), optional
        ``B = sqrt(S) V^*``.
    """

    f_hz: float
    zeta: float
    residue: np.ndarray | None = None
    pole: complex | None = None
    rank: int = 1
    output_shape: np.ndarray | None = None
    input_shape: np.ndarray | None = None

    @property
    def shape(self) -> np.ndarray | None:
        """The residue flattened over (output, input) in C order (for the MAC), or None."""
        return None if self.residue is None else np.asarray(self.residue).ravel()

    @property
    def damping_pct(self) -> float:
        """Damping ratio in %."""
        return 100.0 * self.zeta

    def __repr__(self) -> str:
        rank = f", rank {self.rank}" if self.rank != 1 else ""
        return f"Mode({self.f_hz:.5g} Hz, zeta {self.zeta:.3g}{rank})"
