"""The one cost report of robustctl: the complex-log cost of MACE eq. 5 per channel and in total.

``J = sum_channels sum_freq W |log(G_data / G_model) - c|^2``; the real part of the log is the
log-magnitude error (reported in dB: ``20 log10 e`` times it), the imaginary part the phase
error (rad, wrapped to (-pi, pi]); ``W`` are the data-point weights
(:func:`robustctl.checks.point_weights`) and ``c`` (real, 0 unless ``W`` are the data's own
coherence weights with a known number of averages) what those weights add to the log
magnitude on average (:func:`robustctl.measure.noise.point_weight_bias`).
"""

from __future__ import annotations

import html
import warnings
from dataclasses import dataclass
from typing import Any

import numpy as np

from .checks import UNSET, band_mask, renamed_keyword, user_stacklevel
from .checks import point_weights as point_weights_of
from .errors import DataError, RobustctlDeprecationWarning
from .frd import FrequencyData, as_frequency_data
from .lti import DB_PER_NEPER, align_channels, as_statespace, freqresp, log_ratio
from .measure.estimator import model_view, resolve_estimator, split_hold
from .measure.noise import point_weight_bias
from .plots import channel_label, single_axes
from .table import Table

__all__ = ["LogCost", "cost_report", "channel_cost", "log_error", "log_cost"]


@dataclass(frozen=True, eq=False)
class LogCost:
    """MACE eq. 5 cost of a model against data, per channel and in total: the one cost report.

    ``rc.fit_measurement_model`` (``mm.cost``), ``RationalFit.cost()`` and ``rc.compare``
    (``cmp.log_cost``; ``cmp.cost`` and ``cmp.channel_cost`` read it) all return this type.

    Attributes
    ----------
    per_channel : ndarray, shape (n_out, n_in)
        ``sum_k W |log(G_data/G_model)|^2`` of each channel (dimensionless; ``W`` the
        data-point weights, 1 when unweighted).
    total : float
        Sum over channels (MACE eq. 5).
    rms_db : ndarray, shape (n_out, n_in)
        RMS log-magnitude error of each channel, dB.
    rms_phase_deg : ndarray, shape (n_out, n_in)
        RMS phase error of each channel, degrees.
    n_freq : int
        Number of frequency points scored.
    outputs, inputs : tuple of str
    """

    per_channel: np.ndarray
    total: float
    rms_db: np.ndarray
    rms_phase_deg: np.ndarray
    n_freq: int
    outputs: tuple[str, ...]
    inputs: tuple[str, ...]

    @property
    def rms_db_total(self) -> float:
        """RMS log-magnitude error over all channels, dB."""
        return float(np.sqrt(np.mean(self.rms_db**2)))

    @property
    def mean(self) -> float:
        """``total / (n_freq * n_channels)``: the mean squared complex-log error."""
        return self.total / (self.n_freq * self.per_channel.size)

    def table(self) -> Table:
        """One row per channel: cost, rms magnitude error (dB), rms phase error (deg)."""
        rows = [
            (f"{o} <- {i}", self.per_channel[a, b], self.rms_db[a, b], self.rms_phase_deg[a, b])
            for a, o in enumerate(self.outputs)
            for b, i in enumerate(self.inputs)
        ]
        rows.append(("total", self.total, self.rms_db_total, float(np.sqrt(np.mean(self.rms_phase_deg**2)))))
        cols = ("channel", "J (MACE eq. 5)", "rms |log| error (dB)", "rms phase error (deg)")
        return Table(cols, rows, title="Complex-log cost")

    def summary(self) -> str:
        """One sentence: total, mean per point and RMS errors."""
        o, i = np.unravel_index(int(np.argmax(self.per_channel)), self.per_channel.shape)
        return (
            f"J = {self.total:.4g} (MACE eq. 5) over {self.n_freq} frequencies x {self.per_channel.size} "
            f"channels ({self.mean:.3g} per point); rms error {self.rms_db_total:.3g} dB in magnitude, "
            f"{float(np.sqrt(np.mean(self.rms_phase_deg**2))):.3g} deg in phase; worst channel "
            f"{self.outputs[o]} <- {self.inputs[i]}."
        )

    def plot(self, fig: Any = None) -> Any:
        """Cost per channel as a bar chart (matplotlib Figure)."""
        fig, ax = single_axes(fig, max(4.0, 0.5 * self.per_channel.size + 2), 3.5)
        labels = [channel_label(o, i) for o in self.outputs for i in self.inputs]
        ax.bar(range(len(labels)), self.per_channel.ravel())
        ax.set_xticks(range(len(labels)))
        ax.set_xticklabels(labels, rotation=60, fontsize=7)
        ax.set_ylabel("J per channel (MACE eq. 5)")
        ax.set_xlabel("channel (output <- input)")
        return fig

    def _repr_html_(self) -> str:
        return f"<p>{html.escape(self.summary())}</p>" + self.table()._repr_html_()


def cost_report(
    error: np.ndarray,
    outputs: tuple[str, ...] = (),
    inputs: tuple[str, ...] = (),
    point_weights: np.ndarray | None = None,
    mask: np.ndarray | None = None,
    bias: np.ndarray | None = None,
) -> LogCost:
    """The :class:`LogCost` of a complex log error ``e`` (shape (K, n_out, n_in)).

    ``per_channel = sum_k W |e - c|^2`` over the points in ``mask`` (``W`` the point weights,
    default 1; ``c`` the real offset that coherence weights add to ``Re e``,
    :func:`robustctl.measure.noise.point_weight_bias`, default 0); the RMS errors are those of ``e``
    itself, unweighted, over the same points.
    """
    e = np.asarray(error, dtype=complex)
    scored = e if bias is None else e - np.asarray(bias, dtype=float)
    m = (
        np.ones(e.shape, dtype=bool)
        if mask is None
        else np.broadcast_to(
            np.asarray(mask, dtype=bool).reshape(e.shape[:1] + (1, 1)) if np.ndim(mask) == 1 else mask,
            e.shape,
        )
    )
    w = np.ones(e.shape) if point_weights is None else np.broadcast_to(point_weights, e.shape)
    count = np.maximum(m.sum(axis=0), 1)
    per = np.sum(np.where(m, w * np.abs(scored) ** 2, 0.0), axis=0)
    rms_db = DB_PER_NEPER * np.sqrt(np.sum(np.where(m, e.real**2, 0.0), axis=0) / count)
    rms_ph = np.degrees(np.sqrt(np.sum(np.where(m, e.imag**2, 0.0), axis=0) / count))
    n_out, n_in = per.shape
    outputs = tuple(outputs) or tuple(f"y{k + 1}" for k in range(n_out))
    inputs = tuple(inputs) or tuple(f"u{k + 1}" for k in range(n_in))
    return LogCost(per, float(per.sum()), rms_db, rms_ph, int(m.any(axis=(1, 2)).sum()), outputs, inputs)


def channel_cost(
    g_data: np.ndarray,
    g_model: np.ndarray,
    outputs: tuple[str, ...] = (),
    inputs: tuple[str, ...] = (),
    mask: np.ndarray | None = None,
) -> LogCost:
    """MACE eq. 5 of ``g_model`` against ``g_data`` (both shape (K, n_out, n_in)), unweighted.

    ``mask`` (shape (K,) or (K, n_out, n_in), boolean) restricts the scored points, e.g. to
    frequencies of high coherence.
    """
    e = log_ratio(np.asarray(g_data, dtype=complex), np.asarray(g_model, dtype=complex))
    return cost_report(e, outputs, inputs, mask=mask)


# ---------------------------------------------------------------------------- log error
def _model_response(data: FrequencyData, model: Any, estimator: Any = False) -> FrequencyData:
    if isinstance(model, FrequencyData):
        model = align_channels(data, model)
        if model.n_freq != data.n_freq or not np.allclose(model.f_hz, data.f_hz, rtol=1e-9, atol=0):
            raise DataError(
                f"the model FrequencyData has {model.n_freq} points "
                f"({model.f_hz[0]:g}-{model.f_hz[-1]:g} Hz) but the data has {data.n_freq} "
                f"({data.f_hz[0]:g}-{data.f_hz[-1]:g} Hz); evaluate the model on data.f_hz."
            )
        return model
    settings = resolve_estimator(estimator, data, model)
    if settings is None:
        return align_channels(data, freqresp(model, data.f_hz))
    bare, hold = split_hold(model)
    sys = as_statespace(bare)
    g = model_view(sys, hold, data.f_hz, settings)
    return align_channels(data, FrequencyData(data.f_hz, g, inputs=list(sys.input_labels),
                                      outputs=list(sys.output_labels)))


def _model_and_data(model: Any, data: Any, func: str) -> tuple[Any, FrequencyData]:
    """The ``(model, data)`` order; an old ``(data, system)`` call is recognised and warned about."""
    old_order = isinstance(model, FrequencyData) and not isinstance(data, (FrequencyData, tuple))
    if old_order and data is not None and not hasattr(data, "omega"):
        warnings.warn(
            f"{func}(data, model) is deprecated; the order is {func}(model, data) as in rc.compare.",
            RobustctlDeprecationWarning,
            stacklevel=user_stacklevel(),
        )
        model, data = data, model
    return model, as_frequency_data(data)


def log_error(
    model: Any, data: Any, band: tuple[float, float] | None = None, *, estimator: Any = "auto"
) -> np.ndarray:
    """The complex-log error ``log(G_data / G_model)`` (MACE eq. 5), shape (n_freq, n_out, n_in).

    Its real part is the log-magnitude error in nepers (x ``DB_PER_NEPER`` = 20/ln 10 for
    dB), its imaginary part the phase error in rad (principal value in (-pi, pi]).

    Parameters
    ----------
    model : system, or FrequencyData on the data's grid
        Anything :func:`robustctl.lti.as_statespace` accepts (evaluated at ``data.f_hz``), or a computed
        response. Channels are matched by :func:`robustctl.checks.match_channels`: by name
        (reordered if needed), or by position when one side carries default names.
    data : FrequencyData, (f_hz, response) pair or control.FrequencyResponseData
        The measured response. The old order ``log_error(data, system)`` still works (with a
        DeprecationWarning) when it is unambiguous; two FrequencyData are read as (model, data).
    band : (f_lo_hz, f_hi_hz), optional
        Restrict to this frequency band (Hz), inclusive (:func:`robustctl.checks.check_band`).
    estimator : "auto", True, False or EstimatorSettings
        See a system "as the H1 estimator sees it" when the data carry their estimator settings
        (:func:`robustctl.measure.estimator.resolve_estimator`; the rule of ``rc.compare``).

    Returns
    -------
    ndarray, complex
    """
    model, data = _model_and_data(model, data, "log_error")
    return _log_error(model, data, band_mask(data.f_hz, band), estimator)


def _log_error(model: Any, data: FrequencyData, mask: np.ndarray, estimator: Any = "auto") -> np.ndarray:
    if not np.all(mask):
        if isinstance(model, FrequencyData) and model.n_freq == mask.size:
            model = model.replace(f_hz=model.f_hz[mask], response=model.response[mask], coherence=None)
        data = data.points(mask)  # checked where it entered: not validated again
    gm = _model_response(data, model, estimator).response
    gd = data.response
    for name, g in (("data", gd), ("model", gm)):
        zero = np.argwhere(g == 0)
        if zero.size:
            k, o, i = zero[0]
            raise DataError(
                f"the {name} response is exactly zero at {data.f_hz[k]:g} Hz "
                f"(output {data.outputs[o]!r}, input {data.inputs[i]!r}); the log error is undefined "
                "there. Drop that channel or band."
            )
    return log_ratio(gd, gm)


def log_cost(
    model: Any,
    data: Any,
    band: tuple[float, float] | None = None,
    point_weights: Any = "auto",
    *,
    weights: Any = UNSET,
    estimator: Any = "auto",
) -> float:
    """The weighted complex-log cost of MACE eq. 5: ``J = sum W |log(G_data / G_model) - c|^2``.

    ``c`` (real) is 0 except with coherence weights (``"auto"`` or ``"coherence"``) on data
    whose number of averages is known: then what those weights add to the log magnitude on
    average (:func:`robustctl.measure.noise.coherence_weight_bias`).

    The same number as ``rc.compare(model, data, band, point_weights).cost`` (with
    ``min_channel_db=None``, which keeps every channel) and as a MeasurementModel's cost.

    Parameters
    ----------
    model, data, band
        As for :func:`log_error` (same order as :func:`robustctl.compare`).
    point_weights : None, "auto", "coherence" or array_like
        Data-point weights ``W`` on the squared error (:func:`robustctl.checks.point_weights`):
        ``"auto"`` (default) coherence weights when the data carry coherence, else uniform;
        ``None`` uniform; an array of shape (n_freq,) or broadcastable to (n_freq, n_out,
        n_in), on the band's points or on the full data grid.
    weights
        Deprecated name of ``point_weights``.
    estimator : "auto", True, False or EstimatorSettings
        As for :func:`log_error` (and ``rc.compare``): one cost for the same inputs.

    Returns
    -------
    float
        The weighted sum over channels and frequencies (dimensionless).
    """
    point_weights = renamed_keyword(point_weights, weights, "point_weights", "weights", default="auto")
    model, data = _model_and_data(model, data, "log_cost")
    mask = band_mask(data.f_hz, band)
    w = point_weights_of(point_weights, data, mask)
    err = _log_error(model, data, mask, estimator)
    bias = point_weight_bias(point_weights, data, mask)  # what own-coherence weights add to Re err
    if bias is not None:
        err = err - bias
    return float(np.sum(w * np.abs(err) ** 2))
