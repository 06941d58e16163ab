"""Significance tests of ``rc.diagnose``: effective points of correlated residuals, the nested
F/chi-square test of a candidate, Vuong's test between rivals (Vuong 1989, eq. 5.6), Holm's
adjustment (Holm 1979), the null fit's chi-square and the scoring of the fitted candidates."""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import numpy as np

from ..residual import Residual
from .localize import channel_pair_pattern, channel_pattern
from .results import CandidateResult
from .sentences import _hold_note, _where, _with_sentence


# ============================================================================ statistics
def effective_points(e: np.ndarray) -> tuple[float, float]:
    """Effective number of independent real residual entries, ``n (1 - rho) / (1 + rho)``.

    Parameters
    ----------
    e : ndarray, complex, shape (n_freq, n_out, n_in)
        Complex log residual.

    Returns
    -------
    n_eff : float
    rho : float
        Pooled lag-one autocorrelation along frequency of the real and imaginary parts
        (each channel's mean removed), clipped to [0, 0.995].
    """
    parts = np.concatenate([e.real.reshape(e.shape[0], -1), e.imag.reshape(e.shape[0], -1)], axis=1)
    n = parts.size
    if parts.shape[0] < 3:
        return float(n), 0.0
    x = parts - parts.mean(axis=0)
    den = float(np.sum(x * x))
    rho = float(np.sum(x[1:] * x[:-1]) / den) if den > 0 else 0.0
    rho = min(max(rho, 0.0), 0.995)
    return n * (1.0 - rho) / (1.0 + rho), rho


def _testable_rows(res: Residual) -> np.ndarray:
    """Rows of the residual vector where the noise model holds (``NoiseModel.testable``: coherence
    significantly above zero, ``sigma`` small enough for ``ln H1`` to be near Gaussian); all rows
    without a noise model. Elsewhere the log error is heavy-tailed, and a candidate that moves a
    weak cross channel (a tiny misalignment) would fit its outliers."""
    if res.noise is None:
        return np.ones(res.n, dtype=bool)
    ok = np.broadcast_to(res.noise.testable, res.data.shape).ravel()
    return np.concatenate([ok, ok])


def _row_noise(res: Residual) -> np.ndarray | None:
    """Noise variance of each row of the weighted residual vector, or None.

    The variance of a projection of the residual on a smooth direction is that of its rows times
    the Satterthwaite factor of contiguous bins, ``1 + 2 sum_m r_m`` (the noise model's
    ``chi2_factor``: output noise and leakage alike, :mod:`robustctl.measure.noise`), not the smaller
    factor of output noise alone (``dof_factor``), which underrated the variance along a fitted
    change and made p-values anti-conservative."""
    if res.noise is None:
        return None
    v = (res.point_weights * res.noise.sigma**2 * res.noise.chi2_factor).ravel()
    return np.concatenate([v, v])


#: Half-width (points along frequency) of the running mean that estimates the local variance of a
#: misfit (:func:`_local_variance`).
MISFIT_HALF_WIDTH = 8


def _local_variance(vec: np.ndarray, shape: tuple) -> np.ndarray:
    """Local variance of each row of a residual vector: the running mean over
    ``2 MISFIT_HALF_WIDTH + 1`` frequencies of its squares, real and imaginary parts pooled
    (a heteroscedasticity-consistent scale, White 1980, smoothed along frequency)."""
    from scipy.ndimage import uniform_filter1d

    half = vec.size // 2
    nf = shape[0]
    sq = vec[:half].reshape(nf, -1) ** 2 + vec[half:].reshape(nf, -1) ** 2
    loc = 0.5 * uniform_filter1d(sq, 2 * MISFIT_HALF_WIDTH + 1, axis=0, mode="nearest")
    v = loc.ravel()
    return np.concatenate([v, v])


def _misfit_variance(left: np.ndarray, res: Residual) -> tuple[np.ndarray, float]:
    """Per-row variance of the misfit ``left`` and its AR(1) inflation ``kappa = (1 + rho) / (1 - rho)``
    (``rho`` the lag-one autocorrelation along frequency, :func:`effective_points`): the variance
    of a projection of an AR(1) sequence on a smooth direction is ``kappa`` times that of its
    rows (Bartlett 1946)."""
    _, rho = effective_points(res.unstack(left))
    return _local_variance(left, res.data.shape), (1.0 + rho) / (1.0 - rho)


def _misfit_along(left: np.ndarray, delta: np.ndarray, res: Residual) -> tuple[float, float]:
    """Variance of the misfit ``left`` projected on the unit direction ``delta / |delta|``, and the
    effective number of points behind it: ``(v, nu)``.

    The misfit is modelled as a random field whose rows have the local variance ``s^2``
    (:func:`_local_variance`), correlated along frequency like an AR(1) sequence (inflation
    ``kappa``, :func:`_misfit_variance`) and across channels and real/imaginary parts by the
    correlation matrix ``R`` of the normalised misfit (a model error at one resonance shows in
    every channel that sees the mode): ``v = kappa sum_f a_f^T R a_f / |delta|^2`` with
    ``a_f = delta_f s_f`` (a sandwich estimate of the projection's variance, White 1980, with the
    separable correlation). ``nu``: the participation number of ``delta^2`` over ``kappa`` and
    the largest eigenvalue of ``R``."""
    local, kappa = _misfit_variance(left, res)
    nf = res.data.shape[0]

    def cols(x: np.ndarray) -> np.ndarray:  # (nf, 2 n_channels): real parts, then imaginary parts
        return np.concatenate([x[: x.size // 2].reshape(nf, -1), x[x.size // 2:].reshape(nf, -1)], axis=1)

    sd = np.sqrt(np.maximum(cols(local), 0.0))
    sd = np.where(sd > 1e-9 * max(float(sd.max()), 1e-300), sd, 0.0)  # round-off of the running mean
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        z = np.where(sd > 0, cols(left) / np.where(sd > 0, sd, 1.0), 0.0)
    g = z.T @ z / nf
    dg = np.sqrt(np.maximum(np.diag(g), 1e-300))
    R = g / np.outer(dg, dg)
    R[np.diag(g) <= 0] = 0.0
    R[:, np.diag(g) <= 0] = 0.0
    a = cols(delta) * sd
    d2 = np.asarray(delta, dtype=float) ** 2
    total = float(d2.sum())
    v = kappa * float(np.einsum("fi,ij,fj->", a, R, a)) / total
    lam = max(1.0, float(np.linalg.eigvalsh(R)[-1])) if R.size else 1.0
    nu = max(1.0, total**2 / float(d2 @ d2) / (kappa * lam))
    return v, nu


def _candidate_test(
    drop: float, delta: np.ndarray, left: np.ndarray, row_noise: np.ndarray | None, res: Residual
) -> tuple[float, float, str]:
    """Test of one fitted candidate: ``(T, p, scale)``.

    Under "the effect is absent" the cost drop ``Delta J`` of a one-parameter fit is the residual
    projected on the fitted change ``delta``: ``Delta J ~ v chi2_1`` with ``v = sum delta_i^2 v_i /
    sum delta_i^2`` the variance along it (a likelihood-ratio test with one degree of freedom;
    a parameter held at a bound makes it a conservative chi-bar-square). Two variances are at
    hand: the noise model's (``row_noise``, with the bins' correlation) and the misfit the
    candidate leaves (``left``, correlated along frequency and across channels,
    :func:`_misfit_along`). The larger is used: within the noise the two agree; with model
    error (the parameters-only fit beyond the noise) the misfit is the scale against which a
    candidate must stand out, and its estimate carries ``nu`` effective points, so ``T`` is then
    referred to ``F(1, nu)``. NaNs without a noise model.
    """
    if row_noise is None:
        return math.nan, math.nan, ""
    from scipy.stats import chi2, f

    d2 = np.asarray(delta, dtype=float) ** 2
    total = float(d2.sum())
    if total <= 0 or drop <= 0:
        return 0.0, 1.0, "noise"
    v_noise = float(d2 @ row_noise) / total
    v_mis, nu = _misfit_along(left, delta, res)
    if v_mis <= v_noise:
        t = drop / max(v_noise, 1e-300)
        return t, float(chi2.sf(t, 1)), "noise"
    t = drop / v_mis
    return t, float(f.sf(t, 1, nu)), "misfit"


def _rival_test(best_vec: np.ndarray, vec: np.ndarray, row_noise: np.ndarray | None, res: Residual):
    """Vuong's (1989) test of the best candidate against a rival: ``(z, p)``, ``p`` one-sided
    ("the best explains the data no better").

    ``m_i = r_rival,i^2 - r_best,i^2`` is the pointwise difference of the two fits' squared
    residuals (log-likelihood ratio terms); ``z = sum m_i / sqrt(kappa n s_m^2)`` with ``s_m^2`` their
    sample variance (Vuong's eq. 5.6: the variance is estimated from the data, so a rival that
    loses only on a few points is not separated by them) and ``kappa`` the AR(1) inflation of
    ``m`` along frequency. NaNs without a noise model."""
    if row_noise is None:
        return math.nan, math.nan
    from scipy.stats import norm

    m = vec**2 - best_vec**2
    n = m.size
    x = m.reshape(2, res.data.shape[0], -1).transpose(1, 0, 2).reshape(res.data.shape[0], -1)
    xc = x - x.mean(axis=0)
    den = float(np.sum(xc * xc))
    rho = min(max(float(np.sum(xc[1:] * xc[:-1]) / den), 0.0), 0.995) if den > 0 else 0.0
    kappa = (1.0 + rho) / (1.0 - rho)
    var = float(np.var(m)) * n * kappa
    z = float(m.sum()) / math.sqrt(max(var, 1e-300))
    return z, float(norm.sf(z))


def _holm(p_raw: list[float], m: int) -> list[float]:
    """Holm's (1979) step-down adjustment of ``p_raw`` within a family of ``m >= len(p_raw)``
    tests (the others count as not rejected): ``p_(k) = max_{j <= k} min(1, (m - j + 1) p_(j))``.
    Controls the family-wise error rate, so the smallest adjusted p-value (the best candidate's,
    Bonferroni's ``m p``) is conservative under "no effect is missing"."""
    out = [math.nan] * len(p_raw)
    finite = sorted((p, i) for i, p in enumerate(p_raw) if np.isfinite(p))
    run = 0.0
    for j, (p, i) in enumerate(finite):
        run = max(run, min(1.0, (m - j) * p))
        out[i] = run
    return out


def _at_bound(
    effect: Any, value: float, extra: Mapping[str, float] | None = None, screened: Any = None
) -> bool:
    """Whether a fitted value sits at a bound of the effect's parameter away from neutral (a
    +200 % gain error at the gain's upper bound: the data ask for more than the effect allows),
    or a value fitted with the size (``extra``: a resonator's frequency at its 1 mHz floor, a mass
    on a mount too soft to be a resonator) sits at any bound of its parameter; ``extra`` is keyed by
    the parameter names of the effect as ``screened`` (a retuned effect's names carry its value)."""
    if _is_switch(effect):
        return False
    par = effect.parameters[0]
    lo, hi = par.bounds
    for b in (lo, hi):
        if np.isfinite(b) and b != par.neutral and abs(value - b) <= 1e-6 * max(abs(b - par.neutral), 1e-300):
            return True
    bounds = {p.name: p.bounds for p in (screened or effect).parameters[1:]}
    for name, v in (extra or {}).items():
        for b in bounds.get(name, ()):
            if np.isfinite(b) and abs(v - b) <= 1e-6 * max(abs(b), 1e-300):
                return True
    return False


def _is_switch(effect: Any) -> bool:
    """An effect with discrete states (gravity on/off, swapped cables, a sign flip, a units slip,
    a sensor on another node): screened at its states, fitted with the state fixed."""
    return bool(getattr(effect, "toggle", False)) or bool(getattr(effect, "switch", False))


def _null_test(res: Residual, j_u: np.ndarray) -> tuple[float, float]:
    """``(dispersion, p)``: is the parameters-only fit within the noise? The normalised residual
    on the testable points against a chi-square with the noise model's Satterthwaite factor
    (:func:`robustctl.measure.noise.chi2_verdict`); NaNs without a noise model."""
    if res.noise is None:
        return math.nan, math.nan
    from scipy.stats import chi2

    base = (res.point_weights * res.noise.sigma**2).ravel()
    ok = ((res.point_weights > 0) & res.noise.testable).ravel()
    ok = np.concatenate([ok, ok]) & (np.concatenate([base, base]) > 0)
    if not ok.any():
        return math.nan, math.nan
    z2 = j_u[ok] ** 2 / np.concatenate([base, base])[ok]
    c = max(float(res.noise.chi2_factor), 1.0)
    s, n = float(z2.sum()), int(ok.sum())
    return s / n, float(chi2.sf(s / c, n / c))


#: Share of the null fit's excess misfit one output row (input column) must hold to be named.
CHANNEL_SHARE = 0.5
#: Share of the excess two output rows (input columns) must hold together, overall and in every
#: frequency segment holding a real part of it, to be named as a pair (:func:`_pair_verdict`).
PAIR_SHARE = 0.8


def _channel_verdict(res: Residual, j_u: np.ndarray) -> str:
    """Name the output row (or input column) that holds an unexplained misfit, when its pattern is
    a channel's: that row or column holds most of it at every frequency (:func:`channel_pattern`);
    a structural fault, at its modes in every channel that sees them, is named by its bands and
    modes instead (:func:`robustctl.correlate.diagnosis.localize.misfit_bands`). Without a noise
    model the row or column holding most of the squared misfit is named."""
    d = res.data
    if res.noise is not None:
        pattern = channel_pattern(res, j_u, CHANNEL_SHARE)
        if pattern is None:
            return _pair_verdict(res, j_u)
        side, k, share = pattern
    else:
        per = np.abs(res.unstack(j_u)) ** 2
        total = float(per.sum())
        if total <= 0:
            return ""
        side, k, share = "", 0, 0.0
        for name, axis, n in (("output", (0, 2), d.n_out), ("input", (0, 1), d.n_in)):
            part = per.sum(axis=axis) / total
            if n > 1 and part.max() > CHANNEL_SHARE and part.max() > 1.5 / n:
                side, k, share = name, int(np.argmax(part)), float(part.max())
                break
        if not side:
            return ""
    what, check = (
        (f"output {d.outputs[k]}'s row", "its calibration") if side == "output"
        else (f"input {d.inputs[k]}'s column", "the force measurement's calibration")
    )
    return (
        f"The misfit sits in {what} ({100 * share:.0f}% of it, at every frequency); no candidate explains "
        f"it: check its cable, sign and location (node and direction), and {check}."
    )


def _pair_verdict(res: Residual, j_u: np.ndarray) -> str:
    """Name two output rows (input columns) that together hold an unexplained misfit at every
    frequency (:func:`channel_pair_pattern`, :data:`PAIR_SHARE`): two cables swapped, or two
    sensors (shakers) exchanged or mislabelled; "" when the pattern is not two channels'."""
    pattern = channel_pair_pattern(res, j_u, PAIR_SHARE)
    if pattern is None:
        return ""
    side, (i, j), share = pattern
    names = res.data.outputs if side == "output" else res.data.inputs
    what = "rows" if side == "output" else "columns"
    return (
        f"The misfit sits in {side}s {names[i]} and {names[j]}'s {what} ({100 * share:.0f}% of it, at every "
        "frequency); no candidate explains it: check whether their cables are swapped, then each one's "
        "sign, location (node and direction) and calibration."
    )


def _score(
    res0: Residual,
    screens: list[dict],
    order: list[int],
    top: list[int],
    fits: list[dict],
    twins: dict[int, int],
    j_u: np.ndarray,
    st: dict[str, Any],
) -> tuple[list, dict]:
    """CandidateResults: fitted ones by gain (tests, sentence), then the rest by fraction.

    Each fitted candidate is tested alone (:func:`_candidate_test`); the p-values are then
    adjusted over the ``m`` screened candidates (:func:`_holm`), and each rival is compared with the
    best (:func:`_rival_test`)."""
    from dataclasses import replace

    results, explained = [], {}
    row_noise = st["row_noise"]

    def twins_of(k: int) -> tuple[str, ...]:
        return tuple(screens[t]["effect"].name for t, i in twins.items() if i == k)

    raw = []
    for k, fit in zip(top, fits):
        s = screens[k]
        effect = s["effect"].with_values(**{s["effect"].param_names[0]: fit["value"], **fit.get("extra", {})})
        gain = _reduction(fit["cost"], st["cost_u"])
        delta = j_u - fit["vector"]
        ok = st["testable"]  # the test counts the points where ln H1 is near Gaussian (noise module)
        left = fit["vector"] * ok
        f_stat, p_val, scale = _candidate_test(float(j_u[ok] @ j_u[ok] - left @ left), delta * ok, left,
                                               row_noise, res0)
        raw.append(p_val)
        results.append(
            _candidate_result(
                s, effect, fit["cost"], st, twins_of(k), fitted=True,
                gain=gain,
                f_stat=f_stat,
                p_value=p_val,
                update_values={n: v for n, v in fit["x"].items() if n in st["upd"]},
                where=_where(res0, delta),
                level=st["alpha"] if row_noise is not None else math.nan,
                p_raw=p_val,
                scale=scale,
                at_bound=_at_bound(effect, float(fit["value"]), fit.get("extra"), s["effect"]),
            )
        )
        explained[effect.name] = res0.unstack(delta)
    adjusted = _holm(raw, st["m"])
    vectors = {results[i].name: fits[i]["vector"] for i in range(len(results))}
    results = [
        replace(
            r,
            p_value=p,
            significant=bool(
                np.isfinite(p)
                and p < st["alpha"]
                and r.gain >= st["min_gain"]
                and not r.at_bound
                and st["cost_u"] - r.cost > 1e-10 * st["cost_nominal"]
            ),
        )
        for r, p in zip(results, adjusted)
    ]
    order_fit = sorted(range(len(results)),
                       key=lambda i: (results[i].at_bound, -round(results[i].gain, 9), i))
    results = [results[i] for i in order_fit]
    if results:
        lead = next((r for r in results if not r.at_bound), results[0])
        for i, r in enumerate(results):
            if r is not lead:
                z, p = _rival_test(vectors[lead.name], vectors[r.name], row_noise, res0)
                results[i] = replace(r, z_vs_best=z, p_vs_best=p)
    explained = {r.name: explained[r.name] for r in results[:2]}
    for k in order:
        if k in top:
            continue
        s = screens[k]
        effect = s["effect"].with_values(**{s["effect"].param_names[0]: s["value"]})
        cost = st["cost_u"] * (1 - s["fraction"])
        results.append(_candidate_result(s, effect, cost, st, twins_of(k), fitted=False, gain=s["fraction"]))
    return [_with_sentence(r) for r in results], explained


def _candidate_result(
    s: dict, effect: Any, cost: float, st: dict, equivalent: tuple, *, fitted: bool, **figures: Any
) -> CandidateResult:
    """One ranked candidate, fitted or screened only: what both know (its screen ``s``, its cost
    and the diagnosis state ``st``) and the ``figures`` only the fit gives."""
    return CandidateResult(
        effect=effect,
        fraction=s["fraction"],
        angle_deg=s["angle"],
        fitted=fitted,
        cost=cost,
        reduction=_reduction(cost, st["cost_nominal"]),
        equivalent=equivalent,
        min_gain=st["min_gain"],
        note=_hold_note(effect, st["fs_hz"]),
        **figures,
    )


def _reduction(cost: float, reference: float) -> float:
    return max(0.0, 1.0 - cost / reference) if reference > 0 else 0.0


