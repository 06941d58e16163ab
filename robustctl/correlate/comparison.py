"""Where does the model fail? ``rc.compare`` (MACE eq. 5, Table 1, and the channel structure).

The complex log error ``e = log(G_data / G_model)`` (MACE eq. 5) is broken down

* by channel: cost per (output, input) pair, log-magnitude error in dB and phase error in
  degrees at every frequency;
* by frequency: the worst bands, contiguous regions where the RMS error over channels
  exceeds a threshold, ranked by their share of the cost;
* by mode: a table in the style of MACE Table 1 (frequency and damping of model and data
  modes, their errors in %, and the MAC of their residue shapes);
* by structure: because log errors of a sensor gain, a sensor filter or delay add to every
  channel of that sensor's row (and actuator errors to every channel of that actuator's
  column), the per-frequency two-way split ``e_ij(w) = mu(w) + a_i(w) + b_j(w) + r_ij(w)``
  (least squares, i.e. a two-way analysis of variance) tells sensor-side (rows ``a``),
  actuator-side (columns ``b``) and structural (the non-separable rest ``r``, and a common
  part ``mu`` that is not a pure gain or delay) errors apart;
* against the noise: per channel and frequency section, a chi-square test of the residual
  normalised by the data's noise model (:mod:`robustctl.measure.noise`,
  :mod:`robustctl.correlate.verdict`) says whether the misfit is within the noise; only what
  is not is flagged as failing. Data that carry their H1 estimator settings are compared with
  the model as the estimator sees it (window leakage, :mod:`robustctl.measure.estimator`).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np
import scipy.optimize
import scipy.signal

from ..checks import UNSET, integer, match_channels, positive_number, renamed_keyword
from ..cost import LogCost, cost_report
from ..errors import DataError
from ..frd import FrequencyData
from ..lti import DB_PER_NEPER, as_statespace, pole_frequency_damping
from ..measure.noise import NoiseModel
from ..modes import Mode, mac, pair_modes
from ..plots import (
    channel_label,
    colorbar,
    error_heat_map,
    grid_columns,
    log_frequency_axis,
    magnitude_label,
    new_figure,
)
from ..table import Table, result_html
from .residual import NEGLIGIBLE_DB, Residual, as_model, check_data, log_ratio
from .verdict import ALPHA, NoiseTest, no_noise_sentence, noise_test

__all__ = [
    "Comparison",
    "compare",
    "Band",
    "ErrorStructure",
    "Mode",
    "error_structure",
    "statespace_modes",
    "peak_pick_modes",
    "mac",
    "pair_modes",
]

# ---------------------------------------------------------------------------- modes


def statespace_modes(
    sys: Any,
    band: tuple[float, float],
    out_idx: list[int] | None = None,
    in_idx: list[int] | None = None,
    max_zeta: float = 0.5,
) -> list[Mode]:
    """Modes of a state space with natural frequency in ``band`` (Hz) and ``zeta < max_zeta``.

    The shape of mode k is its residue ``(C v_k)(w_k B)`` (eigenvector v_k, left
    eigenvector row w_k of ``V^-1``), restricted to the channels ``out_idx`` x ``in_idx``.
    """
    A, B, C = (np.asarray(m, dtype=float) for m in (sys.A, sys.B, sys.C))
    if A.size == 0:
        return []
    lam, V = np.linalg.eig(A)
    try:
        W = np.linalg.inv(V)
    except np.linalg.LinAlgError:
        W = np.linalg.pinv(V)
    out_idx = list(range(C.shape[0])) if out_idx is None else out_idx
    in_idx = list(range(B.shape[1])) if in_idx is None else in_idx
    f_hz, zetas = pole_frequency_damping(lam)
    modes = []
    for k in np.flatnonzero(lam.imag > 0):
        f, zeta = f_hz[k], zetas[k]
        if not band[0] <= f <= band[1] or zeta >= max_zeta:
            continue
        res = np.outer(C[out_idx] @ V[:, k], W[k] @ B[:, in_idx])
        modes.append(Mode(float(f), float(zeta), residue=res, pole=complex(lam[k])))
    return sorted(modes, key=lambda m: m.f_hz)


def measurement_modes(
    mm: Any, band: tuple[float, float], outputs, inputs, max_zeta: float = 0.5
) -> list[Mode]:
    """Modes of a measurement model inside ``band`` (Hz), residues in the data's channel order.

    A result whose ``.modes`` is a sequence of :class:`~robustctl.modes.Mode` (a
    ``MeasurementModel``) gives its identified modes (a group of rank > 1 stays one mode);
    any other system (see :func:`robustctl.as_statespace`) gives the eigenstructure of its
    state space (:func:`statespace_modes`). Channels are matched by
    :func:`robustctl.checks.match_channels`.
    """
    sys = as_statespace(mm)
    out_idx = match_channels(sys.output_labels, outputs, "outputs")
    in_idx = match_channels(sys.input_labels, inputs, "inputs")
    modes = getattr(mm, "modes", None)
    if isinstance(modes, (tuple, list)) and modes and all(isinstance(m, Mode) for m in modes):
        found = [
            replace(m, residue=None if m.residue is None else np.asarray(m.residue)[np.ix_(out_idx, in_idx)])
            for m in modes
        ]
        return sorted((m for m in found if band[0] <= m.f_hz <= band[1]), key=lambda m: m.f_hz)
    return statespace_modes(sys, band, out_idx, in_idx, max_zeta=max_zeta)


def _half_power(f: np.ndarray, s: np.ndarray, k: int, lo: int, hi: int) -> float:
    """Half-power damping ratio of the peak at index k; the search stays in [lo, hi]."""
    level = s[k] / np.sqrt(2.0)
    fp = f[k]
    left = right = None
    for i in range(k, lo, -1):
        if s[i - 1] <= level:
            t = (level - s[i - 1]) / (s[i] - s[i - 1])
            left = f[i - 1] + t * (f[i] - f[i - 1])
            break
    for i in range(k, hi):
        if s[i + 1] <= level:
            t = (s[i] - level) / (s[i] - s[i + 1])
            right = f[i] + t * (f[i + 1] - f[i])
            break
    if left is not None and right is not None:
        return (right - left) / (2 * fp)
    if left is not None:
        return (fp - left) / fp
    if right is not None:
        return (right - fp) / fp
    return float("nan")


def peak_pick_modes(
    f_hz: np.ndarray, response: np.ndarray, prominence: float = 0.5, max_modes: int = 40, channels: Any = None
) -> list[Mode]:
    """Modes from the peaks of the channel-normalised summed magnitude ``sum |G_ij| / rms_ij``.

    Peaks need a prominence of ``prominence`` nepers (0.5 ~ 4.3 dB) in ``ln S``; their
    frequency is refined by a parabola through ``ln S``, damping is the half-power
    bandwidth ``(f2 - f1) / (2 f_peak)`` (one-sided when a neighbour hides one side),
    and the shape is the response at the peak (every channel).

    ``channels`` (bool, shape ``(n_out, n_in)``, optional): the channels summed in ``S`` (default
    all). :func:`compare` passes the channels its cost keeps: a channel decoupled by symmetry
    holds round-off of the others (1e-15 of them), which the normalisation would raise to the
    weight of a measured channel, so that its peaks, set by rounding (another BLAS kernel, another
    eigensolver), would be picked as modes.
    """
    f = np.asarray(f_hz, dtype=float)
    g = np.asarray(response)
    flat = g.reshape(g.shape[0], -1)
    if channels is not None:
        mask = np.asarray(channels)
        if mask.shape != g.shape[1:] or mask.dtype != bool or not mask.any():
            raise DataError(
                f"channels must be a boolean array of shape {g.shape[1:]} (outputs x inputs) with at "
                f"least one True; got shape {mask.shape}, dtype {mask.dtype}. Pass None to sum every channel."
            )
        flat = flat[:, mask.ravel()]
    rms = np.sqrt(np.mean(np.abs(flat) ** 2, axis=0))
    s = np.sum(np.abs(flat) / np.where(rms > 0, rms, 1.0), axis=1)
    ls = np.log(np.maximum(s, 1e-300))
    peaks, props = scipy.signal.find_peaks(ls, prominence=prominence)
    if peaks.size > max_modes:
        keep = np.argsort(props["prominences"])[::-1][:max_modes]
        peaks = np.sort(peaks[keep])
    bounds = np.concatenate([[0], (peaks[:-1] + peaks[1:]) // 2, [f.size - 1]])
    modes = []
    for j, k in enumerate(peaks):
        fk = f[k]
        if 0 < k < f.size - 1:
            y0, y1, y2 = ls[k - 1], ls[k], ls[k + 1]
            den = y0 - 2 * y1 + y2
            if den < 0:
                off = 0.5 * (y0 - y2) / den
                fk = f[k] + off * (f[k + 1] - f[k - 1]) / 2
        zeta = _half_power(f, s, k, bounds[j], bounds[j + 1])
        modes.append(Mode(float(fk), float(zeta), residue=g[k].copy()))
    return modes


# ---------------------------------------------------------------------------- structure
@dataclass(frozen=True)
class ErrorStructure:
    """Two-way split of the complex log error over channels (sensor rows, actuator columns).

    Per frequency ``e_ij = mu + a_i + b_j + r_ij`` with ``sum a = sum b = 0`` and ``r``
    orthogonal to both (least squares); energies are summed over the band and given as
    fractions of the total ``sum |e|^2``.

    Attributes
    ----------
    common, sensor, actuator, interaction : float
        Energy fractions of ``mu``, the row effects ``a``, the column effects ``b`` and the
        non-separable rest ``r`` (they add up to 1).
    row_energy : ndarray (n_out,)
        Energy of each output's row mean ``mu + a_i`` (which sensor carries the error).
    column_energy : ndarray (n_in,)
        Energy of each input's column mean ``mu + b_j``.
    dominant_output, dominant_input : str
        The output row / input column with the largest energy.
    kind : str
        ``"sensor"``, ``"actuator"``, ``"common"`` (a gain/delay shared by all channels),
        ``"structural"`` or ``"none"`` (no error).
    common_delay_s : float
        Delay (s) of a least-squares fit ``mu ~ c0 - j w tau`` to the common part.
    """

    common: float
    sensor: float
    actuator: float
    interaction: float
    row_energy: np.ndarray
    column_energy: np.ndarray
    dominant_output: str
    dominant_input: str
    kind: str
    common_delay_s: float = 0.0

    @property
    def structural(self) -> float:
        """Share not attributable to one side: interaction, plus the common part unless it is a
        pure gain/delay."""
        return self.interaction + (0.0 if self.kind == "common" else self.common)

    def describe(self) -> str:
        """The verdict in plain words."""
        pct = (
            f"sensor rows {self.sensor:.0%}, actuator columns {self.actuator:.0%}, "
            f"common {self.common:.0%}, channel-specific {self.interaction:.0%}"
        )
        if self.kind in ("sensor", "actuator"):
            signal, name, line = (
                ("output", self.dominant_output, "row")
                if self.kind == "sensor"
                else ("input", self.dominant_input, "column")
            )
            return (
                f"{self.kind}-side: the error is mostly the same along {signal} {name!r}'s {line} "
                f"(a gain, filter or delay of that {self.kind}) [{pct}]."
            )
        if self.kind == "common":
            return (
                f"common to all channels: a shared gain or delay (fitted delay "
                f"{self.common_delay_s * 1e3:.3g} ms) [{pct}]."
            )
        if self.kind == "structural":
            return (
                f"structural: the error differs from channel to channel in a way no sensor or actuator "
                f"error explains (mode frequencies, shapes or damping) [{pct}]."
            )
        return "no error."


def _common_is_gain_delay(mu: np.ndarray, w: np.ndarray) -> tuple[bool, float]:
    """Fit ``mu(w) ~ c0 - j w tau`` (complex c0, real tau); True if it explains >= 90 %."""
    energy = float(np.sum(np.abs(mu) ** 2))
    if energy == 0:
        return False, 0.0
    # unknowns: Re c0, Im c0, tau ; real equations for Re and Im parts
    n = mu.size
    A = np.zeros((2 * n, 3))
    A[:n, 0] = 1.0
    A[n:, 1] = 1.0
    A[n:, 2] = -w
    b = np.concatenate([mu.real, mu.imag])
    sol, *_ = np.linalg.lstsq(A, b, rcond=None)
    rest = float(np.sum((A @ sol - b) ** 2))
    return rest <= 0.1 * energy, float(sol[2])


def error_structure(
    error: np.ndarray, w: np.ndarray, outputs: Sequence[str], inputs: Sequence[str]
) -> ErrorStructure:
    """Split the complex log error (n_freq, n_out, n_in) into common, row, column and rest.

    Parameters
    ----------
    error : ndarray, complex, shape (n_freq, n_out, n_in)
    w : ndarray (n_freq,)
        Angular frequencies in rad/s (for the common-delay fit).
    outputs, inputs : sequence of str

    Returns
    -------
    ErrorStructure
        ``kind`` is decided in this order: ``"none"`` if there is no error;
        ``"structural"`` if the channel-specific rest holds >= 40 %; ``"sensor"`` if the row
        share is at least twice the column share and >= 25 %; ``"actuator"`` likewise;
        ``"common"`` if the common part dominates and is a gain/delay; else ``"structural"``.
    """
    e = np.asarray(error, dtype=complex)
    no, ni = e.shape[1:]
    mu = e.mean(axis=(1, 2))
    rows = e.mean(axis=2)  # (nf, no) = mu + a
    cols = e.mean(axis=1)  # (nf, ni) = mu + b
    a = rows - mu[:, None]
    b = cols - mu[:, None]
    rest = e - mu[:, None, None] - a[:, :, None] - b[:, None, :]
    total = float(np.sum(np.abs(e) ** 2))
    row_energy = np.sum(np.abs(rows) ** 2, axis=0) * ni
    col_energy = np.sum(np.abs(cols) ** 2, axis=0) * no
    dom_o = outputs[int(np.argmax(row_energy))]
    dom_i = inputs[int(np.argmax(col_energy))]
    if total <= 1e-30 * max(e.size, 1):
        return ErrorStructure(0.0, 0.0, 0.0, 0.0, row_energy, col_energy, dom_o, dom_i, "none")
    fc = float(np.sum(np.abs(mu) ** 2)) * no * ni / total
    fs = float(np.sum(np.abs(a) ** 2)) * ni / total
    fa = float(np.sum(np.abs(b) ** 2)) * no / total
    fr = float(np.sum(np.abs(rest) ** 2)) / total
    is_gd, tau = _common_is_gain_delay(mu, np.asarray(w, dtype=float))
    if fr >= 0.4:
        kind = "structural"
    elif fs >= 2 * fa and fs >= 0.25:
        kind = "sensor"
    elif fa >= 2 * fs and fa >= 0.25:
        kind = "actuator"
    elif fc >= 0.5 and is_gd:
        kind = "common"
    else:
        kind = "structural"
    return ErrorStructure(fc, fs, fa, fr, row_energy, col_energy, dom_o, dom_i, kind, tau if is_gd else 0.0)


# ---------------------------------------------------------------------------- bands
@dataclass(frozen=True)
class Band:
    """A contiguous frequency region where the model fails.

    Attributes
    ----------
    lo_hz, hi_hz : float
        Edges (Hz), the first and last failing data points.
    peak_hz : float
        Frequency of the largest RMS error in the band.
    peak_error_db : float
        That RMS error as an equivalent magnitude error in dB (``|e|`` in nepers x 8.686;
        phase counts with 1 rad = 8.686 dB).
    share : float
        Fraction of the total cost (eq. 5, unweighted) inside the band.
    channel : str
        The channel with the largest error energy in the band, ``"output <- input"``.
    """

    lo_hz: float
    hi_hz: float
    peak_hz: float
    peak_error_db: float
    share: float
    channel: str


def _worst_bands(
    f: np.ndarray, e: np.ndarray, outputs, inputs, threshold_db: float, n_bands: int
) -> tuple[Band, ...]:
    power = np.abs(e) ** 2
    rms = np.sqrt(power.reshape(f.size, -1).mean(axis=1)) * DB_PER_NEPER
    total = float(power.sum()) or 1.0
    bad = rms > threshold_db
    edges = np.flatnonzero(np.diff(np.concatenate([[0], bad.astype(int), [0]])))
    bands = []
    for start, stop in zip(edges[::2], edges[1::2]):
        sl = slice(start, stop)
        ch = power[sl].sum(axis=0)
        o, i = np.unravel_index(int(np.argmax(ch)), ch.shape)
        k = start + int(np.argmax(rms[sl]))
        bands.append(
            Band(
                float(f[start]),
                float(f[stop - 1]),
                float(f[k]),
                float(rms[k]),
                float(power[sl].sum()) / total,
                f"{outputs[o]} <- {inputs[i]}",
            )
        )
    bands.sort(key=lambda b: -b.share)
    return tuple(bands[:n_bands])


# ---------------------------------------------------------------------------- result
@dataclass(frozen=True, eq=False)
class ModeRow:
    """One row of the mode table (MACE Table 1); errors are ``(data - model) / model`` in %."""

    f_model: float
    f_data: float
    zeta_model: float
    zeta_data: float
    mac: float

    @property
    def f_error_pct(self) -> float:
        return 100.0 * (self.f_data - self.f_model) / self.f_model

    @property
    def zeta_error_pct(self) -> float:
        return 100.0 * (self.zeta_data - self.zeta_model) / self.zeta_model


@dataclass(frozen=True, eq=False)
class Comparison:
    """Result of :func:`compare`: where and how a model disagrees with data.

    Attributes
    ----------
    log_cost : LogCost
        The cost report (the package's one type): MACE's J (eq. 5) on the band with the
        point weights, per channel and in total. ``cost`` (= ``log_cost.total``),
        ``channel_cost`` (= ``log_cost.per_channel``) and ``cost_per_point``
        (= ``log_cost.mean``) read it.
    f_hz : ndarray (n_freq,)
        Band frequencies, Hz.
    error : ndarray complex (n_freq, n_out, n_in)
        Unweighted ``log(G_data / G_model)``.
    mag_error_db, phase_error_deg : ndarray (n_freq, n_out, n_in)
        Its real part in dB and imaginary part in degrees (data minus model).
    bands : tuple of Band
        Worst frequency bands, largest share of the cost first.
    modes : tuple of ModeRow
        Paired (and unpaired, with NaN on the missing side) modes in the band.
    mode_source : str
        ``"measurement model"`` or ``"peak picking"`` (frequencies and shapes only: the data's
        damping is NaN, since a half-power bandwidth read off an H1 estimate measures the
        window's leakage as much as the structure; pass ``measurement_model=``). For an impact
        test seen through its exponential window both the data and the model (as the estimator
        sees it) are peak picked, since the window's damping moves the peaks.
    structure : ErrorStructure
        Sensor / actuator / structural split of the error.
    outputs, inputs : tuple of str
    data : FrequencyData
        The banded data.
    model_response : ndarray complex (n_freq, n_out, n_in)
    model_name : str
    threshold_db : float
        Threshold used for the bands.
    dropped : tuple of (output, input, level_dB)
        Negligible channels left out of the cost (weight 0).
    noise : NoiseModel or None
        The data's noise model on the band (None: no significance claims are made).
    noise_test : NoiseTest or None
        Chi-square verdicts per channel and section (:mod:`robustctl.correlate.verdict`).
    estimator_note : str
        How the model was seen: ``"model seen through the H1 estimator: 4096-pt hamming at 200
        Hz"``, or as the plain FRF and why (``"compared as the plain FRF: the data do not say how
        they were estimated"``; :func:`robustctl.measure.estimator.experiment_view`).
    warnings : tuple of str
        Warnings raised while comparing (e.g. units).
    model_modes, data_modes : tuple of Mode
        The modes found in the model and in the data (measurement model or peak picking) on
        the band, before pairing (:class:`robustctl.Mode`).
    """

    log_cost: LogCost
    f_hz: np.ndarray
    error: np.ndarray
    mag_error_db: np.ndarray
    phase_error_deg: np.ndarray
    bands: tuple[Band, ...]
    modes: tuple[ModeRow, ...]
    mode_source: str
    structure: ErrorStructure
    outputs: tuple[str, ...]
    inputs: tuple[str, ...]
    data: FrequencyData = field(repr=False)
    model_response: np.ndarray = field(repr=False)
    model_name: str = "model"
    threshold_db: float = 3.0
    dropped: tuple[tuple[str, str, float], ...] = ()
    noise: NoiseModel | None = field(default=None, repr=False)
    noise_test: NoiseTest | None = None
    estimator_note: str = ""
    warnings: tuple[str, ...] = ()

    @property
    def within_noise(self) -> bool | None:
        """True/False: the misfit is / is not within the noise everywhere; None: no noise model."""
        return None if self.noise_test is None else self.noise_test.within
    model_modes: tuple[Mode, ...] = field(default=(), repr=False)
    data_modes: tuple[Mode, ...] = field(default=(), repr=False)

    @property
    def cost(self) -> float:
        """MACE's J (eq. 5) on the band, with the point weights."""
        return self.log_cost.total

    @property
    def channel_cost(self) -> np.ndarray:
        """J per channel, shape (n_out, n_in) (sums to ``cost``)."""
        return self.log_cost.per_channel

    @property
    def cost_per_point(self) -> float:
        """``cost / (n_freq * n_out * n_in)`` (comparable across bands and data sets)."""
        return self.log_cost.mean

    # ------------------------------------------------------------------ tables
    def table(self) -> Table:
        """Per-channel table: cost, its share, RMS magnitude (dB) and phase (deg) errors."""
        rows = []
        for o, out in enumerate(self.outputs):
            for i, inp in enumerate(self.inputs):
                rows.append(
                    (
                        out,
                        inp,
                        float(self.channel_cost[o, i]),
                        float(100 * self.channel_cost[o, i] / self.cost) if self.cost > 0 else 0.0,
                        float(np.sqrt(np.mean(self.mag_error_db[:, o, i] ** 2))),
                        float(np.sqrt(np.mean(self.phase_error_deg[:, o, i] ** 2))),
                        float(np.max(np.abs(self.mag_error_db[:, o, i]))),
                    )
                )
        rows.sort(key=lambda r: -r[2])
        return Table(
            (
                "output",
                "input",
                "cost J",
                "share (%)",
                "rms mag err (dB)",
                "rms phase err (deg)",
                "max |mag err| (dB)",
            ),
            rows,
            title=f"{self.model_name} vs data: cost per channel (MACE eq. 5)",
        )

    def mode_table(self) -> Table:
        """Modes in the style of MACE Table 1; errors ``(data - model)/model`` in %."""
        rows = [
            (
                k + 1,
                m.f_model,
                m.f_data,
                m.f_error_pct,
                100 * m.zeta_model,
                100 * m.zeta_data,
                m.zeta_error_pct,
                m.mac,
            )
            for k, m in enumerate(self.modes)
        ]
        return Table(
            (
                "mode",
                "f model (Hz)",
                "f data (Hz)",
                "f error (%)",
                "zeta model (%)",
                "zeta data (%)",
                "zeta error (%)",
                "MAC",
            ),
            rows,
            title=f"modes: model vs data ({self.mode_source}{_DAMPING_NOTE.get(self.mode_source, '')})",
        )

    def band_table(self) -> Table:
        """The worst bands."""
        rows = [(b.lo_hz, b.hi_hz, b.peak_hz, b.peak_error_db, 100 * b.share, b.channel) for b in self.bands]
        return Table(
            ("lo (Hz)", "hi (Hz)", "peak (Hz)", "peak rms err (dB)", "share of cost (%)", "worst channel"),
            rows,
            title=f"bands where the RMS error exceeds {self.threshold_db:g} dB",
        )

    def summary(self) -> str:
        """A few sentences in plain words."""
        nf, no, ni = self.error.shape
        kept = np.ones((no, ni), dtype=bool)
        for o, i, _lv in self.dropped:
            kept[self.outputs.index(o), self.inputs.index(i)] = False
        lines = [
            f"{self.model_name} against {no}x{ni} channels on {self.f_hz[0]:.4g}-{self.f_hz[-1]:.4g} Hz "
            f"({nf} points): cost J = {self.cost:.4g} ({self.cost_per_point:.3g} per point; RMS error "
            f"{_rms(self.mag_error_db, kept):.2f} dB in magnitude, "
            f"{_rms(self.phase_error_deg, kept):.1f} deg in phase"
            + (f", over the {int(kept.sum())} channels kept" if not kept.all() else "") + ")."
        ]
        o, i = np.unravel_index(int(np.argmax(self.channel_cost)), self.channel_cost.shape)
        lines.append(
            f"Worst channel: {self.outputs[o]} <- {self.inputs[i]} "
            f"({100 * self.channel_cost[o, i] / max(self.cost, 1e-300):.4g}% of the cost)."
        )
        if self.estimator_note:
            lines.append(self.estimator_note[:1].upper() + self.estimator_note[1:] + ".")
        if self.noise_test is None:
            lines.append(no_noise_sentence())
        else:
            lines.append(self.noise_test.sentence())
        verb = "fails most" if self.noise_test is not None else "is largest"
        if self.bands:
            parts = [
                f"{b.lo_hz:.4g}-{b.hi_hz:.4g} Hz ({100 * b.share:.4g}% of the cost, peak "
                f"{b.peak_error_db:.4g} dB at {b.peak_hz:.4g} Hz)"
                for b in self.bands[:3]
            ]
            lines.append(f"It {verb} in " + "; ".join(parts) + ".")
        elif self.noise_test is None or not self.noise_test.within:
            lines.append(f"The RMS error stays below {self.threshold_db:g} dB everywhere in the band.")
        paired = [m for m in self.modes if np.isfinite(m.f_model) and np.isfinite(m.f_data)]
        if paired:
            worst = max(paired, key=lambda m: abs(m.f_error_pct))
            lines.append(
                f"{len(paired)} modes paired ({self.mode_source}); largest frequency error "
                f"{worst.f_error_pct:+.4g}% at {worst.f_model:.4g} Hz (model) vs "
                f"{worst.f_data:.4g} Hz (data)."
            )
        if self.noise_test is not None and self.noise_test.within:
            lines.append("Error structure: not assessed (the misfit is noise).")
        else:
            lines.append("Error structure: " + self.structure.describe())
        lines += [f"Warning: {w}" for w in self.warnings]
        if self.dropped:
            dead = [f"{o} <- {i}" for o, i, lv in self.dropped if lv == -np.inf]
            names = ", ".join(f"{o} <- {i} ({lv:.0f} dB)" for o, i, lv in self.dropped if lv > -np.inf)
            if names:
                lines.append(f"Left out as negligible (decoupled) channels: {names}.")
            if dead:
                lines.append("Left out as identically zero in the data (a dead or disconnected sensor or "
                             f"actuator? check the cable): {', '.join(dead)}.")
        return "\n".join(lines)

    def _repr_html_(self) -> str:
        noise = None if self.noise_test is None else self.noise_test.table()
        return result_html(self.summary(), self.table(), self.band_table(), self.mode_table(), noise)

    def __repr__(self) -> str:
        return f"Comparison(cost={self.cost:.4g}, kind={self.structure.kind!r}, bands={len(self.bands)})"

    # ------------------------------------------------------------------ plots
    def plot(self, fig: Any = None, *, phase: bool = False) -> Any:
        """Data vs model per channel (failing bands shaded; ``phase=True`` adds a phase row) and
        the error heat map (:meth:`plot_error_map`), on log-frequency axes over the compared band.

        Every channel gets a panel: a full matrix of up to 3 inputs one column per input, a
        single input's channels wrapped into a near-square grid
        (:func:`robustctl.plots.grid_columns`).

        Returns the matplotlib Figure.
        """
        nf, no, ni = self.error.shape
        rows = 2 if phase else 1
        pairs = [(o, i) for o in range(no) for i in range(ni)]
        ncols = grid_columns(len(pairs), ni)
        nrows = int(np.ceil(len(pairs) / ncols))
        map_h = 0.25 * len(pairs) + 1.2
        fig = fig or new_figure(3.2 * ncols + 1, (2.4 + 1.4 * phase) * nrows + map_h + 0.6)
        per_row = [1.0, 0.6][:rows] * nrows
        grid = fig.add_gridspec(rows * nrows + 1, ncols, height_ratios=per_row + [map_h / 2.4])
        f = self.f_hz
        for k, (o, i) in enumerate(pairs):
            r, c = divmod(k, ncols)
            ax = fig.add_subplot(grid[rows * r, c])
            ax.loglog(f, np.abs(self.data.response[:, o, i]), "k.", ms=2, label="data")
            ax.loglog(f, np.abs(self.model_response[:, o, i]), "C0-", lw=1, label=self.model_name)
            for b in self.bands:
                ax.axvspan(b.lo_hz, b.hi_hz, color="C3", alpha=0.15, lw=0)
            ax.set_title(channel_label(self.outputs[o], self.inputs[i]), fontsize=8)
            ax.set_ylabel(magnitude_label(self.data, self.outputs[o], self.inputs[i]), fontsize=7)
            log_frequency_axis(ax, f, label=not phase)
            ax.xaxis.label.set_size(7)
            ax.tick_params(which="both", labelsize=7)
            if k == 0:
                ax.legend(fontsize=7)
            if phase:
                axp = fig.add_subplot(grid[rows * r + 1, c], sharex=ax)
                axp.plot(f, np.degrees(np.angle(self.data.response[:, o, i])), "k.", ms=2)
                axp.plot(f, np.degrees(np.angle(self.model_response[:, o, i])), "C0-", lw=1)
                axp.set_ylabel("phase (deg)", fontsize=7)
                log_frequency_axis(axp, f)
                axp.xaxis.label.set_size(7)
                axp.tick_params(which="both", labelsize=7)
        self.plot_error_map(ax=fig.add_subplot(grid[rows * nrows, :]))
        return fig

    def within_noise_mask(self) -> np.ndarray | None:
        """``(n_out * n_in, n_freq)`` bool: points whose channel and section the noise test finds
        within the noise (rows output-major, as the heat map); None without a noise test."""
        if self.noise_test is None:
            return None
        nf, no, ni = self.error.shape
        mask = np.zeros((no * ni, nf), dtype=bool)
        for cell in self.noise_test.cells:
            if cell.within and cell.output in self.outputs and cell.input in self.inputs:
                row = self.outputs.index(cell.output) * ni + self.inputs.index(cell.input)
                mask[row] |= (self.f_hz >= cell.lo_hz) & (self.f_hz <= cell.hi_hz)
        return mask

    def plot_error_map(self, fig: Any = None, *, ax: Any = None) -> Any:
        """The complex-log error per channel over frequency (dB equivalent), cells within the noise
        grey (:func:`robustctl.plots.error_heat_map`); returns the Figure."""
        nf, no, ni = self.error.shape
        if ax is None:
            fig = fig or new_figure(9.0, 0.25 * no * ni + 1.8)
            ax = fig.add_subplot(1, 1, 1)
        emap = np.abs(self.error.reshape(nf, -1)).T * DB_PER_NEPER
        labels = [channel_label(a, b) for a in self.outputs for b in self.inputs]
        within = self.within_noise_mask()
        im = error_heat_map(ax, self.f_hz, emap, labels, within)
        if within is None or not within.all():  # an all-grey map has no colour to read
            colorbar(ax.figure, im, ax, "error (dB)")
        return ax.figure


# ---------------------------------------------------------------------------- compare
def _rms(values: np.ndarray, kept: np.ndarray) -> float:
    """Root mean square of ``values`` (n_freq, n_out, n_in) over the channels ``kept``."""
    return float(np.sqrt(np.mean(values[:, kept] ** 2))) if kept.any() else float("nan")


#: What the mode table says of the data's damping, by mode source.
_DAMPING_NOTE = {"peak picking": "; the data's damping needs measurement_model="}


def _mode_rows(model_modes: list[Mode], data_modes: list[Mode]) -> tuple[ModeRow, ...]:
    rows = []
    nan = float("nan")
    for i, j in pair_modes(model_modes, data_modes):
        a = model_modes[i] if i is not None else None
        b = data_modes[j] if j is not None else None
        rows.append(
            ModeRow(
                a.f_hz if a else nan,
                b.f_hz if b else nan,
                a.zeta if a else nan,
                b.zeta if b else nan,
                mac(a.shape, b.shape) if a and b else nan,
            )
        )
    return tuple(rows)


def compare(
    model: Any,
    data: FrequencyData,
    band: Sequence[float] | None = None,
    point_weights: Any = "auto",
    measurement_model: Any = None,
    *,
    threshold_db: float = 3.0,
    n_bands: int = 5,
    max_zeta: float = 0.5,
    min_channel_db: float | None = NEGLIGIBLE_DB,
    weights: Any = UNSET,
    estimator: Any = "auto",
    noise: Any = "auto",
    alpha: float = ALPHA,
    n_sections: int = 6,
) -> Comparison:
    """Compare a physical model with measured frequency responses (MACE eq. 5, Table 1).

    Parameters
    ----------
    model : system
        A PhysicalModel, MeasurementModel, ``control.StateSpace``, transfer function or
        anything :func:`robustctl.as_statespace` accepts. Channels are matched by
        :func:`robustctl.checks.match_channels`.
    data : FrequencyData, (f_hz, response) pair or control.FrequencyResponseData
        Measured responses (Hz).
    band : (f_lo_hz, f_hi_hz), optional
        Band in Hz; default every data point (:func:`robustctl.checks.check_band`).
    point_weights : "auto", None, "coherence" or array_like
        Data-point weights ``W`` on the squared log error (:func:`robustctl.checks.point_weights`);
        the dB/phase errors are unweighted. ``weights=`` is its deprecated name.
    weights
        Deprecated name of ``point_weights``.
    measurement_model : system, optional
        An ``rc.fit_measurement_model`` result (its identified ``.modes``) or any other system
        (the eigenstructure of its state space) gives the measured modes. Default: peak
        picking of the data.
    threshold_db : float
        RMS error over channels (dB-equivalent ``|log ratio|``; 1 rad of phase = 8.7 dB) above
        which a frequency point belongs to a failing band.
    n_bands : int
        How many worst bands to keep.
    max_zeta : float
        Model poles with a damping ratio at or above this are not listed as modes.
    min_channel_db : float or None
        Negligible channels (see :class:`Residual`) get weight 0 and are left out of the
        cost, the bands and the structure split; they stay in the dB/phase maps.
    estimator : "auto", True, False or EstimatorSettings
        Compare the model "as the H1 estimator sees it" (:func:`robustctl.measure.estimator.estimator_view`)
        as far as the data's experiment description (``data.experiment``) establishes it
        (``"auto"``): window leakage for random excitation with known settings, the sampled
        zero-order hold for held inputs, the plain FRF for undescribed data; stated in the summary.
    noise : "auto", NoiseModel or None
        The data's noise model. ``"auto"``: :func:`robustctl.noise_model` (coherence and
        averages; else the measurement model's residual; else none, and no significance claims).
    alpha : float
        Family-wise false-alarm rate of the chi-square verdicts (:mod:`~robustctl.correlate.verdict`).
    n_sections : int
        Frequency sections (equal point counts) per channel for the verdicts.

    Returns
    -------
    Comparison
        Failing bands are listed only where the misfit is beyond the noise (all of them when
        there is no noise model).

    Raises
    ------
    DataError
        Mismatched signal names or counts, or a band outside the data.
    """
    point_weights = renamed_keyword(point_weights, weights, "point_weights", "weights", default="auto")
    threshold_db = positive_number(threshold_db, "threshold_db", unit="dB")
    n_bands = integer(n_bands, "n_bands", lo=0)
    max_zeta = positive_number(max_zeta, "max_zeta")
    model = as_model(model)
    alpha = positive_number(alpha, "alpha")
    n_sections = integer(n_sections, "n_sections", lo=1)
    checked = check_data(data, band, noise, measurement_model)
    res = Residual.of_checked(model, checked, point_weights, min_channel_db, estimator)
    g_model = res.model_response()
    d = res.data
    error = log_ratio(d.response, g_model)
    weighted = res.weights * res.error(g_model)  # the cost's error: coherence weights' bias removed
    report = cost_report(error, d.outputs, d.inputs, point_weights=res.point_weights, bias=res.bias)
    f = d.f_hz
    span = (float(f[0]), float(f[-1]))
    model_modes = statespace_modes(model.statespace(), span, res._out_idx, res._in_idx, max_zeta=max_zeta)
    keep = np.any(res.weights > 0, axis=0)
    if measurement_model is not None:
        data_modes = measurement_modes(measurement_model, span, d.outputs, d.inputs, max_zeta=max_zeta)
        source = "measurement model"
    else:
        # a half-power bandwidth read off an H1 estimate measures the window's leakage as much as
        # the structure (40-110 % off on lightly damped modes): frequencies and shapes only
        data_modes = [replace(m, zeta=float("nan")) for m in peak_pick_modes(f, d.response, channels=keep)]
        source = "peak picking"
        if getattr(res.estimator, "impact", False):  # the window's damping moves the peaks: pick both
            model_modes = peak_pick_modes(f, g_model, channels=keep)
            source = "peak picking of both, as the impact estimator sees them"
    test = noise_test(error, res.noise, f, d.outputs, d.inputs, keep, n_sections, alpha)
    bands = _worst_bands(f, error * (res.weights > 0), d.outputs, d.inputs, threshold_db, n_bands)
    if test is not None:
        bands = tuple(b for b in bands if test.fails_at(b.lo_hz, b.hi_hz))
    notes = _units_warnings(model, data_modes, span, res, max_zeta)
    return Comparison(
        log_cost=report,
        f_hz=f,
        error=error,
        mag_error_db=error.real * DB_PER_NEPER,
        phase_error_deg=np.degrees(error.imag),
        bands=bands,
        modes=_mode_rows(model_modes, data_modes),
        mode_source=source,
        structure=error_structure(weighted, d.w, d.outputs, d.inputs),
        outputs=d.outputs,
        inputs=d.inputs,
        data=d,
        model_response=g_model,
        model_name=getattr(model, "name", "model"),
        threshold_db=float(threshold_db),
        dropped=tuple(res.dropped),
        noise=res.noise,
        noise_test=test,
        estimator_note=res.describe_estimator(),
        warnings=tuple(notes),
        model_modes=tuple(model_modes),
        data_modes=tuple(data_modes),
    )


def _units_warnings(model: Any, data_modes: list[Mode], span: tuple[float, float], res: Residual,
                    max_zeta: float) -> list[str]:
    """Warn when the model's modes sit a factor near 2 pi from the data's (Hz against rad/s).

    Counted are the data's modes that pair with a model mode at a factor (the model's modes,
    searched up to 8 x the band, are dense at the top: counting them would let any factor win
    there), and only when 2 pi pairs more of them than any physical scale factor in [1/2, 2]
    (stiffness or mass errors up to a factor 4): otherwise a few pair at 2 pi by chance once
    parameter errors of 10-50 % move every mode off the model's frequency (3-D frames with their
    modulus 20 % and 50 % high were told of a units slip)."""
    wide = (span[0] / 8.0, span[1] * 8.0)
    model_modes = statespace_modes(model.statespace(), wide, res._out_idx, res._in_idx, max_zeta=max_zeta)
    notes = []
    fm = np.array([m.f_hz for m in model_modes])
    fd = np.array([m.f_hz for m in data_modes])
    if fm.size == 0 or fd.size == 0:
        return notes

    def hits(factor: float) -> int:  # data modes with a model mode within 5 % of factor * f_model
        return int(sum(np.any(np.abs(np.log(x / (factor * fm))) < 0.05) for x in fd))

    direct = max(hits(float(x)) for x in np.exp(np.linspace(np.log(0.5), np.log(2.0), 57)))
    up, down = hits(2 * np.pi), hits(1 / (2 * np.pi))
    if max(up, down) >= 2 and max(up, down) > direct:
        which = "rad/s where Hz is expected (data frequencies 2 pi too high)" if up > down else (
            "Hz where rad/s was expected (model frequencies 2 pi too high)")
        msg = (
            f"{max(up, down)} of the data's modes sit a factor 2 pi = 6.28 from the model's modes: a "
            f"units slip, {which}? rc.FrequencyData takes f_hz in Hz; a model's s-domain is in rad/s."
        )
        import warnings as _w

        _w.warn(msg, UserWarning, stacklevel=3)
        notes.append(msg)
    return notes
