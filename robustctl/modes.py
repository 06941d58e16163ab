"""The one ``Mode`` type: a structural mode seen by a model or in measured data.

Used by ``rc.compare`` (model, measured and peak-picked modes), ``rc.fit_measurement_model``
(identified modes) and everything that pairs or tabulates modes; :func:`mac` and
:func:`pair_modes` pair them.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.optimize

__all__ = ["Mode", "mac", "pair_modes"]


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


# ---------------------------------------------------------------------------- pairing
def mac(a: np.ndarray | None, b: np.ndarray | None) -> float:
    """Complex modal assurance criterion in [0, 1]; NaN when a shape is missing."""
    if a is None or b is None:
        return float("nan")
    a = np.asarray(a, dtype=complex).ravel()
    b = np.asarray(b, dtype=complex).ravel()
    den = np.vdot(a, a).real * np.vdot(b, b).real
    if den <= 0:
        return float("nan")
    return float(abs(np.vdot(a, b)) ** 2 / den)


#: Weight of ``|ln(f_model / f_data)|`` against ``1 - MAC`` when both modes have shapes: the MAC
#: decides, the frequency only breaks near-ties (1 % of frequency counts as 0.001 of MAC).
FREQUENCY_TIE_WEIGHT = 0.1
#: Weight of ``|ln(f_model / f_data)|`` when a shape is missing (frequency-only pairing).
FREQUENCY_WEIGHT = 10.0


def pair_modes(
    model: list[Mode],
    measured: list[Mode],
    tol: float = 0.2,
    *,
    max_ratio: float = 4.0,
    min_mac: float = 0.8,
    min_pair_mac: float = 0.5,
) -> list[tuple[int | None, int | None]]:
    """Pair model and measured modes: the assignment of largest total MAC within a frequency window.

    Where both modes have shapes (a residue over the same channels), a pair is allowed when its
    relative frequency distance ``|ln(f_model / f_data)|`` is within ``ln(1 + tol)`` and its
    MAC at least ``min_pair_mac``, or -- a mode moved by a large model error, up to a factor
    ``max_ratio`` -- when its shapes agree (``MAC >= min_mac``); its cost is ``(1 - MAC) +
    FREQUENCY_TIE_WEIGHT |ln(f_model / f_data)|``, so the Hungarian assignment
    (``scipy.optimize.linear_sum_assignment``) maximises the summed MAC and the frequency
    only breaks near-ties (MAC-first pairing as in FE model updating practice, Friswell &
    Mottershead, *Finite Element Model Updating in Structural Dynamics*, sec. 4.2). A model
    mode whose own measured counterpart is missing (outside the band, or not picked) is thus
    not paired with a neighbour of another shape that happens to sit close in frequency.

    Where a shape is missing (NaN MAC), only frequency pairs: within ``tol``, at cost
    ``FREQUENCY_WEIGHT |ln(f_model / f_data)|``.

    Parameters
    ----------
    model, measured : list of Mode
        Modes of the model and of the data.
    tol : float
        Frequency window of an ordinary pair (relative, 0.2 = 20 %).
    max_ratio : float
        Largest frequency ratio of a pair whose shapes agree.
    min_mac : float
        MAC a pair beyond ``tol`` needs.
    min_pair_mac : float
        MAC a pair within ``tol`` needs when both shapes are known.

    Returns
    -------
    list of (int or None, int or None)
        ``(i_model, i_measured)`` index pairs sorted by frequency, with ``None`` on the side
        of an unpaired mode.
    """
    nm, nd = len(model), len(measured)
    pairs: list[tuple[int | None, int | None]] = []
    used_m, used_d = set(), set()
    if nm and nd:
        big = 1e6
        cost = np.full((nm, nd), big)
        near, far = np.log1p(tol), np.log(max(float(max_ratio), 1.0 + tol))
        for i, a in enumerate(model):
            for j, b in enumerate(measured):
                rel = abs(np.log(a.f_hz / b.f_hz))
                if rel > far:
                    continue
                m = mac(a.shape, b.shape) if _same_channels(a, b) else float("nan")
                if np.isnan(m):
                    if rel <= near:
                        cost[i, j] = FREQUENCY_WEIGHT * rel
                elif (rel <= near and m >= min_pair_mac) or m >= min_mac:
                    cost[i, j] = (1.0 - m) + FREQUENCY_TIE_WEIGHT * rel
        rows, cols = scipy.optimize.linear_sum_assignment(cost)
        for i, j in zip(rows, cols):
            if cost[i, j] < big:
                pairs.append((int(i), int(j)))
                used_m.add(int(i))
                used_d.add(int(j))
    pairs += [(i, None) for i in range(nm) if i not in used_m]
    pairs += [(None, j) for j in range(nd) if j not in used_d]

    def key(p):
        i, j = p
        return model[i].f_hz if i is not None else measured[j].f_hz

    return sorted(pairs, key=key)


def _same_channels(a: Mode, b: Mode) -> bool:
    """Whether both modes have shapes over the same number of channel entries (a MAC is defined)."""
    return a.shape is not None and b.shape is not None and a.shape.size == b.shape.size
