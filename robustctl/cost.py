"""The one cost report of robustctl: the complex-log cost of MACE eq. 5 per channel and in total.

``J = sum_channels sum_freq W |log(G_data / G_model) - c|^2``; the real part of the log is the
log-magnitude error (reported in dB: ``20 log10 e`` times it), the imaginary part the phase
error (rad, wrapped to (-pi, pi]); ``W`` are the data-point weights
(:func:`robustctl.checks.point_weights`) and ``c`` (real, 0 unless ``W`` are the data's own
coherence weights with a known number of averages) what those weights add to the log
magnitude on average (:func:`robustctl.checks.point_weight_bias`).
"""

from __future__ import annotations

import html
from dataclasses import dataclass
from typing import Any

import numpy as np

from .lti import DB_PER_NEPER, log_ratio
from .table import Table

__all__ = ["LogCost", "cost_report", "channel_cost"]


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
        from .plots import channel_label, new_figure

        fig = fig or new_figure(max(4.0, 0.5 * self.per_channel.size + 2), 3.5)
        ax = fig.add_subplot(1, 1, 1)
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
    :func:`robustctl.checks.point_weight_bias`, default 0); the RMS errors are those of ``e``
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
