"""The screening and fitting engine of ``rc.diagnose``: secant screening of the candidates in the
complement of the update parameters' sensitivities, size probes, local and polishing fits, the
null fit of the update parameters alone."""

from __future__ import annotations

import copy
import math
from concurrent.futures import Executor
from dataclasses import dataclass
from typing import Any

import numpy as np

from ...budget import Deadline
from ...errors import RobustctlError
from ...executors import parallel_map_shared
from ...physical.reduction import point_change, point_modal
from ..optimize import levenberg_marquardt, marquardt_step, parameter_bounds
from ..residual import CheckedData, Residual, sensitivities
from ..updating import coarse_start
from .results import MODEL_ERROR_DISPERSION
from .significance import _is_switch
from .workers import _check_budget


# ============================================================================ helpers
def _residual_for(base: Residual, model: Any) -> Residual:
    """The same data, band and weights with another model (channels are unchanged)."""
    res = copy.copy(base)
    res.model = model
    return res


def _orthonormal(J: np.ndarray) -> np.ndarray:
    if J.size == 0 or J.shape[1] == 0:
        return np.zeros((J.shape[0], 0))
    norms = np.linalg.norm(J, axis=0)
    Jn = J[:, norms > 0] / norms[norms > 0]
    if Jn.shape[1] == 0:
        return np.zeros((J.shape[0], 0))
    U, s, _ = np.linalg.svd(Jn, full_matrices=False)
    return U[:, s > 1e-8 * s[0]]


def _project(Q: np.ndarray, x: np.ndarray) -> np.ndarray:
    return x - Q @ (Q.T @ x) if Q.shape[1] else x


#: Peaks of the misfit at which an effect with a second value to choose (``Effect.retune``: an attached
#: resonator's frequency) is screened, the largest first; each is then refined by :data:`RETUNE_STEPS`.
RETUNE_PEAKS = 4
#: Relative offsets around the best peak tried to refine a retuned effect's value (the peak of the
#: misfit sits within a few half-power bandwidths of the mode it lacks).
RETUNE_STEPS = (-0.04, -0.015, 0.015, 0.04)
#: Candidates with a retuned value are first screened at the misfit's largest peak only; this many
#: of the best (by the share explained there) are then screened at every peak and refined.
RETUNE_TOP = 3


def _misfit_peaks(res_u: Residual, r_perp: np.ndarray, n: int) -> list[float]:
    """The ``n`` largest local maxima (Hz) of the misfit left by updating, summed over the channels
    (smoothed over three bins), at least 5 % apart."""
    e = res_u.unstack(r_perp)
    power = np.sum(np.abs(e) ** 2, axis=tuple(range(1, e.ndim)))
    if power.size < 3:
        return []
    smooth = np.convolve(power, np.ones(3) / 3.0, mode="same")
    inner = np.flatnonzero((smooth[1:-1] >= smooth[:-2]) & (smooth[1:-1] > smooth[2:])) + 1
    f = np.asarray(res_u.f_hz, dtype=float)
    found: list[float] = []
    for k in inner[np.argsort(-smooth[inner], kind="stable")]:
        if all(abs(f[k] / g - 1.0) >= 0.05 for g in found):
            found.append(float(f[k]))
        if len(found) == n:
            break
    return found


def _screen_retuned(
    res_u: Residual, model_u: Any, j_u: np.ndarray, Q: np.ndarray, r_perp: np.ndarray, effect: Any
) -> dict[str, Any]:
    """Screen an effect whose second value first order cannot see (``Effect.retune``: a resonator's
    frequency) at its own value and at the :data:`RETUNE_PEAKS` largest peaks of the misfit, then
    around the best by :data:`RETUNE_STEPS`; the screen of the best, with that effect."""
    tried: dict[float, dict] = {}

    def at(value: float) -> dict:
        key = float(f"{value:.6g}")
        if key not in tried:
            tried[key] = _screen_one(res_u, model_u, j_u, Q, r_perp, effect.retuned(key), retune=False)
            tried[key].pop("model", None)
        return tried[key]

    current = float(getattr(effect, effect.retune))
    for value in [current, *_misfit_peaks(res_u, r_perp, RETUNE_PEAKS)]:
        at(value)
    best_key = max(tried, key=lambda k: (tried[k]["fraction"], -k))
    for step in RETUNE_STEPS:
        at(best_key * (1.0 + step))
    best = max(tried.values(), key=lambda sc: (sc["fraction"], -float(getattr(sc["effect"], effect.retune))))
    return dict(best, evals=sum(sc["evals"] for sc in tried.values()))


def _screen_one(
    res_u: Residual, model_u: Any, j_u: np.ndarray, Q: np.ndarray, r_perp: np.ndarray, effect: Any,
    retune: Any = "peak", probe: bool = True,
) -> dict[str, Any]:
    """Secant of one candidate from neutral to its typical size, projected (step 2). An effect with
    a value to retune (``Effect.retune``) is screened at the misfit's largest peak (``retune="peak"``:
    the first pass over them all), or at every peak and around
    the best (``"all"``: :func:`_screen_retuned`); ``retune=False`` screens it as it is. ``probe``:
    walk out to larger sizes (:func:`_probe_sizes`) when the secant asks for more."""
    if retune and getattr(effect, "retune", None) is not None and not _is_switch(effect):
        if retune == "all":
            return _screen_retuned(res_u, model_u, j_u, Q, r_perp, effect)
        peaks = _misfit_peaks(res_u, r_perp, 1)
        if peaks:
            return _screen_one(res_u, model_u, j_u, Q, r_perp, effect.retuned(peaks[0]), retune=False)
    neutral = effect.with_values(**effect.neutral_values)
    m_c = neutral.apply(model_u)
    res_c = _residual_for(res_u, m_c)
    if _is_switch(effect) and not effect.toggle:
        return _screen_switch(res_c, m_c, j_u, Q, r_perp, effect)
    pname = effect.param_names[0]
    lo, hi = effect.parameters[0].bounds
    step = effect.typical_size
    v0 = effect.parameters[0].neutral
    trial = v0 + step if v0 + step <= hi else v0 - step
    try:
        sens = sensitivities(res_c, [pname], at={pname: trial}, origin={pname: v0}, j0=j_u)
    except RobustctlError as exc:  # e.g. the gravity preload does not converge with the effect
        return dict(
            effect=effect,
            model=m_c,
            fraction=0.0,
            angle=90.0,
            value=v0,
            d=np.zeros_like(j_u),
            evals=1,
            error=str(exc),
        )
    d = sens.dJ[:, 0]
    d_perp = _project(Q, d)
    dd, rr = float(d_perp @ d_perp), float(r_perp @ r_perp)
    if dd <= 0 or rr <= 0:
        return dict(effect=effect, model=m_c, fraction=0.0, angle=90.0, value=v0, d=d, evals=sens.n_evals)
    coef = -float(d_perp @ r_perp) / dd  # in units of the secant (trial - v0)
    cos2 = float(d_perp @ r_perp) ** 2 / (dd * rr)
    value = v0 + coef * (trial - v0)
    clipped = min(max(value, lo), hi)
    if effect.toggle:
        clipped = hi if coef > 0.5 else lo
    c_clip = (clipped - v0) / (trial - v0)
    left = r_perp + d_perp * c_clip
    fraction = max(0.0, 1.0 - float(left @ left) / rr)
    angle = math.degrees(math.acos(min(1.0, math.sqrt(cos2))))
    evals = sens.n_evals
    if probe and coef < 0 and getattr(effect, "sweep", None) == "group" and clipped != v0:
        # an element group's secant taken the other way than the data ask (a seam softer than
        # modelled, the step calibrated stiffer): the change moves the modes it strains by bandwidths
        # and the secant's linear share across neutral is no guide, nor is its estimate's size (at
        # 20,000 DOFs a seam at 40 % was estimated at 5 %: a share of 0.25 there, 0.89 at its 40 %)
        share, v_share, n_s = _group_sizes(res_c, pname, v0, clipped, Q, rr)
        evals += n_s
        if share > fraction:
            fraction = share
            if v_share != v0:
                clipped = v_share
    if probe and not effect.toggle and abs(coef) > PROBE_MIN_COEF:  # a switch has no sizes to probe
        probed, value_p, n_p = _probe_sizes(res_c, pname, (v0, lo, hi), trial - v0, coef, Q, rr, fraction)
        evals += n_p
        if probed > fraction:
            fraction, clipped = probed, value_p
    if getattr(effect, "coarse_screen", False):
        coarse, value_c, n_c = _coarse_sizes(res_c, pname, (v0, lo, hi), step, Q, rr)
        evals += n_c
        if coarse > fraction:
            fraction, clipped = coarse, value_c
    return dict(effect=effect, model=m_c, fraction=fraction, angle=angle, value=clipped, d=d, evals=evals)


#: Fractions of the way from neutral to a group's secant estimate at which :func:`_group_sizes`
#: evaluates its share, then refined twice by halving the spacing around the best.
GROUP_FRACTIONS = (0.25, 0.5, 0.75, 1.0)
GROUP_REFINE = 2


def _group_sizes(res_c: Residual, pname: str, v0: float, estimate: float, Q: np.ndarray,
                 rr: float) -> tuple[float, float, int]:
    """The best share ``1 - |P j(v)|^2 / |P j_u|^2`` (update parameters re-fitted linearly, as
    :func:`_probe_sizes`) at :data:`GROUP_FRACTIONS` of the way from ``v0`` to ``estimate``, refined
    :data:`GROUP_REFINE` times around the best by halving the spacing: ``(share, value,
    evaluations)``, the share 0 and the value ``v0`` when nothing could be evaluated."""
    seen: dict[float, float] = {}

    def share_at(t: float) -> None:
        t = float(min(max(t, 0.0), 1.0))
        if t == 0.0 or t in seen:
            return
        try:
            j = res_c.vector(**{pname: v0 + t * (estimate - v0)})
        except RobustctlError:
            seen[t] = -np.inf
            return
        seen[t] = 1.0 - float(np.sum(_project(Q, j) ** 2)) / rr if np.all(np.isfinite(j)) else -np.inf

    for t in GROUP_FRACTIONS:
        share_at(t)
    spacing = GROUP_FRACTIONS[1] - GROUP_FRACTIONS[0]
    for _ in range(GROUP_REFINE):
        spacing /= 2.0
        best_t = max(seen, key=lambda t: (seen[t], -t))
        share_at(best_t - spacing)
        share_at(best_t + spacing)
    best_t = max(seen, key=lambda t: (seen[t], -t))
    if not np.isfinite(seen[best_t]):
        return 0.0, v0, len(seen)
    return max(seen[best_t], 0.0), v0 + best_t * (estimate - v0), len(seen)


def _screen_switch(
    res_c: Residual, m_c: Any, j_u: np.ndarray, Q: np.ndarray, r_perp: np.ndarray, effect: Any
) -> dict[str, Any]:
    """Screen a switched effect (a test-setup error: swapped cables, a sign flip, a units slip, a
    sensor on another node) at each of its states (``effect.states``): the share of the residual
    left by updating that the state removes once the update parameters are re-fitted linearly,
    ``1 - |P j(state)|^2 / |P j_u|^2``; the best state is kept. ``d`` is its change ``j - j_u``."""
    pname = effect.param_names[0]
    v0 = float(effect.parameters[0].neutral)
    rr = float(r_perp @ r_perp)
    best = dict(effect=effect, model=m_c, fraction=0.0, angle=90.0, value=v0, d=np.zeros_like(j_u), evals=0)
    for v in _likely_states(res_c, j_u, effect):
        best["evals"] += 1
        try:
            j = res_c.vector(**{pname: float(v)})
        except RobustctlError:
            continue
        if not np.all(np.isfinite(j)) or rr <= 0:
            continue
        share = 1.0 - float(np.sum(_project(Q, j) ** 2)) / rr
        if share > best["fraction"]:
            d = j - j_u
            dp = _project(Q, d)
            nd = float(np.linalg.norm(dp))
            cos = abs(float(dp @ r_perp)) / (nd * math.sqrt(rr)) if nd > 0 else 0.0
            angle = math.degrees(math.acos(min(1.0, cos)))
            best.update(fraction=share, value=float(v), d=d, angle=angle)
    return best


#: Units-slip factors evaluated per channel, nearest the channel's offset first (the null fit's
#: parameters may absorb part of a slip, so the nearest factor to what is left can be the wrong one).
UNITS_NEAREST = 2


def _likely_states(res: Residual, j_u: np.ndarray, effect: Any) -> tuple[float, ...]:
    """The states of a switched effect worth evaluating: for a units slip the :data:`UNITS_NEAREST`
    factors nearest the channel's mean log-magnitude offset (``exp`` of the weighted mean of
    ``Re ln(G_data / G)`` over its row or column: a slip ``f`` makes it ``ln f``, less what the
    null fit's parameters absorbed); every state otherwise."""
    states = tuple(effect.states)
    if not getattr(effect, "gain_states", False) or len(states) < 2:
        return states
    names = res.data.outputs if effect.side == "output" else res.data.inputs
    if effect.location not in names:
        return states
    k = names.index(effect.location)
    w2 = res.point_weights
    e_w = res.unstack(j_u)
    with np.errstate(divide="ignore", invalid="ignore"):
        e = np.where(res.weights > 0, e_w / np.where(res.weights > 0, res.weights, 1.0), 0.0)
    sel = (slice(None), k, slice(None)) if effect.side == "output" else (slice(None), slice(None), k)
    total = float(np.sum(w2[sel]))
    if total <= 0:
        return states
    offset = float(np.sum(w2[sel] * e[sel].real)) / total
    return tuple(sorted(states, key=lambda f: abs(math.log(f) - offset))[:UNITS_NEAREST])


#: Multiples of the calibrated step (a 2 % change of the most affected modal ``w^2``) at
#: which each candidate is also evaluated in screening: an effect that moves a mode by a
#: factor of 4 changes its ``w^2`` by 1500 %, far outside the secant's linear range.
SCREEN_MULTIPLES = (10.0, 100.0, 1000.0)
#: A candidate is probed at :data:`SCREEN_MULTIPLES` only when its secant's linear estimate
#: ``|c|`` (in units of the secant step) exceeds this: the data then ask for more of the effect
#: than the step measured, the sign of a large effect (the chain's large-error cases: 2 to 55).
PROBE_MIN_COEF = 1.0


def _probe_sizes(
    res_c: Residual,
    pname: str,
    span: tuple,
    step: float,
    coef: float,
    Q: np.ndarray,
    rr: float,
    linear_share: float = 0.0,
) -> tuple[float, float, int]:
    """Screen a candidate at sizes spanning decades (large effects are far from linear).

    The candidate is evaluated at ``v0 + m * step`` for ``m`` in :data:`SCREEN_MULTIPLES`
    (in the direction of the secant's linear estimate, within the bounds), each with the
    update parameters re-fitted linearly: the share explained is ``1 - |P j(v)|^2 / |P j_u|^2``
    (``P`` projects out the update parameters' sensitivities, as in step 2). The probe walks
    outwards while the share grows, starting from ``linear_share`` (the secant's prediction):
    an effect the secant already describes costs one evaluation more, a large one a few.
    Returns ``(share, value, evaluations)``; the share is 0 when nothing was evaluated.
    """
    v0, lo, hi = span
    sign = 1.0 if coef >= 0 else -1.0
    best, best_v, n, last = 0.0, v0, 0, float(linear_share)
    for m in SCREEN_MULTIPLES:
        v = float(np.clip(v0 + sign * m * step, lo, hi))
        if v == v0 or (n and v == best_v):
            break
        n += 1
        try:
            j = res_c.vector(**{pname: v})
        except RobustctlError:  # e.g. a mass so large the preload fails: stop walking out
            break
        if not np.all(np.isfinite(j)):
            break
        share = 1.0 - float(np.sum(_project(Q, j) ** 2)) / rr
        if share > best:
            best, best_v = share, v
        if share < last:
            break
        last = share
    return max(best, 0.0), best_v, n


#: Sizes (in decades above its typical size) at which an effect that first order cannot see
#: (``Effect.coarse_screen``: a joint from rigid to pinned) is screened: 1.5 decades apart up to
#: 7.5 decades, five evaluations (the local fit starts from the best; diagnose's budget is shared).
COARSE_DECADES = (1.5, 3.0, 4.5, 6.0, 7.5)
#: Refinements of the coarse screen around its best size, each halving the spacing (two sizes each):
#: a joint between two decades' sizes starts its local fit within 0.2 decade of its value.
COARSE_REFINE = 3


def _coarse_sizes(res_c: Residual, pname: str, span: tuple, step: float, Q: np.ndarray,
                  rr: float) -> tuple[float, float, int]:
    """A coarse nonlinear screen over an effect's whole range: the share explained (as in
    :func:`_probe_sizes`, update parameters re-fitted linearly) at ``v0 + step 10^k`` for ``k`` in
    :data:`COARSE_DECADES` (within the bounds; the walk ends at a bound). Returns
    ``(share, value, evaluations)``."""
    v0, lo, hi = span
    sign = 1.0 if v0 + step <= hi else -1.0

    def share_at(v: float) -> float | None:
        try:
            j = res_c.vector(**{pname: v})
        except RobustctlError:  # e.g. a size the model cannot be built with
            return None
        if not np.all(np.isfinite(j)):
            return None
        return 1.0 - float(np.sum(_project(Q, j) ** 2)) / rr

    best, best_v, best_k, n = 0.0, v0, None, 0

    def probe(k: float) -> float | None:
        """Share explained at ``10**k`` steps from the start (None: clipped back to the start)."""
        nonlocal best, best_v, best_k, n
        v = float(np.clip(v0 + sign * step * 10.0**k, lo, hi))
        if v == v0:
            return None
        n += 1
        share = share_at(v)
        if share is not None and share > best:
            best, best_v, best_k = share, v, k
        return v

    for k in COARSE_DECADES:
        v = probe(k)
        if v is None or v in (lo, hi):
            break
    if best_k is not None:  # halve the spacing COARSE_REFINE times around the best
        spacing = COARSE_DECADES[1] - COARSE_DECADES[0] if len(COARSE_DECADES) > 1 else 1.0
        for _ in range(COARSE_REFINE):
            spacing /= 2.0
            centre = best_k
            for k in (centre - spacing, centre + spacing):
                probe(k)
    return max(best, 0.0), best_v, n


@dataclass
class _Null:
    """The null fit: update parameters, their values, bounds and frozen Jacobian."""

    names: tuple[str, ...]
    x: dict[str, float]
    x0: dict[str, float]
    lo: np.ndarray
    hi: np.ndarray
    jac: np.ndarray  # d j / d alpha per unit parameter, (n, p)
    j: np.ndarray
    cost: float
    cut: bool = False  # the time budget stopped the fit

    @property
    def Q(self) -> np.ndarray:  # noqa: N802 - the orthonormal basis of span(jac)
        if not hasattr(self, "_Q"):
            self._Q = _orthonormal(self.jac)
        return self._Q


def _fit_one(
    res_u: Residual, null: _Null, screen: dict[str, Any], max_iter: int, budget: Deadline
) -> dict[str, Any]:
    """Short bounded local fit of one candidate with the update parameters (step 3).

    Gauss-Newton/Marquardt on ``[alpha_update, v]`` with the update parameters' Jacobian
    frozen at the null fit and the candidate's column refreshed each iteration by a secant
    (two evaluations per iteration instead of ``p + 1``). A point where the model cannot
    be evaluated (e.g. the gravity preload does not converge) counts as a failed step.
    """
    effect = screen["effect"]
    pname, par = effect.param_names[0], effect.parameters[0]
    discrete = _is_switch(effect)
    res_c = _residual_for(res_u, screen["model"])
    names = null.names
    lo_v, hi_v = (screen["value"], screen["value"]) if discrete else par.bounds
    counter = [0]

    def evaluate(uu: np.ndarray, vv: float) -> np.ndarray | None:
        counter[0] += 1
        try:
            r = res_c.vector(**dict(zip(names, (float(x) for x in uu))), **{pname: vv})
        except RobustctlError:
            return None
        return r if np.all(np.isfinite(r)) else None

    starts = [np.array([null.x[n] for n in names], dtype=float)]
    if null.x0 and any(null.x0[n] != null.x[n] for n in names):
        starts.append(np.array([null.x0[n] for n in names], dtype=float))
    start = _start_value(effect, screen["value"], discrete, evaluate, null.Q, starts)
    if start is None:  # no trial size can be evaluated: nothing gained
        return dict(x=dict(null.x), cost=null.cost, vector=null.j, evals=counter[0], value=float(par.neutral))
    u, v, r = start
    cost, lam = float(r @ r), 1e-2
    if discrete and names:
        return _fit_switched(res_c.model.with_values(**{pname: v}), res_u, names, u, v, r, max_iter,
                             budget, counter[0])
    cut = False
    for _ in range(int(max_iter)):
        if budget.expired():
            cut = True
            break
        cols = [null.jac]
        if not discrete:
            h = max(0.05 * abs(v - float(par.neutral)), 0.1 * effect.typical_size)
            h = h if v + h <= hi_v else -h
            r_h = evaluate(u, v + h)
            if r_h is None:
                break
            cols.append(((r_h - r) / h)[:, None])
        A = np.hstack(cols)
        if A.shape[1] == 0:
            break
        new = _marquardt_try(
            A,
            r,
            cost,
            lam,
            lambda st, u=u, v=v: (
                np.clip(u + st[: len(names)], null.lo, null.hi),
                v if discrete else float(np.clip(v + st[-1], lo_v, hi_v)),
            ),
            evaluate,
        )
        if new is None:
            break
        (u_new, v_new), r, c_new, lam = new
        rel, u, v, cost = (cost - c_new) / cost, u_new, v_new, c_new
        if rel < 1e-3:
            break
    return dict(x=dict(zip(names, (float(x) for x in u))), cost=cost, vector=r, evals=counter[0], value=v,
                cut=cut)


def _fit_switched(model_on: Any, res_u: Residual, names: tuple[str, ...], u: np.ndarray, v: float,
                  r: np.ndarray, max_iter: int, budget: Deadline, evals: int) -> dict[str, Any]:
    """The local fit of a discrete candidate (gravity switched on or off): a full LM fit of the
    update parameters with the switch set (their sensitivities refreshed each iteration).

    The null fit's Jacobian, which the secant fits of :func:`_fit_one` keep, belongs to the
    other state: gravity changes the pendulum modes by factors, so a fit on the frozen Jacobian
    stops at once and the true switch ranked below springs that mimic it (a hanging chain:
    the switch explained 34 % of the residual, refitted 99.9 %)."""
    cost = float(r @ r)
    x = dict(zip(names, (float(a) for a in u)))
    out = dict(x=x, cost=cost, vector=r, evals=evals, value=v, cut=False)
    if budget.expired():
        return dict(out, cut=True)
    try:
        lm = levenberg_marquardt(_residual_for(res_u, model_on), names, x0=x, max_iter=max_iter,
                                 time_budget_s=budget)
    except RobustctlError:
        return out
    out["evals"] += lm.n_evals
    if not lm.cost < cost:
        return out
    return dict(out, x={n: float(lm.x[n]) for n in names}, cost=float(lm.cost), vector=lm.vector,
                cut=lm.stopped_by_budget)


def _fit_task(shared: tuple, screen: dict[str, Any]) -> dict[str, Any]:
    """One local fit (:func:`parallel_map_shared` task): ``shared = (res_u, null, max_iter, budget)``."""
    res_u, null, max_iter, budget = shared
    return _fit_one(res_u, null, screen, max_iter, budget)


#: A local fit whose cost is within this factor of the best one's is a contender: it is polished
#: by a full Levenberg-Marquardt fit before the ranking (:func:`_polish`).
CONTENDER_RATIO = 2.0
#: Iteration cap of the polishing fits (each refreshes all sensitivities; they stop earlier once
#: the relative cost change is below 1e-4). On the Caltech truss below 30 Hz two reached the
#: converged costs to four digits; on a 3-D frame with 5 % sensor noise and E, floor masses off
#: by 15 % and 10 %, two left the true spring 20 % above its converged cost, behind a mimicking
#: spring whose lead the Vuong test then called significant (z = 7.8; converged: true first, the
#: mimic behind by z = 8.6).
POLISH_ITER = 8


def _noise_cost(res: Residual) -> float | None:
    """The cost the noise alone gives, ``E[J] = sum W sigma^2`` over both parts (None without a
    noise model)."""
    if res.noise is None:
        return None
    return float(2.0 * np.sum(res.point_weights * res.noise.sigma**2))


def _polish(
    res_u: Residual, null: _Null, screens: list[dict], top: list[int], fits: list[dict], executor: Any,
    budget: Deadline, noise_cost: float | None = None,
) -> tuple[list[dict], int]:
    """Full LM fits of the contenders (step 3b): the local fits freeze the update parameters'
    sensitivities at the null fit, which may have bent them to mimic the missing effect, so
    two candidates whose local fits end close may rank in the wrong order (on the Caltech truss
    below 30 Hz the true taut wires stopped at half their tension, behind stiffer diagonals).
    Contenders -- fits within :data:`CONTENDER_RATIO` of the best cost -- are refitted with
    refreshed sensitivities (:func:`levenberg_marquardt`, up to :data:`POLISH_ITER` iterations) from
    their local fit. A clear winner is polished alone when its local fit leaves more than
    :data:`MODEL_ERROR_DISPERSION` x the noise's cost (``noise_cost``): its test is against the
    misfit it leaves, so a fit stopped short (a large effect's local fit on the frozen sensitivities)
    would understate it. Returns the fits and the evaluations.
    """
    costs = [f["cost"] for f in fits]
    if not fits or not null.names:
        return fits, 0
    best = min(costs)
    todo = [i for i, c in enumerate(costs) if c <= CONTENDER_RATIO * best
            and not _is_switch(screens[top[i]]["effect"])]
    if len(todo) < 2:
        lead = int(np.argmin(costs))
        short = noise_cost is not None and best > MODEL_ERROR_DISPERSION * noise_cost
        if not (short and lead in todo):
            return fits, 0
        todo = [lead]

    done = parallel_map_shared(_polish_task, (res_u, null.names, budget),
                               [(screens[top[i]], fits[i]) for i in todo], executor, desc="polishing fits")
    out = list(fits)
    for i, new in zip(todo, done):
        out[i] = new
    return out, sum(f["evals"] for f in done)


def _polish_task(shared: tuple, item: tuple) -> dict:
    """One contender's full LM fit from its local fit (:func:`parallel_map_shared` task;
    ``shared = (res_u, update names, budget)``, ``item = (screen, local fit)``)."""
    res_u, names, budget = shared
    s, fit = item
    effect = s["effect"]
    pname = effect.param_names[0]
    # an effect's retuned value (a resonator's frequency) is fitted with its size
    extra = tuple(p.name for p in effect.parameters[1:] if p.free) if effect.retune is not None else ()
    res_c = _residual_for(res_u, s["model"])
    try:
        lm = levenberg_marquardt(res_c, names + (pname,) + extra, x0={**fit["x"], pname: fit["value"]},
                                 max_iter=POLISH_ITER, ftol=1e-4, time_budget_s=budget)
    except RobustctlError:
        return dict(fit, evals=0)
    if not lm.cost < fit["cost"]:
        return dict(fit, evals=lm.n_evals)
    x = dict(lm.x)
    return dict(x={n: x[n] for n in names}, cost=float(lm.cost), vector=lm.vector, evals=lm.n_evals,
                value=float(x[pname]), cut=lm.stopped_by_budget, extra={n: float(x[n]) for n in extra})


#: Multiples of an effect's typical size tried as starting values of its local fit.
_START_MULTIPLES = (1.0, 3.0, 10.0, 30.0, 100.0)


def _start_value(effect: Any, v_lin: float, discrete: bool, evaluate, Q: np.ndarray, starts: list):
    """Starting point of a local fit: update values and a candidate size.

    Structural effects are far from linear in their parameter (a mass moves lightly
    damped resonances by several half-power bandwidths), so the linear estimate of the
    screening may sit in the wrong basin; and the null fit may have bent the update
    parameters to mimic the missing effect. The trials are the screening estimate and
    multiples of the typical size, each from the null-fit and from the model's own update
    values (``starts``), scored by ``|P j|^2``: the cost left once the update parameters are
    re-fitted linearly (``P`` projects out their sensitivities). Returns ``(u, v, j)`` or None.
    """
    par = effect.parameters[0]
    trials = [float(v_lin)]
    if not discrete:
        neutral = float(par.neutral)
        sign = 1.0 if v_lin >= neutral else -1.0
        lo, hi = par.bounds
        trials += [float(np.clip(neutral + sign * m * effect.typical_size, lo, hi)) for m in _START_MULTIPLES]
    best = None
    for u in starts:
        for v in dict.fromkeys(trials):  # unique, in order
            r = evaluate(u, v)
            if r is None:
                continue
            score = float(np.sum(_project(Q, r) ** 2))
            if best is None or score < best[0]:
                best = (score, u, v, r)
    return None if best is None else best[1:]


def _marquardt_try(A, r, cost, lam, to_point, evaluate, tries: int = 4):
    """Up to ``tries`` damped steps with growing damping; the first that lowers the cost.

    Returns ``(point, r_new, cost_new, lam_next)`` or None.
    """
    for _ in range(tries):
        point = to_point(marquardt_step(A, r, lam))
        r_new = evaluate(*point)
        if r_new is not None:
            c_new = float(r_new @ r_new)
            if c_new < cost:
                return point, r_new, c_new, max(lam / 10.0, 1e-6)
        lam *= 10.0
    return None


def _equivalent(screens: list[dict[str, Any]]) -> dict[int, int]:
    """Candidates whose secant equals an earlier one's (to 1e-6): index -> earlier index.

    A delay or filter on *every* output acts exactly like one on every input (scalar factors
    commute), so such pairs are indistinguishable; the earlier (sensor-side) one is kept.
    Distances come from one Gram matrix, ``|d_i - d_k|^2 = |d_i|^2 + |d_k|^2 - 2 d_i.d_k``
    (a pair that passes is confirmed directly: the expansion cancels digits).
    """
    twins: dict[int, int] = {}
    shapes = {s["d"].shape for s in screens}
    if len(screens) < 2 or len(shapes) != 1:
        return twins
    D = np.array([s["d"] for s in screens], dtype=float)
    sq = np.einsum("ij,ij->i", D, D)
    dist2 = sq[:, None] + sq[None, :] - 2.0 * (D @ D.T)
    for k in range(1, len(screens)):
        if sq[k] == 0:
            continue
        for i in np.flatnonzero(dist2[k, :k] <= 1e-10 * sq[k]):
            if i not in twins and np.linalg.norm(D[i] - D[k]) <= 1e-6 * math.sqrt(sq[k]):
                twins[k] = int(i)
                break
    return twins


def _residual(model: Any, checked: CheckedData, weights, min_db, estimator="auto") -> tuple[Residual, tuple]:
    """The residual, with channels the model leaves decoupled weighted 0.

    A channel whose model response stays ``min_db`` dB below both the largest
    channel of its output row and of its input column (decoupled by symmetry, e.g. a
    torque about one axis seen by a gyro about another) gives a log error of the data's
    noise against a numerically zero model: no effect can explain it, so it would only
    blur the statistics. It is left out and listed in ``Diagnosis.ignored_channels``.
    """
    res = Residual.of_checked(model, checked, weights, min_db, estimator)
    return res, tuple((o, i) for o, i, _level in res.dropped)


#: Candidates screened within this factor of the best screening share are fitted too, beyond
#: ``n_fit`` (up to :data:`TIE_MAX_FACTOR` x ``n_fit``): screening shares of near-ties say little
#: about the fits (a first-order share overrates a candidate far outside its linear range).
TIE_SHARE = 0.95
#: Cap of the fits with near-tied screening shares, as a multiple of ``n_fit``.
TIE_MAX_FACTOR = 2


def _to_fit(screens: list[dict], order: list[int], n_fit: int) -> list[int]:
    """The candidates given a local fit: the ``n_fit`` best screened, and those tied with the best
    screening share within :data:`TIE_SHARE` (at most ``TIE_MAX_FACTOR * n_fit`` in all)."""
    top = [k for k in order[:n_fit] if screens[k]["fraction"] > 0]
    if not top:
        return top
    level = TIE_SHARE * screens[order[0]]["fraction"]
    more = [k for k in order[n_fit:TIE_MAX_FACTOR * n_fit] if screens[k]["fraction"] >= level]
    return top + more


def _screen_all(
    res_u: Residual, model_u: Any, null: _Null, cands: list, executor, deadline: Deadline,
) -> tuple:
    """Screen every candidate (step 2): the screens, indistinguishable twins, and the
    order of the others by the fraction they explain.

    A structure in reduced coordinates (:func:`robustctl.physical.reduction.band_limited`) has
    its point effects (an added mass, a grounded spring or dashpot at each node: three per DOF)
    scored in closed form on the reduced modal model (:func:`_screen_points`); every other
    candidate, and every candidate of any other model, by the exact path. The candidates given
    local fits are then fitted by the exact path whichever way they were screened (their screen
    gets its model from :func:`_with_models`)."""
    r_perp = _project(null.Q, null.j)
    fast = _screen_points(res_u, model_u, null, r_perp, cands, executor, deadline)
    exact_idx = (list(range(len(cands))) if fast is None
                 else [k for k in range(len(cands)) if k not in fast or fast[k].get("rescreen")])
    screens: list[dict | None] = [None] * len(cands)
    for k, sc in (fast or {}).items():
        if not sc.get("rescreen"):
            screens[k] = sc
    shared = (res_u, model_u, null.j, null.Q, r_perp, deadline, len(cands))
    done = parallel_map_shared(_screen_task, shared, [cands[k] for k in exact_idx], executor,
                               desc="screening")
    tuned = [i for i, k in enumerate(exact_idx) if getattr(cands[k], "retune", None) is not None
             and not _is_switch(cands[k])]
    tuned = sorted(tuned, key=lambda i: (-round(done[i]["fraction"], 9), i))[:RETUNE_TOP]
    if tuned:  # the best of them at every peak of the misfit and around the best
        again = parallel_map_shared(_retune_task, shared, [cands[exact_idx[i]] for i in tuned], executor,
                                    desc="retuning")
        for i, sc in zip(tuned, again):
            done[i] = sc
    for k, sc in zip(exact_idx, done):  # each candidate's model, rebuilt here on model_u (see _screen_task)
        sc["model"] = sc["effect"].with_values(**sc["effect"].neutral_values).apply(model_u)
        screens[k] = sc
    twins = {exact_idx[t]: exact_idx[i] for t, i in _equivalent([screens[k] for k in exact_idx]).items()}
    if fast is not None:
        twins.update(_sketch_twins({k: fast[k] for k in fast
                                    if k not in twins and not fast[k].get("rescreen")}))
    order = sorted(
        (k for k in range(len(screens)) if k not in twins),
        key=lambda k: (-round(screens[k]["fraction"], 9), k),
    )
    return screens, twins, order


def _with_models(screens: list[dict], ks: list[int], model_u: Any) -> None:
    """Give the screens ``ks`` their candidate's model on ``model_u`` (at neutral) where they have
    none (the closed-form screening keeps scalars only)."""
    for k in ks:
        s = screens[k]
        if "model" not in s:
            s["model"] = s["effect"].with_values(**s["effect"].neutral_values).apply(model_u)


#: Point effects scored per task of the closed-form screening (the memory of a task is a few
#: ``n_freq x n_out x n_in`` arrays per size tried, whatever the number of candidates).
POINT_CHUNK = 128
#: Sizes of a point effect's one-parameter fit in the closed-form screening, in multiples of its
#: typical size (:attr:`Effect.typical_size`), refined twice around the best by
#: :data:`POINT_REFINE` sub-steps.
#: The calibrated typical size moves the most affected mode by 2 % (``w^2``); on a large structure a
#: point mass that changes the response by bandwidths (a 0.03 kg sensor on a 1,000-DOF grid: 1/20
#: of its typical size) is far below it, and a large effect far above, hence six decades (the two
#: refinements then bracket the best to 10 % in size).
POINT_MULTIPLES = tuple(10.0 ** np.arange(-3.0, 3.01, 1.0))
POINT_REFINE = 4


def _screen_points(res_u: Residual, model_u: Any, null: _Null, r_perp: np.ndarray, cands: list,
                   executor, deadline: Deadline) -> dict[int, dict] | None:
    """Closed-form screening of the point effects of a reduced structure, or None (any other
    model, or a model whose I/O stages are not a per-channel factor on the structure's response).

    Each point effect (its class has a ``point_unit``: a mass, grounded spring or dashpot) is a
    low-rank change of the reduced modal model at the null fit
    (:class:`robustctl.physical.reduction.PointModal`:
    structural dynamic modification by Sherman-Morrison-Woodbury, with the static residual
    flexibility of the changed DOFs and of the outputs to them: a solve per DOF scored in closed
    form, made here, so that worker processes score the same), and the model's response is
    the structure's times the per-channel factor ``G_u / H_u`` of the null-fit model. Its
    one-parameter fit minimises ``|P j(v)|^2`` (``P`` projects out the update parameters'
    sensitivities, as the exact screening does) over :data:`POINT_MULTIPLES` of its typical size,
    refined around the best; the share ``1 - |P j(v*)|^2 / |P j_u|^2``, the angle of the secant
    at the typical size and ``v*`` are kept, with a three-number sketch of the secant for the
    twin test -- scalars only, streamed in chunks of :data:`POINT_CHUNK`."""
    points = [k for k, c in enumerate(cands)
              if getattr(c, "point_unit", None) is not None and not _is_switch(c)]
    if not points:
        return None
    try:
        pm = point_modal(model_u, res_u.f_hz)
    except RobustctlError:
        return None
    if pm is None:
        return None
    data = res_u.data
    if not (set(data.outputs) <= set(pm.outputs) and set(data.inputs) <= set(pm.inputs)):
        return None
    oi = [pm.outputs.index(o) for o in data.outputs]
    ii = [pm.inputs.index(i) for i in data.inputs]
    h_u = pm.H[:, oi][:, :, ii]
    g_u = res_u.model_response()
    if not np.all(np.abs(h_u) > 0) or not np.all(np.isfinite(g_u)):
        return None
    struct = model_u.build_structure()
    mats = struct.matrices()
    items = []
    for k in points:
        change = point_change(cands[k], model_u, struct, mats)
        if change is not None:
            items.append((k, cands[k], change))
    if not items:
        return None
    sketch = np.random.default_rng(20261127).standard_normal((res_u.n, 2))
    ratio = g_u / h_u
    identity = oi == list(range(len(pm.outputs))) and ii == list(range(len(pm.inputs)))
    half = res_u.n // 2
    shared = dict(pm=pm, oi=None if identity else oi, ii=None if identity else ii,
                  ratio=None if np.allclose(ratio, 1.0, rtol=1e-13, atol=0) else ratio, data=data.response,
                  Q_parts=(null.Q[:half], null.Q[half:]),
                  log_abs_data=np.log(np.maximum(np.abs(data.response), 1e-300)), weights=res_u.weights,
                  bias=res_u.bias, Q=null.Q, r_perp=r_perp, j_u=null.j, sketch=sketch, deadline=deadline,
                  n=len(cands))
    out: dict[int, dict] = {}
    if len(items) > PRESCREEN_MIN:
        items, rest = _prescreen(shared, items, PRESCREEN_KEEP)
        out.update({k: dict(sc, effect=cands[k]) for k, sc in rest.items()})
    # the changed DOFs' residual flexibility (a solve per DOF, here: the same in every process)
    items = [(k, c, ch) for (k, c, _), ch in zip(items, pm.with_residuals([it[2] for it in items]))]
    chunks = [items[i:i + POINT_CHUNK] for i in range(0, len(items), POINT_CHUNK)]
    for part in parallel_map_shared(_points_task, shared, chunks, executor, desc="point screening"):
        for k, sc in part:
            out[k] = dict(sc, effect=cands[k])
    # the stages must act per channel: the closed form at the best candidate's fitted size
    # against one exact evaluation, else every candidate goes the exact way
    best = max((k for k in out if not out[k].get("first_order")), key=lambda k: (out[k]["fraction"], -k))
    item = next(it for it in items if it[0] == best)
    if _point_form_holds(res_u, model_u, shared, item, out[best]["value"]):
        return out
    # it fails at the best one's fitted size but holds for one of the next best (the best a large mass
    # or spring far outside the closed form's range, where the residual's inertia and the changed modes'
    # damping it leaves out matter): the stages do act per channel, and the leaders are screened
    # again by the exact path
    fitted = sorted((k for k in out if not out[k].get("first_order")), key=lambda k: (-out[k]["fraction"], k))
    if not any(_point_form_holds(res_u, model_u, shared, next(it for it in items if it[0] == k),
                                 out[k]["value"]) for k in fitted[1:POINT_FORM_TRIES]):
        return None
    for k in fitted[:POINT_RESCREEN]:
        out[k] = dict(out[k], rescreen=True)
    return out


#: Candidates tried for the closed form's check (:func:`_screen_points`) before every point effect
#: goes the exact way.
POINT_FORM_TRIES = 6


#: Point effects screened again by the exact path (the best by their closed-form share) when the
#: closed form misses the exact change at the best one's fitted size (:func:`_screen_points`).
POINT_RESCREEN = 32


#: More single-DOF point effects than this (a structure of over 1,000 DOFs with the default three per
#: DOF) are first ranked by their first-order share (:func:`_prescreen`) and only the best
#: :data:`PRESCREEN_KEEP` of them fitted in closed form; fewer are all fitted.
PRESCREEN_MIN = 3_000
#: The point effects a first-order prescreen keeps for the closed-form fit.
PRESCREEN_KEEP = 2_000
#: DOFs per block of the first-order prescreen (its memory: ``n_freq x n_out x n_in`` complex
#: numbers per DOF of a block, 50 MB for 400 frequencies x 8 x 2 channels).
PRESCREEN_BLOCK = 512


def _prescreen(shared: dict, items: list, keep: int) -> tuple[list, dict[int, dict]]:
    """The ``keep`` point effects of ``items`` with the largest first-order share, and the scores
    of the others.

    A point effect of size ``v`` at DOF ``j`` changes the structure's response by
    ``-v A~_j B B~_j + O(v^2)`` (:class:`robustctl.physical.reduction.PointModal`, ``B(w) = dk - w^2 dm
    + j w dc`` its unit change), so the weighted complex log error by ``e'_j = W A~_j B B~_j / H``
    per unit size: its share ``(e'_j . r_perp)^2 / (|P e'_j|^2 |r_perp|^2)`` of the residual left by
    the update parameters (``P`` projects out their sensitivities) is what a small size of it
    explains (the cosine squared of the angle between the residual and the effect's direction,
    to first order). ``A~_j``, ``B~_j`` for a block of DOFs are two matrix products with the
    reduced mode shapes at those DOFs (``O(n_freq (n_out + n_in) r)`` per DOF; ``A~_j`` with the
    outputs' residual flexibility to ``j``, ``PointModal.resid_c``), against the
    closed form's ``O(n_freq r)`` per size tried and some 20 sizes per effect. Effects on more
    than one DOF are all kept. The others get that share as their ``fraction``, the angle, their
    neutral value and ``first_order=True`` (a first-order share is not a fitted one: it can
    understate an effect far outside its linear range)."""
    pm = shared["pm"]
    single = [it for it in items if it[2].dofs.size == 1]
    if len(single) <= keep:
        return items, {}
    multi = [it for it in items if it[2].dofs.size != 1]
    r = shared["r_perp"]
    half = r.size // 2
    rr = float(r @ r)
    Qr, Qi = shared["Q_parts"]
    r_re, r_im = r[:half], r[half:]
    n_f = pm.w.size
    AZ = (pm.zinv[:, None, :] * pm.cphi[None]).reshape(-1, pm.zinv.shape[1])  # (n_f p, r)
    BZ = (pm.zinv[:, None, :] * pm.phib.T[None]).reshape(-1, pm.zinv.shape[1])  # (n_f m, r)
    p, m = pm.cphi.shape[0], pm.phib.shape[1]
    AZr, AZi, BZr, BZi = (np.ascontiguousarray(x) for x in (AZ.real, AZ.imag, BZ.real, BZ.imag))
    oi = slice(None) if shared["oi"] is None else shared["oi"]
    ii = slice(None) if shared["ii"] is None else shared["ii"]
    h = pm.H[:, oi][:, :, ii]
    scale = shared["weights"] / h  # (n_f, o, i)
    w = pm.w
    dofs = np.array(sorted({int(it[2].dofs[0]) for it in single}))
    where = {int(j): t for t, j in enumerate(dofs)}
    units = sorted({(float(it[2].mass[0, 0]), float(it[2].stiffness[0, 0]), float(it[2].damping[0, 0]))
                    for it in single})
    share = np.zeros((len(units), dofs.size))
    for start in range(0, dofs.size, PRESCREEN_BLOCK):
        _check_budget(shared["deadline"], f"the screening of {shared['n']} candidates")
        block = dofs[start:start + PRESCREEN_BLOCK]
        U = pm.V[block].T  # (r, c), real: two real products each (half the work of a complex one)
        At = (AZr @ U + 1j * (AZi @ U)).reshape(n_f, p, -1)
        if pm.resid_c is not None:  # the outputs' residual flexibility to the DOFs (R b = 0: none for B~)
            At = At + pm.resid_c[:, block][None]
        At = At * pm.k_out[:, :, None]
        Bt = (BZr @ U + 1j * (BZi @ U)).reshape(n_f, m, -1)
        u = At[:, oi][:, :, None, :] * Bt[:, ii][:, None, :, :] * scale[..., None]  # (n_f, o, i, c)
        u = u.reshape(-1, block.size)
        u_re, u_im = np.ascontiguousarray(u.real), np.ascontiguousarray(u.imag)
        u2 = u_re * u_re + u_im * u_im
        for t, (dm, dk, dc) in enumerate(units):
            # the unit's factor f (per frequency) moved onto the residual and Q: (u f) . r =
            # u_re . (r_re f_re + r_im f_im) + u_im . (r_im f_re - r_re f_im), |u f|^2 = |f|^2 |u|^2
            f = (dk - w**2 * dm + 1j * w * dc).repeat(u.shape[0] // n_f)
            fr, fi = f.real[:, None], f.imag[:, None]
            L_re = np.hstack([r_re[:, None] * fr + r_im[:, None] * fi, Qr * fr + Qi * fi])
            L_im = np.hstack([r_im[:, None] * fr - r_re[:, None] * fi, Qi * fr - Qr * fi])
            both = L_re.T @ u_re + L_im.T @ u_im  # (1 + n_Q, c): the dot, then Q^T (u f)
            dot = both[0]
            norm = (f.real**2 + f.imag**2) @ u2
            if Qr.shape[1]:
                proj = both[1:]
                norm = norm - np.einsum("ij,ij->j", proj, proj)
            with np.errstate(all="ignore"):
                sh = np.where((norm > 0) & np.isfinite(norm) & (rr > 0), dot**2 / (norm * rr), 0.0)
            share[t, start:start + block.size] = np.clip(np.nan_to_num(sh), 0.0, 1.0)
    unit_of = {u_: t for t, u_ in enumerate(units)}
    scored = []
    for it in single:
        ch = it[2]
        t = unit_of[(float(ch.mass[0, 0]), float(ch.stiffness[0, 0]), float(ch.damping[0, 0]))]
        scored.append((float(share[t, where[int(ch.dofs[0])]]), it))
    order = sorted(range(len(scored)), key=lambda i: (-scored[i][0], scored[i][1][0]))
    kept = [scored[i][1] for i in order[:keep]]
    rest = {}
    for i in order[keep:]:
        sh, (k, effect, _change) = scored[i]
        rest[k] = dict(fraction=sh, angle=math.degrees(math.acos(min(1.0, math.sqrt(sh)))),
                       value=float(effect.parameters[0].neutral), evals=0,
                       sketch=(float("nan"),) * 3, first_order=True, stage="first order")
    return multi + kept, rest


#: The closed form is trusted when its change of the residual at the best candidate's fitted size
#: is within this fraction of the exact change (what it leaves out -- the inertia of the changed
#: DOF's residual flexibility, the changed modes' damping -- is a few percent of a change in the band).
POINT_FORM_TOL = 0.3


def _point_form_holds(res_u: Residual, model_u: Any, shared: dict, item: tuple, value: float) -> bool:
    """Whether the closed form's change of the residual at the best candidate's fitted ``value``
    is within :data:`POINT_FORM_TOL` of the exact evaluation's (one model evaluation)."""
    k, effect, change = item
    pname = effect.param_names[0]
    trial = float(value)
    if trial == float(effect.parameters[0].neutral):
        trial = _point_sizes(effect)[1]
    m_c = effect.with_values(**effect.neutral_values).apply(model_u)
    try:
        j_exact = _residual_for(res_u, m_c).vector(**{pname: trial})
    except RobustctlError:
        return False
    j_fast = _point_vectors(shared, shared["pm"].terms(change), np.array([trial]))[0]
    d = j_exact - shared["j_u"]
    nd = float(np.linalg.norm(d))
    return bool(np.all(np.isfinite(j_fast)) and nd > 0
                and float(np.linalg.norm(j_fast - j_exact)) <= POINT_FORM_TOL * nd)


def _point_sizes(effect: Any) -> tuple[np.ndarray, float]:
    """The sizes of a point effect's one-parameter fit (:data:`POINT_MULTIPLES` of its typical size
    from neutral, in the directions its bounds allow) and its secant's trial size."""
    par = effect.parameters[0]
    v0, (lo, hi), step = float(par.neutral), par.bounds, float(effect.typical_size)
    trial = v0 + step if v0 + step <= hi else v0 - step
    sizes = []
    for sign in (1.0, -1.0):
        if (sign > 0 and v0 + step <= hi) or (sign < 0 and v0 - step >= lo):
            sizes += [float(np.clip(v0 + sign * m * step, lo, hi)) for m in POINT_MULTIPLES]
    return np.array(sorted(set(sizes))), float(trial)


def _point_errors(shared: dict, terms: tuple, values: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Weighted complex log errors of the closed-form responses at ``values`` (principal branch, the
    phase wrapped to (-pi, pi] as :func:`robustctl.lti.log_ratio`), as their real and imaginary
    parts: two C-contiguous arrays (n_v, n_freq * n_out * n_in)."""
    pm = shared["pm"]
    h = pm.responses(terms, values)
    if shared["oi"] is not None:
        h = h[:, :, shared["oi"]][:, :, :, shared["ii"]]
    g = h if shared["ratio"] is None else shared["ratio"][None] * h
    q = shared["data"][None] * np.conj(g)
    with np.errstate(all="ignore"):
        re = np.square(g.real)
        re += np.square(g.imag)
        np.log(re, out=re)
        re *= 0.5
        np.subtract(shared["log_abs_data"][None], re, out=re)
        im = np.arctan2(q.imag, q.real)
        bias = shared["bias"]
        if bias is not None:
            re -= bias.real[None]
            if np.iscomplexobj(bias):
                im -= bias.imag[None]
        re *= shared["weights"][None]
        im *= shared["weights"][None]
    return re.reshape(len(values), -1), im.reshape(len(values), -1)


def _point_vectors(shared: dict, terms: tuple, values: np.ndarray) -> np.ndarray:
    """Residual vectors (n_v, n) of the closed-form responses at ``values``."""
    return np.concatenate(_point_errors(shared, terms, values), axis=1)


def _point_left(shared: dict, terms: tuple, values: np.ndarray, known: tuple | None = None) -> np.ndarray:
    """``|P j(v)|^2 = |j|^2 - |Q^T j|^2`` at each size (``Q`` orthonormal; inf where not finite).
    ``known``: ``(v, re, im)``, the log errors at one size ``v`` already made (not made again)."""
    at = None if known is None else values == known[0]
    if at is None or not np.any(at):
        re, im = _point_errors(shared, terms, values)
    else:  # each size's errors are elementwise in it: the same numbers made alone or in a batch
        re = np.empty((values.size, known[1].size))
        im = np.empty_like(re)
        re[at], im[at] = known[1], known[2]
        if not np.all(at):
            re[~at], im[~at] = _point_errors(shared, terms, values[~at])
    total = np.einsum("ij,ij->i", re, re) + np.einsum("ij,ij->i", im, im)
    Qr, Qi = shared["Q_parts"]
    if Qr.shape[1]:
        proj = re @ Qr + im @ Qi
        total = total - np.einsum("ij,ij->i", proj, proj)
    return np.where(np.isfinite(total), np.maximum(total, 0.0), np.inf)


def _points_task(shared: dict, chunk: list) -> list:
    """Closed-form screening of one chunk of point effects (:func:`parallel_map_shared` task)."""
    _check_budget(shared["deadline"], f"the screening of {shared['n']} candidates")
    Q, r_perp, j_u = shared["Q"], shared["r_perp"], shared["j_u"]
    rr = float(r_perp @ r_perp)
    out = []
    for k, effect, change in chunk:
        terms = shared["pm"].terms(change)
        sizes, trial = _point_sizes(effect)
        v0 = float(effect.parameters[0].neutral)
        lo, hi = effect.parameters[0].bounds

        t_re, t_im = _point_errors(shared, terms, np.array([trial]))

        def share_of(values, terms=terms, known=(trial, t_re[0], t_im[0])):
            return _point_left(shared, terms, values, known)

        d = np.concatenate([t_re[0], t_im[0]]) - j_u
        d_perp = _project(Q, d)
        dd = float(d_perp @ d_perp)
        if dd > 0 and np.isfinite(dd):  # the secant's linear estimate, as the exact screening's
            v_lin = float(np.clip(v0 - float(d_perp @ r_perp) / dd * (trial - v0), lo, hi))
            sizes = np.array(sorted({*sizes.tolist(), v_lin} - {v0}))
        left = share_of(sizes)
        for _ in range(2):  # refine between the best size's neighbours
            i = int(np.argmin(left))
            a, b = sizes[max(i - 1, 0)], sizes[min(i + 1, sizes.size - 1)]
            if a > 0 and b > 0:
                extra = np.geomspace(a, b, POINT_REFINE + 2)[1:-1]
            else:
                extra = np.linspace(a, b, POINT_REFINE + 2)[1:-1]
            extra = np.clip(extra, lo, hi)
            sizes, left = np.concatenate([sizes, extra]), np.concatenate([left, share_of(extra)])
            order = np.argsort(sizes, kind="stable")
            sizes, left = sizes[order], left[order]
        i = int(np.argmin(left))
        fraction = max(0.0, 1.0 - float(left[i]) / rr) if rr > 0 and np.isfinite(left[i]) else 0.0
        value = float(sizes[i]) if fraction > 0 else v0
        cos = abs(float(d_perp @ r_perp)) / math.sqrt(dd * rr) if dd > 0 and rr > 0 else 0.0
        angle = math.degrees(math.acos(min(1.0, cos))) if np.isfinite(cos) else 90.0
        sk = d @ shared["sketch"] if np.all(np.isfinite(d)) else np.full(2, np.nan)
        out.append((k, dict(fraction=fraction, angle=angle, value=value, evals=0,
                            sketch=(float(d @ d), *map(float, sk)), stage="closed form")))
    return out


def _sketch_twins(screens: dict[int, dict]) -> dict[int, int]:
    """Point effects whose secants agree (to 1e-9) in the sketch kept by :func:`_points_task` (its
    squared norm and two fixed random projections): index -> earlier index, as :func:`_equivalent`."""
    keys = sorted(screens)
    rows = [(k, np.asarray(screens[k]["sketch"], dtype=float)) for k in keys]
    rows = [(k, s) for k, s in rows if np.all(np.isfinite(s)) and s[0] > 0]
    rows.sort(key=lambda ks: ks[1][0])
    twins: dict[int, int] = {}
    for a in range(len(rows)):
        ka, sa = rows[a]
        b = a + 1
        while b < len(rows) and rows[b][1][0] - sa[0] <= 1e-9 * sa[0]:
            kb, sb = rows[b]
            if np.all(np.abs(sa[1:] - sb[1:]) <= 1e-9 * math.sqrt(sa[0] * sa.size)):
                late, early = max(ka, kb), min(ka, kb)
                twins.setdefault(late, twins.get(early, early))
            b += 1
    return twins


def _retune_task(shared: tuple, effect: Any) -> dict:
    """One candidate's full retuning screen (:func:`_screen_retuned`; ``shared`` as :func:`_screen_task`)."""
    res_u, model_u, j_u, Q, r_perp, deadline, n = shared
    _check_budget(deadline, f"the screening of {n} candidates")
    out = _screen_one(res_u, model_u, j_u, Q, r_perp, effect, retune="all")
    out.pop("model", None)
    return out


def _screen_task(shared: tuple, effect: Any) -> dict:
    """One candidate's screening (:func:`parallel_map_shared` task; ``shared`` from
    :func:`_screen_all`)."""
    res_u, model_u, j_u, Q, r_perp, deadline, n = shared
    _check_budget(deadline, f"the screening of {n} candidates")
    out = _screen_one(res_u, model_u, j_u, Q, r_perp, effect)
    # not sent back: a model pickled alone carries its own copy of the structure's matrices
    # (1.2 GB for 6,000 candidates of a 2,000-DOF grid); _screen_all rebuilds it on model_u
    out.pop("model", None)
    return out


def _null_fit(
    res0: Residual,
    upd: tuple[str, ...],
    max_iter: int,
    executor: Executor | None,
    budget: Deadline,
    j0: np.ndarray,
    coarse: bool = True,
) -> tuple[_Null, int]:
    """Bounded LM fit of the update parameters alone (step 1), from the nominal residual ``j0``.

    It starts where :func:`~robustctl.correlate.updating.update` would (its coarse multi-start,
    ``coarse_start``): with parameters 20-50 % off, modes have moved by several bandwidths and
    LM from the model's values stops in a local minimum of the complex-log cost, which leaves
    the parameter error in the residual for the candidates to mimic (a wrong effect ranks first).
    ``coarse=False`` starts LM from the model's values: a chain's next step, whose model carries
    the update parameters and earlier effects as the previous step fitted them with its lead
    (the coarse trials, each a new reduction of a large structure, would start from a fitted point).
    """
    lo, hi = parameter_bounds(res0.model, upd, None)
    if not upd:
        return _Null((), {}, {}, lo, hi, np.zeros((res0.n, 0)), j0, float(j0 @ j0)), 0
    start = sensitivities(res0, upd, j0=j0, executor=executor)
    x0, n_coarse = coarse_start(res0, upd, start, ()) if coarse else ({}, 0)
    x_model = {n: res0.model.param(n).value for n in upd}
    kw = dict(max_iter=max_iter, executor=executor, time_budget_s=budget)
    if x0:
        lm = levenberg_marquardt(res0, upd, x0={**x_model, **x0}, **kw)
    else:
        lm = levenberg_marquardt(res0, upd, start=start, **kw)
    null = _Null(upd, dict(lm.x), x_model, lo, hi, lm.jacobian, lm.vector, lm.cost)
    null.cut = lm.stopped_by_budget
    return null, start.n_evals + n_coarse + lm.n_evals


