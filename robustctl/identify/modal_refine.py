"""Nonlinear least-squares refinement of a modal model: poles and rank-k mode shapes together.

VF and Chebyshev/SK fit full-rank residues; a physical mode has a rank-1 residue ``c b^T``
(Caltech eq. 9), which is far fewer parameters. Fitting the poles *with* that structure uses the
information that two near-coincident modes have different shapes, which a full-rank fit cannot:
on the simulated Caltech experiment the 1.17/1.19 Hz pair (0.41 of a resolution bin apart)
moves from up to 0.7 % frequency and 30 % damping error to under 0.1 % and about 20 %.

The model is ``G(s) = D + sum_terms [c b^T/(s-p) + conj(c b^T)/(s-conj p)]`` with one term per
kept rank of each complex pole; the residual is ``rw (G - g)`` with ``rw = sqrt(w)/|g|`` (the
relative, log-like error of MACE eq. 5). For given poles and input shapes ``b`` it is linear in
every output's shapes ``c`` and feedthrough row ``D``, which are eliminated (variable projection,
Golub & Pereyra 1973, :class:`.block_refine._Projection`): ``scipy.optimize.least_squares``
(trust region, the projected residual's exact Jacobian) moves only ``log(-Re p)``, ``Im p`` and
the real and imaginary parts of every ``b``, with the damping ratio bounded below by
``ZETA_MIN``. Real poles are held, with their residues or (``real_residues=True``) with the
residues of those in the band (``REAL_SPAN``) eliminated with ``c`` and ``D``.

The Jacobian of that problem has ``2 K n_out n_in`` rows and ``2 n_modes (1 + n_in)`` columns
(the full problem's, with ``c`` and ``D`` as unknowns, about ``2 n_modes (n_out + n_in)``), which
explodes on modal tests with dozens of channels and
modes (2 x 28 channels, 25 modes, 800 points: 1.2 GB, more than ten minutes). There
:func:`refine_modes_local` refines one cluster of neighbouring modes at a time on the
frequencies around it, the other modes' terms held fixed (block Gauss-Seidel over the modes):
each block has a few dozen parameters and rows, so the cost grows linearly with the number of
channels and of modes. :func:`refine_modes_auto` chooses between the two by the Jacobian's size.
"""

from __future__ import annotations

from dataclasses import replace
from typing import Any

import numpy as np

from ..budget import Deadline
from ..threads import limit_blas
from .block_refine import NOT_AN_OSCILLATION, ZETA_MIN, _Projection, _solve_bounded, refine_cluster
from .poles import evaluate
from .rational_fit import RationalFit
from .realization import residue_factors
from .refine import _row_weights, refine_residues
from .tail import complex_tails

__all__ = ["refine_modes", "refine_modes_local", "refine_modes_auto", "ZETA_MIN", "DENSE_MAX_ENTRIES"]

#: largest dense Jacobian (complex entries) refined in one problem; larger ones go block by block.
#: The trust-region solver takes an SVD of the whole Jacobian at every step: at 1.1 M entries
#: (5 modes, 2 x 8 channels, 400 points) that is 7 s against 1 s block by block, for the same
#: accuracy (0.001 % in frequency); 0.5 M keeps the small SISO and few-channel fits dense.
DENSE_MAX_ENTRIES = 500_000
#: relative cost, step and gradient tolerance of the dense refinement: the optimum converged far
#: below any decision taken on it, so that round-off (another BLAS kernel, a 1e-12 change of the data)
#: moves the refined model by round-off, not by where an unconverged iteration happened to stop
REFINE_TOL = 1e-12
#: real poles from the band's lowest frequency to this many times its top (rad/s) have their
#: residues refitted with the modes' shapes and ``D`` (the poles held: the data barely locate a
#: filler); a real pole further out is nearly a constant over the band, collinear with ``D`` and
#: with heavily damped pairs, and one below the band a trend: both are held with their residues
REAL_SPAN = 1.0
#: relative fall of the blocks' summed cost below which the block Gauss-Seidel sweeps stop
SWEEP_TOL = 1e-9


@limit_blas
def refine_modes(
    fit: RationalFit,
    weights: np.ndarray | None = None,
    max_nfev: int = 400,
    which: np.ndarray | None = None,
    truncation: Any = None,
    real_residues: bool = False,
) -> RationalFit:
    """Refine poles and rank-``ranks`` mode shapes of ``fit`` against ``fit.data`` (see module doc).

    Parameters
    ----------
    fit : RationalFit
        Starting model (poles, residues, ranks) with its data.
    weights : ndarray, optional
        Weights on squared residuals (default: coherence-based, as :func:`fit_rational`).
    max_nfev : int
        Cap on residual evaluations of the trust-region solver (a bound on the work; the
        refinement stops at ``REFINE_TOL`` well before it).
    which : ndarray of int, optional
        Indices of the complex poles to refine (default: all with a non-zero rank); the other
        poles' terms are held fixed.
    truncation : TruncationSettings, optional
        Impact record settings: fit the response the truncated record sees, every complex
        pole's term minus its record-end tail (eq. T1 of :mod:`.leakage`, derivative eq. T1'
        of :mod:`.tail`), to the raw data; the returned model is the untruncated one.
    real_residues : bool
        Also refit the residues of the real poles in the band (from its lowest frequency to
        ``REAL_SPAN`` times its top; the poles held) with the shapes and ``D``, so that the refined
        model is stationary in them too (default: held with their start's residues).

    Returns
    -------
    RationalFit
        Refined model; the starting one if the refinement does not lower the cost.
    """
    data = fit.data
    oscillating = np.abs(fit.poles.real) < NOT_AN_OSCILLATION * np.abs(fit.poles.imag)
    cplx = np.flatnonzero((fit.poles.imag != 0) & (fit.ranks > 0) & oscillating)
    if which is not None:
        cplx = np.intersect1d(cplx, which)
    if data is None or cplx.size == 0:
        return fit
    s = 2j * np.pi * data.f_hz
    rw = _row_weights(fit, weights)
    w = np.abs(s)
    inside = (np.abs(fit.poles) >= w.min()) & (np.abs(fit.poles) <= REAL_SPAN * w.max())
    real = np.flatnonzero((fit.poles.imag == 0) & inside & bool(real_residues))
    fixed = np.setdiff1d(np.arange(fit.poles.size), np.union1d(cplx, real))
    held = evaluate(s, fit.poles[fixed], fit.residues[fixed], np.zeros_like(fit.d))
    target = data.response - held + complex_tails(s, fit.poles[fixed], fit.residues[fixed], truncation)
    term_pole, bs = [], []
    for j, g in enumerate(cplx):
        _, b = residue_factors(fit.residues[g], int(fit.ranks[g]))
        term_pole += [j] * b.shape[0]
        bs += list(b)
    n_out, n_in = fit.d.shape
    poles0 = fit.poles[cplx]
    real_terms = 1.0 / (s[:, None] - fit.poles[real].real[None, :])  # (K, R)
    proj = _Projection(s, target, rw, cplx.size, n_in, truncation, np.array(term_pole), False, floor=0.0,
                       real_terms=real_terms)
    bs = np.array(bs)
    mine = np.concatenate([cplx, real])
    start = evaluate(s, fit.poles[mine], fit.residues[mine], fit.d)
    start -= complex_tails(s, poles0, fit.residues[cplx], truncation)
    before = float(np.sum(np.abs(rw * (start - target)) ** 2))  # the starting model's own cost
    theta = _solve_bounded(proj, poles0, bs, max_nfev, before, REFINE_TOL)
    if theta is None:
        return fit
    poles_c, b, _, x, _, coef, _ = proj.state(theta)
    n_terms = b.shape[0]
    c = coef[:, : 2 * n_terms : 2] + 1j * coef[:, 1 : 2 * n_terms : 2]  # (n_out, T)
    poles, residues = np.array(fit.poles), np.array(fit.residues)
    poles[cplx] = poles_c
    residues[cplx] = 0
    for term, j in enumerate(term_pole):
        residues[cplx[j]] += np.outer(c[:, term], b[term])
    d = coef[:, 2 * n_terms : 2 * n_terms + n_in].reshape(n_out, n_in)
    residues[real] = np.moveaxis(coef[:, 2 * n_terms + n_in :].reshape(n_out, real.size, n_in), 1, 0)
    if not (np.all(np.isfinite(residues)) and np.all(np.isfinite(d)) and np.all(np.isfinite(poles))):
        return fit
    return replace(fit, poles=poles, residues=residues, d=d)


def _dense_entries(fit: RationalFit) -> int:
    n_out, n_in = fit.d.shape
    cplx = (fit.poles.imag != 0) & (fit.ranks > 0)
    n_par = int(np.sum(cplx * (2 + 2 * fit.ranks * (n_out + n_in)))) + n_out * n_in
    k = 0 if fit.data is None else fit.data.f_hz.size
    return k * n_out * n_in * n_par


def _clusters(f_hz: np.ndarray, zeta: np.ndarray, idx: np.ndarray) -> list[np.ndarray]:
    """Neighbouring modes whose half-power bands (``f (1 +- 3 zeta)``) overlap share a block."""
    order = idx[np.argsort(f_hz[idx])]
    out, cur = [], [order[0]]
    for a, b in zip(order[:-1], order[1:]):
        if f_hz[b] * (1 - 3 * zeta[b]) <= f_hz[a] * (1 + 3 * zeta[a]):
            cur.append(b)
        else:
            out.append(np.array(cur))
            cur = [b]
    out.append(np.array(cur))
    return out


def _window(f_data: np.ndarray, f_hz: np.ndarray, zeta: np.ndarray, block: np.ndarray) -> np.ndarray:
    """Frequencies that inform a block: its modes' bands widened to 10 half-power half-widths
    (at least 8 points either side)."""
    lo = np.min(f_hz[block] * (1 - 10 * np.maximum(zeta[block], 1e-4)))
    hi = np.max(f_hz[block] * (1 + 10 * np.maximum(zeta[block], 1e-4)))
    first = int(np.searchsorted(f_data, f_hz[block].min())) - 8
    last = int(np.searchsorted(f_data, f_hz[block].max())) + 8
    i0 = max(0, min(int(np.searchsorted(f_data, lo)), first))
    i1 = min(f_data.size, max(int(np.searchsorted(f_data, hi)), last))
    return np.arange(i0, i1)


@limit_blas
def refine_modes_local(
    fit: RationalFit,
    weights: np.ndarray | None = None,
    sweeps: int = 8,
    deadline: Deadline | None = None,
    progress: bool = False,
    truncation: Any = None,
) -> RationalFit:
    """Block Gauss-Seidel refinement (at most ``sweeps`` sweeps over the blocks, until the blocks'
    summed cost falls by less than ``SWEEP_TOL`` relative in a sweep): each cluster of
    overlapping rank-1 modes refined by variable projection (:func:`.block_refine.refine_cluster`:
    poles and input shapes nonlinear, output shapes and a local constant eliminated per output) on
    the frequencies around it, every other term held fixed. Stops once ``deadline`` (a
    :class:`robustctl.budget.Deadline`) has expired. The residual is the relative one of MACE
    eq. 5 with the full data's weights; a block keeps its start when refining does not lower its
    cost. With ``truncation`` every complex term is the truncated record's (eq. T1, as
    :func:`refine_modes`).
    """
    from tqdm.auto import tqdm

    if fit.data is None:
        return fit
    idx = np.flatnonzero((fit.poles.imag != 0) & (fit.ranks == 1))
    if idx.size == 0:
        return fit
    data = fit.data
    s = 2j * np.pi * data.f_hz
    rw = _row_weights(fit, weights)
    previous = np.inf
    for _ in range(int(sweeps)):
        total = 0.0
        blocks = _clusters(fit.f_hz, fit.zeta, idx)
        for block in tqdm(blocks, desc="modal refinement", disable=not progress, leave=False):
            if deadline is not None and deadline.expired():
                return fit
            rows = _window(data.f_hz, fit.f_hz, fit.zeta, block)
            others = np.setdiff1d(np.arange(fit.poles.size), block)
            rest = evaluate(s[rows], fit.poles[others], fit.residues[others], fit.d)
            rest -= complex_tails(s[rows], fit.poles[others], fit.residues[others], truncation)
            factors = [residue_factors(fit.residues[k], 1) for k in block]
            cs = np.array([f[0][:, 0] for f in factors])
            bs = np.array([f[1][0] for f in factors])
            p, c, b, before, after = refine_cluster(
                s[rows], data.response[rows] - rest, rw[rows], fit.poles[block], cs, bs, truncation=truncation
            )
            total += min(before, after)
            if not after < before:
                continue
            poles, residues = np.array(fit.poles), np.array(fit.residues)
            poles[block] = p
            residues[block] = c[:, :, None] * b[:, None, :]
            fit = replace(fit, poles=poles, residues=residues)
        if not total < previous * (1 - SWEEP_TOL):  # the blocks' summed cost has settled
            break
        previous = total
    return fit


def refine_modes_auto(
    fit: RationalFit,
    weights: np.ndarray | None = None,
    deadline: Deadline | None = None,
    progress: bool = False,
    truncation: Any = None,
    real_residues: bool = False,
) -> RationalFit:
    """:func:`refine_modes` (all modes together; with ``real_residues`` the in-band real poles'
    residues refitted too) when its Jacobian has at most ``DENSE_MAX_ENTRIES`` entries, else
    :func:`refine_modes_local` (block by block) followed by one alternating least-squares pass
    over all shapes (:func:`refine_residues`; not with ``truncation``, whose leaked terms that
    pass does not model)."""
    if _dense_entries(fit) <= DENSE_MAX_ENTRIES:
        return refine_modes(fit, weights, truncation=truncation, real_residues=real_residues)
    fit = refine_modes_local(fit, weights, deadline=deadline, progress=progress, truncation=truncation)
    return fit if truncation is not None else refine_residues(fit, weights, sweeps=1)
