"""Automatic model order in one pass: an order scan that reuses the previous order's poles, read
as a stabilisation diagram.

At order ``n`` (pole pairs) vector fitting starts from the ``n - 1`` poles of the previous order
plus one new pair placed where the weighted residual of that order is largest (Gustavsen &
Semlyen 1999 relocation, warm-started, a few iterations), so the scan costs about as much as a
handful of cold fits instead of one per order. Each pole is compared with the nearest pole of
the previous order: stable in frequency (``F_TOL``), damping (``ZETA_TOL``) and shape (modal
assurance criterion of the residues above ``MAC_TOL``) -- the classical stabilisation diagram
of experimental modal analysis (Ewins, *Modal Testing*, sec. 4.4; Peeters et al. 2004,
PolyMAX). A pole stable over ``CHAIN`` consecutive orders, inside the band, below the filler
damping and carrying at least ``MIN_CONTRIBUTION`` of the weighted data (and
``REL_CONTRIBUTION`` of the largest pole's share) is physical. There is
no damping floor: very lightly damped modes count when they are stable. The scan stops when
neither the number of physical poles nor the cost has improved for ``PATIENCE`` orders.
"""

from __future__ import annotations

import html
from dataclasses import dataclass

import numpy as np

from ..budget import Deadline
from ..lti import pole_frequency_damping
from ..table import Table
from .poles import (
    GramWeights,
    basis_gram,
    coefficients_to_residues,
    evaluate,
    partial_fraction_basis,
    reflect_unstable,
)
from .selection import ZETA_FILLER, pole_contributions
from .vector_fitting import StepWeights, initial_poles, vf_poles

__all__ = ["StabilisationDiagram", "stabilisation_scan", "residues_normal", "NormalWeights", "distinct_modes"]

F_TOL = 0.01  #: relative frequency change of a stable pole between orders
ZETA_TOL = 0.2  #: relative damping change of a stable pole
MAC_TOL = 0.9  #: modal assurance criterion of the residues of a stable pole
DUPLICATE_MAC = 0.9  #: MAC above which two poles on one peak are one mode (close modes differ more)
CHAIN = 3  #: consecutive stable orders that make a pole physical
MIN_CONTRIBUTION = 1e-2  #: smallest weighted share of the data a physical pole carries
REL_CONTRIBUTION = 1e-3  #: ... and smallest share relative to the largest pole's
PATIENCE = 4  #: orders without a new physical pole and without ``min_gain`` cost gain before stopping
WARM_ITERS = 8  #: VF relocations per order (warm start)
INHERIT_TOL = 0.02  #: frequency change over which a physical pole passes its status on
INHERIT_SHARE = 0.3  #: share of the physical pole's contribution the inheriting pole needs


@dataclass(frozen=True, eq=False)
class StabilisationDiagram:
    """The order scan of an automatic measurement model (a stabilisation diagram).

    Attributes
    ----------
    orders : ndarray of int, shape (n_orders,)
        Pole pairs of each fit.
    f_hz, zeta, contribution : tuple of ndarray
        Per order: natural frequency (Hz), damping ratio and weighted share of the data of each
        complex pole.
    status : tuple of ndarray of str
        Per order and pole: ``"new"``, ``"f"`` (frequency stable), ``"fd"`` (and damping),
        ``"fds"`` (and shape, MAC) against the previous order.
    chain : tuple of ndarray of int
        Consecutive orders over which each pole has been ``"fds"``-stable.
    physical : tuple of ndarray of bool
        Poles judged physical at each order (see module doc).
    cost : ndarray, shape (n_orders,)
        Complex-log cost (MACE eq. 5) of each order's rational fit.
    band_hz : (float, float)
    f_data : ndarray
        Frequencies of the data (Hz), for the background curve of :meth:`plot`.
    level_db : ndarray
        RMS over channels of the data magnitude (dB), the background curve.
    """

    orders: np.ndarray
    f_hz: tuple
    zeta: tuple
    contribution: tuple
    status: tuple
    chain: tuple
    physical: tuple
    cost: np.ndarray
    band_hz: tuple[float, float]
    f_data: np.ndarray
    level_db: np.ndarray

    @property
    def n_physical(self) -> np.ndarray:
        """Number of physical poles at each order."""
        return np.array([int(p.sum()) for p in self.physical])

    def table(self) -> Table:
        """One row per order: pole pairs, stable poles, physical poles, cost."""
        rows = [
            (int(n), int(np.sum(st == "fds")), int(ph.sum()), float(c))
            for n, st, ph, c in zip(self.orders, self.status, self.physical, self.cost)
        ]
        return Table(
            ("pole pairs", "stable (f, zeta, shape)", "physical", "J (MACE eq. 5)"),
            rows,
            title=f"Stabilisation diagram, band {self.band_hz[0]:.4g}-{self.band_hz[1]:.4g} Hz",
        )

    def plot(self, ax=None):
        """Poles per order over frequency (``o`` stable in f/zeta/shape, ``+`` f and zeta,
        ``.`` f only, ``x`` new; filled red: physical) over the data's rms magnitude."""
        import matplotlib.pyplot as plt

        if ax is None:
            fig, ax = plt.subplots(figsize=(9, 5))
        else:
            fig = ax.figure
        styles = {
            "fds": ("o", "tab:green"),
            "fd": ("+", "tab:blue"),
            "f": (".", "tab:gray"),
            "new": ("x", "0.6"),
        }
        for n, f, st, ph in zip(self.orders, self.f_hz, self.status, self.physical):
            for key, (marker, color) in styles.items():
                m = st == key
                if np.any(m):
                    ax.plot(f[m], np.full(m.sum(), n), marker, color=color, ms=4, ls="none")
            if np.any(ph):
                ax.plot(f[ph], np.full(ph.sum(), n), "o", mfc="none", mec="tab:red", ms=7, ls="none")
        ax.set_xlabel("frequency (Hz)")
        ax.set_ylabel("pole pairs in the fit")
        ax.set_xlim(*self.band_hz)
        twin = ax.twinx()
        twin.plot(self.f_data, self.level_db, color="k", lw=0.8, alpha=0.5)
        twin.set_ylabel("rms |G| over channels (dB)")
        ax.set_title("Stabilisation diagram (red rings: physical poles)")
        return fig

    def _repr_html_(self) -> str:
        head = html.escape(repr(self))
        return f"<p><b>{head}</b></p>" + self.table()._repr_html_()

    def __repr__(self) -> str:
        return (
            f"StabilisationDiagram(orders {int(self.orders[0])}-{int(self.orders[-1])}, "
            f"{int(self.n_physical[-1])} physical poles at the last order)"
        )


class NormalWeights:
    """What :func:`residues_normal` uses unchanged for every pole set on the data ``g``, ``rw``
    (shape (K, n_ch)): the squared row weights (prepared for :func:`.poles.basis_gram`) and the
    weighted data. Formed once for many pole sets (an order scan, a significance test)."""

    def __init__(self, g: np.ndarray, rw: np.ndarray):
        self.w2 = rw**2
        self.gram = GramWeights(self.w2)
        self.w2g = self.w2 * g


def residues_normal(
    s: np.ndarray, g: np.ndarray, rw: np.ndarray, poles: np.ndarray, weights: NormalWeights | None = None
):
    """Per-channel residues and feedthrough for fixed poles from the normal equations of all
    channels at once (every channel's Gram matrix from first moments of the partial fractions,
    :func:`.poles.basis_gram`, O(K n) per channel and no (K, n^2) product; the fast VF of
    Deschrijver et al. 2008); ``g``, ``rw`` of shape (K, n_ch); ``weights``: their
    :class:`NormalWeights` when already formed. Returns residues (n_p, n_ch) and d (n_ch,)."""
    if weights is None:
        weights = NormalWeights(g, rw)
    w2 = weights.w2
    if np.all(poles.real < 0) and np.all(s.real == 0):
        # Re(B^H diag(w2_c) B) per channel
        gram, phi = basis_gram(s, poles, weights.gram, with_basis=True)
        basis = np.hstack([phi, np.ones((s.size, 1))])
    else:  # the moments need stable poles on the imaginary axis: the direct product per channel
        basis = np.hstack([partial_fraction_basis(s, poles), np.ones((s.size, 1))])
        gram = np.einsum("kc,kiw->cwi", w2, (np.conj(basis)[:, :, None] * basis[:, None, :])).real
    rhs = (np.conj(basis).T @ weights.w2g).real.T  # Re(B^H diag(w2_c) g_c), (n_ch, m)
    scale = 1.0 / np.sqrt(np.maximum(np.einsum("cii->ci", gram), 1e-300))
    gs = gram * scale[:, :, None] * scale[:, None, :]
    try:
        x = np.linalg.solve(gs, (rhs * scale)[:, :, None])[:, :, 0] * scale
    except np.linalg.LinAlgError:
        x = np.array([np.linalg.lstsq(a, b, rcond=None)[0] for a, b in zip(gs, rhs * scale)]) * scale
    x = x.T  # (m, n_ch)
    return coefficients_to_residues(x[:-1], poles), x[-1]


def _mac(a: np.ndarray, b: np.ndarray) -> float:
    den = np.vdot(a, a).real * np.vdot(b, b).real
    return float(np.abs(np.vdot(a, b)) ** 2 / den) if den > 0 else 0.0


def _compare(prev, cur) -> tuple[np.ndarray, np.ndarray]:
    """Status and chain of each current complex pole against the previous order's."""
    f, z, r = cur
    status = np.full(f.size, "new", dtype="<U3")
    chain = np.zeros(f.size, dtype=int)
    if prev is None or prev[0].size == 0:
        return status, chain
    fp, zp, rp, chp = prev
    for j in range(f.size):
        i = int(np.argmin(np.abs(fp - f[j])))
        if abs(fp[i] - f[j]) > F_TOL * f[j]:
            continue
        status[j] = "f"
        same_shape = _mac(rp[i], r[j]) >= MAC_TOL
        if abs(zp[i] - z[j]) > ZETA_TOL * max(z[j], 1e-12):
            # damping is the noisiest estimate (leakage, noise): a pole stable in frequency and
            # shape keeps its chain, without extending it
            chain[j] = chp[i] if same_shape else 0
            continue
        status[j] = "fd"
        if not same_shape:
            continue
        status[j] = "fds"
        chain[j] = chp[i] + 1
    return status, chain


def _inherited(ever, f: np.ndarray, contrib: np.ndarray) -> np.ndarray:
    """Poles within ``INHERIT_TOL`` in frequency of a pole physical at the previous order and
    carrying at least ``INHERIT_SHARE`` of its contribution: a physical mode stays physical while
    the added poles reshuffle its neighbourhood (its damping and shape may move for an order)."""
    out = np.zeros(f.size, dtype=bool)
    if ever is None or ever[0].size == 0:
        return out
    fp, cp = ever
    for j in range(f.size):
        i = int(np.argmin(np.abs(fp - f[j])))
        out[j] = abs(fp[i] - f[j]) <= INHERIT_TOL * f[j] and contrib[j] >= INHERIT_SHARE * cp[i]
    return out


def distinct_modes(
    idx: np.ndarray, poles: np.ndarray, residues: np.ndarray, contrib: np.ndarray
) -> np.ndarray:
    """Drop poles that duplicate a neighbour: closer than three half-power half-widths
    (``3 zeta f``) with the same shape (MAC of the residues above ``DUPLICATE_MAC``). Window leakage
    and noise make a fit spend two poles on one broadened peak; two real modes that close have
    different shapes (the Caltech bending pairs), which is what tells them apart. Keeps the
    larger contributor of each duplicate; returns the kept indices."""
    f, z = pole_frequency_damping(poles)
    keep = list(idx[np.argsort(-contrib[idx], kind="stable")])
    out: list[int] = []
    for j in keep:
        near = [
            i
            for i in out
            if abs(f[i] - f[j]) < 3 * max(z[i] * f[i], z[j] * f[j])
            and _mac(residues[i].ravel(), residues[j].ravel()) > DUPLICATE_MAC
        ]
        if not near:
            out.append(j)
    return np.array(sorted(out, key=lambda i: f[i]), dtype=int)


def _new_pair(s: np.ndarray, resid_w2: np.ndarray, poles: np.ndarray) -> complex:
    """A pole pair at the frequency of the largest weighted residual (3-point smoothed), 1 % damped."""
    e = np.convolve(resid_w2, np.ones(3) / 3, mode="same")
    w = float(np.abs(s[int(np.argmax(e))]))
    return complex(-0.01 * w, w)


def stabilisation_scan(
    s: np.ndarray,
    g: np.ndarray,
    rw: np.ndarray,
    band_hz: tuple[float, float],
    max_pairs: int,
    deadline: Deadline | None = None,
    progress: bool = False,
    min_gain: float = 0.02,
):
    """Scan 1..``max_pairs`` pole pairs (warm-started VF), building the stabilisation diagram.

    Parameters
    ----------
    s : ndarray, complex, shape (K,)
        Laplace variable on the band, rad/s.
    g, rw : ndarray, shape (K, n_ch)
        Data and relative row weights ``sqrt(w)/|g|``.
    band_hz : (float, float)
    max_pairs : int
        Largest number of pole pairs.
    deadline : Deadline, optional
        Opt-in time budget (:class:`robustctl.budget.Deadline`): once expired the scan stops
        with what it has.
    progress : bool
        tqdm bar over the orders.
    min_gain : float
        Relative cost decrease that counts as progress of an order (besides a new physical pole).

    Returns
    -------
    diagram : StabilisationDiagram
    last : tuple (poles, residues (n_p, n_ch), d (n_ch,), indices of the distinct physical poles)
        of the latest order with the most distinct physical poles
    """
    from tqdm.auto import tqdm

    w_s = float(np.max(np.abs(s)))
    f_data = np.abs(s) / (2 * np.pi)
    rows: list[tuple] = []
    prev, poles, best_cost, stale, best_phys = None, None, np.inf, 0, 0
    last, resid_w2, ever = None, None, None
    step_weights, normal_weights = StepWeights(g, rw), NormalWeights(g, rw)  # the same at every order
    bar = tqdm(total=max_pairs, desc="order scan", disable=not progress, leave=False)
    for n in range(1, max_pairs + 1):
        if deadline is not None and rows and deadline.expired():
            break
        if poles is None:
            start = initial_poles(2 * n, float(np.abs(s).min()), w_s)
        else:
            start = np.append(poles, _new_pair(s, resid_w2, poles))
        new, _, _ = vf_poles(s / w_s, g, rw, 2 * n, max_iter=WARM_ITERS, tol=1e-6, start=start / w_s,
                             weights=step_weights)
        poles = reflect_unstable(new * w_s)[0]
        res, d = residues_normal(s, g, rw, poles, normal_weights)
        model = evaluate(s, poles, res[:, :, None], d[:, None])[:, :, 0]
        resid_w2 = np.sum(np.abs(rw * (g - model)) ** 2, axis=1)
        with np.errstate(divide="ignore", invalid="ignore"):
            e = np.log(g / np.where(model == 0, 1e-300, model))
        cost = float(np.sum(np.abs(e.real) ** 2 + np.angle(g * np.conj(model)) ** 2))
        contrib = pole_contributions(s, g[:, :, None], rw[:, :, None], poles, res[:, :, None])
        f, z = pole_frequency_damping(poles)
        c = poles.imag != 0
        status, chain = _compare(prev, (f[c], z[c], res[c]))
        inside = (f[c] >= band_hz[0]) & (f[c] <= band_hz[1]) & (z[c] < ZETA_FILLER)
        floor = max(MIN_CONTRIBUTION, REL_CONTRIBUTION * float(contrib.max(initial=0.0)))
        phys = (chain >= CHAIN - 1) & inside & (contrib[c] >= floor)
        phys |= _inherited(ever, f[c], contrib[c]) & inside & (contrib[c] >= floor)
        rows.append((n, f[c], z[c], contrib[c], status, chain, phys, cost))
        prev = (f[c], z[c], res[c], chain)
        ever = (f[c][phys], contrib[c][phys])
        kept = distinct_modes(np.flatnonzero(c)[phys], poles, res, contrib)
        if last is None or kept.size >= last[3].size:  # the latest order with the most modes
            last = (poles, res, d, kept)
        bar.update(1)
        improved = kept.size > best_phys or cost < (1 - min_gain) * best_cost
        best_phys, best_cost = max(best_phys, kept.size), min(best_cost, cost)
        stale = 0 if improved else stale + 1
        if stale >= PATIENCE:
            break
    bar.close()
    level = 20 * np.log10(np.sqrt(np.mean(np.abs(g) ** 2, axis=1)))
    cols = list(zip(*rows))
    diagram = StabilisationDiagram(
        np.array(cols[0]),
        tuple(cols[1]),
        tuple(cols[2]),
        tuple(cols[3]),
        tuple(cols[4]),
        tuple(cols[5]),
        tuple(cols[6]),
        np.array(cols[7]),
        band_hz,
        f_data,
        level,
    )
    return diagram, last
