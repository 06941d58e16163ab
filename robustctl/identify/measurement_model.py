"""``fit_measurement_model``: the project's yardstick, the best linear description of what was
measured, in one call.

The procedure (:mod:`.modal_fit`): (1) a common-denominator rational fit (VF or Chebyshev)
of the band with spare poles, or the Caltech route of one SIMO fit per input joined by
:func:`combine_simo` and reduced by :func:`group_modes`; (2) exactly ``n_modes`` modes chosen
by contribution (:mod:`.selection`; close pairs split by residue rank, fillers apart), each
with a rank-1 residue (Caltech eq. 9); (3) poles and shapes refined together by nonlinear
least squares (:mod:`.modal_refine`: all at once on small problems, block by block by
variable projection on large ones); (4) optionally, for white-noise tests estimated by
:func:`robustctl.estimate_frf`, a few fixed-point steps that undo the estimator's window
leakage (see :mod:`.leakage`); (5) for impact data with an exponential window, the window's
damping removed; (6) the complex-log cost of MACE eq. 5. With ``n_modes=None`` the order
comes from a one-pass stabilisation diagram (:mod:`.stabilisation`). Iteration caps bound the
work; an opt-in time budget ends it early and the result says so (``stopped_by_budget``). The
returned model is one system: its residues are its realisation's factors, every pole is damped
by at least ``STABILITY_ZETA``, and the cost is that system's.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, fields, replace
from typing import Any

import numpy as np

from ..budget import as_deadline
from ..checks import UNSET, band_data, renamed_keyword
from ..errors import FitError, RobustctlError
from ..frd import FrequencyData, as_frequency_data
from ..lti import DB_PER_NEPER, log_ratio, pole_frequency_damping, rebuild_statespace, statespace_state
from ..modes import Mode
from ..plots import bode_grid
from ..table import Table, result_html
from ..threads import limit_blas
from ._problem import prepare_problem
from .cost import LogCost, channel_cost
from .leakage import (
    BOUND_ZETA,
    EstimatorSettings,
    TruncationSettings,
    estimator_settings,
    expected_h1,
    truncation_settings,
)
from .modal_fit import FitSettings, _log_cost, fit_best, fit_with_leakage, shift_poles, spare_pairs
from .modal_refine import ZETA_MIN
from .rational_fit import IdentifyWarning, RationalFit
from .realization import residue_factors
from .refine import _row_weights, refine_residues
from .selection import ZETA_FILLER, pole_contributions
from .significance import PoleEvidence, pole_evidence
from .stabilisation import (
    MIN_CONTRIBUTION,
    REL_CONTRIBUTION,
    StabilisationDiagram,
    distinct_modes,
    stabilisation_scan,
)

__all__ = ["Mode", "MeasurementModel", "fit_measurement_model", "StabilisationDiagram", "pinned_modes",
           "leakage_consistency"]

#: default time budget of one fit_measurement_model call: none (iteration caps bound the work, so
#: the result depends only on the input and the options, never on the clock or the load)
TIME_BUDGET_S = None
#: a leakage-corrected model is flagged when its expected H1 misses the raw data by more than
#: INCONSISTENT_RATIO times its miss of the corrected data plus INCONSISTENT_DB (weighted rms, dB)
INCONSISTENT_RATIO, INCONSISTENT_DB = 1.25, 0.25


@dataclass(frozen=True, eq=False)
class MeasurementModel:
    """A measurement model: state space, modes and complex-log cost against the data.

    Attributes
    ----------
    sys : control.StateSpace
        Real modal realisation with the data's signal names.
    modes : tuple of Mode
        The physical modes the data support, sorted by frequency: complex poles inside the band,
        damping between the bound and ``ZETA_FILLER`` (0.2), significant against the noise near
        their resonance, of nearly collinear phase, one per peak and (automatic order) stable
        across the scan's orders (:func:`.significance.pole_evidence`). With ``n_modes=N`` there
        are N of them, or fewer with an :class:`IdentifyWarning` giving the number the data
        support; fillers are apart.
    cost : LogCost
        MACE eq. 5 of ``sys`` against ``data`` (per channel and total).
    fit : RationalFit
        The underlying pole-residue model (ranks as realised).
    data : FrequencyData
        The band data the model was scored on (leakage-corrected when ``leakage_corrected``).
    raw_data : FrequencyData
        The band data as measured.
    leakage_corrected : bool
        Whether the estimator's window leakage was undone before fitting.
    order_scan : tuple of (int, float)
        ``(pole pairs, total cost)`` of every order tried by the automatic order selection.
    fillers : tuple of Mode
        Poles kept in ``sys`` and ``fit`` that are not modes: outside the band, heavily damped
        (``zeta >= 0.2``), real, at the damping bound, not significant against the noise, of
        scattered phase or a second pole on a mode's peak (``evidence.reason``); they stand for
        out-of-band modes, residual flexibility and what the estimator and the noise add.
    stabilisation : StabilisationDiagram or None
        The automatic order's stabilisation diagram (``None`` with a given ``n_modes``).
    window_tau_s : float or None
        Time constant of the exponential window undone in ``sys``, ``modes`` and ``fit``
        (poles moved by ``+1/tau``); ``cost`` and :meth:`plot` compare the windowed model
        with the (windowed) data.
    stopped_by_budget : bool
        Whether the opt-in ``time_budget_s`` ended the fit early (the model is then the best
        found so far and depends on the machine's speed and load).
    corrections : tuple of str
        The corrections applied to the data or the model, in words (empty: a plain fit).
    evidence : PoleEvidence or None
        Per pole of ``fit``: the tests that make it a mode or a filler (significance against the
        noise, phase collinearity, stability across orders; :mod:`.significance`).
    """

    sys: Any
    modes: tuple[Mode, ...]
    cost: LogCost
    fit: RationalFit
    data: FrequencyData
    raw_data: FrequencyData
    leakage_corrected: bool = False
    order_scan: tuple[tuple[int, float], ...] = ()
    fillers: tuple[Mode, ...] = ()
    stabilisation: Any = None
    window_tau_s: float | None = None
    stopped_by_budget: bool = False
    corrections: tuple[str, ...] = ()
    evidence: Any = None

    def statespace(self):
        """The real modal ``control.StateSpace`` (the state-space protocol, :func:`rc.as_statespace`)."""
        return self.sys

    @property
    def inputs(self) -> tuple[str, ...]:
        return tuple(self.fit.inputs)

    @property
    def outputs(self) -> tuple[str, ...]:
        return tuple(self.fit.outputs)

    def summary(self) -> str:
        """A few sentences in plain words."""
        lo, hi = self.band_hz
        lines = [
            f"MeasurementModel of {len(self.outputs)} outputs x {len(self.inputs)} inputs on "
            f"{lo:.4g}-{hi:.4g} Hz: {self.n_modes} modes, {self.sys.nstates} states.",
            f"Complex-log cost J = {self.cost.total:.4g} (MACE eq. 5), rms log-magnitude error "
            f"{self.cost.rms_db_total:.3g} dB.",
        ]
        if self.fillers:
            lines.append(
                f"{len(self.fillers)} filler pole(s) (outside the band, heavily damped, not significant "
                "against the noise, of scattered phase or a second pole on a mode's peak) are kept in the "
                "model and listed in .fillers, not counted as modes."
            )
        if self.leakage_corrected and truncation_settings(self.raw_data.meta) is not None:
            lines.append(
                "The data were corrected for the truncation of the responses at the record end "
                "(rectangular-window leakage of the impact test) before fitting."
            )
        elif self.leakage_corrected:
            lines.append("The data were corrected for the H1 estimator's window leakage before fitting.")
        if self.window_tau_s is not None:
            lines.append(
                f"The exponential window's damping (tau = {self.window_tau_s:.4g} s) was removed from "
                "the modes."
            )
        lines.append("Corrections: " + ("; ".join(self.corrections) if self.corrections else "none applied")
                     + ".")
        zeta, re_max = self.stability_margin
        lines.append(
            f"Asymptotically stable: smallest pole damping ratio {zeta:.3g} (margin {STABILITY_ZETA:g}), "
            f"largest real part {re_max:.4g} 1/s."
        )
        if self.stopped_by_budget:
            lines.append(
                "STOPPED BY THE TIME BUDGET: the model is the best found before time_budget_s ran out and "
                "depends on this machine's speed and load."
            )
        if self.stabilisation is not None:
            lines.append(
                f"Order chosen by the stabilisation diagram over {self.stabilisation.orders.size} orders "
                "(.stabilisation.plot())."
            )
        return "\n".join(lines)

    def __reduce__(self):
        """Pickle the state space as matrices and names (python-control's StateSpace holds a lambda)."""
        state = {f.name: getattr(self, f.name) for f in fields(self)}
        state["sys"] = statespace_state(self.sys)
        return (_rebuild_measurement_model, (state,))

    @property
    def stability_margin(self) -> tuple[float, float]:
        """``(smallest damping ratio, largest real part in 1/s)`` over the poles of ``sys``."""
        p = np.linalg.eigvals(np.asarray(self.sys.A)) if self.sys.nstates else np.zeros(0)
        if p.size == 0:
            return 1.0, -np.inf
        zeta = -p.real / np.maximum(np.abs(p), np.finfo(float).tiny)
        return float(zeta.min()), float(p.real.max())

    @property
    def n_modes(self) -> int:
        """Number of modes (sum of mode ranks)."""
        return int(sum(m.rank for m in self.modes))

    @property
    def band_hz(self) -> tuple[float, float]:
        return self.fit.band_hz

    def freqresp(self, f_hz: Any) -> FrequencyData:
        """Model response at ``f_hz`` (Hz)."""
        return self.fit.freqresp(f_hz)

    def table(self) -> Table:
        """One row per mode: frequency, damping, rank, largest residue entry."""
        rows = [
            (k, m.f_hz, 100 * m.zeta, m.rank, float(np.max(np.abs(m.residue))))
            for k, m in enumerate(self.modes, start=1)
        ]
        cols = ("mode", "f (Hz)", "damping (%)", "rank", "max |residue|")
        title = (
            f"Measurement model: {self.n_modes} modes, band {self.band_hz[0]:.4g}-{self.band_hz[1]:.4g} Hz, "
            f"rms log-magnitude error {self.cost.rms_db_total:.3g} dB"
        )
        return Table(cols, rows, title=title)

    def plot(self, max_channels: int = 9):
        """Data and model per channel, magnitude and phase (matplotlib Figure)."""
        fit = self.fit if self.window_tau_s is None else shift_poles(self.fit, -1.0 / self.window_tau_s)
        model = fit.freqresp(self.data.f_hz)
        label = "data (leakage-corrected)" if self.leakage_corrected else "data"
        return bode_grid(
            [self.data, model],
            [label, f"model ({self.n_modes} modes)"],
            max_channels=max_channels,
            phase=True,
            title=f"Measurement model, rms error {self.cost.rms_db_total:.3g} dB",
        )

    def _repr_html_(self) -> str:
        return result_html(self.summary(), self.table(), self.cost.table())

    def __repr__(self) -> str:
        return (
            f"MeasurementModel({self.n_modes} modes, {self.sys.nstates} states, "
            f"rms error {self.cost.rms_db_total:.3g} dB, J = {self.cost.total:.4g})"
        )


# ---------------------------------------------------------------------------- procedure
def _settings(
    fd: FrequencyData, correct_leakage: Any, correct_window: bool
) -> EstimatorSettings | TruncationSettings | None:
    """Welch settings for the H1 leakage correction, or an impact record's truncation settings
    (applied with ``correct_window``: the rectangular window's leakage), or None."""
    if correct_leakage not in (True, False, "auto"):
        raise FitError(f"correct_leakage must be True, False or 'auto'; got {correct_leakage!r}.")
    impact = truncation_settings(fd.meta)
    if impact is not None and (correct_window or correct_leakage is True):
        return impact
    if correct_leakage is False:
        return None
    st = estimator_settings(fd.meta)
    if correct_leakage is True and st is None:
        raise FitError(
            "correct_leakage=True needs the estimator settings (fs_hz, nperseg, window) in data.meta, "
            "as recorded by rc.estimate_frf; pass correct_leakage=False for other data."
        )
    return st


def _score(fit: RationalFit, data: FrequencyData) -> LogCost:
    return channel_cost(data.response, fit.response(data.f_hz), fit.outputs, fit.inputs)


def _mode(p: complex, r: np.ndarray, k: int) -> Mode:
    f, z = pole_frequency_damping(np.array([p]))
    c, b = residue_factors(r.real if p.imag == 0 else r, int(k))
    return Mode(float(f[0]), float(z[0]), r, complex(p), int(k), output_shape=c, input_shape=b)


def _is_mode(m: Mode, band_hz: tuple[float, float]) -> bool:
    """A physical mode: a complex pole inside the band, damping below ``ZETA_FILLER``, rank 1."""
    return m.pole.imag != 0 and band_hz[0] <= m.f_hz <= band_hz[1] and m.zeta < ZETA_FILLER


def _modes(
    fit: RationalFit, evidence: PoleEvidence, n_modes: int | None
) -> tuple[tuple[Mode, ...], tuple[Mode, ...]]:
    """Modes (the poles :func:`.significance.pole_evidence` finds physical; with ``n_modes`` the
    ``n_modes`` most significant of them) and fillers (every other kept pole), each sorted by
    frequency."""
    terms = enumerate(zip(fit.poles, fit.residues, fit.ranks))
    items = [(j, _mode(p, r, k)) for j, (p, r, k) in terms if k > 0]
    physical = np.flatnonzero(evidence.physical)
    if n_modes is not None and physical.size > n_modes:
        physical = physical[np.argsort(-evidence.significance[physical], kind="stable")[:n_modes]]
    modes = [m for j, m in items if j in set(physical.tolist())]
    fillers = [m for j, m in items if j not in set(physical.tolist())]
    return tuple(sorted(modes, key=lambda m: m.f_hz)), tuple(sorted(fillers, key=lambda m: m.f_hz))


#: most relocations of a mode pole that is no mode to where a mode is missing (n_modes=N)
MAX_RELOCATIONS = 3
#: most rounds of :func:`_prune_noise_poles` (the refit after one round may turn a spare,
#: overdamped pole into a new lightly damped one that fits noise)
PRUNE_ROUNDS = 3


def _relocate_fillers(
    fit: RationalFit, n_mode_poles: int, evidence: PoleEvidence, n_modes: int, run, diagram=None
):
    """With ``n_modes=N`` and fewer than N physical modes: move a mode pole the evidence calls a
    filler (noise, leakage, a trend near the band edge) to the frequency where the noise-normalised
    complex-log residual is largest away from the modes' own peaks (within three half-power
    half-widths; 3-bin smoothed: the peak the model misses), 1 % damped, refit
    the shapes and refine; kept when it adds a physical mode and does not raise the weighted
    complex-log cost (MACE eq. 5). At most ``MAX_RELOCATIONS`` tries,
    each a refinement."""
    from .modal_refine import refine_modes_auto
    from .poles import fit_residues

    data = fit.data
    s = 2j * np.pi * data.f_hz
    tried: list[float] = []
    for _ in range(MAX_RELOCATIONS):
        n_phys = int(evidence.physical.sum())
        spare = [j for j in range(n_mode_poles) if not evidence.physical[j] and fit.poles[j].imag != 0]
        if n_phys >= n_modes or not spare or run.expired():
            break
        sigma = _noise_sigma(fit)
        e = np.sum(np.abs(log_ratio(data.response, fit.response(data.f_hz))) ** 2 / sigma**2, axis=(1, 2))
        e = np.convolve(e, np.ones(3) / 3, mode="same")
        for f0 in tried:
            e[np.abs(data.f_hz / f0 - 1) < 0.01] = 0.0
        for j in np.flatnonzero(evidence.physical):  # a mode's own peak: its misfit is no missing mode
            e[np.abs(data.f_hz - fit.f_hz[j]) <= 3 * fit.zeta[j] * fit.f_hz[j]] = 0.0
        k = int(np.argmax(e))
        tried.append(float(data.f_hz[k]))
        weakest = min(spare, key=lambda j: evidence.significance[j])
        w = 2 * np.pi * float(data.f_hz[k])
        poles = np.array(fit.poles, dtype=complex)
        poles[weakest] = complex(-0.01 * w, w * np.sqrt(1 - 1e-4))
        residues, d = fit_residues(s, data.response, _row_weights(fit, None), poles)
        trial = refine_residues(replace(fit, poles=poles, residues=residues, d=d), sweeps=2)
        if run.refine:
            try:
                trial = refine_modes_auto(trial, deadline=run.deadline, progress=run.progress)
            except ValueError:
                continue
        trial = _stable(_realised(trial), run)
        ev = pole_evidence(trial, diagram)
        better = _log_cost(trial, data) <= _log_cost(fit, data)
        if int(ev.physical.sum()) > n_phys and better and np.all(np.isfinite(trial.poles)):
            fit, evidence = trial, ev
    return fit, evidence


def _prune_noise_poles(fit: RationalFit, evidence: PoleEvidence, run, diagram=None):
    """With ``n_modes=N``: drop the complex poles that fit noise, then refine the rest once more.

    A fit asked for more modes than the data hold spends the spare poles on noise: lightly damped
    (below ``ZETA_FILLER``) or outside the band, not physical, and not significant against the noise (the
    :func:`.significance.pole_evidence` test; a pole outside the band, which that test does not
    score, by the same test over the whole band). Where such a pole settles is decided by the
    refinement's path, not by the data (on a two-output test of three modes and an overdamped pair
    asked for five modes, a 1e-12 change of the data sent a spare pole from 4.07 Hz to 13.7 Hz
    and moved the cost by 5e-3), and the joint refinement around such poles has flat directions
    that leave it short of an optimum. Without them the model is refitted (shapes by alternating
    least squares, then poles and shapes jointly) from the other poles, an optimum the data
    determine: a 1e-12 change then moves that test's cost by 1e-11. Dropping them raises the cost
    by what the noise explains (that test: 1.8 %). Only where the joint refinement is dense
    (:func:`.modal_refine.refine_modes_auto`; a large problem is refined cluster by cluster, a
    noise pole in a cluster of its own). Returns the fit and its new evidence, or both unchanged
    when no pole fits noise."""
    from .modal_refine import DENSE_MAX_ENTRIES, _dense_entries, refine_modes_auto
    from .poles import fit_residues
    from .significance import _significance

    if _dense_entries(fit) > DENSE_MAX_ENTRIES:  # block by block, each cluster's own optimum
        return fit, evidence
    poles = np.asarray(fit.poles)
    zeta = -poles.real / np.maximum(np.abs(poles), np.finfo(float).tiny)
    f_pole = np.abs(poles) / (2 * np.pi)
    outside = (f_pole < fit.data.f_hz[0]) | (f_pole > fit.data.f_hz[-1])
    light = ((poles.imag != 0) & (np.asarray(fit.ranks) > 0) & ((zeta < ZETA_FILLER) | outside)
             & ~evidence.physical)
    if not np.any(light):
        return fit, evidence
    sig = np.where(evidence.candidate, evidence.significance, np.inf)
    unscored = light & ~evidence.candidate
    if np.any(unscored):
        sig[unscored] = _significance(fit, unscored, local=False)[unscored]
    keep = ~(light & (sig < 1))
    if np.all(keep):
        return fit, evidence
    data = fit.data
    s = 2j * np.pi * data.f_hz
    residues, d = fit_residues(s, data.response, _row_weights(fit, None), poles[keep])
    trial = refine_residues(replace(fit, poles=poles[keep], residues=residues, d=d, ranks=fit.ranks[keep]),
                            sweeps=2)
    if run.refine and not run.expired():
        try:
            trial = refine_modes_auto(trial, deadline=run.deadline, progress=run.progress)
        except ValueError:  # a singular step: keep the model as it was
            return fit, evidence
    trial = _stable(_realised(trial), run)
    if not np.all(np.isfinite(trial.poles)):
        return fit, evidence
    return trial, pole_evidence(trial, diagram)


def _noise_sigma(fit: RationalFit) -> np.ndarray:
    from .significance import _noise_scale

    return _noise_scale(fit)[0]


def _promote_twins(evidence: PoleEvidence, n_modes: int) -> PoleEvidence:
    """With ``n_modes=N`` and fewer than N modes: candidates that are significant against the noise
    and stable across orders but share a mode's peak or have a shape of scattered phase count as
    modes too, most significant first (a close pair of nearly equal shapes, which the fit can only
    part with mixed shapes and the automatic order lists as one mode). Poles that fit noise or a
    trend (not significant, not stable) never do."""
    short = n_modes - int(evidence.physical.sum())
    ok = evidence.candidate & ~evidence.physical & evidence.stable & (evidence.significance >= 1)
    idx = np.flatnonzero(ok)
    if short <= 0 or idx.size == 0:
        return evidence
    take = idx[np.argsort(-evidence.significance[idx], kind="stable")[:short]]
    physical, twin = evidence.physical.copy(), evidence.twin.copy()
    physical[take], twin[take] = True, False
    return replace(evidence, physical=physical, twin=twin)


def _rank_one_modes(fit: RationalFit, evidence: PoleEvidence, diagram) -> tuple[RationalFit, PoleEvidence]:
    """Physical modes realised at rank 1 (Caltech eq. 9): a pole the selection kept as a filler
    (numerical rank) that the evidence finds to be a mode gets a rank-1 shape, refitted with the
    others by alternating least squares, so that it counts as one mode."""
    wide = evidence.physical & (np.asarray(fit.ranks) > 1)
    if not np.any(wide):
        return fit, evidence
    ranks = np.where(wide, 1, fit.ranks)
    fit = _realised(refine_residues(replace(fit, ranks=ranks), sweeps=2))
    return fit, pole_evidence(fit, diagram)


def _diagram_or_none(band: FrequencyData, run: FitSettings, max_modes: int, parsimony: float, weights):
    """The stabilisation diagram of ``band`` (as the automatic order scans it), or None when the
    scan fails numerically: with a given ``n_modes`` it only tests the modes' stability."""
    with warnings.catch_warnings(), np.errstate(over="ignore", invalid="ignore", divide="ignore"):
        warnings.simplefilter("ignore")
        try:
            return _scan(band, run, max_modes, parsimony, weights, False)[1]
        except (np.linalg.LinAlgError, ValueError, FloatingPointError, ZeroDivisionError, IndexError):
            return None


def _grouped_modes(fit: RationalFit, n_mode_poles: int) -> np.ndarray:
    """The Caltech route's modes (bool per pole): the first ``n_mode_poles`` poles that are complex,
    in band and lightly damped."""
    out = np.zeros(fit.poles.size, dtype=bool)
    f, zeta = fit.f_hz, fit.zeta
    inside = (fit.poles.imag != 0) & (f >= fit.band_hz[0]) & (f <= fit.band_hz[1]) & (zeta < ZETA_FILLER)
    out[:n_mode_poles] = inside[:n_mode_poles]
    return out & (np.asarray(fit.ranks) > 0)


def _scan(band: FrequencyData, run: FitSettings, max_modes: int, parsimony: float, weights, progress):
    """The stabilisation diagram of ``band`` and the number of modes it finds (1..max_modes)."""
    prob = prepare_problem(band, 2, None, weights)
    k = prob.s.size
    g = prob.g.reshape(k, -1)
    rw = np.sqrt(prob.w.reshape(k, -1)) / np.abs(g)
    diagram, last = stabilisation_scan(
        prob.s, g, rw, prob.band_hz, max_modes + spare_pairs(max_modes), run.deadline, progress, parsimony
    )
    return prob, diagram, last, int(min(max(last[3].size, 1), max_modes))


def _weak_modes(fit: RationalFit, n_mode_poles: int) -> np.ndarray:
    """Modes of a fitted model (bool over its poles) whose contribution is below the stabilisation
    diagram's floor (``MIN_CONTRIBUTION``, ``REL_CONTRIBUTION`` of the largest), that are fillers
    promoted to make up the count, that duplicate a neighbour (one peak, one shape), or whose
    damping the refinement left at its lower bound ``ZETA_MIN`` (below ``BOUND_ZETA``: no interior
    optimum, the data do not determine that pole's decay, as for a pole fitting the noise of an
    antiresonance; a real lightly damped mode has an interior optimum however small): poles the
    scan counted that the final model does not need."""
    s = 2j * np.pi * fit.data.f_hz
    contrib = pole_contributions(s, fit.data.response, _row_weights(fit, None), fit.poles, fit.residues)
    floor = max(MIN_CONTRIBUTION, REL_CONTRIBUTION * float(contrib.max(initial=0.0)))
    f, zeta = fit.f_hz[:n_mode_poles], fit.zeta[:n_mode_poles]
    filler = (f < fit.band_hz[0]) | (f > fit.band_hz[1]) | (zeta >= ZETA_FILLER)  # promoted to fill the count
    at_bound = zeta < BOUND_ZETA
    idx = np.arange(n_mode_poles)
    twin = ~np.isin(idx, distinct_modes(idx, fit.poles, fit.residues, contrib))  # one peak, one shape
    weak = np.zeros(fit.poles.size, dtype=bool)
    weak[:n_mode_poles] = (contrib[:n_mode_poles] < floor) | filler | at_bound | twin
    weak[_lone_peak(f, at_bound & (contrib[:n_mode_poles] >= floor), ~weak[:n_mode_poles], contrib)] = False
    return weak


def _lone_peak(f: np.ndarray, bound: np.ndarray, kept: np.ndarray, contrib: np.ndarray) -> list[int]:
    """Of strong poles at the damping bound that straddle one peak (within 1 % of each other, as a
    truncation-leakage doublet does) with no kept mode there, the strongest: the peak is a mode
    (its damping comes back in the warm refit); dropping every pole would lose it."""
    out = []
    for k in sorted(np.flatnonzero(bound), key=lambda j: -contrib[j]):
        near = np.abs(f / f[k] - 1) < 0.01
        doublet = np.count_nonzero(near & bound) >= 2  # a lone pole at the bound is no mode
        if doublet and not np.any(near & kept) and not any(abs(f[j] / f[k] - 1) < 0.01 for j in out):
            out.append(int(k))
    return out


def _without_weak(
    band: FrequencyData, fit: RationalFit, n_mode_poles: int, used: FrequencyData, run, warm: bool = False
):
    """Refit without the weak modes: from scratch, or with ``warm`` from ``fit`` without them on
    the data it used (the remaining modes preferred)."""
    weak = _weak_modes(replace(fit, data=used), n_mode_poles)
    n = n_mode_poles - int(weak.sum())
    if not 0 < n < n_mode_poles or run.expired():
        return fit, n_mode_poles, used
    if not warm:
        return fit_best(band, n, run)
    keep = ~weak
    start = replace(fit, poles=fit.poles[keep], residues=fit.residues[keep], ranks=fit.ranks[keep])
    return fit_with_leakage(band, n, run, first=replace(start, data=used), prefer=np.arange(keep.sum()) < n)


def _scan_fit(prob, diagram, last) -> tuple[RationalFit, np.ndarray]:
    """The scan's chosen order as a RationalFit on the scanned data, and its physical poles (bool)."""
    poles, res, d, phys = last
    shape = (poles.size,) + prob.g.shape[1:]
    first = RationalFit(
        poles, res.reshape(shape), d.reshape(prob.g.shape[1:]), np.ones(poles.size, dtype=int),
        prob.inputs, prob.outputs, prob.band_hz, "vf", int(diagram.orders[-1]), True, prob.data,
    )
    return first, np.isin(np.arange(poles.size), phys)


def _automatic(
    band: FrequencyData, run: FitSettings, max_modes: int, parsimony: float, weights, progress, scans=None
):
    """Stabilisation-diagram order selection, then the modal model of the chosen order; modes the
    final model does not need (below the contribution floor) are dropped by one refit. ``scans``
    (a dict, optional) keeps the scan for a second call on the same band (the scan does not depend
    on the corrections: it runs on the band as measured).

    An impact record that leaks (truncated decays, eq. T1 of :mod:`.leakage`) makes the scan of
    the raw data find extra stable poles that model the leakage; once the refinement with the
    truncation in its model (eq. T1) has corrected the data, they no longer carry data or sit at
    the damping bound, and are dropped by a warm refit."""
    if scans is None or "scan" not in scans:
        scanned = _scan(band, run, max_modes, parsimony, weights, progress)
        if scans is not None:
            scans["scan"] = scanned
    prob, diagram, last, n = scanned if scans is None else scans["scan"]
    welch = run.settings is not None and not isinstance(run.settings, TruncationSettings)
    if run.groups is not None or welch:
        fit, n_mode_poles, used = fit_best(band, n, run)
    else:
        first, prefer = _scan_fit(prob, diagram, last)
        fit, n_mode_poles, used = fit_best(band, n, run, first=first, prefer=prefer)
    if run.groups is None:
        warm = isinstance(run.settings, TruncationSettings)
        fit, n_mode_poles, used = _without_weak(band, fit, n_mode_poles, used, run, warm)
    return fit, n_mode_poles, used, diagram


def _window_tau(fd: FrequencyData, correct_window: Any) -> float | None:
    tau = fd.meta.get("exp_window_tau_s") if isinstance(fd.meta, dict) else None
    if tau is None:  # a file described as an impact test with an exponential window
        tau = getattr(fd.experiment, "exp_window_tau_s", None)
    if correct_window is False or tau is None:
        return None
    return float(tau)


@limit_blas
def fit_measurement_model(
    data: Any,
    n_modes: int | None = None,
    band: tuple[float, float] | None = None,
    method: str = "vf",
    groups: Any = None,
    point_weights: Any = "auto",
    correct_leakage: bool | str = False,
    rank_tol: float = 0.1,
    max_modes: int = 60,
    parsimony: float = 0.02,
    target_db: float | None = None,
    max_iter: int | None = None,
    refine: bool = True,
    *,
    weights: Any = UNSET,
    correct_window: bool = True,
    time_budget_s: float | None = TIME_BUDGET_S,
    progress: bool | None = None,
) -> MeasurementModel:
    """Identify a measurement model of frequency-response data in one call.

    Parameters
    ----------
    data : FrequencyData (or what :func:`fit_rational` accepts)
        Measured response, Hz.
    n_modes : int, optional
        Number of modes: exactly this many are returned (sorted by frequency). The rational fit
        behind them has ``2 (n_modes + spare)`` poles (``spare = max(2, ceil(n_modes/5))``),
        which finds close pairs a fit of ``2 n_modes`` poles merges (on small problems the fits
        with 0 and up to 2 more spare pairs are finished too and the lowest weighted cost wins,
        see :func:`~robustctl.identify.modal_fit.fit_best`); the ``n_modes`` in-band,
        lightly damped poles of largest contribution are the modes, out-of-band and heavily
        damped ones are kept as ``fillers``, the others dropped (:mod:`.selection`). With
        ``groups``: the modes per SIMO fit. ``None``: chosen automatically in one pass by the
        stabilisation diagram of a warm-started order scan (:mod:`.stabilisation`; returned as
        ``stabilisation``): the poles stable in frequency, damping and shape over three
        orders that carry a share of the data. No damping floor.
    band : (f_lo, f_hi), optional
        Band in Hz.
    method : {"vf", "chebyshev"}
        Pole identification (see :func:`fit_rational`).
    groups : optional
        Use the Caltech route: one SIMO fit of ``n_modes`` modes per input, combined, then
        grouped by :func:`group_modes` with this ``groups`` argument (e.g. ``(2, 1, 2, 1)``).
    point_weights : "auto", None, "coherence" or array_like
        Data-point weights of the fits on the squared log error
        (:func:`robustctl.checks.point_weights`; default coherence weights when the data carry
        coherence). ``weights=`` is the deprecated name. The reported ``cost`` is unweighted.
    weights
        Deprecated name of ``point_weights``.
    correct_leakage : False, True or "auto"
        Undo the H1 estimator's window leakage (see :mod:`robustctl.identify.leakage`). It
        assumes white (flat-spectrum) ZOH excitation, as in the Caltech random-noise tests, and
        the estimator settings in ``data.meta``; "auto" applies it when those settings are
        there. Off by default: with coloured or swept inputs (e.g. the DaISy records) the
        white-noise leakage model is wrong and makes the fit worse. The correction is a
        deconvolution driven by the model: lightly damped modes outside the band whose leakage
        reaches it (a test article's suspension modes just below), weak cross channels and
        antiresonances let it follow the model instead of the data; an :class:`IdentifyWarning`
        says so when the model's expected H1 misses the raw data by clearly more than the model
        misses the corrected data (:func:`leakage_consistency`), and another names the modes left
        at the lower damping bound (:func:`pinned_modes`).
    rank_tol : float
        With ``groups``: relative singular-value threshold of automatic mode counts in
        :func:`group_modes`. Without: unused (every mode has a rank-1 residue ``c b^T``).
    max_modes : int
        Largest number of modes the automatic selection returns.
    parsimony : float
        Automatic selection: the relative cost decrease an added order must bring (besides a
        new stable pole) for the scan to go on.
    target_db : float, optional
        Required rms log-magnitude error (dB); a :class:`FitError` says so when it is missed.
    max_iter : int, optional
        Iteration cap of each pole identification (default: that of :func:`fit_rational`).
    refine : bool
        Refine poles and mode shapes together by nonlinear least squares with the rank
        structure imposed (:func:`refine_modes`, block by block on large problems:
        :func:`~robustctl.identify.modal_refine.refine_modes_auto`); this is what resolves
        near-coincident modes.
    correct_window : bool
        When ``data.meta`` or ``data.experiment`` holds ``exp_window_tau_s`` (set by
        :func:`robustctl.estimate_frf_impact` with an exponential window, or stated), move every pole by
        ``+1/tau``: ``zeta_true = zeta_meas - 1/(tau w_n)`` (Ewins, sec. 3.11). For every
        impact record (rectangular or exponential window) whose responses have not decayed by
        the record end, also try undoing the truncation (leakage): the refinement fits the
        truncated record's response to the raw data (:mod:`robustctl.identify.leakage`, eq. T1).
        The corrected model is kept only when its expected H1 (the model with its record-end
        tail) misses the data by less than the plain fit does; ``corrections`` and the summary
        say which was kept (``correct_leakage=True`` forces the correction).
    time_budget_s : float, Deadline or None
        Opt-in wall-time budget of the whole call, seconds (or a caller's shared Deadline).
        ``None`` (default): the work is
        bounded by iteration caps only, so the result depends on the input and options alone.
        With a budget, when it runs out the order scan, pole iterations and refinement stop with
        the best model so far: the result says so (``stopped_by_budget``, its summary) and a
        :class:`robustctl.BudgetWarning` is issued; such a model depends on the machine's speed
        and load (the policy of :mod:`robustctl.budget`; a :class:`~robustctl.Deadline` is shared).
    progress : bool, optional
        tqdm bars over the order scan and the block refinement (default: when stderr is a
        terminal).

    Returns
    -------
    MeasurementModel
        Its ``sys`` (:meth:`~MeasurementModel.statespace`), ``fit``, :meth:`~MeasurementModel.freqresp`,
        ``cost`` and plots are one model: the realisation's factors are the fit's residues. Every
        pole has a damping ratio of at least ``STABILITY_ZETA`` (1e-6): the model is
        asymptotically stable with that margin.

    Raises
    ------
    FitError
        Bad options, a missed ``target_db``, or a fit that fails numerically (the message names
        the order, the step and what to change).
    """
    import sys

    max_modes, parsimony = _check_selection(max_modes, parsimony)
    clock = as_deadline(time_budget_s, FitError)
    point_weights = renamed_keyword(point_weights, weights, "point_weights", "weights", default="auto")
    fd = as_frequency_data(data)
    band_fd = band_data(fd, band)
    st = _settings(fd, correct_leakage, correct_window)
    tau = _window_tau(fd, correct_window)
    show = sys.stderr.isatty() if progress is None else bool(progress)
    kw = dict(method=method, point_weights=point_weights, max_iter=max_iter)
    run = FitSettings(groups, st, kw, rank_tol, refine, clock if clock.active else None, progress=show)
    diagram = None
    order = "automatic order" if n_modes is None else f"n_modes={_check_modes(n_modes)}"
    scans: dict = {}  # the order scan of band_fd, shared by the corrected and the plain fit
    fit, n_mode_poles, used, diagram = _fit_core(band_fd, run, n_modes, max_modes, parsimony, point_weights,
                                                 show, order, scans)
    declined = None
    chosen = isinstance(st, TruncationSettings) and correct_leakage is not True
    if chosen and used.meta.get("leakage_corrected"):
        # the truncation correction is chosen only where it lowers the error against the H1 data
        plain = _fit_core(band_fd, replace(run, settings=None), n_modes, max_modes, parsimony, point_weights,
                          show, order, scans)
        with_t, without = _raw_miss_db(fit, used), _raw_miss_db(plain[0], plain[2])
        if not with_t < without:
            fit, n_mode_poles, used, diagram = plain
            declined = (with_t, without)
    _check_finite(fit, used, order)
    # a given order, or data the fit corrected: a scan of the data the model was fitted to judges
    # the modes' stability across orders (leakage biases the raw data's poles)
    judge = diagram if not used.meta.get("leakage_corrected") else None
    if judge is None and groups is None:
        top = min(max_modes, max(1, used.f_hz.size // 4))  # orders the band's points can carry
        judge = _diagram_or_none(used, run, top, parsimony, point_weights)
    evidence = pole_evidence(replace(fit, data=used), judge)
    if groups is None:
        fit, evidence = _rank_one_modes(replace(fit, data=used), evidence, judge)
    if n_modes is not None and groups is None:
        evidence = _promote_twins(evidence, n_modes)
    if n_modes is not None and groups is None and not isinstance(st, TruncationSettings):
        with warnings.catch_warnings(), np.errstate(over="ignore", invalid="ignore", divide="ignore"):
            warnings.simplefilter("ignore", IdentifyWarning)
            fit, evidence = _relocate_fillers(replace(fit, data=used), n_mode_poles, evidence, n_modes, run,
                                              judge)
            if not used.meta.get("leakage_corrected"):
                for _ in range(PRUNE_ROUNDS):
                    n_before = len(fit.poles)
                    fit, evidence = _prune_noise_poles(replace(fit, data=used), evidence, run, judge)
                    evidence = _promote_twins(evidence, n_modes)
                    if len(fit.poles) == n_before:
                        break
    stopped = run.expired()
    cost = _score(fit, used)
    scan = () if diagram is None else tuple((int(n), float(c)) for n, c in zip(diagram.orders, diagram.cost))
    if target_db is not None and cost.rms_db_total > target_db:
        raise FitError(
            f"the measurement model reaches {cost.rms_db_total:.3g} dB rms log-magnitude error, above the "
            f"target {target_db:g} dB; raise n_modes (or leave it None), narrow the band or relax target_db."
        )
    if stopped:
        clock.warn("fit_measurement_model (the time budget ran out; raise time_budget_s, narrow the band or "
                   "give n_modes)", stacklevel=4)
    if isinstance(st, EstimatorSettings) and used.meta.get("leakage_corrected"):
        miss_raw, miss_used = leakage_consistency(fit, band_fd, used, st, point_weights)
        if miss_raw > INCONSISTENT_RATIO * miss_used + INCONSISTENT_DB:
            warnings.warn(
                f"the leakage correction is not self-consistent: the model's expected H1 estimate misses "
                f"the raw data by {miss_raw:.3g} dB (weighted rms complex-log error) while the model "
                f"fits the corrected data to {miss_used:.3g} dB. The correction follows the model where "
                "the data do not pin it (weak channels, antiresonances, lightly damped modes outside the "
                "band or at the damping bound); compare with correct_leakage=False.",
                IdentifyWarning,
                stacklevel=3,
            )
    if groups is not None:  # the Caltech route's grouped modes (ranks up to 2) are its mode poles
        evidence = replace(evidence, physical=_grouped_modes(fit, n_mode_poles))
    if tau is not None:
        fit = shift_poles(fit, 1.0 / tau)
    modes, fillers = _modes(fit, evidence, n_modes if groups is None else None)
    if n_modes is not None and groups is None and sum(m.rank for m in modes) < n_modes:
        warnings.warn(
            f"n_modes={n_modes} was asked but the data support {sum(m.rank for m in modes)} physical "
            f"mode(s) in {band_fd.f_hz[0]:.4g}-{band_fd.f_hz[-1]:.4g} Hz (complex, in band, damping below "
            f"{ZETA_FILLER:g}); the other poles are fillers (.fillers). Lower n_modes or widen the band.",
            IdentifyWarning,
            stacklevel=3,
        )
    pinned = pinned_modes(modes)
    if pinned:
        warnings.warn(pinned_message(pinned, bool(used.meta.get("leakage_corrected"))), IdentifyWarning,
                      stacklevel=3)
    if fillers:
        warnings.warn(
            f"{len(fillers)} filler pole(s) (outside the band, heavily damped, real, not significant "
            "against the noise, of scattered phase or a second pole on a mode's peak) are kept in the "
            "model; they are listed in MeasurementModel.fillers (reasons: .evidence), not in .modes.",
            IdentifyWarning,
            stacklevel=3,
        )
    leaked = bool(used.meta.get("leakage_corrected"))
    return MeasurementModel(
        fit.statespace(), modes, cost, fit, used, band_fd, leaked, scan, fillers, diagram, tau, stopped,
        _corrections(st, leaked, tau, declined), evidence,
    )


def _fit_core(band_fd, run, n_modes, max_modes, parsimony, point_weights, show, order, scans=None):
    """The fit of :func:`fit_measurement_model` for one setting of the corrections, realised and
    stable; numerical failures become a :class:`FitError` naming the order, the step and the fix.
    ``scans``: the automatic order's scan kept across the calls on ``band_fd`` (:func:`_automatic`)."""
    diagram = None
    with warnings.catch_warnings(), np.errstate(over="ignore", invalid="ignore", divide="ignore"):
        warnings.simplefilter("ignore", IdentifyWarning)
        try:
            if n_modes is None:
                fit, n_mode_poles, used, diagram = _automatic(
                    band_fd, run, max_modes, parsimony, point_weights, show, scans
                )
            else:
                fit, n_mode_poles, used = fit_best(band_fd, _check_modes(n_modes), run)
            fit = _stable(_realised(fit), run)
        except RobustctlError:  # already says what is wrong and how to fix it
            raise
        except (np.linalg.LinAlgError, ValueError, FloatingPointError, ZeroDivisionError) as exc:
            kind = "plain" if run.settings is None else "leakage-corrected"
            raise FitError(
                f"the modal fit ({order}, {kind}) failed numerically in its pole identification or "
                f"refinement ({type(exc).__name__}: {exc}). Lower n_modes or max_modes, narrow the band, "
                "or pass refine=False or correct_leakage=False."
            ) from exc
    return fit, n_mode_poles, used, diagram


def _raw_miss_db(fit: RationalFit, used: FrequencyData) -> float:
    """Unweighted rms log-magnitude error (dB) of ``fit`` as the H1 estimate sees it against the
    measured data: against the data it was fitted to, which for the truncation-corrected route are
    the raw H1 data plus the model's own record-end tail (eq. T1), so that both routes are scored
    on what the estimator would have produced from them."""
    return float(_score(fit, used).rms_db_total)


def _corrections(st: Any, leaked: bool, tau: float | None, declined=None) -> tuple[str, ...]:
    """The corrections applied, in words (for the summary and ``MeasurementModel.corrections``)."""
    out = []
    if declined is not None:
        out.append(
            f"record truncation tried and not applied (its expected H1 missed the data by "
            f"{declined[0]:.3g} dB rms, the plain fit by {declined[1]:.3g} dB)"
        )
    if leaked and isinstance(st, TruncationSettings):
        out.append("record truncation (impact responses cut at the record end, eq. T1)")
    elif leaked:
        out.append("H1 estimator window leakage (white ZOH excitation)")
    if tau is not None:
        out.append(f"exponential window damping (tau = {tau:.4g} s)")
    return tuple(out)


def _realised(fit: RationalFit) -> RationalFit:
    """``fit`` with every residue replaced by the product of the factors its realisation keeps
    (rank ``ranks[k]``, Caltech eqs. 9-10; a rank-0 pole's term vanishes, a real pole's residue is
    real): then :meth:`RationalFit.response`, :meth:`RationalFit.statespace` and the cost describe
    one and the same model, to round-off."""
    residues = np.array(fit.residues, dtype=complex)
    for k, (p, r, rank) in enumerate(zip(fit.poles, fit.residues, fit.ranks)):
        c, b = residue_factors(r.real if p.imag == 0 else r, int(rank))
        residues[k] = c @ b if int(rank) > 0 else 0.0
    return replace(fit, residues=residues, d=np.real(fit.d).astype(float))


#: smallest damping ratio of a returned pole (the refinement's bound ``ZETA_MIN``): the stated
#: stability margin of every measurement model
STABILITY_ZETA = ZETA_MIN


def _stable(fit: RationalFit, run: FitSettings) -> RationalFit:
    """Every pole with damping ratio at least ``STABILITY_ZETA`` (asymptotically stable with that
    margin). A pole below it (a marginal or unstable pole of a fit that was not refined) is moved
    onto the margin and the shapes refitted to the data; a pole at the origin is refused."""
    mag = np.abs(fit.poles)
    if np.any(mag == 0):
        raise FitError(
            "the fit has a pole at s = 0 (an integrator), which no measurement model of a structure may "
            "have; raise the band's lower edge or use refine=True."
        )
    low = -fit.poles.real < STABILITY_ZETA * mag * (1 - 1e-12)
    if not np.any(low):
        return fit
    poles = np.where(low, -STABILITY_ZETA * mag + 1j * fit.poles.imag, fit.poles)
    moved = replace(fit, poles=poles.astype(complex))
    return _realised(refine_residues(moved, sweeps=2)) if fit.data is not None else moved


def _check_finite(fit: RationalFit, used: FrequencyData, order: str) -> None:
    """A :class:`FitError` (not NaN matrices) when the fit's numbers are not finite."""
    parts = (fit.poles, fit.residues, fit.d, used.response)
    if not all(np.all(np.isfinite(x)) for x in parts):
        raise FitError(
            f"the modal fit ({order}) produced non-finite poles, shapes or corrected data (an internal "
            "exponential or division left the floating-point range). Lower n_modes, narrow the band, or "
            "pass correct_leakage=False / refine=False."
        )


def leakage_consistency(
    fit: RationalFit, raw: FrequencyData, used: FrequencyData, settings: EstimatorSettings, point_weights: Any
) -> tuple[float, float]:
    """Weighted rms complex-log misses ``|ln(model / data)|`` (MACE eq. 5, magnitude and phase, in
    dB): the model's expected H1 estimate against the raw data, and the model against the
    leakage-corrected data it was fitted to.

    A correction that undoes the estimator's leakage leaves the two equal (the fixed point
    ``E[H1 of M] = data`` of :mod:`.leakage`); a first much larger than the second says the
    corrected data moved where the raw data do not follow (the correction is a deconvolution,
    unstable where the data do not determine the model).
    """
    from ..checks import point_weights as weights_of

    w = weights_of(point_weights, raw)
    tiny = np.finfo(float).tiny

    def miss(model: np.ndarray, data: np.ndarray) -> float:
        d = np.abs(log_ratio(data, model))
        return float(DB_PER_NEPER * np.sqrt(np.sum(w * d**2) / max(np.sum(w), tiny)))

    expected = expected_h1(fit, raw.f_hz, settings)
    return miss(expected, raw.response), miss(fit.response(used.f_hz), used.response)


def pinned_modes(modes: tuple[Mode, ...]) -> tuple[Mode, ...]:
    """Modes whose damping the refinement left at its lower bound (``zeta < BOUND_ZETA``).

    Such a pole has no interior optimum: the data do not determine its decay (a peak narrower
    than the frequency resolution, a leakage correction driven by dynamics the model lacks, or a
    pole fitting noise); its damping is no measurement.
    """
    return tuple(m for m in modes if m.zeta < BOUND_ZETA)


def pinned_message(pinned: tuple[Mode, ...], leakage_corrected: bool) -> str:
    """The warning for modes at the damping bound (see :func:`pinned_modes`)."""
    where = ", ".join(f"{m.f_hz:.4g} Hz" for m in pinned)
    hint = (
        " The data were leakage-corrected: the correction (robustctl.identify.leakage) needs in the "
        "model every lightly damped mode whose leakage reaches the band (e.g. suspension modes just "
        "below it); "
        "try correct_leakage=False or a band that holds them."
        if leakage_corrected
        else " Its damping is below what the frequency resolution resolves, or the pole fits noise."
    )
    return (
        f"{len(pinned)} mode(s) at {where} sit at the lower damping bound (zeta < {BOUND_ZETA:.2g}): "
        f"the data do not determine their damping.{hint}"
    )


def _check_selection(max_modes: Any, parsimony: Any) -> tuple[int, float]:
    """Validated settings of the automatic order selection."""
    integer = isinstance(max_modes, (int, np.integer)) and not isinstance(max_modes, (bool, np.bool_))
    if not integer or max_modes < 1:
        raise FitError(
            f"max_modes must be a positive integer (the largest n_modes tried); got {max_modes!r}."
        )
    try:
        parsimony = float(parsimony)
    except (TypeError, ValueError):
        parsimony = float("nan")
    if not (np.isfinite(parsimony) and parsimony >= 0):
        raise FitError(
            f"parsimony must be a finite relative cost slack >= 0 (0.1: within 10 % of the best order); "
            f"got {parsimony!r}."
        )
    return int(max_modes), parsimony


def _check_modes(n_modes: Any) -> int:
    if isinstance(n_modes, (bool, np.bool_)) or not isinstance(n_modes, (int, np.integer)) or n_modes < 1:
        raise FitError(f"n_modes must be a positive integer (or None for automatic); got {n_modes!r}.")
    return int(n_modes)


def _rebuild_measurement_model(state: dict) -> MeasurementModel:
    state = dict(state, sys=rebuild_statespace(state["sys"]))
    return MeasurementModel(**state)
