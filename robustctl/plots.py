"""Matplotlib figures shared by the result objects and the report.

Figures are built with ``matplotlib.figure.Figure`` (no pyplot state), so scripts never leak
open figures and nothing is shown twice. Inside a Jupyter kernel the first figure registers
IPython's PNG formatter for figures (what ``%matplotlib inline`` does, unless the user chose
a format already): a returned Figure then displays as a picture with no magic.
"""

from __future__ import annotations

import sys
from collections.abc import Sequence
from typing import Any

import numpy as np

from .errors import DataError
from .frd import FrequencyData

__all__ = [
    "bode_grid",
    "channel_label",
    "colorbar",
    "annotated_matrix",
    "grid_columns",
    "log_frequency_axis",
    "magnitude_label",
    "new_figure",
    "label_axes",
    "single_axes",
]


def _show_figures_in_kernel(figure_class: type) -> None:
    """Inside an IPython kernel (Jupyter, VS Code), make returned Figures display as PNG.

    Does nothing in scripts and terminals, or when a figure formatter is registered already
    (the user's ``%matplotlib inline`` / ``%config InlineBackend.figure_formats`` win).
    """
    ipython = sys.modules.get("IPython")
    shell = ipython.get_ipython() if ipython is not None else None
    if shell is None or getattr(shell, "kernel", None) is None:
        return
    formatters = shell.display_formatter.formatters
    for mime in ("image/png", "image/svg+xml", "application/pdf", "image/jpeg"):
        try:
            formatters[mime].lookup_by_type(figure_class)
            return
        except KeyError:
            continue
    from IPython.core.pylabtools import select_figure_formats

    select_figure_formats(shell, {"png"})


def new_figure(width: float = 9.0, height: float = 6.0):
    """A fresh ``matplotlib.figure.Figure`` of the given size (inches).

    In a Jupyter kernel the returned Figure renders as a picture (see the module docstring).
    """
    from matplotlib.figure import Figure

    _show_figures_in_kernel(Figure)
    return Figure(figsize=(width, height), layout="constrained")


def single_axes(fig: Any = None, width: float = 9.0, height: float = 6.0) -> tuple[Any, Any]:
    """The one axes of a result plot: on ``fig`` when given, else on a fresh Figure of the given size.

    Parameters
    ----------
    fig : matplotlib Figure, optional
    width, height : float
        Size (inches) of the fresh Figure when ``fig`` is None.

    Returns
    -------
    fig : matplotlib Figure
    ax : matplotlib Axes
        ``fig.add_subplot(1, 1, 1)``.

    See Also
    --------
    new_figure, label_axes
    """
    fig = fig or new_figure(width, height)
    return fig, fig.add_subplot(1, 1, 1)


def label_axes(ax: Any, xlabel: str, ylabel: str, title: str) -> None:
    """Label both axes, title the axes and draw the legend in the one small size of result plots.

    Parameters
    ----------
    ax : matplotlib Axes
    xlabel, ylabel : str
        Axis labels, with units in parentheses.
    title : str

    See Also
    --------
    new_figure : the Figure the axes belong to.
    """
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    ax.set_title(title)
    ax.legend(fontsize=8)


def _channels(reference: FrequencyData, max_channels: int) -> list[tuple[int, int]]:
    pairs = [(i, j) for i in range(reference.n_out) for j in range(reference.n_in)]
    return pairs[:max_channels]


def channel_label(output: str, input: str) -> str:
    """The one channel-label style of every figure and table: ``"output <- input"``."""
    return f"{output} <- {input}"


def magnitude_label(data: FrequencyData, output: str, input: str) -> str:
    """``"|G| (m/s^2/V)"`` from ``data.units`` (output unit over input unit), ``"|G|"`` if unknown."""
    units = data.units or {}
    out_u, in_u = units.get(output), units.get(input)
    if out_u and in_u:
        return f"|G| ({out_u}/{in_u})"
    if out_u or in_u:
        return f"|G| ({out_u or '1'}/{in_u or '1'})"
    return "|G| (data units)"


def grid_columns(n_panels: int, n_in: int) -> int:
    """Columns of a channel grid: one per input when the full matrix fits (2x2 on 2 columns, 3x3
    on 3); a single input's channels side by side up to 4, beyond that wrapped into a
    near-square grid of at most 4 columns (12 outputs: 4 x 3, not a tall narrow column);
    otherwise 3."""
    if n_in == 1 and n_panels > 1:
        return int(n_panels if n_panels <= 4 else min(4, np.ceil(np.sqrt(n_panels))))
    if n_panels % max(n_in, 1) == 0 and 1 < n_in <= 3 and n_panels > n_in:
        return n_in
    return max(1, min(3, n_panels))


def shown_channels_title(shown: int, total: int, keyword: str = "channels=") -> str:
    """``"9 of 12 channels shown: pass channels= for others"`` when channels are left out, else ``""``."""
    if shown >= total:
        return ""
    return f"{shown} of {total} channels shown: pass {keyword} for others"


def error_heat_map(
    ax: Any, f_hz: np.ndarray, error_db: np.ndarray, labels: Sequence[str], within: np.ndarray | None = None
) -> Any:
    """The error of each channel over frequency as a heat map, cells within the noise grey.

    Parameters
    ----------
    ax : matplotlib Axes
    f_hz : ndarray (n_freq,)
    error_db : ndarray (n_channels, n_freq)
        ``|log(G_data / G_model)|`` in dB (20 log10 e per neper).
    labels : sequence of str
        One per channel (row).
    within : ndarray of bool (n_channels, n_freq), optional
        Points whose channel and section the noise test finds within the noise: drawn grey, and
        left out of the colour scale (their colour would claim an error the data cannot show).

    Returns
    -------
    The QuadMesh of the coloured cells (for a colour bar).
    """
    from matplotlib.colors import ListedColormap

    rows = np.arange(len(labels))
    values = np.asarray(error_db, dtype=float)
    grey = np.zeros_like(values, dtype=bool) if within is None else np.asarray(within, bool)
    shown = np.ma.masked_array(values, mask=grey)
    vmax = float(shown.max()) if shown.count() else 1.0
    if grey.any():
        ax.pcolormesh(f_hz, rows, np.ma.masked_array(np.ones_like(values), mask=~grey),
                      cmap=ListedColormap(["0.82"]), shading="nearest", vmin=0, vmax=1)
    im = ax.pcolormesh(f_hz, rows, shown, cmap="magma", shading="nearest", vmin=0.0, vmax=max(vmax, 1e-12))
    log_frequency_axis(ax, f_hz)
    ax.set_ylim(len(labels) - 0.5, -0.5)
    ax.set_yticks(rows)
    ax.set_yticklabels(list(labels), fontsize=6)
    ax.set_ylabel("channel", fontsize=7)
    note = "; grey: within the noise" if grey.any() else ""
    ax.set_title(f"|log(G_data / G_model)| (dB equivalent){note}", fontsize=8)
    return im


def sub_decade_labels(decades: float) -> tuple[float, ...]:
    """Which minor ticks of each decade a log axis spanning ``decades`` labels: 2, 3 and 5 up to
    1.2 decades, 2 and 5 up to 2.5 decades (1.5-60 Hz then reads 2, 5, 10, 20, 50), none beyond
    (the decade ticks are enough)."""
    if decades <= 1.2:
        return (2.0, 3.0, 5.0)
    if decades <= 2.5:
        return (2.0, 5.0)
    return ()


def plain_number(x: float) -> str:
    """``x`` as a plain number: ``3.61``, ``0.002``, ``1.2e+06`` (4 significant digits, no
    ``x10^n`` mathtext)."""
    return f"{x:.4g}"


def _plain_log_formatter(minor: bool) -> Any:
    """Tick labels ``f"{x:g}"`` on a log axis; minor ticks labelled at the sub-decade marks of
    :func:`sub_decade_labels` (on short axes, where the decade ticks alone are too few)."""
    from matplotlib.ticker import Formatter

    class PlainLogFormatter(Formatter):
        def __call__(self, x: float, pos: Any = None) -> str:
            if minor:
                lo, hi = sorted(self.axis.get_view_interval())
                mantissa = round(x / 10.0 ** np.floor(np.log10(x) + 1e-9), 6) if x > 0 else 0.0
                if not lo > 0 or mantissa not in sub_decade_labels(float(np.log10(hi / lo))):
                    return ""
            return plain_number(x)

    return PlainLogFormatter()


def plain_log_axis(ax: Any, which: str = "y") -> None:
    """Plain-number tick labels on a log axis (``3.6`` rather than ``3.6086x10^0``), with sub-decade
    labels on short axes (:func:`sub_decade_labels`)."""
    axis = ax.yaxis if which == "y" else ax.xaxis
    axis.set_major_formatter(_plain_log_formatter(minor=False))
    axis.set_minor_formatter(_plain_log_formatter(minor=True))


def log_frequency_axis(ax: Any, f_hz: np.ndarray, label: bool = True) -> None:
    """Log frequency axis over the data's full range, labelled in Hz.

    Tick labels are plain numbers (``0.6``, ``2``, ``10``; matplotlib's default ``6x10^-1``
    style overlaps on narrow panels); over more than three decades only 2 and 5 of each
    decade get a minor tick (the tick artists dominate the drawing time of a Bode grid).
    """
    from matplotlib.ticker import LogLocator

    lo, hi = float(f_hz[0]), float(f_hz[-1])
    ax.set_xscale("log")
    ax.set_xlim(lo, hi)
    ax.xaxis.set_major_formatter(_plain_log_formatter(minor=False))
    ax.xaxis.set_minor_formatter(_plain_log_formatter(minor=True))
    if lo > 0 and np.log10(hi / lo) > 3.0:
        ax.xaxis.set_minor_locator(LogLocator(subs=(2.0, 5.0)))
    else:
        ax.xaxis.set_minor_locator(LogLocator(subs=tuple(float(k) for k in range(2, 10))))
    if label:
        ax.set_xlabel("frequency (Hz)")


def _channel_axes(fig: Any, pairs: list[tuple[int, int]], n_in: int, rows_per: int) -> list[list[Any]]:
    """``rows_per`` stacked axes per channel (magnitude first), channels on a grid; unused cells hidden."""
    ncols = grid_columns(len(pairs), n_in)
    nrows = int(np.ceil(len(pairs) / ncols))
    axes = fig.subplots(nrows * rows_per, ncols, squeeze=False, sharex=True)
    stacks = []
    for k in range(nrows * ncols):
        r, c = divmod(k, ncols)
        cell = [axes[r * rows_per + rr, c] for rr in range(rows_per)]
        if k < len(pairs):
            stacks.append(cell)
        else:
            for ax in cell:
                fig.delaxes(ax)
    return stacks


def bode_grid(
    datasets: Sequence[FrequencyData],
    labels: Sequence[str] | None = None,
    *,
    max_channels: int = 9,
    channels: Sequence[tuple[int, int]] | None = None,
    shade_bands: Sequence[tuple[float, float]] = (),
    title: str = "",
    phase: bool = False,
    coherence: bool = False,
    channel_notes: Sequence[Sequence[str]] | None = None,
):
    """Magnitude (and optionally phase and coherence) of several FRD sets, one panel per channel.

    Every axis is labelled with its quantity and units (``data.units`` of the first set), the
    frequency axis is logarithmic over the first set's full range, channels are titled
    ``"output <- input"`` and a full ``n_out x n_in`` matrix of up to 3 inputs is laid out
    one column per input.

    Parameters
    ----------
    datasets : sequence of FrequencyData
        The first sets the channel layout; the others must share its signal names.
    labels : sequence of str, optional
        Legend entries, one per dataset.
    max_channels : int
        At most this many channels (output/input pairs, row by row: output-major) are drawn;
        a full matrix is laid out with one row per output and one column per input.
    channels : sequence of (int, int), optional
        The (output index, input index) pairs to draw instead (``max_channels`` is then unused).
    shade_bands : sequence of (lo_hz, hi_hz)
        Frequency bands to shade (e.g. where a model fails).
    title : str
        Figure title (channels left out by ``max_channels`` are stated above it: "9 of 12
        channels shown: pass max_channels= for others").
    phase : bool
        Add a phase row (deg) under each magnitude panel.
    coherence : bool
        Add a coherence row for every set that carries coherence.
    channel_notes : sequence (per dataset) of sequence (per channel) of str, optional
        Appended to the legend entry of that dataset in that channel (e.g. ``"fit 87%"``).

    Returns
    -------
    matplotlib.figure.Figure
    """
    if not datasets:
        raise DataError("bode_grid needs at least one FrequencyData.")
    ref = datasets[0]
    for d in datasets[1:]:
        if d.inputs != ref.inputs or d.outputs != ref.outputs:
            raise DataError(
                f"cannot overlay data with signals {d.outputs}x{d.inputs} on {ref.outputs}x{ref.inputs}."
            )
    labels = list(labels) if labels is not None else [f"set {k + 1}" for k in range(len(datasets))]
    pairs = list(channels) if channels is not None else _channels(ref, max_channels)
    coherence = coherence and any(d.coherence is not None for d in datasets)
    rows_per = 1 + bool(phase) + bool(coherence)
    ncols = grid_columns(len(pairs), ref.n_in)
    nrows = int(np.ceil(len(pairs) / ncols))
    fig = new_figure(3.6 * ncols + 0.4, (2.3 + 1.4 * (rows_per - 1)) * nrows + 0.6)
    stacks = _channel_axes(fig, pairs, ref.n_in, rows_per)
    for k, ((i, j), stack) in enumerate(zip(pairs, stacks)):
        ax = stack[0]
        for n, (d, lab) in enumerate(zip(datasets, labels)):
            note = channel_notes[n][k] if channel_notes is not None and channel_notes[n] else ""
            style = dict(lw=1.0, color=f"C{n}") if n else dict(lw=1.2, color="k")
            ax.loglog(d.f_hz, np.abs(d.response[:, i, j]), label=f"{lab} ({note})" if note else lab, **style)
        for lo, hi in shade_bands:
            ax.axvspan(lo, hi, color="tab:red", alpha=0.12, lw=0)
        ax.set_title(channel_label(ref.outputs[i], ref.inputs[j]), fontsize=9)
        ax.set_ylabel(magnitude_label(ref, ref.outputs[i], ref.inputs[j]), fontsize=8)
        if channel_notes is not None or k == 0:
            ax.legend(fontsize=7)
        row = 1
        if phase:
            axp = stack[row]
            for n, d in enumerate(datasets):
                phase_deg = np.degrees(np.angle(d.response[:, i, j]))
                axp.plot(d.f_hz, phase_deg, lw=0.8, color=f"C{n}" if n else "k")
            axp.set_ylabel("phase (deg)", fontsize=8)
            row += 1
        if coherence:
            axc = stack[row]
            for n, d in enumerate(datasets):
                if d.coherence is not None:
                    axc.plot(d.f_hz, d.coherence[:, i, j], lw=0.8, color=f"C{n}" if n else "k")
            axc.set_ylim(0, 1.05)
            axc.set_ylabel("coherence (-)", fontsize=8)
        for ax_k in stack:
            log_frequency_axis(ax_k, ref.f_hz, label=ax_k is stack[-1])
            ax_k.tick_params(which="both", labelsize=7)
    left_out = "" if channels is not None else shown_channels_title(len(pairs), ref.n_out * ref.n_in,
                                                                     "max_channels=")
    title = "\n".join(t for t in (left_out, title) if t)
    if title:
        fig.suptitle(title)
    return fig


def colorbar(fig: Any, mappable: Any, ax: Any, label: str) -> Any:
    """A labelled colour bar without minor ticks (their labels overlap on a log or short bar)."""
    bar = fig.colorbar(mappable, ax=ax)
    bar.minorticks_off()
    bar.set_label(label, fontsize=8)
    bar.ax.tick_params(labelsize=7)
    return bar


def annotated_matrix(
    ax: Any,
    values: np.ndarray,
    row_labels: Sequence[str],
    col_labels: Sequence[str],
    *,
    fmt: str = ".2f",
    max_cells: int = 400,
    dark_below: float = 0.6,
) -> Any:
    """A matrix of values in [0, 1] as a coloured grid (viridis), each cell's value written in.

    The one heat map of robustctl (MAC matrices, the orthogonality of update parameters).

    Parameters
    ----------
    ax : matplotlib Axes
        Where to draw.
    values : ndarray (n, m)
        The matrix; the colour scale is fixed to [0, 1].
    row_labels, col_labels : sequence of str
        Tick labels of the ``n`` rows and ``m`` columns (columns rotated 60 degrees).
    fmt : str
        Format of the written values (e.g. ``".2f"``).
    max_cells : int
        Write the values only when ``n m <= max_cells`` (larger grids stay legible uncluttered).
    dark_below : float
        Values below it are written in white (on the dark end of the map), the others in black.

    Returns
    -------
    matplotlib.image.AxesImage
        The image, for :func:`colorbar`.
    """
    values = np.asarray(values)
    n, m = values.shape
    im = ax.imshow(values, vmin=0.0, vmax=1.0, cmap="viridis")
    ax.set_xticks(range(m), col_labels, rotation=60, ha="right", fontsize=7)
    ax.set_yticks(range(n), row_labels, fontsize=7)
    if n * m <= max_cells:
        for i in range(n):
            for k in range(m):
                ax.text(k, i, format(values[i, k], fmt), ha="center", va="center", fontsize=6,
                        color="w" if values[i, k] < dark_below else "k")
    return im
