"""The closed loop of D-K iteration and its mu on a frequency grid: the default grid, the
verification grid through the closed loop's resonances, the verified (refined) peak."""

from __future__ import annotations

from typing import Any

import numpy as np

from ...interconnect import lft
from ...lti import freqresp_array, pole_frequency_damping
from ..mu.bounds import mu
from ..uncertainty.blocks import BlockStructure


def closed_loop(P: Any, K: Any, nmeas: int, ncon: int):
    """The lower LFT ``Fl(P, K)`` (``w -> z``, ``u = K y``; Zhou, Doyle & Glover eq. 10.1).

    :func:`robustctl.interconnect.lft` with the plant's partition given explicitly.
    """
    return lft(P, K, nmeas, ncon)


# ---------------------------------------------------------------------------- grid
def default_grid(P: Any, per_decade: int = 30, max_points: int = 400) -> np.ndarray:
    """A log grid (Hz) spanning P's dynamics: a decade below its slowest and 1.5 above its fastest pole.

    Poles slower than 1e-6 of the fastest (integrators moved off the axis, like the
    distillation example's ``10 s + 1e-5``) do not stretch the grid.
    """
    wn = np.abs(np.linalg.eigvals(np.asarray(P.A, dtype=float))) if P.nstates else np.zeros(0)
    wn = wn[wn > 1e-6 * wn.max()] if wn.size and wn.max() > 0 else np.array([1.0])
    lo, hi = np.log10(wn.min() / 10 / (2 * np.pi)), np.log10(wn.max() * 30 / (2 * np.pi))
    n = int(min(max_points, max(50, per_decade * (hi - lo))))
    return np.logspace(lo, hi, n)


def _resonance_points(cl: Any, f_hz: np.ndarray, zeta_max: float = 0.2) -> np.ndarray:
    """Grid points at and around the lightly damped closed-loop poles inside ``f_hz``'s range."""
    if cl.nstates == 0:
        return f_hz
    fn, zeta = pole_frequency_damping(np.linalg.eigvals(np.asarray(cl.A)))
    keep = (zeta < zeta_max) & (fn >= f_hz[0]) & (fn <= f_hz[-1]) & (fn > 0)
    extra = (fn[keep, None] * (1 + np.outer(zeta[keep], [-1.0, -0.5, 0.0, 0.5, 1.0]))).ravel()
    extra = extra[(extra >= f_hz[0]) & (extra <= f_hz[-1])]
    return np.unique(np.concatenate([f_hz, extra]))


def verification_grid(cl: Any, f_hz: np.ndarray, per_interval: int = 2) -> np.ndarray:
    """A denser grid (Hz) on which the returned controller's mu is verified.

    DC; a decade below and above ``f_hz`` (10 points per decade); ``f_hz`` with
    ``per_interval`` log-spaced points inside each interval; and at every lightly damped
    (``zeta < 0.2``) closed-loop pole in that range, 9 points across ``+-2 zeta`` of its
    frequency. D-K judges its iterations on ``f_hz``: on a random 16-state modal plant the
    peak of mu between two of its points was 0.1 % above the grid's, and a fitted D-scale
    can move between the points and beyond the grid's ends.
    """
    f = np.asarray(f_hz, dtype=float)
    t = np.arange(1, per_interval + 1) / (per_interval + 1)
    inner = (f[:-1, None] * (f[1:, None] / f[:-1, None]) ** t).ravel()
    lo, hi = np.log10(f[0]), np.log10(f[-1])
    ends = np.concatenate([np.logspace(lo - 1, lo, 11), np.logspace(hi, hi + 1, 11)])
    parts = [np.zeros(1), f, inner, ends]
    if cl.nstates:
        fn, zeta = pole_frequency_damping(np.linalg.eigvals(np.asarray(cl.A, dtype=float)))
        keep = (zeta < 0.2) & (fn > 0) & (fn >= ends[0]) & (fn <= ends[-1])
        parts.append((fn[keep, None] * (1 + np.outer(zeta[keep], np.linspace(-2, 2, 9)))).ravel())
    g = np.unique(np.concatenate(parts))
    return g[g >= 0]


def verified_mu(cl: Any, blocks: BlockStructure, f_hz: np.ndarray, n_peaks: int = 5,
                 n_steps: int = 24) -> Any:
    """mu of ``cl`` on :func:`verification_grid`, with its ``n_peaks`` highest local maxima
    refined by golden-section search between their neighbours (all peaks at once, one mu call
    of ``n_peaks`` matrices per step) and the maxima found added to the result.

    The grid alone is not enough at a lightly damped resonance: points ``zeta / 2`` apart
    can sit 3 % below its peak (a two-mode plant: 1.0829 on the grid, 1.0862 at the peak).
    """
    f = verification_grid(cl, f_hz)
    m = mu(freqresp_array(cl, f), blocks, f_hz=f)
    u = m.upper
    inner = np.flatnonzero((u[1:-1] >= u[:-2]) & (u[1:-1] >= u[2:])) + 1
    top = inner[np.argsort(-u[inner])[:n_peaks]]
    top = top[f[top - 1] > 0]  # DC has no log neighbour
    if top.size == 0:
        return m

    def upper(x: np.ndarray) -> np.ndarray:
        fx = np.exp(x)
        return mu(freqresp_array(cl, fx), blocks, f_hz=fx, lower=False).upper

    a, b = np.log(f[top - 1]), np.log(f[top + 1])
    r = 0.5 * (np.sqrt(5.0) - 1.0)
    c, d = b - r * (b - a), a + r * (b - a)
    uc, ud = upper(c), upper(d)
    for _ in range(n_steps):
        right = uc < ud  # the maximum lies in [c, b]
        a, b = np.where(right, c, a), np.where(right, b, d)
        c, d = np.where(right, d, b - r * (b - a)), np.where(right, a + r * (b - a), c)
        new = upper(np.where(right, d, c))
        uc, ud = np.where(right, ud, new), np.where(right, new, uc)
    found = np.exp(np.where(uc >= ud, c, d))
    extra = mu(freqresp_array(cl, found), blocks, f_hz=found)
    return _merged(m, extra)


def _merged(a: Any, b: Any) -> Any:
    """Two MuResults of the same loop on different frequencies as one (sorted by frequency)."""
    from dataclasses import replace

    f = np.concatenate([a.f_hz, b.f_hz])
    order = np.argsort(f, kind="stable")
    f = f[order]
    keep = np.concatenate([[True], np.diff(f) > 0])
    idx = order[keep]

    def cat(x: np.ndarray, y: np.ndarray) -> np.ndarray:
        return np.concatenate([x, y])[idx]

    upper, lower = cat(a.upper, b.upper), cat(a.lower, b.lower)
    k, kw = int(np.argmax(upper)), int(np.argmax(lower))
    worst = a if a.lower.max() >= b.lower.max() else b
    return replace(
        a, f_hz=f[keep], upper=upper, lower=lower, peak=float(upper[k]), f_peak_hz=float(f[keep][k]),
        d_scales=cat(a.d_scales, b.d_scales),
        d_matrices=tuple(cat(x, y) for x, y in zip(a.d_matrices, b.d_matrices)),
        g_scales=None if a.g_scales is None else cat(a.g_scales, b.g_scales),
        g_matrices=(None if a.g_matrices is None
                    else tuple(cat(x, y) for x, y in zip(a.g_matrices, b.g_matrices))),
        worst_perturbation=worst.worst_perturbation, f_worst_hz=float(f[keep][kw]),
    )


# ---------------------------------------------------------------------------- D step
def mu_of(cl: Any, blocks: BlockStructure, f_hz: np.ndarray, refine: bool) -> tuple[Any, np.ndarray]:
    """mu of the closed loop ``cl`` on ``f_hz`` (plus its resonance points when ``refine``) and
    the responses it was computed from."""
    f = _resonance_points(cl, f_hz) if refine else f_hz
    H = freqresp_array(cl, f)
    return mu(H, blocks, f_hz=f), H


