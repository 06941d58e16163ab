"""D-scale fitting of D-K iteration: scaling the plant by fitted D(s), the fits' orders,
band checks and fallbacks, the constant autoscaling of a plant."""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from concurrent.futures import Executor
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from ...budget import Deadline
from ...checks import integer
from ...errors import SynthesisError
from ...executors import parallel_map
from ...interconnect import PartitionedPlant
from ...lti import freqresp_array, zpk_statespace
from ..hinf.synthesis import hinfsyn
from ..plant import GeneralizedPlant
from ..uncertainty.blocks import BlockStructure
from ..uncertainty.magfit import fit_magnitude
from .verify import default_grid

#: Highest D-scale order tried when ``order_d`` is None.
MAX_AUTO_ORDER_D = 8
#: The K step designs at gamma_opt (1 + HINF_BACKOFF): a 1 % back-off would cost 1 % of mu per iteration.
HINF_BACKOFF = 1e-3
#: Most states one block's D-scale may add to the scaled plant (order x (rows + cols)).
MAX_D_STATES_PER_BLOCK = 24
#: Target accuracy of each D fit (dB), passed to fit_magnitude: its least-squares fit lies
#: within this (plus a tenth) of the optimal max error. 0.1 dB, with the least-squares fits,
#: left D-K on the D12 = 0 plant of bench_dk at mu 0.867 (0.345 at 0.02 dB) and mu-tools' HIMAT
#: at 0.983 (0.974).
FIT_TOL_DB = 0.02
#: With a float ``rho``, each D fit is the analytic centre of the fits within ``(1 + rho)``
#: times the bisection's level (fit_magnitude's ``centre``). None (the default): fit_magnitude's
#: own fit, the least-squares fit within the bisection's level (unique, moved by rounding of the
#: optimal scales in proportion, as the centre; its max error within the bisection's
#: tolerance). The centre's max error sits at its level, ~5 % above the LP's, and D-K on the
#: distillation column reached 1.0285 (automatic orders) against 0.9996 with the LP's fits.
FIT_CENTRE: float | None = None
#: Orders the automatic choice may drop below the previous iteration's (0: an order once
#: needed is kept).
ORDER_D_DROP = 0
#: Accept the lowest D order whose scaled bound peak is within this fraction of mu's peak
#: (loose on purpose: a tight tolerance picks high orders that stall D-K).
ORDER_D_RTOL = 0.05
#: Serially, a block with at least this many candidate D orders fits the highest first and
#: keeps it without fitting the others when even it misses ORDER_D_RTOL; fewer candidates are
#: scanned upwards (smaller controllers, less time).
SHORTCUT_MIN_ORDERS = 6
#: A block's best bound this factor above what it can reach (times 1 + ORDER_D_RTOL) counts as a
#: broken fit: the orders below the previous iteration's are tried too.
ORDER_D_BROKEN = 1.25
#: H-infinity syntheses the automatic scaling may spend on its constant block scales.
AUTOSCALE_EVALS = 60
#: Nelder-Mead stops when the simplex's ln gamma agree within this (its points within 0.05 in ln d).
AUTOSCALE_FATOL = 1e-3
#: ln of the common block-scale factors the search scans before its Nelder-Mead refinement.
AUTOSCALE_SCAN = (-6.0, -4.5, -3.0, -1.5, 0.0, 1.5, 3.0, 4.5, 6.0)
#: Most scaled blocks (all but the last) for which that search runs (else the covariant start).
AUTOSCALE_MAX_BLOCKS = 6
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
                       options={"initial_simplex": simplex, "xatol": 0.05, "fatol": AUTOSCALE_FATOL,
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


def _fit_one(args: tuple) -> Any:
    """One D-scale fit (module level so a process executor can pickle it)."""
    f_hz, mag, order, deadline = args
    return _into_band(fit_magnitude(f_hz, mag, order, tol_db=FIT_TOL_DB, time_budget_s=deadline,
                                    centre=FIT_CENTRE), f_hz)


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
    dc = freqresp_array(cl, np.zeros(1))
    return np.concatenate([dc, np.asarray(cl.D, dtype=complex)[None]], axis=0)


def _edge_scales(fit: Any) -> np.ndarray:
    """``|d(0)|`` and ``|d(inf)|`` of a fitted SISO scale."""
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
