"""mu-synthesis by D-K iteration: H-infinity synthesis alternating with D-scale fits.

The structured singular value of the closed loop ``M = Fl(P, K)`` is bounded above by
``inf_D sigma_max(D M D^-1)`` (Packard & Doyle 1993, eq. 8.1; Zhou, Doyle & Glover 1996,
sec. 11.3). D-K iteration (Doyle 1985; Balas & Doyle's Caltech truss design, seed paper
"Identification of Flexible Structures for Robust Control", Fig. 1) minimises this bound
over ``K`` and ``D(s)`` alternately (Skogestad & Postlethwaite 2005, sec. 8.12.1):

1. **K step** -- ``K = argmin || D Fl(P, K) D^-1 ||_inf`` by H-infinity synthesis on the
   scaled plant ``diag(D, I) P diag(D^-1, I)`` (the scales act on the uncertainty and
   performance channels only, so ``K`` works unchanged on the unscaled ``P``);
2. **D step** -- the mu upper bound of ``Fl(P, K)`` on a frequency grid gives optimal
   constant scales ``d_i(f)`` per block; each ``|d_i(j 2 pi f)|`` is fitted by a stable,
   minimum-phase ``d_i(s)`` (its inverse is stable too), the last block normalised to 1;
3. repeat while the peak of mu falls.

The best controller (lowest peak of mu) is kept.

Alternating minimisation creeps on flat problems: on Skogestad & Postlethwaite's
distillation example mu is flat from DC to 0.3 Hz after three iterations and plain D-K
gains 0.1-0.3 % per iteration (1.0277, 1.0215, 1.0174, 1.0145, 1.0134, ...). From the third
iteration on, the D step is therefore a short line search along the change of the optimal
scales between the last two controllers (over-relaxation of the fixed-point iteration):
targets ``ln d_k + beta (ln d_k - ln d_{k-1})`` for ``beta`` in :data:`D_STEPS`, each fitted
with the orders chosen for ``beta = 0`` and scored by the K step's verified gamma (the D-K
objective ``inf_K ||D Fl(P, K) D^-1||_inf``, an upper bound on the next peak of mu); the
lowest gamma wins. On the distillation example this gives 1.1809, 1.0284, 1.0139, 1.0035,
0.9918 (plain D-K: 1.0145 at iteration 5).

With real scalar blocks (``real="mixed"``, the default) the iteration is D-G-K (Young 1996,
"Controller design for mixed uncertainties", Automatica 32(8)): the analysis is mixed mu,
the scales offered to the K step are the complex analysis' wherever they keep the mixed
bound and the mixed ones elsewhere, the G-scales become stable filters absorbed by a loop
transformation (:mod:`robustctl.robust.dgk`), and the K step searches the level it can
certify. On Wie & Bernstein's two-mass-spring benchmark (spring in [0.5, 2] as a real block,
:func:`robustctl.examples.two_mass_spring_plant`), started from the user's scaling
(``autoscale=False``), D-G-K reaches mixed mu 0.867 where complex D-K stops at 0.983; with
the automatic scaling's three starts complex D-K reaches 0.869 and D-G-K 0.867.

The returned controller is the best of the iterations, and its mu is verified on a denser
and wider grid with a search of its highest maxima (:func:`verification_grid`): the
iterations judge mu on a finite grid, which can miss a lightly damped resonance's peak.
An iteration whose mu rises above the best before it says so (``DKIteration.note``).
"""

from __future__ import annotations

import sys
import time
from collections.abc import Callable, Mapping, Sequence
from concurrent.futures import Executor
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from ..budget import Deadline, as_deadline
from ..checks import flag, integer, positive_number
from ..errors import PlantError, SynthesisError
from ..executors import check_executor, parallel_map
from ..interconnect import PartitionedPlant
from ..lti import is_stable
from ..table import Table
from .blocks import Block, BlockStructure
from .partitioned import as_partitioned
from .plant import GeneralizedPlant

__all__ = ["DKIteration", "DKResult", "Reduction", "dksyn"]

#: Highest D-scale order tried when ``order_d`` is None.
MAX_AUTO_ORDER_D = 8
#: The K step designs at gamma_opt (1 + HINF_BACKOFF): a 1 % back-off would cost 1 % of mu per iteration.
HINF_BACKOFF = 1e-3
#: Most states one block's D-scale may add to the scaled plant (order x (rows + cols)).
MAX_D_STATES_PER_BLOCK = 24
#: Target accuracy of each D fit (dB), passed to fit_magnitude.
FIT_TOL_DB = 0.1
#: Orders the automatic choice may drop below the previous iteration's (0: an order once
#: needed is kept).
ORDER_D_DROP = 0
#: Accept the lowest D order whose scaled bound peak is within this fraction of mu's peak
#: (loose on purpose: a tight tolerance picks high orders that stall D-K).
ORDER_D_RTOL = 0.05
#: A reduced controller is kept when the peak of mu rises by at most this fraction.
REDUCE_MU_RTOL = 0.02
#: ``reduce="auto"`` truncates at least the states whose Hankel singular value is below this
#: fraction of the largest (numerically non-minimal: their truncation changes K by at most
#: ``2 sum sigma_i``, below 1e-7 of its gain).
HSV_RTOL = 1e-9
#: Serially, a block with at least this many candidate D orders fits the highest first and
#: keeps it without fitting the others when even it misses ORDER_D_RTOL; fewer candidates are
#: scanned upwards (smaller controllers, less time).
SHORTCUT_MIN_ORDERS = 6
#: A block's best bound this factor above what it can reach (times 1 + ORDER_D_RTOL) counts as a
#: broken fit: the orders below the previous iteration's are tried too.
ORDER_D_BROKEN = 1.25
#: Extrapolation steps ``beta`` of the D step's line search (module docstring); 0 is plain D-K.
D_STEPS = (0.0, 0.5, 1.0)
#: H-infinity syntheses the automatic scaling may spend on its constant block scales.
AUTOSCALE_EVALS = 60
#: Starts of the automatically scaled D-K (ln of a factor on all block scales but the last).
AUTOSCALE_STARTS = (0.0, -1.5, 1.5)
#: A start whose verified mu is below this ends the multi-start (robust performance certified).
AUTOSCALE_CERTIFIED = 1.0
#: ln of the common block-scale factors the search scans before its Nelder-Mead refinement.
AUTOSCALE_SCAN = (-6.0, -4.5, -3.0, -1.5, 0.0, 1.5, 3.0, 4.5, 6.0)
#: Most scaled blocks (all but the last) for which that search runs (else the covariant start).
AUTOSCALE_MAX_BLOCKS = 6
#: H-infinity syntheses of one D-G-K K step's search for its level (:func:`_mixed_k_step`).
MIXED_K_EVALS = 5
#: ``|ln gamma|`` at which that search stops (the level is then within about 0.5 %).
MIXED_K_TOL = 5e-3
#: A verified peak of mu this fraction above the iteration grid's draws a RuntimeWarning.
VERIFY_WARN_RTOL = 0.01


# ---------------------------------------------------------------------------- plant
def _complexified(blocks: BlockStructure) -> BlockStructure:
    """Real scalar blocks treated as complex ones (D-K has no G-scales; conservative)."""
    return BlockStructure(tuple(
        Block("complex", b.rows, b.cols, b.name) if b.kind == "real" else b for b in blocks
    ))


def _as_plant(gp: Any) -> GeneralizedPlant:
    """A GeneralizedPlant or ``(P, nmeas, ncon, blocks)`` as a checked continuous-time plant with blocks."""
    if isinstance(gp, tuple) and len(gp) == 4:
        P, nmeas, ncon, blocks = gp
        return as_partitioned(P, nmeas, ncon, blocks, who="dksyn", allow_discrete=False, need_blocks=True)
    if isinstance(gp, PartitionedPlant):
        return as_partitioned(gp, who="dksyn", allow_discrete=False, need_blocks=True)
    raise PlantError(
        f"dksyn takes a GeneralizedPlant (rc.generalized_plant) or a tuple (P, nmeas, ncon, blocks); "
        f"got a {type(gp).__name__}."
    )


# ---------------------------------------------------------------------------- state space
def _siso_inverse(d: Any):
    """``1/d(s)`` of a bi-proper SISO system: (A - B C/D, B/D, -C/D, 1/D)."""
    import control

    A, B, C, D = (np.asarray(m, dtype=float) for m in (d.A, d.B, d.C, d.D))
    dd = float(D[0, 0])
    if abs(dd) < 1e-12:
        raise SynthesisError(
            "a fitted D-scale is strictly proper and cannot be inverted; fit a bi-proper one."
        )
    return control.ss(A - B @ C / dd, B / dd, -C / dd, np.array([[1.0 / dd]]))


def _diag_system(parts: Sequence[tuple[Any, int]]):
    """``blkdiag(d_1 I_n1, d_2 I_n2, ...)`` for SISO systems ``d_k`` (or floats)."""
    import control

    systems = []
    for d, n in parts:
        sys1 = control.ss([], [], [], [[float(d)]]) if np.isscalar(d) else d
        systems += [sys1] * n
    return control.append(*systems)


def _scale_plant(plant: GeneralizedPlant, d_fits: Sequence[Any]):
    """``diag(D_L, I_y) P diag(D_R^-1, I_u)`` with ``D_L = blkdiag(d_i I_cols_i)``,
    ``D_R = blkdiag(d_i I_rows_i)`` (the last block's scale is 1)."""
    import control

    if not d_fits:
        return plant.P
    d_all = list(d_fits) + [1.0]
    inv_all = [_siso_inverse(d) for d in d_fits] + [1.0]
    left = _diag_system([(d, b.cols) for d, b in zip(d_all, plant.blocks)] + [(1.0, plant.nmeas)])
    right = _diag_system([(d, b.rows) for d, b in zip(inv_all, plant.blocks)] + [(1.0, plant.ncon)])
    scaled = control.series(right, plant.P, left)
    A, B, C = _balanced(*(np.asarray(m, dtype=float) for m in (scaled.A, scaled.B, scaled.C)))
    return control.ss(A, B, C, scaled.D,
                      inputs=list(plant.P.input_labels), outputs=list(plant.P.output_labels))


@dataclass(frozen=True)
class _Scaling:
    """Constant channel scales of :func:`_autoscaled`: ``P_s = diag(D_z, S_y) P diag(D_w^-1, S_u)``."""

    su: np.ndarray
    sy: np.ndarray
    d: np.ndarray


def _constant_scaled(plant: GeneralizedPlant, su: np.ndarray, sy: np.ndarray, d: np.ndarray):
    """``diag(D_z, S_y) P diag(D_w^-1, S_u)`` for constant scales."""
    import control

    P = plant.P
    dz = np.concatenate([np.full(b.cols, di) for b, di in zip(plant.blocks, d)])
    dw = np.concatenate([np.full(b.rows, 1.0 / di) for b, di in zip(plant.blocks, d)])
    left, right = np.concatenate([dz, sy]), np.concatenate([dw, su])
    A, B, C, D = (np.asarray(m, dtype=float) for m in (P.A, P.B, P.C, P.D))
    return control.ss(A, B * right[None, :], left[:, None] * C, left[:, None] * D * right[None, :],
                      inputs=list(P.input_labels), outputs=list(P.output_labels))


def _autoscaled(plant: GeneralizedPlant,
                hinf_options: Mapping | None = None) -> tuple[GeneralizedPlant, _Scaling]:
    """The plant with its channels scaled so that D-K does not depend on the user's units.

    Neither the control/measurement scales (the controller absorbs them: ``K = S_u K_s S_y``)
    nor constant per-block scales (a constant D-scale) change mu of any closed loop, but both
    change the first H-infinity step and the numbers every later step works with: on
    Skogestad & Postlethwaite's distillation column written with ``G0 / 100`` (the book's
    unscaled units) D-K stopped at mu 1.09 after 10 iterations against 0.99 for the scaled
    plant. Here, from the plant's response on its default grid: each control ``u_j`` is scaled
    by ``1 / max_f |P22[:, j]|`` and then each measurement by ``1 / max_f |P22_s[i, :]|`` (unit
    peak gain per channel); each block by ``d_i = sqrt(n21_i / n12_i)`` (last block 1), with
    ``n12_i = max_f sigma_max(P12 rows of block i)`` and ``n21_i = max_f sigma_max(P21 columns
    of block i)``: this balances ``d_i / d_j`` of the closed loop's off-diagonal blocks
    ``P12_i K P21_j`` for a controller of unit gain (the ratio of ``d_i`` is unchanged by any
    rescaling of a block's channels, which it undoes). Zero or non-finite gains keep scale 1.

    That start is only covariant, not good (the distillation column's first K step reached
    gamma 97 there, against 1.18 with the book's units), so the block scales are then moved by
    a search in ``ln d`` for the lowest gamma of the first K step (a constant-D mu-synthesis
    step): a coarse scan of a common factor over :data:`AUTOSCALE_SCAN`, then Nelder-Mead
    from its best point (:data:`AUTOSCALE_EVALS` H-infinity syntheses at most, an initial
    simplex of ``e^2`` steps). Started from a covariant point and driven by an invariant objective,
    the search finds the same scales for any units (1.121 on both the scaled and the
    ``G0 / 100`` column).
    """
    from scipy.optimize import minimize

    from ..lti import freqresp_array
    from .hinf_synthesis import hinfsyn

    P = plant.P
    f = default_grid(P, per_decade=10, max_points=120)
    H = freqresp_array(P, f)
    nw, nz = plant.nw, plant.nz

    def inv_peak(x: np.ndarray) -> float:
        v = float(np.max(x)) if x.size else 0.0
        return 1.0 / v if np.isfinite(v) and v > 1e-300 else 1.0

    P22 = H[:, nz:, nw:]
    su = np.array([inv_peak(np.linalg.norm(P22[:, :, j], axis=1)) for j in range(plant.ncon)])
    P22s = P22 * su[None, None, :]
    sy = np.array([inv_peak(np.linalg.norm(P22s[:, i, :], axis=1)) for i in range(plant.nmeas)])
    P12 = H[:, :nz, nw:] * su[None, None, :]
    P21 = sy[None, :, None] * H[:, nz:, :nw]
    logd = []
    for o, i in zip(plant.blocks.row_slices(), plant.blocks.col_slices()):
        n12 = float(np.max(np.linalg.norm(P12[:, o, :], ord=2, axis=(1, 2)))) if plant.ncon else 0.0
        n21 = float(np.max(np.linalg.norm(P21[:, :, i], ord=2, axis=(1, 2)))) if plant.nmeas else 0.0
        ok = n12 > 1e-300 and n21 > 1e-300 and np.isfinite(n12 * n21)
        logd.append(0.5 * np.log(n21 / n12) if ok else 0.0)
    d0 = np.exp(np.array(logd) - logd[-1])
    nb = len(d0) - 1
    opts = {"gamma_tol": 1e-2, "backoff": HINF_BACKOFF,
            **{k: v for k, v in (hinf_options or {}).items() if k == "method"}}

    def gamma_of(x: np.ndarray) -> float:
        d = d0 * np.exp(np.append(x, 0.0))
        try:
            h = hinfsyn(PartitionedPlant(_constant_scaled(plant, su, sy, d), plant.nmeas, plant.ncon), **opts)
        except SynthesisError:
            return 1e3
        return float(np.log(h.gamma)) if np.isfinite(h.gamma) and h.gamma > 0 else 1e3

    x = np.zeros(nb)
    if 0 < nb <= AUTOSCALE_MAX_BLOCKS:
        # a coarse scan along the common direction (all blocks but the last together), then
        # Nelder-Mead from its best point
        scan = [(gamma_of(np.full(nb, t)), t) for t in AUTOSCALE_SCAN]
        g0, t0 = min(scan)
        x = np.full(nb, t0)
        simplex = np.vstack([x, x + 2.0 * np.eye(nb)])
        res = minimize(gamma_of, x, method="Nelder-Mead",
                       options={"initial_simplex": simplex, "xatol": 0.05, "fatol": 1e-3,
                                "maxfev": AUTOSCALE_EVALS})
        if res.fun < g0:
            x = res.x
    d = d0 * np.exp(np.append(x, 0.0))
    Ps = _constant_scaled(plant, su, sy, d)
    return GeneralizedPlant(Ps, plant.nmeas, plant.ncon, blocks=plant.blocks), _Scaling(su, sy, d)


def _unscaled_controller(K: Any, sc: _Scaling):
    """``S_u K_s S_y``: the controller of the scaled plant for the user's plant."""
    import control

    A, B, C, D = (np.asarray(m, dtype=float) for m in (K.A, K.B, K.C, K.D))
    return control.ss(A, B * sc.sy[None, :], sc.su[:, None] * C, sc.su[:, None] * D * sc.sy[None, :],
                      inputs=list(K.input_labels), outputs=list(K.output_labels))


def _unscaled_mu(m: Any, sc: _Scaling) -> Any:
    """A MuResult of the scaled loop with its scales for the user's loop (``X_i`` times ``d_i^2``)."""
    d = sc.d
    d_mats = tuple(x * di for x, di in zip(m.d_matrices, d))
    g_mats = None if m.g_matrices is None else tuple(g * di**2 for g, di in zip(m.g_matrices, d))
    g_sc = None if m.g_scales is None else np.asarray(m.g_scales) * (d**2)[None, :]
    return replace(m, d_scales=np.asarray(m.d_scales) * d[None, :], d_matrices=d_mats, g_matrices=g_mats,
                   g_scales=g_sc)


def _balanced(A: np.ndarray, B: np.ndarray, C: np.ndarray) -> tuple[np.ndarray, ...]:
    """Diagonal similarity ``T^-1 A T`` balancing ``A`` (Parlett-Reinsch, powers of 2: exact).

    The series connection of the D-scales, their inverses and ``P`` has entries spread over
    many decades; balancing keeps the K step's Riccati equations and rank tests well scaled.
    """
    from scipy.linalg import matrix_balance

    if A.shape[0] == 0:
        return A, B, C
    _, (t, _) = matrix_balance(A, permute=False, separate=True)
    return A * t[None, :] / t[:, None], B / t[:, None], C * t[None, :]


def closed_loop(P: Any, K: Any, nmeas: int, ncon: int):
    """The lower LFT ``Fl(P, K)`` (``w -> z``, ``u = K y``; Zhou, Doyle & Glover eq. 10.1).

    :func:`robustctl.interconnect.lft` with the plant's partition given explicitly.
    """
    from ..interconnect import lft

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
    from ..lti import pole_frequency_damping

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
    from ..lti import pole_frequency_damping

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


def _verified_mu(cl: Any, blocks: BlockStructure, f_hz: np.ndarray, n_peaks: int = 5,
                 n_steps: int = 24) -> Any:
    """mu of ``cl`` on :func:`verification_grid`, with its ``n_peaks`` highest local maxima
    refined by golden-section search between their neighbours (all peaks at once, one mu call
    of ``n_peaks`` matrices per step) and the maxima found added to the result.

    The grid alone is not enough at a lightly damped resonance: points ``zeta / 2`` apart
    can sit 3 % below its peak (a two-mode plant: 1.0829 on the grid, 1.0862 at the peak).
    """
    from ..lti import freqresp_array
    from .mu_bounds import mu

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
def _fit_one(args: tuple) -> Any:
    """One D-scale fit (module level so a process executor can pickle it)."""
    from .magfit import fit_magnitude

    f_hz, mag, order, deadline = args
    return _into_band(fit_magnitude(f_hz, mag, order, tol_db=FIT_TOL_DB, time_budget_s=deadline), f_hz)


def _into_band(fit: Any, f_hz: np.ndarray, margin: float = 10.0) -> Any:
    """The fit with poles and zeros above ``margin`` times the band's top moved to that edge.

    A D-scale still rolling off at the grid's top end gets a zero (or pole) decades above it
    (2.8e4 rad/s over a 60 rad/s grid on the distillation example), which
    :func:`_dynamics_in_band` refuses: the order search then settles for a lower order (3
    instead of 4 there, and D-K stalled at mu = 1.002 instead of reaching 0.991, 0.05 dB fits). Moving a
    root ``r`` above the band to ``hi r / |r|`` with the gain scaled by ``|r| / hi`` (zeros;
    the inverse for poles) keeps the ``|1 - s/r|``-normalised magnitude: in the band
    ``|d(j w)|`` changes by at most ``sqrt(1 + 1/margin^2) - 1`` (0.5 %), at its top edge,
    where mu is far below its peak. Roots below the band are left to the band check (moving
    a zero at the origin into the band changed the Caltech plant's scaled norm from 1.08 to
    3.3). Fits without such roots are returned unchanged.
    """
    from ..lti import zpk_statespace

    if fit.nstates == 0 or abs(float(np.asarray(fit.D)[0, 0])) < 1e-12:
        return fit
    hi = 2 * np.pi * f_hz[-1] * margin
    poles = np.linalg.eigvals(np.asarray(fit.A, dtype=float))
    zeros = np.linalg.eigvals(np.asarray(_siso_inverse(fit).A, dtype=float))
    if np.all(np.abs(poles) <= hi) and np.all(np.abs(zeros) <= hi):
        return fit
    gain = float(np.asarray(fit.D)[0, 0])
    moved = []
    for roots, sign in ((zeros, 1.0), (poles, -1.0)):
        r = roots.astype(complex)
        big = np.abs(r) > hi
        gain *= float(np.prod(np.abs(r[big]) / (hi * 0.999))) ** sign
        u = r[big] / np.abs(r[big])
        # a root of a nearly strictly proper fit (|D| ~ 1e-9) can come out in the right half
        # plane from rounding: its mirror image has the same magnitude response
        r[big] = hi * 0.999 * (-np.abs(u.real) + 1j * u.imag)
        moved.append(r)
    return zpk_statespace(moved[0], moved[1], gain)


def _scaled_bound(H: np.ndarray, blocks: BlockStructure, d: np.ndarray) -> np.ndarray:
    """``sigma_max(D_L H D_R^-1)`` per frequency for positive scales ``d`` (nf, n_blocks)."""
    dl = np.concatenate([np.repeat(d[:, [i]], b.cols, axis=1) for i, b in enumerate(blocks)], axis=1)
    dr = np.concatenate([np.repeat(d[:, [i]], b.rows, axis=1) for i, b in enumerate(blocks)], axis=1)
    return np.linalg.norm(dl[:, :, None] * H / dr[:, None, :], ord=2, axis=(1, 2))


def _edge_response(cl: Any) -> np.ndarray:
    """The closed loop ``M`` at ``w = 0`` and ``w = inf`` (its D matrix), shape (2, p, m).

    The D-scale fits are judged on the mu grid, but a fitted scale keeps changing beyond it
    when it has a root near a grid end: on the Caltech demo plant an order-2 scale with a zero
    just below the grid fell 10x from the grid's first point to DC, so that the fitted bound
    1.02 hid a scaled norm of 4.17 at DC and the next K step could not do better than 3.84
    (mu 1.006 -> 1.08). Judging the fits also at the two ends closes that gap.
    """
    from ..lti import freqresp_array

    dc = freqresp_array(cl, np.zeros(1))
    return np.concatenate([dc, np.asarray(cl.D, dtype=complex)[None]], axis=0)


def _edge_scales(fit: Any) -> np.ndarray:
    """``|d(0)|`` and ``|d(inf)|`` of a fitted SISO scale."""
    from ..lti import freqresp_array

    dc = complex(freqresp_array(fit, np.zeros(1))[0, 0, 0])
    return np.array([abs(dc), abs(float(np.asarray(fit.D)[0, 0]))])


def _fit_d_scales(
    H: np.ndarray, m: Any, blocks: BlockStructure, order_d: int | Sequence[int] | None,
    executor: Executor | None, previous: Sequence[int] = (), H_edges: np.ndarray | None = None,
    deadline: Deadline | None = None, scaled_bound: Callable | None = None,
) -> tuple[list[Any], tuple[int, ...], float]:
    """Fit each block's ``|d_i|`` (last block = 1); choose the order by the scaled bound.

    Blocks are fitted in turn (greedy, uniform log-Chebyshev fits: weighting the fit towards
    the peak of mu left the scaled bound higher off the peak, and destabilised the K step, in
    trials on the distillation example; so did fits that reproduce mu within 1 % at every
    frequency: the next K step reached 1.045 against 1.028 from the 4 %-loss fit): block ``i``
    takes the lowest order (from ORDER_D_DROP below the previous iteration's order up to
    MAX_AUTO_ORDER_D when ``order_d`` is None) whose fit, with blocks ``< i`` at their chosen
    fits and blocks ``> i`` at their optimal constant scales, keeps ``max_f sigma_max(D M
    D^-1)`` within ``ORDER_D_RTOL`` of what block ``i`` can reach (the larger of mu's peak and
    that bound with block ``i`` at its optimal scales); if none does, the one with the lowest
    bound (with ``SHORTCUT_MIN_ORDERS`` or more candidates, serially, the highest, fitted
    first so that the others need no fit when it misses too; with an executor all orders are
    fitted in parallel). When every allowed order's fit has dynamics outside the band, or the
    best bound is ``ORDER_D_BROKEN`` times above the reachable one, the lower orders are tried
    too (highest first; order 0 is always in band). With ``H_edges`` (:func:`_edge_response`)
    the bound also covers ``w = 0`` and ``w = inf``, where the optimal scales are taken as
    those at the grid's ends. Past ``deadline`` no further order is fitted once one is in
    band. Returns the fits, their orders and the joint bound with all fitted scales (an upper
    bound on the next K step's gamma).
    """
    from ..lti import freqresp_array

    deadline = deadline or Deadline(None)
    f = np.asarray(m.f_hz, dtype=float)
    d = np.asarray(m.d_scales, dtype=float)
    d = d / d[:, [-1]]
    nb = len(blocks) - 1
    if nb == 0:
        return [], (), float(np.max(m.upper))
    orders = _orders(order_d, nb)
    if order_d is None:
        orders = [[o for o in cand if o * (b.rows + b.cols) <= MAX_D_STATES_PER_BLOCK] or [0]
                  for cand, b in zip(orders, blocks)]
    if order_d is None and len(previous) == nb:
        orders = [[o for o in cand if o >= p - ORDER_D_DROP] or [max(cand)]
                  for cand, p in zip(orders, previous)]
    peak = float(np.max(m.upper))
    chosen, chosen_orders = [], []
    joint = d.copy()
    edges = d[[0, -1]].copy()  # the scales at w = 0 and inf: the grid ends' until fitted

    def bound_of(scales: np.ndarray, edge_scales: np.ndarray) -> float:
        if scaled_bound is not None:  # D-G-K: the transformed bound (scales on the grid, at the edges)
            return max(scaled_bound(scales, False), scaled_bound(edge_scales, True))
        b = float(np.max(_scaled_bound(H, blocks, scales)))
        return b if H_edges is None else max(b, float(np.max(_scaled_bound(H_edges, blocks, edge_scales))))

    def judge(i: int, o: int, fit: Any) -> tuple | None:
        """``(bound, fit, order, scales on the grid, scales at the edges)``; None out of band."""
        if not _dynamics_in_band(fit, f):
            return None
        trial, trial_edges = joint.copy(), edges.copy()
        trial[:, i] = np.abs(freqresp_array(fit, f)[:, 0, 0])
        trial_edges[:, i] = _edge_scales(fit)
        return (bound_of(trial, trial_edges), fit, o, trial[:, i], trial_edges[:, i])

    def scan(i: int, candidates: Sequence[int], acceptable: float) -> tuple | None:
        """The first candidate order (in the given sequence) whose bound is within
        ORDER_D_RTOL of mu's peak, else the one with the lowest bound; None if every fit
        has dynamics outside the band. Serially, with ``SHORTCUT_MIN_ORDERS`` or more
        candidates, the highest is tried first: when even it misses the tolerance, it is
        taken without fitting the others (on a 28-state plant with five scaled blocks two
        blocks went through all nine orders, 37 fits and 39 s of a 51 s D-K run). Past
        ``deadline`` no further order is tried once one is in band."""
        if executor is not None:
            jobs = [(f, d[:, i], o, deadline) for o in candidates]
            fitted = dict(zip(candidates, parallel_map(_fit_one, jobs, executor, progress=False)))
        else:
            fitted = {}
        if executor is None and len(candidates) >= SHORTCUT_MIN_ORDERS:
            top = max(candidates)
            fitted[top] = _fit_one((f, d[:, i], top, deadline))
            first = judge(i, top, fitted[top])
            if first is not None and first[0] > acceptable:
                return first
        best = None
        for o in candidates:
            if o not in fitted:
                fitted[o] = _fit_one((f, d[:, i], o, deadline))
            trial = judge(i, o, fitted[o])
            if trial is not None and (best is None or trial[0] < best[0]):
                best = trial
            if best is not None and (best[0] <= acceptable or deadline.expired()):
                break
        return best

    for i in range(nb):
        # what this block's fit can reach: the bound with its optimal scales (the earlier
        # blocks' fits and the edges may keep it above mu's peak whatever block i does)
        acceptable = max(peak, bound_of(joint, edges)) * (1 + ORDER_D_RTOL)
        best = scan(i, orders[i], acceptable)
        lower = list(range(min(orders[i]) - 1, -1, -1))
        if lower and (best is None or best[0] > acceptable * ORDER_D_BROKEN):
            # every allowed order had out-of-band dynamics, or a bound far above what the
            # block can reach: the lower orders too, highest first (order 0, a constant, is
            # always in band). Falling back straight to a constant raised mu from 1.20 to 1.39
            # on a random 28-state plant with five scaled blocks (an order-8 scale whose order
            # could not drop); on a random 12-state plant the only allowed order's fit rose 15x
            # beyond the grid's top (bound 3.2 at w = inf against mu 0.48) and the next K
            # step's gamma was 3.1.
            low = scan(i, lower, acceptable)
            if low is not None and (best is None or low[0] < best[0]):
                best = low
        assert best is not None
        chosen.append(best[1])
        chosen_orders.append(best[2])
        joint[:, i], edges[:, i] = best[3], best[4]
    return chosen, tuple(chosen_orders), bound_of(joint, edges)


@dataclass(frozen=True)
class _DCandidate:
    """D-scales offered to the next K step: the fits, their orders, the extrapolation step."""

    fits: tuple[Any, ...]
    orders: tuple[int, ...]
    beta: float = 0.0
    bound: float = float("nan")
    g_fits: tuple[Any, ...] = ()
    level: float = float("nan")


def _log_scales(m: Any) -> tuple[np.ndarray, np.ndarray]:
    """``(f_hz, ln d_i(f))`` of a mu result's optimal scales, relative to the last block."""
    d = np.asarray(m.d_scales, dtype=float)
    return np.asarray(m.f_hz, dtype=float), np.log(d[:, :-1] / d[:, [-1]])


def _extrapolated(m: Any, previous: tuple[np.ndarray, np.ndarray], orders: Sequence[int],
                  betas: Sequence[float], executor: Executor | None,
                  deadline: Deadline | None = None) -> list[_DCandidate]:
    """Fits of ``ln d_k + beta (ln d_k - ln d_{k-1})`` per block (the line search's candidates).

    ``previous`` is the last controller's ``(f_hz, ln d)`` (interpolated in log frequency onto
    this grid); each block keeps the order chosen for ``beta = 0``. Candidates whose fit has
    dynamics outside the band (see :func:`_dynamics_in_band`) are dropped.
    """
    f, logd = _log_scales(m)
    f_old, logd_old = previous
    old = np.stack([np.interp(np.log(f), np.log(f_old), logd_old[:, i]) for i in range(logd.shape[1])],
                   axis=1)
    steps = [b for b in betas if b != 0.0]
    deadline = deadline or Deadline(None)
    jobs = [(f, np.exp(logd[:, i] + b * (logd[:, i] - old[:, i])), o, deadline)
            for b in steps for i, o in enumerate(orders)]
    fits = list(parallel_map(_fit_one, jobs, executor, progress=False) if executor is not None
                else (_fit_one(j) for j in jobs))
    nb, out = len(orders), []
    for k, b in enumerate(steps):
        group = fits[k * nb:(k + 1) * nb]
        if all(_dynamics_in_band(g, f) for g in group):
            out.append(_DCandidate(tuple(group), tuple(orders), b))
    return out


def _dynamics_in_band(fit: Any, f_hz: np.ndarray, margin: float = 10.0) -> bool:
    """True when the fit is bi-proper and its poles and zeros lie within ``margin`` of the band.

    Poles or zeros far outside the data are extrapolation artifacts: they add nearly
    uncontrollable slow or stiff fast states to the scaled plant that spoil the K step's
    Riccati equations (a pole at 2e-5 rad/s under a 1e-3 rad/s grid broke slycot's sb10ad).
    """
    if fit.nstates == 0:
        return True
    if abs(float(np.asarray(fit.D)[0, 0])) < 1e-9:
        return False  # strictly proper: no stable inverse
    lo, hi = 2 * np.pi * f_hz[0] / margin, 2 * np.pi * f_hz[-1] * margin
    wn = np.abs(np.concatenate([np.linalg.eigvals(np.asarray(fit.A)),
                                np.linalg.eigvals(np.asarray(_siso_inverse(fit).A))]))
    return bool(np.all((wn >= lo) & (wn <= hi)))


def _orders(order_d: Any, nb: int) -> list[list[int]]:
    if order_d is None:
        return [list(range(MAX_AUTO_ORDER_D + 1))] * nb
    if np.ndim(order_d) == 0:
        return [[_check_order(order_d)]] * nb
    if len(order_d) != nb:
        raise SynthesisError(
            f"order_d needs one order per scaled block ({nb}, the last block is normalised); "
            f"got {list(order_d)}."
        )
    return [[_check_order(o)] for o in order_d]


def _check_order(o: Any) -> int:
    return integer(o, "order_d", SynthesisError, lo=0, hi=20, alternative="None for automatic")


# ---------------------------------------------------------------------------- results
@dataclass(frozen=True)
class DKIteration:
    """One D-K iteration.

    Attributes
    ----------
    index : int
        1-based iteration number.
    gamma : float
        H-infinity norm of the scaled closed loop reached by the K step.
    mu_peak : float
        Peak over frequency of the mu upper bound of the unscaled closed loop.
    f_peak_hz : float
        Frequency of that peak (Hz).
    controller_order : int
        States of the controller.
    d_orders : tuple of int
        Orders of the D-scales used in this iteration's K step (empty in the first).
    time_s : float
        Wall-clock time of the iteration (s).
    mu : MuResult
        The mu analysis of this iteration's closed loop.
    fitted_bound : float
        ``max_f sigma_max(D M D^-1)`` of this closed loop with the (``beta = 0``) fitted
        D-scales offered to the next K step: an upper bound on their gamma (NaN when no fit followed).
    d_step : float
        The line search's extrapolation step ``beta`` of the D-scales used in this K step
        (0: plain D-K; see the module docstring).
    n_candidates : int
        D-scale candidates whose K step was tried in this iteration.
    note : str
        Set when this iteration's peak of mu is above the best before it (the D fits only
        approximate the optimal scales, so D-K need not descend): the two peaks, and the
        K step's gamma when it was already above that best (the fitted scales, not the K
        step, lost the ground).
    """

    index: int
    gamma: float
    mu_peak: float
    f_peak_hz: float
    controller_order: int
    d_orders: tuple[int, ...]
    time_s: float
    mu: Any = field(repr=False)
    fitted_bound: float = float("nan")
    d_step: float = 0.0
    n_candidates: int = 1
    note: str = ""


@dataclass(frozen=True)
class Reduction:
    """A final balanced-truncation reduction of the controller, re-checked by mu.

    ``accepted`` is False (and the full controller kept) when the reduced controller does
    not stabilise the plant or raises mu by more than ``mu_rtol``. ``method`` is "balanced",
    "weighted" or "coprime" and ``error`` the truncation's error figure at ``order_after``
    (:mod:`robustctl.robust.controller_reduction`): the a-priori bound ``2 sum sigma_tail`` on
    ``||K - Kr||_inf`` (balanced), the achieved ``||(K - Kr)(I - G K)^-1 G||_inf`` (weighted;
    below 1 certifies stability), or the achieved coprime-factor error (coprime).
    """

    order_before: int
    order_after: int
    mu_peak_before: float
    mu_peak_after: float
    accepted: bool
    reason: str
    method: str = "balanced"
    error: float = float("nan")


@dataclass(frozen=True)
class DKResult:
    """The result of :func:`dksyn`.

    Attributes
    ----------
    K : control.StateSpace
        The best controller (inputs: the plant's measurements, outputs: its controls), or
        its reduction when ``reduce`` was given and accepted.
    mu_peak : float
        Peak of the mu upper bound of ``Fl(P, K)`` on the verification grid
        (:func:`verification_grid`: DC, the iteration grid made three times denser and a
        decade wider each way, and the lightly damped closed-loop poles); < 1: robust
        stability / performance certified there for the block structure (mixed mu with
        real="mixed", else real blocks complexified).
    mu : MuResult
        mu analysis of the returned controller's closed loop on the verification grid.
    closed_loop : control.StateSpace
        ``Fl(P, K)``, ``w -> z``.
    history : tuple of DKIteration
    best_iteration : int
        The iteration whose controller was kept (1-based).
    stop_reason : str
    blocks : BlockStructure
    d_scales : tuple of control.StateSpace
        The fitted D-scales used for the best controller's K step (one per block but the last).
    reduction : Reduction or None
    grid_mu_peak : float
        The returned controller's peak of mu on the iteration grid (what the iteration saw;
        ``mu_peak`` is at least this).
    stopped_by_budget : bool
        A ``time_budget_s`` ended the iteration (or a K step's bisection) early: the result
        depends on the machine's speed (:mod:`robustctl.budget`).
    """

    K: Any
    mu_peak: float
    mu: Any
    closed_loop: Any
    history: tuple[DKIteration, ...]
    best_iteration: int
    stop_reason: str
    blocks: BlockStructure
    d_scales: tuple[Any, ...] = ()
    reduction: Reduction | None = None
    grid_mu_peak: float = float("nan")
    stopped_by_budget: bool = False

    @property
    def time_s(self) -> float:
        """Total wall-clock time of the iterations (s)."""
        return float(sum(h.time_s for h in self.history))

    def table(self) -> Table:
        """One row per iteration: gamma, peak mu, controller order, D orders, line-search step, time."""
        rows = [
            (h.index, h.gamma, h.mu_peak, h.f_peak_hz, h.controller_order,
             " ".join(str(o) for o in h.d_orders) or "-", f"{h.d_step:g} of {h.n_candidates}",
             h.fitted_bound, h.time_s, "best" if h.index == self.best_iteration else "")
            for h in self.history
        ]
        cols = ("iteration", "gamma", "mu peak", "f peak (Hz)", "K order", "D orders", "D step",
                "next bound", "time (s)", "")
        return Table(cols, rows, title="D-K iteration")

    def summary(self) -> str:
        """A short account of the iteration."""
        verdict = "certified (< 1)" if self.mu_peak < 1 else "not certified (>= 1)"
        text = (
            f"D-K iteration: peak mu {self.mu_peak:.4f} {verdict} at {self.mu.f_peak_hz:.3g} Hz with a "
            f"{self.K.nstates}-state controller (iteration {self.best_iteration} of {len(self.history)}, "
            f"{self.time_s:.2f} s; stopped: {self.stop_reason})."
        )
        if self.mu_peak > self.grid_mu_peak * (1 + 1e-3):
            text += (f" Between and beyond the iteration grid's points mu reaches {self.mu_peak:.4f} "
                     f"(the grid saw {self.grid_mu_peak:.4f}).")
        if self.stopped_by_budget:
            text += (" The time budget stopped the iteration early: the result depends on the "
                     "machine's speed (time_budget_s=None for one that does not).")
        rises = [h for h in self.history if h.note]
        if rises:
            text += " " + " ".join(f"Iteration {h.index}: {h.note}." for h in rises)
        if self.reduction is not None:
            r = self.reduction
            text += (
                f" Reduction {r.order_before} -> {r.order_after} states: mu {r.mu_peak_before:.4f} -> "
                f"{r.mu_peak_after:.4f} ({'accepted' if r.accepted else 'rejected: ' + r.reason})."
            )
        return text

    def plot(self):
        """mu upper bound over frequency per iteration, and the peak of mu per iteration."""
        from ..plots import new_figure

        fig = new_figure(10.0, 4.5)
        ax1, ax2 = fig.subplots(1, 2, width_ratios=(2, 1))
        for h in self.history:
            ax1.semilogx(h.mu.f_hz, h.mu.upper, lw=2.0 if h.index == self.best_iteration else 1.0,
                         label=f"iteration {h.index}: {h.mu_peak:.3f}")
        ax1.axhline(1.0, color="k", ls=":", lw=0.8)
        ax1.set(xlabel="frequency (Hz)", ylabel="mu upper bound", title="mu of Fl(P, K) per iteration")
        ax1.legend(fontsize=8)
        it = [h.index for h in self.history]
        ax2.plot(it, [h.mu_peak for h in self.history], "o-", label="peak mu")
        ax2.plot(it, [h.gamma for h in self.history], "s--", label="gamma (scaled)")
        ax2.axhline(1.0, color="k", ls=":", lw=0.8)
        ax2.set(xlabel="iteration", title="D-K history")
        ax2.set_xticks(it)
        ax2.legend(fontsize=8)
        return fig

    def _repr_html_(self) -> str:
        import html

        return f"<p>{html.escape(self.summary())}</p>" + self.table()._repr_html_()

    def __repr__(self) -> str:
        return (f"DKResult(mu_peak={self.mu_peak:.4f}, K order={self.K.nstates}, "
                f"iterations={len(self.history)})")


# ---------------------------------------------------------------------------- the loop
def _mu_of(cl: Any, blocks: BlockStructure, f_hz: np.ndarray, refine: bool) -> tuple[Any, np.ndarray]:
    from ..lti import freqresp_array
    from .mu_bounds import mu

    f = _resonance_points(cl, f_hz) if refine else f_hz
    H = freqresp_array(cl, f)
    return mu(H, blocks, f_hz=f), H


def _check_args(max_iter: Any, time_budget_s: Any, f_hz: Any) -> np.ndarray | None:
    integer(max_iter, "max_iter", SynthesisError, lo=1, hi=100)
    as_deadline(time_budget_s, SynthesisError)  # None, seconds >= 0 or a caller's Deadline
    if f_hz is None:
        return None
    try:
        f = np.asarray(f_hz, dtype=float).ravel()
    except (TypeError, ValueError):
        f = np.full(1, np.nan)
    if f.size < 3 or not np.all(np.isfinite(f)) or np.any(f <= 0) or np.any(np.diff(f) <= 0):
        raise SynthesisError(
            "f_hz must be at least 3 positive, finite, increasing frequencies in Hz, e.g. "
            f"np.logspace(-3, 2, 200); got {f_hz!r}."
        )
    return f


def _check_options(progress: Any, rtol: Any, patience: Any, hinf_options: Any, callback: Any) -> dict:
    """The keyword options of :func:`dksyn`, checked before any work (SynthesisError naming each)."""
    if progress is not None:
        flag(progress, "progress", SynthesisError)
    positive_number(rtol, "rtol", SynthesisError)
    integer(patience, "patience", SynthesisError, lo=1)
    if callback is not None and not callable(callback):
        raise SynthesisError(f"callback must be a function of one DKIteration (or None); got {callback!r}.")
    if hinf_options is None:
        return {}
    allowed = ("method", "gamma_tol", "backoff", "time_budget_s")
    if not isinstance(hinf_options, Mapping) or not set(hinf_options) <= set(allowed):
        raise SynthesisError(
            f"hinf_options must be a dict with keys among {allowed} (rc.hinfsyn's options); "
            f"got {hinf_options!r}."
        )
    if "time_budget_s" in hinf_options:
        Deadline(hinf_options["time_budget_s"], error=SynthesisError)
    for key in ("gamma_tol", "backoff"):
        if key in hinf_options:
            positive_number(hinf_options[key], f"hinf_options[{key!r}]", SynthesisError,
                            allow_zero=key == "backoff")
    if hinf_options.get("method", "riccati") not in ("riccati", "lmi"):
        raise SynthesisError(
            f"hinf_options['method'] must be 'riccati' or 'lmi'; got {hinf_options['method']!r}."
        )
    return dict(hinf_options)


_DK_OPTIONS = ("max_iter", "order_d", "f_hz", "executor", "time_budget_s", "reduce", "rtol", "patience",
               "hinf_options", "callback", "real", "autoscale", "gamma")


def check_dk_options(options: Any, where: str) -> None:
    """Refuse, before any design, keyword options that :func:`dksyn` would refuse (all but
    ``order_d`` and ``reduce``, which need the plant): unknown names and bad values."""
    unknown = sorted(set(options) - set(_DK_OPTIONS))
    if unknown:
        raise SynthesisError(
            f"{where} got unknown D-K option(s) {unknown}; the options are {list(_DK_OPTIONS)}."
        )
    _check_args(options.get("max_iter", 10), options.get("time_budget_s"), options.get("f_hz"))
    _check_options(None, options.get("rtol", 1e-3), options.get("patience", 1), options.get("hinf_options"),
                   options.get("callback"))
    check_executor(options.get("executor"))
    if options.get("order_d") is not None:
        _orders(options["order_d"], 1 if np.ndim(options["order_d"]) == 0 else len(options["order_d"]))


def dksyn(
    gp: Any,
    max_iter: int = 10,
    order_d: int | Sequence[int] | None = None,
    f_hz: Any = None,
    executor: Executor | None = None,
    time_budget_s: float | None = None,
    reduce: int | str | tuple | None = None,
    progress: bool | None = None,
    *,
    rtol: float = 1e-3,
    patience: int = 1,
    hinf_options: dict[str, Any] | None = None,
    callback: Callable[[DKIteration], None] | None = None,
    real: str = "mixed",
    autoscale: bool = True,
    gamma: float | None = None,
) -> DKResult:
    """mu-synthesis by D-K iteration (Skogestad & Postlethwaite 2005, sec. 8.12.1).

    Parameters
    ----------
    gp : GeneralizedPlant or tuple (P, nmeas, ncon, blocks)
        The plant ``[w; u] -> [z; y]``. Its first inputs/outputs are the uncertainty and
        performance channels in block order (block ``i`` maps its ``cols_i`` z channels to
        its ``rows_i`` w channels); ``blocks`` in any form ``as_block_structure`` takes, e.g.
        mussv rows ``[[1, 1], [1, 1], [2, 2]]``; real scalar blocks ``[-r, 0]`` are real
        parameters (see ``real``).
    max_iter : int
        Iteration cap (each iteration is one K step and one mu analysis).
    order_d : int, sequence of int or None
        Order of each D-scale fit (one per block but the last); None chooses per block the
        lowest order in 0..8 that keeps the scaled bound within 5 % of what the block can
        reach, else the one with the lowest bound (never below the previous iteration's order unless those
        fits are broken or out of band; at most 24 added states per block, e.g. order 4 for
        a 3 x 3 block). From the third iteration the K step tries the fits of the
        extrapolated scales too (:data:`D_STEPS`, module docstring).
    f_hz : array_like, optional
        Analysis grid (Hz). Default: :func:`default_grid` of ``P``, refined at the lightly
        damped closed-loop poles each iteration.
    executor : concurrent.futures.Executor, optional
        Runs the D-scale fits (block x candidate order) in parallel.
    time_budget_s : float or None
        Optional wall-clock budget (s), by :mod:`robustctl.budget`'s policy. None (default):
        ``max_iter``, ``patience`` and the fits' own iteration caps bound the work, and the
        result depends only on the inputs. A number: the iteration also stops (keeping the
        best controller, ``stopped_by_budget=True``, a BudgetWarning) when what is left would
        not cover another K step as long as the last one; the K steps' gamma bisections and
        the D fits share the budget.
    reduce : int or "auto", optional
        Reduce the final controller to this many states by balanced truncation and re-check
        mu (kept only if it stabilises and raises the peak of mu by at most 2 %). ``"auto"``:
        the smallest such order, by bisection (a few more mu analyses); what a real-time
        implementation wants before :func:`~robustctl.export.export_controller`. A pair
        ``("weighted", order)`` truncates with the closed-loop weight (Enns), ``("coprime",
        order)`` the normalized coprime factors (unstable controllers too); see
        :mod:`robustctl.robust.controller_reduction`.
    progress : bool, optional
        tqdm bar over iterations (default: when stderr is a terminal).
    rtol : float
        The peak of mu must fall by this fraction to count as an improvement.
    patience : int
        Non-improving iterations tolerated before stopping. The default 1 is the D-K rule
        "repeat while the peak mu falls": on the Caltech design plant a second try after a
        worse iteration (mu 0.79 -> 0.95 -> 0.80) cost 40 % more time and never won.
    hinf_options : dict, optional
        Extra keyword arguments for :func:`~robustctl.robust.hinf_synthesis.hinfsyn` (default
        ``backoff=HINF_BACKOFF``, ``time_budget_s``: this call's budget, shared).
    callback : callable, optional
        Called with each :class:`DKIteration`.
    real : {"mixed", "complex"}
        With real blocks, ``"mixed"`` runs D-G-K iteration (Young 1996): each iteration's
        closed loop is analysed with the mixed-mu bound (D- and G-scales), the G-scales are
        fitted by stable filters and absorbed by a loop transformation
        (:mod:`robustctl.robust.dgk`), and the K step finds the smallest level its H-infinity
        synthesis certifies (``DKIteration.gamma`` is then that level, an upper bound on the
        next peak of mixed mu); ``mu_peak`` is mixed mu. ``"complex"``: real blocks are treated
        as complex ones (plain D-K; conservative).
    autoscale : bool
        Scale the plant's channels before the iteration (controls and measurements to unit
        peak gain, constant block scales balancing the closed loop; :func:`_autoscaled`), so
        that the result does not depend on the units the plant was written in. The returned
        controller, closed loop, mu and D-scales are the user's plant's; the history's
        closed loops and scales are the scaled plant's (mu is the same).
    gamma : float, optional
        A fixed design level for the D-K K steps: each H-infinity synthesis designs its
        central controller at ``gamma`` when that is above its optimum (times ``1 +
        backoff``), else at the optimum. A controller designed away from the optimum is
        better conditioned (smaller gains, no near-singular Riccati solutions) at the cost
        of a higher scaled norm. Not used by the D-G-K K step (which searches its level).

    Returns
    -------
    DKResult

    Raises
    ------
    SynthesisError
        A malformed plant or block structure, or no stabilising controller.

    Examples
    --------
    >>> dk = rc.dksyn((P, 2, 2, [[1, 1], [1, 1], [2, 2]]))   # doctest: +SKIP
    >>> dk.mu_peak, dk.table()                                # doctest: +SKIP
    """
    from tqdm import tqdm

    from .hinf_synthesis import hinfsyn

    grid = _check_args(max_iter, time_budget_s, f_hz)
    hinf_options = _check_options(progress, rtol, patience, hinf_options, callback)
    if gamma is not None:
        gamma = positive_number(gamma, "gamma", SynthesisError)
    check_executor(executor)
    plant = _as_plant(gp)
    autoscale = flag(autoscale, "autoscale", SynthesisError)
    if not isinstance(real, str) or real not in ("mixed", "complex"):
        raise SynthesisError(f"real must be 'mixed' (D-G-K with G-scales on the real blocks) or 'complex' "
                             f"(real blocks treated as complex); got {real!r}.")
    mixed = real == "mixed" and plant.blocks.has_real
    blocks = plant.blocks if mixed else _complexified(plant.blocks)
    _orders(order_d, len(blocks) - 1)  # refuse a bad order_d now, not at the first D step
    if autoscale:
        return _autoscaled_dksyn(plant, blocks, dict(
            max_iter=max_iter, order_d=order_d, f_hz=f_hz, executor=executor, time_budget_s=time_budget_s,
            progress=progress, rtol=rtol, patience=patience, hinf_options=hinf_options, callback=callback,
            real=real, gamma=gamma), reduce)
    base = default_grid(plant.P) if grid is None else grid
    show = sys.stderr.isatty() and (progress is None or bool(progress))
    own_clock = not isinstance(time_budget_s, Deadline)  # the autoscaled starts share theirs
    deadline = as_deadline(time_budget_s, SynthesisError)
    history: list[DKIteration] = []
    best: dict[str, Any] | None = None
    candidates = [_DCandidate((), ())]
    previous: tuple[np.ndarray, np.ndarray] | None = None
    stop, stale = f"max_iter={max_iter} reached", 0
    bar = tqdm(total=max_iter, desc="D-K", disable=not show, leave=False)
    try:
        for index in range(1, max_iter + 1):
            t0 = time.perf_counter()
            opts = {"time_budget_s": deadline, "backoff": HINF_BACKOFF, **(hinf_options or {})}
            try:
                hres, cand = _k_step_search(hinfsyn, plant, candidates, opts, index, deadline, gamma)
            except SynthesisError as exc:
                if best is None:
                    raise
                stop = f"K step failed at iteration {index} ({exc})"
                break
            K = hres.K
            cl = closed_loop(plant.P, K, plant.nmeas, plant.ncon)
            m, H = _mu_of(cl, blocks, base, refine=grid is None)
            entry = DKIteration(index, float(hres.gamma), float(m.peak), float(m.f_peak_hz), K.nstates,
                                cand.orders, 0.0, m, d_step=cand.beta, n_candidates=len(candidates))
            improved = best is None or entry.mu_peak < best["it"].mu_peak * (1 - rtol)
            if best is not None and entry.mu_peak > best["it"].mu_peak:
                prev = best["it"]
                why = (f"the K step's gamma {entry.gamma:.4f} on the fitted D-scales was already above "
                       f"it; their bound on the previous loop was {history[-1].fitted_bound:.4f}"
                       if entry.gamma > prev.mu_peak and not mixed else "")
                entry = DKIteration(**{**entry.__dict__, "note": (
                    f"peak mu {entry.mu_peak:.4f} rose above iteration {prev.index}'s {prev.mu_peak:.4f}"
                    + (f" ({why})" if why else ""))})
            if best is None or entry.mu_peak < best["it"].mu_peak:
                best = {"it": entry, "K": K, "cl": cl, "d": cand.fits}
            if hres.info.get("stopped_by_budget"):
                extra = "the K step's gamma bisection was stopped by the time budget"
                entry = DKIteration(**{**entry.__dict__,
                                       "note": f"{entry.note}; {extra}" if entry.note else extra})
            stale = 0 if improved else stale + 1
            # the next iteration needs at least this one's K step and mu analysis: a K step
            # started with too little time left stops its gamma bisection early (gamma 7.3
            # where 1.2 was reachable, on a 28-state plant with five scaled blocks)
            k_time = time.perf_counter() - t0
            out_of_time = deadline.expired() or deadline.remaining() < k_time
            done = stale >= patience or index == max_iter or out_of_time
            bound = float("nan")
            if not done:
                g_fits, level, md, zb = (), float("nan"), m, None
                H_edges = _edge_response(cl)
                if mixed:
                    g_fits, level, md, zb = _g_step(m, H, H_edges, blocks)
                fits, orders, bound = _fit_d_scales(H, md, blocks, order_d, executor, cand.orders,
                                                    H_edges, deadline, zb)
                candidates = [_DCandidate(tuple(fits), orders, 0.0, bound, g_fits, level)]
                if previous is not None and fits:
                    candidates += [replace(c, g_fits=g_fits, level=level) for c in
                                   _extrapolated(md, previous, orders, D_STEPS, executor, deadline)]
                previous = _log_scales(md)
            elapsed = time.perf_counter() - t0
            entry = DKIteration(**{**entry.__dict__, "time_s": elapsed, "fitted_bound": bound})
            history.append(entry)
            if best["it"].index == index:
                best["it"] = entry
            if callback is not None:
                callback(entry)
            bar.update(1)
            bar.set_postfix(mu=f"{entry.mu_peak:.4f}")
            if stale >= patience:
                stop = f"peak mu did not fall by {rtol:g} for {stale} iteration(s)"
                if entry.mu_peak > best["it"].mu_peak:
                    kept = best["it"]
                    stop += f"; iteration {kept.index}'s controller (mu {kept.mu_peak:.4f}) is kept"
                break
            if (out_of_time or deadline.expired() or deadline.remaining() < k_time) and index < max_iter:
                deadline.hit = True
                stop = (f"time budget {deadline.budget_s:g} s: too little left for another iteration "
                        f"(this one's K step and mu analysis took {k_time:.1f} s)")
                break
    finally:
        bar.close()
    assert best is not None
    K, cl, m = best["K"], best["cl"], best["it"].mu
    reduction = None
    if reduce is not None:
        K, cl, m, reduction = _reduce(plant, blocks, K, cl, m, reduce, base, grid is None)
    grid_peak = float(m.peak)
    m = _verified_mu(cl, blocks, m.f_hz)
    d_fits = best["d"]
    if m.peak > grid_peak * (1 + VERIFY_WARN_RTOL):
        import warnings

        warnings.warn(
            f"dksyn: the returned controller's peak of mu is {m.peak:.4g} at {m.f_peak_hz:.3g} Hz on the "
            f"verification grid, but {grid_peak:.4g} on the iteration grid, which misses the peak: the "
            "iterations were judged on too coarse a grid (pass a denser f_hz, or leave it to the default).",
            RuntimeWarning, stacklevel=2,
        )
    stopped = deadline.hit  # shared with the K steps' bisections and the D fits
    if stopped and own_clock:
        deadline.warn("dksyn (D-K iteration)")
    return DKResult(K=K, mu_peak=float(m.peak), mu=m, closed_loop=cl, history=tuple(history),
                    best_iteration=best["it"].index, stop_reason=stop, blocks=plant.blocks,
                    d_scales=d_fits, reduction=reduction, grid_mu_peak=grid_peak,
                    stopped_by_budget=stopped)


def _autoscaled_dksyn(plant: GeneralizedPlant, blocks: BlockStructure, options: dict,
                      reduce: Any) -> DKResult:
    """D-K on the automatically scaled plant (:func:`_autoscaled`) from :data:`AUTOSCALE_STARTS`
    (factors ``e^s`` on all block scales but the last; a further start only while the best
    verified peak of mu is not below :data:`AUTOSCALE_CERTIFIED`): the run with the lowest
    verified peak is kept (then reduced, when asked), and its controller, closed loop, mu and
    D-scales are returned for the user's plant.

    D-K is a local method: on the distillation column the final mu depends on the constant
    block scale it starts from (0.97 from 0.3 times the book's, 1.00 from the book's own, 1.10
    from 1.3 times, the scale whose first K step is best), so starting from several covariant
    points makes the result both independent of the user's units and less a matter of luck.
    """
    from dataclasses import replace as _replace

    import control

    scaled, sc = _autoscaled(plant, options.get("hinf_options"))
    deadline = as_deadline(options["time_budget_s"], SynthesisError)  # shared by the starts
    best = None
    for s in AUTOSCALE_STARTS:
        if best is not None and (deadline.expired() or best[0].mu_peak < AUTOSCALE_CERTIFIED):
            break
        factor = np.exp(np.append(np.full(len(sc.d) - 1, s), 0.0))
        sc_k = _Scaling(sc.su, sc.sy, sc.d * factor)
        P_k = _constant_scaled(plant, sc.su, sc.sy, sc_k.d)
        res = dksyn((P_k, plant.nmeas, plant.ncon, plant.blocks),
                    **{**options, "time_budget_s": deadline}, autoscale=False)
        if best is None or res.mu_peak < best[0].mu_peak:
            best = (res, sc_k, P_k)
    res, sc_k, P_k = best
    K, cl, m, reduction = res.K, res.closed_loop, res.mu, None
    if reduce is not None:
        refine = options.get("f_hz") is None
        base = default_grid(P_k) if refine else np.asarray(options["f_hz"], dtype=float)
        pk = GeneralizedPlant(P_k, plant.nmeas, plant.ncon, blocks=plant.blocks)
        K, cl, m, reduction = _reduce(pk, blocks, K, cl, m, reduce, base, refine)
        if reduction.accepted:
            m = _verified_mu(cl, blocks, m.f_hz)
    K = _unscaled_controller(K, sc_k)
    cl = closed_loop(plant.P, K, plant.nmeas, plant.ncon)
    d_fits = tuple(control.ss(f.A, f.B, f.C * float(di), f.D * float(di))
                   for f, di in zip(res.d_scales, sc_k.d))
    if deadline.hit:
        deadline.warn("dksyn (D-K iteration from the autoscaled starts)")
    return _replace(res, K=K, closed_loop=cl, mu=_unscaled_mu(m, sc_k), mu_peak=float(m.peak),
                    d_scales=d_fits, reduction=reduction, stopped_by_budget=deadline.hit)


def _g_step(m: Any, H: np.ndarray, H_edges: np.ndarray,
            blocks: BlockStructure) -> tuple[tuple[Any, ...], float, Any, Callable]:
    """The G part of a D-G-K step (:mod:`robustctl.robust.dgk`).

    At the level ``beta`` = the peak of mu on the grid: the scales closest to the complex
    analysis' that keep the mixed bound (:func:`~robustctl.robust.dgk.blended_scales`), one
    stable filter ``r_i(s)`` per real block fitted to their G-scales, the MuResult with the
    D-scales ``d_i / sqrt(1 - |r_i|^2)`` that keep their ``X`` (what the D fits follow), and
    the bound the D fits are judged by: ``beta sigma_max(Z)`` with the fitted filters
    (:func:`~robustctl.robust.dgk.transformed_norm`), on the grid and at ``w = 0, inf``.
    """
    from ..lti import freqresp_array
    from .dgk import blended_scales, fit_g_filter, scaled_d_targets, transformed_norm
    from .mu_bounds import mu

    level = float(m.peak)
    f = np.asarray(m.f_hz, dtype=float)
    mc = mu(H, _complexified(blocks), f_hz=f, lower=False)
    d, gam = blended_scales(H, m, mc, blocks, level)
    fits = tuple(fit_g_filter(f, gam[:, k], np.ones(f.size)) for k in range(gam.shape[1]))
    r_grid = np.stack([freqresp_array(r, f)[:, 0, 0] for r in fits], axis=1)
    r_edges = np.stack([np.array([freqresp_array(r, np.zeros(1))[0, 0, 0], complex(np.asarray(r.D)[0, 0])])
                        for r in fits], axis=1)
    md = replace(m, d_scales=scaled_d_targets(d, blocks, np.abs(r_grid)))

    def zbound(scales: np.ndarray, edges: bool) -> float:
        Hx, rx = (H_edges, r_edges) if edges else (H, r_grid)
        return level * float(np.max(transformed_norm(Hx, blocks, scales, rx, level)))

    return fits, level, md, zbound


def _k_step_search(hinfsyn: Callable, plant: GeneralizedPlant, candidates: Sequence[_DCandidate], opts: dict,
                   index: int, deadline: Deadline | None = None,
                   gamma: float | None = None) -> tuple[Any, _DCandidate]:
    """The K step for each D-scale candidate; the lowest verified gamma wins (the line search).

    A candidate whose K step fails is skipped; when all fail, the first failure is raised.
    Past ``deadline`` no further candidate is tried once one has succeeded.
    """

    best, first_error = None, None
    for cand in candidates:
        if best is not None and deadline is not None and deadline.expired():
            break
        P_scaled = _scale_plant(plant, cand.fits)
        try:
            if cand.g_fits:
                hres = _mixed_k_step(hinfsyn, P_scaled, plant, cand, opts, index)
            else:
                scaled = PartitionedPlant(P_scaled, plant.nmeas, plant.ncon)
                hres = _k_step(hinfsyn, scaled, plant, opts, index, gamma)
        except SynthesisError as exc:
            first_error = first_error or exc
            continue
        if best is None or hres.gamma < best[0].gamma:
            best = (hres, cand)
    if best is None:
        assert first_error is not None
        raise first_error
    return best


def _mixed_k_step(hinfsyn: Callable, P_scaled: Any, plant: GeneralizedPlant, cand: _DCandidate, opts: dict,
                  index: int) -> Any:
    """The D-G-K K step: the smallest level ``beta`` at which ``min_K ||Z_beta||_inf <= 1``.

    ``Z_beta = Fl(Theta * (D P D^-1 / beta), K)`` (:func:`~robustctl.robust.dgk.g_transform`)
    with the fitted D-scales and G filters kept: every stable ``|r| < 1`` gives a valid
    multiplier at every level, so ``||Z_beta|| <= 1`` certifies ``mu <= beta`` whatever the
    level the filters were fitted at. ``beta`` is not a factor of ``Z`` (the transformation is
    not homogeneous), so the H-infinity synthesis is repeated: from the analysis' level
    ``beta_0``, the next guess is ``beta_0 gamma_0`` (as if it were), then secant steps on
    ``ln gamma`` against ``ln beta`` (:data:`MIXED_K_EVALS` syntheses at most). Returns the
    design at the smallest level with ``gamma <= 1``, its ``gamma`` replaced by that level (an
    upper bound on the new peak of mixed mu), or the one with the smallest ``beta gamma``.
    """
    from dataclasses import replace as _replace

    from .dgk import g_transform

    def solve(level: float) -> Any:
        scaled = PartitionedPlant(g_transform(P_scaled, plant.blocks, cand.g_fits, level), plant.nmeas,
                                  plant.ncon)
        return _k_step(hinfsyn, scaled, plant, opts, index)

    pts: list[tuple[float, Any]] = []
    x = float(np.log(cand.level))
    for _ in range(MIXED_K_EVALS):
        try:
            h = solve(float(np.exp(x)))
        except SynthesisError:
            if not pts:
                raise
            break
        pts.append((x, h))
        ys = [(px, float(np.log(ph.gamma))) for px, ph in pts]
        if abs(ys[-1][1]) < MIXED_K_TOL:
            break
        feas = [px for px, y in ys if y <= 0]
        infeas = [px for px, y in ys if y > 0]
        if len(ys) == 1:
            x = ys[0][0] + ys[0][1]
        else:
            (x0, y0), (x1, y1) = ys[-2], ys[-1]
            x = x1 - y1 * (x1 - x0) / (y1 - y0) if y1 != y0 else x1 + y1
        if feas and infeas:  # keep the guess inside the bracket
            lo, hi = max(infeas), min(feas)
            if not lo < x < hi:
                x = 0.5 * (lo + hi)
    feasible = [(px, ph) for px, ph in pts if ph.gamma <= 1.0 + 1e-9]
    if feasible:
        px, ph = min(feasible, key=lambda t: t[0])
        level = float(np.exp(px))
    else:
        px, ph = min(pts, key=lambda t: t[0] + np.log(t[1].gamma))
        level = float(np.exp(px)) * ph.gamma
    return _replace(ph, gamma=level, info={**ph.info, "mixed_level": float(np.exp(px)),
                                           "scaled_gamma": ph.gamma, "level_evals": len(pts)})


def _k_step(hinfsyn: Callable, scaled: Any, plant: GeneralizedPlant, opts: dict, index: int,
            gamma: float | None = None) -> Any:
    """One H-infinity synthesis on the scaled plant; refuses a controller that does not stabilise P."""
    hres = hinfsyn(scaled, **opts)
    if gamma is not None and gamma > hres.info.get("gamma_design", hres.gamma):
        # a fixed design level above the optimum: the central controller at that gamma
        hres = hinfsyn(scaled, **{**opts, "backoff": gamma / hres.gamma_opt - 1.0})
    if not is_stable(closed_loop(plant.P, hres.K, plant.nmeas, plant.ncon), margin=0.0):
        raise SynthesisError(
            f"the K step of iteration {index} returned a controller that does not stabilise the plant; "
            "check that (A, B2) is stabilisable and (C2, A) detectable."
        )
    return hres


def _reduce(plant: GeneralizedPlant, blocks: BlockStructure, K: Any, cl: Any, m: Any, order: Any,
            base: np.ndarray, refine: bool, mu_rtol: float = REDUCE_MU_RTOL):
    """Balanced truncation of the controller (Moore 1981; seed eq. 13), re-checked by mu.

    ``order="auto"``: the smallest order whose truncation stabilises the loop and keeps the
    peak of mu within ``mu_rtol`` of the full controller's, found by bisection over the
    orders below the controller's numerically minimal order (Hankel singular values above
    ``HSV_RTOL`` of the largest); at most ``ceil(log2 n) + 1`` mu analyses.
    """
    from ..balanced import balanced_truncation

    method = "balanced"
    if isinstance(order, tuple) and len(order) == 2 and order[0] in ("weighted", "coprime"):
        method, order = order  # controller_reduction.py: closed-loop weighted or coprime-factor truncation
    auto = isinstance(order, str) and order == "auto"
    if not auto:
        integer(order, "reduce (the number of controller states)", SynthesisError, lo=1,
                alternative="'auto', or a pair ('weighted' or 'coprime', that)")
    n = K.nstates
    if not auto and order >= n:
        return K, cl, m, Reduction(n, n, m.peak, m.peak, False, f"the controller has only {n} states")
    if method != "coprime" and not is_stable(K, margin=0.0):
        return K, cl, m, Reduction(n, n if auto else order, m.peak, np.inf, False,
                                   "the controller is unstable (balanced truncation needs a stable one; "
                                   "use reduce=('coprime', order))")
    errors: dict[int, float] = {}
    if method == "balanced":
        hsv, reduce_to = None, balanced_truncation
    else:
        from .controller_reduction import reducer

        try:
            hsv, reduce_to = reducer(K, PartitionedPlant(plant.P, plant.nmeas, plant.ncon), method)
        except SynthesisError as exc:
            return K, cl, m, Reduction(n, n if auto else order, m.peak, np.inf, False, str(exc), method)

    def truncate(r: int) -> Any:
        red = reduce_to(K, r) if method == "balanced" else reduce_to(r)
        errors[r] = float(red.bound if method == "balanced" else red.error)
        return red.sys if method == "balanced" else red.K

    tried: dict[int, tuple] = {}

    def attempt(r: int) -> tuple:
        if r not in tried:
            try:
                tried[r] = _truncated_loop(plant, blocks, K, truncate(r), m, base, refine, mu_rtol)
            except SynthesisError as exc:
                tried[r] = (K, None, None, str(exc))
        return tried[r]

    if not auto:
        Kr, clr, mr, reason = attempt(int(order))
        err = errors.get(int(order), float("nan"))
        if reason:
            return K, cl, m, Reduction(n, order, m.peak, mr.peak if mr is not None else np.inf, False, reason,
                                       method, err)
        return Kr, clr, mr, Reduction(n, order, m.peak, mr.peak, True, "", method, err)
    r = _auto_order(balanced_truncation(K, 1).hsv if hsv is None else hsv, attempt)
    if r is None:
        return K, cl, m, Reduction(n, n, m.peak, m.peak, False, "no truncation kept mu within "
                                   f"{100 * mu_rtol:g} % of the full controller's", method)
    Kr, clr, mr, _ = attempt(r)
    return Kr, clr, mr, Reduction(n, r, m.peak, mr.peak, True, "", method, errors.get(r, float("nan")))


def _auto_order(hsv: np.ndarray, attempt: Callable[[int], tuple]) -> int | None:
    """Smallest order ``r`` with ``attempt(r)`` accepted, by bisection on ``[1, r_min]``, where
    ``r_min`` counts the Hankel singular values above ``HSV_RTOL`` of the largest; orders that
    would split (nearly) equal singular values move up by one. None when no order below the
    controller's own passes."""
    n = hsv.size
    r_min = int(np.count_nonzero(hsv > HSV_RTOL * hsv[0]))
    hi = n if r_min == n or attempt(r_min)[3] else r_min  # attempt(hi) succeeds (hi = n: K itself)
    lo = 0  # attempt(lo) fails (lo = 0: no controller)
    while hi - lo > 1:
        mid = (lo + hi) // 2
        while mid < hi and hsv[mid - 1] <= hsv[mid] * (1 + 1e-6):  # do not split a pair
            mid += 1
        if mid >= hi:
            break
        if attempt(mid)[3]:
            lo = mid
        else:
            hi = mid
    return hi if hi < n else None


def _truncated_loop(plant: GeneralizedPlant, blocks: BlockStructure, K: Any, reduced: Any, m: Any,
                    base: np.ndarray,
                    refine: bool, mu_rtol: float) -> tuple:
    """``(Kr, closed loop, mu, reason)`` of a truncated controller; ``reason`` is empty when it
    stabilises the plant and raises the peak of mu by at most ``mu_rtol``."""
    import control

    Kr = control.ss(reduced.A, reduced.B, reduced.C, reduced.D, inputs=list(K.input_labels),
                    outputs=list(K.output_labels))
    clr = closed_loop(plant.P, Kr, plant.nmeas, plant.ncon)
    if not is_stable(clr, margin=0.0):
        return Kr, clr, None, "the reduced loop is unstable"
    mr, _ = _mu_of(clr, blocks, base, refine)
    if mr.peak > m.peak * (1 + mu_rtol):
        return Kr, clr, mr, f"peak mu rose by more than {100 * mu_rtol:g} %"
    return Kr, clr, mr, ""
