"""Which fitted poles are modes: contribution, band, damping; exactly ``n`` modes; fillers apart.

A rational fit with spare poles (``2 (n + spare)`` poles for ``n`` modes) finds close pairs that
a fit of exactly ``2 n`` poles merges, at the price of extra poles that fit noise or model
what lies outside the band. A pole's *contribution* is the weighted size of its term in the
fit, ``||rw (R_k/(s-p_k) + conj)|| / ||rw g||`` with the relative row weights
``rw = sqrt(w)/|g|`` of MACE eq. 5: a physical mode carries a large share of the data, a
noise pole a small one. Poles are sorted into

* **modes**: complex, natural frequency inside the band, damping below ``ZETA_FILLER``;
  the ``n`` of largest contribution (exactly ``n``);
* **fillers**: poles outside the band, heavily damped or real: kept in the model (they stand
  for out-of-band modes and residual flexibility) but reported apart;
* **dropped**: in-band, lightly damped poles beyond the ``n`` largest (noise).

No damping floor: a very lightly damped pole is a mode when it contributes.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..lti import pole_frequency_damping

__all__ = [
    "ZETA_FILLER",
    "SPLIT_RATIO",
    "PoleClasses",
    "pole_contributions",
    "classify_poles",
    "mode_counts",
    "split_pole",
]

#: damping ratio above which a pole counts as a filler (a broad term, not a resonance)
ZETA_FILLER = 0.2
#: second-to-first singular value ratio of a residue above which the pole stands for two modes
SPLIT_RATIO = 0.25


@dataclass(frozen=True)
class PoleClasses:
    """Indices into a pole set: ``modes`` (sorted by frequency), ``fillers``, ``dropped``."""

    modes: np.ndarray
    fillers: np.ndarray
    dropped: np.ndarray
    contribution: np.ndarray

    @property
    def kept(self) -> np.ndarray:
        return np.concatenate([self.modes, self.fillers])


def pole_contributions(s: np.ndarray, g: np.ndarray, rw: np.ndarray, poles, residues) -> np.ndarray:
    """Weighted norm of each pole's term relative to the weighted data norm.

    Parameters
    ----------
    s : ndarray, complex, shape (K,)
        Laplace variable, rad/s.
    g, rw : ndarray, shape (K, n_out, n_in)
        Data and row weights of the relative residual.
    poles : ndarray, complex, shape (n_p,)
    residues : ndarray, complex, shape (n_p, n_out, n_in)

    Returns
    -------
    ndarray, shape (n_p,)
    """
    k = s.size
    w = rw.reshape(k, -1)
    out = np.empty(len(poles))
    for j, (p, r) in enumerate(zip(poles, residues.reshape(len(poles), -1))):
        term = (1.0 / (s - p))[:, None] * r
        term = term + (1.0 / (s - np.conj(p)))[:, None] * np.conj(r) if p.imag != 0 else term.real + 0j
        out[j] = np.linalg.norm(w * term)
    return out / max(float(np.linalg.norm(w * g.reshape(k, -1))), np.finfo(float).tiny)


def mode_counts(
    residues: np.ndarray, poles: np.ndarray | None = None, ratio: float = SPLIT_RATIO
) -> np.ndarray:
    """Modes each pole stands for: 2 when its residue's second singular value exceeds ``ratio``
    times the first (two close modes with different shapes merged into one pole, Caltech eq. 10)
    and, given ``poles``, no other complex pole lies within its half-power band ``f (1 +- 2 zeta)``
    (then the pair already has its two poles); else 1."""
    if residues.size == 0 or min(residues.shape[1:]) < 2:
        return np.ones(len(residues), dtype=int)
    sv = np.linalg.svd(residues, compute_uv=False)
    counts = np.where(sv[:, 1] > ratio * np.maximum(sv[:, 0], 1e-300), 2, 1)
    if poles is not None:
        f, zeta = pole_frequency_damping(poles)
        cplx = poles.imag != 0
        for i in np.flatnonzero(counts == 2):
            near = cplx & (np.abs(f - f[i]) < 2 * zeta[i] * f[i])
            near[i] = False
            if np.any(near):
                counts[i] = 1
    return counts


def split_pole(pole: complex, residue: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Two poles ``p (1 -+ delta)`` (``delta`` a quarter of the damping ratio, at least 1e-4) with
    the rank-1 residues of the first two SVD terms of ``residue``: the start of a close pair."""
    u, sv, vh = np.linalg.svd(residue, full_matrices=False)
    zeta = -pole.real / abs(pole)
    delta = max(0.25 * zeta, 1e-4)
    poles = np.array([pole.real + 1j * pole.imag * (1 - delta), pole.real + 1j * pole.imag * (1 + delta)])
    res = np.array([sv[0] * np.outer(u[:, 0], vh[0]), sv[1] * np.outer(u[:, 1], vh[1])])
    return poles, res


def classify_poles(
    poles: np.ndarray,
    contribution: np.ndarray,
    band_hz: tuple[float, float],
    n_modes: int | None = None,
    zeta_filler: float = ZETA_FILLER,
    min_contribution: float = 0.0,
    counts: np.ndarray | None = None,
    exclude: np.ndarray | None = None,
    promote: bool = True,
) -> PoleClasses:
    """Sort poles into modes, fillers and dropped poles (see module doc).

    Parameters
    ----------
    poles : ndarray, complex
        One pole per conjugate pair plus real poles, rad/s.
    contribution : ndarray
        :func:`pole_contributions` of each pole.
    band_hz : (float, float)
        The fitted band, Hz.
    n_modes : int, optional
        Exactly this many modes: the largest contributors among the candidates; if there are
        fewer candidates, the largest-contributing complex fillers are promoted. ``None``:
        every candidate above ``min_contribution``.
    zeta_filler : float
        Damping ratio from which a complex pole is a filler.
    min_contribution : float
        With ``n_modes=None``, candidates below this contribution are dropped.
    counts : ndarray of int, optional
        Modes each pole stands for (:func:`mode_counts`); a pole counting 2 uses two of the
        ``n_modes`` (the caller splits it with :func:`split_pole`), or 1 when only one is left.
    exclude : ndarray of bool, optional
        Poles that are no candidates (duplicates of a mode); they are dropped.
    promote : bool
        With ``n_modes``: make up a shortfall of candidates with excluded poles and complex
        fillers. ``False``: never (fewer than ``n_modes`` modes when the data hold fewer).
    """
    f, zeta = pole_frequency_damping(poles)
    cplx = poles.imag != 0
    cand = cplx & (f >= band_hz[0]) & (f <= band_hz[1]) & (zeta < zeta_filler)
    skip = np.zeros(poles.size, dtype=bool) if exclude is None else np.asarray(exclude, dtype=bool)
    idx = np.flatnonzero(cand & ~skip)
    idx = idx[np.argsort(-contribution[idx], kind="stable")]
    if n_modes is None:
        modes = idx[contribution[idx] >= min_contribution]
    else:
        cnt = np.ones(poles.size, dtype=int) if counts is None else np.asarray(counts)
        total = np.cumsum(cnt[idx])
        modes = idx[: int(np.searchsorted(total, n_modes, side="right"))]
        if modes.size < idx.size and int(cnt[modes].sum()) < n_modes:
            modes = idx[: modes.size + 1]  # the next one, counted once
        n_found = int(np.minimum(cnt[modes], n_modes).sum())
        if promote and n_found < n_modes:  # promote excluded candidates first, then complex fillers
            extra = []
            for pool in (np.flatnonzero(cand & skip), np.flatnonzero(cplx & ~cand)):
                extra += list(pool[np.argsort(-contribution[pool], kind="stable")])
            modes = np.concatenate([modes, np.array(extra[: n_modes - n_found], dtype=int)])
    fillers = np.flatnonzero(~cand & ~skip & ~np.isin(np.arange(poles.size), modes))
    dropped = np.setdiff1d(np.flatnonzero(cand | skip), modes)
    modes = modes[np.argsort(f[modes], kind="stable")]
    return PoleClasses(modes.astype(int), fillers.astype(int), dropped.astype(int), contribution)
