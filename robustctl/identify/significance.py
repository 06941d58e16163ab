"""Which poles of a fitted measurement model are physical modes the data support.

A rational fit with enough poles to describe the data to the noise spends some of them on
what is not a mode of the structure: the estimator's leakage (two poles on one broadened
peak), the noise of weak channels (relative weights give a cross channel a thousand times
below the others the same weight), out-of-band dynamics and the sampling hold. Those poles
stay in the model (the model is its fit) but are *fillers*, not modes. A complex pole is a
mode when all of these hold (the criteria of automated modal analysis: Pappa, Elliott &
Schenk 1993, the consistent-mode indicator; Reynders, Houbrechts & De Roeck 2012, sec. 3):

1. **Band and damping**: natural frequency inside the band, damping ratio between the
   refinement's bound ``BOUND_ZETA`` (a pole left at the bound has no interior optimum: the
   data do not determine its decay) and ``ZETA_FILLER``.
2. **Significance against the noise**: removing the pole and refitting the residues of the
   others (a more flexible model than the modal one, so the test is conservative) raises the
   noise-normalised complex-log residual ``sum |ln(G_data/G_model)|^2 / sigma^2`` by more than
   the upper ``ALPHA`` quantile of the chi-square law of a pole that fits noise
   (``n_par = 2 + 2 (n_out + n_in - 1)`` real parameters, times the Satterthwaite factor of
   correlated bins). ``sigma`` is the coherence-based scatter of the H1 estimate where the
   data carry coherence and averages (Bendat & Piersol, Table 9.6), else the robust local
   scale of the model's own residual (:func:`robustctl.measure.noise.noise_model`): model
   error then counts as noise, which only makes the test stricter.
3. **Shape**: the residue of a lightly damped structural mode is close to a rank-one matrix
   of (nearly) collinear phase: its modal phase collinearity (MPC, Pappa et al. 1993 eq. 9;
   the eigenvalue spread of the 2x2 covariance of the real and imaginary parts of its
   entries) is at least ``MPC_MIN``. A pole of a doublet on one peak, or one fitting noise,
   has a shape of scattered phase. For a single channel the MPC is 1 (no test).
4. **One peak, one mode**: of poles closer than three half-power half-widths
   (``3 zeta f``) with similar shapes (MAC above ``DUPLICATE_MAC``), only the most
   significant one is a mode. A stabilisation diagram, when there is one, adds
   5. **Stability across orders**: a pole within ``F_TOL`` in frequency (or the half-power
   band ``2 zeta f``, for close pairs the scan merges) of poles stable in
   frequency and damping at ``CHAIN`` or more orders of the scan, whose damping is at least
   ``ZETA_RATIO`` times its own (the scan fits the raw data, whose leakage only widens a peak;
   a pole the refinement widened to fit a trend has scan poles far narrower than itself).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..lti import log_ratio, pole_frequency_damping
from .leakage import BOUND_ZETA
from .rational_fit import RationalFit
from .selection import ZETA_FILLER
from .stabilisation import CHAIN, DUPLICATE_MAC, F_TOL, NormalWeights, residues_normal

__all__ = ["MPC_MIN", "ALPHA", "PoleEvidence", "pole_evidence", "modal_phase_collinearity"]

#: smallest modal phase collinearity of a mode's residue (Pappa et al. 1993; 1 = real mode)
MPC_MIN = 0.9
#: false-alarm probability of the significance test of one pole (chi-square upper tail)
ALPHA = 1e-6
#: smallest ratio of the damping of the scan's poles that confirm a mode to the mode's damping
#: (the scan fits the raw data, whose leakage only widens a peak: a real mode's scan damping is
#: about its own or larger; a pole the refinement widened to fit a trend has scan poles far
#: narrower than itself)
ZETA_RATIO = 0.5
#: half-width of the neighbourhood over which a mode's significance is counted, in half-power
#: half-widths ``zeta f`` (at least two bins)
LOCAL_WIDTH = 3.0
#: floor of the relative noise scale (nepers), as a measurement model's residual can be ~0
SIGMA_FLOOR = 1e-4


@dataclass(frozen=True)
class PoleEvidence:
    """Per pole of a fit: the evidence that it is a physical mode (see the module notes).

    Attributes
    ----------
    physical : ndarray of bool
        Poles that pass every test.
    candidate : ndarray of bool
        Complex, in band, damping in ``[BOUND_ZETA, ZETA_FILLER)``.
    significance : ndarray
        Rise of the noise-normalised residual when the pole is removed, in units of the test's
        threshold (``>= 1``: significant).
    mpc : ndarray
        Modal phase collinearity of the residue.
    stable : ndarray of bool
        Stable across the scan's orders (all True without a diagram).
    twin : ndarray of bool
        A less significant pole on the same peak with the same shape as a mode.
    noise : str
        Where the noise scale came from (``"coherence"`` or ``"residual"``).
    """

    physical: np.ndarray
    candidate: np.ndarray
    significance: np.ndarray
    mpc: np.ndarray
    stable: np.ndarray
    twin: np.ndarray
    noise: str

    def reason(self, k: int) -> str:
        """Why pole ``k`` is not a mode, in words (empty for a mode).

        Parameters
        ----------
        k : int
            Index into the fit's poles.
        """
        if self.physical[k]:
            return ""
        if not self.candidate[k]:
            return "outside the band, heavily damped, real or at the damping bound"
        if self.twin[k]:
            return "a second pole on the peak of a mode"
        if self.significance[k] < 1:
            return "not significant against the noise"
        if self.mpc[k] < MPC_MIN:
            return f"shape of scattered phase (MPC below {MPC_MIN:g})"
        return "not stable across model orders"


def modal_phase_collinearity(residue: np.ndarray) -> float:
    """MPC of a residue's entries (Pappa, Elliott & Schenk 1993, eq. 9): ``((l1 - l2)/(l1 + l2))^2``
    with ``l1 >= l2`` the eigenvalues of the 2x2 covariance of their real and imaginary parts;
    1 for entries on one line through the origin (a real mode), 0 for a circular scatter.

    Parameters
    ----------
    residue : array_like, complex
        A pole's residue matrix (any shape; its entries are pooled).

    Returns
    -------
    float
        In [0, 1].
    """
    x = np.asarray(residue).ravel()
    if x.size < 2:
        return 1.0
    m = np.array([[x.real @ x.real, x.real @ x.imag], [x.real @ x.imag, x.imag @ x.imag]])
    ev = np.linalg.eigvalsh(m)
    tot = float(ev.sum())
    return float(((ev[1] - ev[0]) / tot) ** 2) if tot > 0 else 0.0


def _noise_scale(fit: RationalFit) -> tuple[np.ndarray, float, str]:
    """Scatter ``sigma`` of ``ln G_data`` per point and channel (nepers; Re and Im alike), the
    Satterthwaite factor of correlated bins, and the source."""
    from ..measure.noise import noise_model, residual_noise

    data = fit.data
    nm = noise_model(data) if data.coherence is not None else None
    source = "coherence"
    if nm is None:
        nm = residual_noise(data, fit.response(data.f_hz), "the fitted model")
        source = "residual"
    sigma = np.maximum(np.broadcast_to(np.asarray(nm.sigma, dtype=float), data.shape), SIGMA_FLOOR)
    return sigma, max(float(nm.chi2_factor or 1.0), 1.0), source


def _mac(a: np.ndarray, b: np.ndarray) -> float:
    den = np.vdot(a, a).real * np.vdot(b, b).real
    return float(np.abs(np.vdot(a, b)) ** 2 / den) if den > 0 else 0.0


def _stable_across_orders(f_hz: np.ndarray, zeta: np.ndarray, diagram) -> np.ndarray:
    """Poles with a diagram pole within ``F_TOL`` (relative) in frequency or its half-power band
    ``2 zeta f``, and of damping at least
    ``ZETA_RATIO`` times theirs at ``CHAIN`` or more orders, counting only the diagram's poles
    stable in frequency and damping against their previous order (``"fd"``, ``"fds"``)."""
    if diagram is None or len(diagram.f_hz) < CHAIN:  # no scan, or one cut short by a time budget
        return np.ones(f_hz.size, dtype=bool)
    hits = np.zeros(f_hz.size, dtype=int)
    z = np.maximum(zeta, 1e-12)[:, None]
    for f_all, z_all, status in zip(diagram.f_hz, diagram.zeta, diagram.status):
        settled = np.isin(status, ("fd", "fds"))  # stable in frequency and damping at that order
        f_order, z_order = f_all[settled], z_all[settled]
        if f_order.size:
            # within F_TOL, or under the half-power band of a scan pole (a close pair the scan
            # merges into one pole and the rank-1 refinement resolves)
            width = np.maximum(F_TOL * f_hz[:, None], 2 * z_order[None, :] * f_order[None, :])
            near = np.abs(f_order[None, :] - f_hz[:, None]) <= width
            near &= z_order[None, :] >= ZETA_RATIO * z
            hits += np.any(near, axis=1)
    return hits >= CHAIN


def pole_evidence(fit: RationalFit, diagram=None, candidates: np.ndarray | None = None) -> PoleEvidence:
    """The evidence that each pole of ``fit`` (with its data) is a physical mode.

    Parameters
    ----------
    fit : RationalFit
        A fit with ``data`` (the data it was fitted to, Hz).
    diagram : StabilisationDiagram, optional
        The order scan; without it the stability test is skipped.
    candidates : ndarray of bool, optional
        Poles that may be modes at all (default: every pole); others are fillers.

    Returns
    -------
    PoleEvidence
    """
    poles = np.asarray(fit.poles)
    n_p = poles.size
    f, zeta = pole_frequency_damping(poles)
    lo, hi = fit.band_hz
    cand = (poles.imag != 0) & (f >= lo) & (f <= hi) & (zeta >= BOUND_ZETA) & (zeta < ZETA_FILLER)
    cand &= np.asarray(fit.ranks) > 0
    if candidates is not None:
        cand &= np.asarray(candidates, dtype=bool)
    sig = np.zeros(n_p)
    mpc = np.array([modal_phase_collinearity(r) for r in fit.residues])
    if np.any(cand):
        sig = _significance(fit, cand)
    stable = _stable_across_orders(f, zeta, diagram)
    base = cand & (sig >= 1) & stable
    ok = base & (mpc >= MPC_MIN)
    twin = np.zeros(n_p, dtype=bool)
    for j in np.argsort(-sig, kind="stable"):  # most significant first
        if not base[j] or twin[j]:
            continue
        for i in np.flatnonzero(base & ~twin):
            if i == j or not abs(f[i] - f[j]) < 3 * max(zeta[i] * f[i], zeta[j] * f[j]):
                continue
            same = _mac(fit.residues[i].ravel(), fit.residues[j].ravel()) > DUPLICATE_MAC
            # a doublet: two poles of scattered phase whose sum is a mode's shape (one broadened peak)
            joint = modal_phase_collinearity(fit.residues[i] + fit.residues[j])
            doublet = max(mpc[i], mpc[j]) < MPC_MIN <= joint
            if ok[j] and same or doublet:
                ok[j] = True
                twin[i] = True
    return PoleEvidence(ok & ~twin, cand, sig, mpc, stable, twin, _noise_source(fit))


def _noise_source(fit: RationalFit) -> str:
    return "coherence" if fit.data.coherence is not None else "residual"


def _significance(fit: RationalFit, cand: np.ndarray, local: bool = True) -> np.ndarray:
    """Per candidate pole: the rise of ``sum |ln(G/G_model)|^2 / sigma^2`` when the pole is
    removed and the other residues refitted, over the chi-square threshold of a noise pole; summed
    over the pole's own half-power neighbourhood (``local``) or over the whole band (a pole outside
    the band, whose neighbourhood holds no data)."""
    from scipy.stats import chi2

    data = fit.data
    k = data.f_hz.size
    s = 2j * np.pi * data.f_hz
    g = data.response.reshape(k, -1)
    sigma, factor, _ = _noise_scale(fit)
    sigma = sigma.reshape(k, -1)
    # nested least-squares fits in the test's own metric: the relative error over the noise scale
    rw = 1.0 / (np.maximum(np.abs(g), np.finfo(float).tiny) * sigma)
    poles = np.asarray(fit.poles)
    weights = NormalWeights(g, rw)  # the same for every pole set

    def chi(p: np.ndarray) -> np.ndarray:  # per point: noise-normalised residual, residues refitted
        res, d = residues_normal(s, g, rw, p, weights)
        model = np.broadcast_to(d, g.shape).astype(complex)
        for q, r in zip(p, res):
            model = model + (1.0 / (s - q))[:, None] * r
            if q.imag != 0:
                model = model + (1.0 / (s - np.conj(q)))[:, None] * np.conj(r)
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
            return np.sum(np.abs(log_ratio(g, model)) ** 2 / sigma**2, axis=1)

    base = chi(poles)
    f_hz = data.f_hz
    step = np.gradient(f_hz) if f_hz.size > 1 else np.ones(1)
    n_out, n_in = data.response.shape[1:]
    n_par = 2 + 2 * (n_out + n_in - 1) if min(n_out, n_in) > 0 else 2
    threshold = factor * float(chi2.isf(ALPHA, n_par))
    out = np.zeros(fit.poles.size)
    for j in np.flatnonzero(cand):
        drop = chi(np.delete(poles, j))
        fj = abs(poles[j]) / (2 * np.pi)
        zj = -poles[j].real / abs(poles[j])
        near = np.abs(f_hz - fj) <= np.maximum(LOCAL_WIDTH * zj * fj, 2 * step) if local else slice(None)
        gain = float(np.sum(drop[near] - base[near]))
        out[j] = gain / threshold if np.isfinite(gain) else np.inf
    return out


