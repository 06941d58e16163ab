"""Candidates the data cannot tell apart (:class:`Indistinguishable`): collinear fitted changes,
Vuong's z between them and where their fitted models differ."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..residual import Residual
from .results import _DB

# ============================================================================ indistinguishable
#: Smallest cosine between two candidates' fitted changes of the (noise-whitened) residual for
#: them to count as the same explanation: nearly collinear predicted changes.
COLLINEAR = 0.9
#: Smallest divergence (nepers, RMS over channels) that counts as "the models differ" (0.2 dB).
DIFFER_NP = 0.023
#: Fraction of a channel's peak response below which a divergence counts less (-30 dB).
MEASURABLE = 10 ** (-30 / 20)
#: At most this many stretches where fitted models differ are named.
N_DIFFER_BANDS = 3


@dataclass(frozen=True)
class Indistinguishable:
    """Candidates that explain the data equally well in the band (:func:`_indistinguishable`).

    Attributes
    ----------
    names : tuple of str
        The group, best-ranked first.
    z : tuple of float
        Vuong's statistic of each member against the first (0 for the first).
    cosine : tuple of float
        Cosine between each member's fitted change of the whitened residual and the first's.
    differ_lo_hz, differ_hi_hz, peak_hz : float
        Where the fitted models' responses diverge beyond the noise, outside the band (Hz);
        ``differ_lo_hz`` NaN when they agree within the noise everywhere on the grid examined
        (``differ_hi_hz`` is then its upper end, ``peak_hz`` where they differ most).
    peak_db : float
        The largest divergence there (RMS over channels, dB).
    stretches : tuple of (float, float)
        The frequency stretches (Hz) where they differ beyond the noise, nearest first.
    """

    names: tuple[str, ...]
    z: tuple[float, ...]
    cosine: tuple[float, ...]
    differ_lo_hz: float = math.nan
    differ_hi_hz: float = math.nan
    peak_hz: float = math.nan
    peak_db: float = math.nan
    stretches: tuple[tuple[float, float], ...] = ()

    def sentence(self) -> str:
        """``"These explain the data equally well in this band: ...; they differ at ..."``."""
        head = "These explain the data equally well in this band: " + "; ".join(self.names)
        if not np.isfinite(self.differ_lo_hz):
            return (
                f"{head}. Their fitted models differ by at most {self.peak_db:.2g} dB up to "
                f"{self.differ_hi_hz:.3g} Hz (most at {self.peak_hz:.3g} Hz), within the noise: these "
                "sensors and actuators can hardly tell them apart; measure elsewhere on the structure."
            )
        parts = [f"{a:.3g}" if f"{a:.3g}" == f"{b:.3g}" else f"{a:.3g}-{b:.3g}" for a, b in self.stretches]
        where = parts[0] if len(parts) == 1 else ", ".join(parts[:-1]) + " and " + parts[-1]
        return (
            f"{head}. Their fitted models differ at {where} Hz (up to {self.peak_db:.2g} dB at "
            f"{self.peak_hz:.3g} Hz) -- widen the band or measure there."
        )


def _vuong(r_a: np.ndarray, r_b: np.ndarray, row_noise: np.ndarray | None) -> float:
    """Vuong's (1989) statistic for two non-nested fits: ``z = (J_a - J_b) / (2 sqrt(sum v_i d_i^2))``,
    ``d = r_a - r_b``. Both fits explaining the data equally well, ``z ~ N(0, 1)`` (the cost
    difference is the noise projected on ``d``). Without a noise model, ``v_i`` is the pooled
    residual variance of the better fit."""
    d = r_a - r_b
    v = np.full(d.shape, float(r_b @ r_b) / max(r_b.size, 1)) if row_noise is None else row_noise
    den = 2.0 * math.sqrt(max(float((d * d) @ v), 1e-300))
    return (float(r_a @ r_a) - float(r_b @ r_b)) / den


def _whitened(x: np.ndarray, row_noise: np.ndarray | None) -> np.ndarray:
    return x if row_noise is None else x / np.sqrt(np.maximum(row_noise, 1e-300))


def _cosine(a: np.ndarray, b: np.ndarray) -> float:
    na, nb = float(np.linalg.norm(a)), float(np.linalg.norm(b))
    return float(a @ b) / (na * nb) if na > 0 and nb > 0 else 0.0


def _indistinguishable(
    res0: Residual, ranking: list, fitted: dict[str, dict], j_u: np.ndarray, row_noise, alpha: float
) -> Indistinguishable | None:
    """The fitted candidates the data cannot tell from the best one, or None.

    Two candidates are one explanation when (a) their best-fit costs differ by no more than the
    noise explains -- Vuong's (1989) test for non-nested models, ``|z| < z_{alpha/2}`` -- and
    (b) the changes they make to the (noise-whitened) residual are nearly collinear (cosine >=
    :data:`COLLINEAR`): they remove the same error the same way. Where they differ is then found
    from their own predictions (:func:`_where_they_differ`).
    """
    from scipy.stats import norm

    fits = [r for r in ranking if r.fitted and r.name in fitted]
    if len(fits) < 2:
        return None
    best = fits[0]
    r_best = fitted[best.name]["vector"]
    d_best = _whitened(j_u - r_best, row_noise)
    z_crit = float(norm.isf(alpha / 2))
    names, zs, coss = [best.name], [0.0], [1.0]
    for r in fits[1:]:
        vec = fitted[r.name]["vector"]
        z = _vuong(vec, r_best, row_noise)
        cos = _cosine(_whitened(j_u - vec, row_noise), d_best)
        if abs(z) < z_crit and cos >= COLLINEAR:
            names.append(r.name)
            zs.append(z)
            coss.append(cos)
    if len(names) < 2:
        return None
    where = _where_they_differ(res0, [fitted[n]["model"] for n in names])
    return Indistinguishable(tuple(names), tuple(zs), tuple(coss), *where)


def _where_they_differ(res0: Residual, models: list) -> tuple:
    """Outside the band, where the fitted models' responses diverge beyond the noise.

    The models are evaluated on a grid from a tenth of the band's lower edge up to the data's
    Nyquist frequency when the estimator settings are known (else four times the band's upper
    edge); the divergence at each frequency is the RMS over channels and over the members of
    ``|ln(G_k / G_0)|`` against the first, scaled down where ``|G_0|`` is less than
    :data:`MEASURABLE` of its channel's peak (an anti-resonance: a measurement there is noise, and
    a zero shifted by a hair gives a large log ratio). The stretches beyond the band where it
    exceeds ``max(sigma_med, DIFFER_NP)`` (``sigma_med`` the median noise of one testable point of
    the band -- a stretch of such points tells the models apart -- and :data:`DIFFER_NP`, 0.2 dB)
    are reported, the nearest first (above the band, else below it; at most
    :data:`N_DIFFER_BANDS`): ``(lo, hi, peak frequency, peak dB, stretches)`` with ``lo``/``hi``
    the span of the stretches; if nowhere, ``(NaN, grid end, peak frequency, peak dB, ())`` of the
    largest divergence outside the band.
    """
    lo, hi = float(res0.f_hz[0]), float(res0.f_hz[-1])
    fs = None if res0.estimator is None else res0.estimator.fs_hz
    top = 0.5 * fs if fs else 4.0 * hi
    grid = np.geomspace(max(lo / 10.0, 1e-3), max(top, 1.01 * hi), 600)
    div = _divergence(models, grid)
    thr = DIFFER_NP
    if res0.noise is not None:
        ok = res0.noise.testable
        if np.any(ok):
            thr = max(thr, float(np.median(res0.noise.sigma[ok])))
    outside = (grid > hi) | (grid < lo)
    over = outside & (div > thr)
    if not over.any():  # nowhere beyond the noise: say how little they differ, and where most
        k = int(np.flatnonzero(outside)[np.argmax(div[outside])]) if outside.any() else int(np.argmax(div))
        return math.nan, float(grid[-1]), float(grid[k]), float(_DB * div[k]), ()
    side = over & (grid > hi) if np.any(over & (grid > hi)) else over
    edges = np.flatnonzero(np.diff(np.concatenate([[0], side.astype(int), [0]])))
    runs = list(zip(edges[::2], edges[1::2] - 1))
    runs = runs[:N_DIFFER_BANDS] if np.any(over & (grid > hi)) else runs[::-1][:N_DIFFER_BANDS]
    stretches = tuple((float(grid[a]), float(grid[b])) for a, b in runs)
    idx = np.concatenate([np.arange(a, b + 1) for a, b in runs])
    k = int(idx[np.argmax(div[idx])])
    span = [f for st in stretches for f in st]
    return min(span), max(span), float(grid[k]), float(_DB * div[k]), stretches


def _divergence(models: list, grid: np.ndarray) -> np.ndarray:
    """RMS over channels and members of ``|ln(G_k / G_0)|``, discounted at anti-resonances."""
    g0 = models[0].freqresp(grid).response
    level = np.abs(g0) / np.maximum(np.max(np.abs(g0), axis=0), 1e-300)
    seen = np.minimum(1.0, level / MEASURABLE)
    div = np.zeros(grid.size)
    for m in models[1:]:
        g = m.freqresp(grid).response
        with np.errstate(divide="ignore", invalid="ignore"):
            e = np.log(g / g0)
        e = np.where(np.isfinite(e), e, 0.0) * seen
        div += np.mean(np.abs(e) ** 2, axis=(1, 2))
    return np.sqrt(div / (len(models) - 1))
