"""Matplotlib figures shared by the result objects and the report.

Figures are built with ``matplotlib.figure.Figure`` (no pyplot state), so scripts never leak
open figures and nothing is shown twice. Inside a Jupyter kernel the first figure registers
IPython's PNG formatter for figures (what ``%matplotlib inline`` does, unless the user chose
a format already): a returned Figure then displays as a picture with no magic.
"""

from __future__ import annotations

import sys
from collections.abc import Sequence

import numpy as np

from .errors import DataError
from .frd import FrequencyData

__all__ = ["bode_grid", "new_figure"]


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


def _channels(reference: FrequencyData, max_channels: int) -> list[tuple[int, int]]:
    pairs = [(i, j) for j in range(reference.n_in) for i in range(reference.n_out)]
    return pairs[:max_channels]


def bode_grid(
    datasets: Sequence[FrequencyData],
    labels: Sequence[str] | None = None,
    *,
    max_channels: int = 9,
    shade_bands: Sequence[tuple[float, float]] = (),
    title: str = "",
    phase: bool = False,
):
    """Magnitude (and optionally phase) of several FRD sets, one panel per channel.

    Parameters
    ----------
    datasets : sequence of FrequencyData
        The first sets the channel layout; the others must share its signal names.
    labels : sequence of str, optional
        Legend entries, one per dataset.
    max_channels : int
        At most this many channels (output/input pairs, input-major) are drawn.
    shade_bands : sequence of (lo_hz, hi_hz)
        Frequency bands to shade (e.g. where a model fails).
    title : str
        Figure title.
    phase : bool
        Add a phase row under each magnitude panel.

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
    pairs = _channels(ref, max_channels)
    ncols = min(3, len(pairs))
    nrows = int(np.ceil(len(pairs) / ncols))
    rows_per = 2 if phase else 1
    fig = new_figure(3.4 * ncols, 2.4 * nrows * rows_per)
    axes = fig.subplots(nrows * rows_per, ncols, squeeze=False, sharex=True)
    for k, (i, j) in enumerate(pairs):
        r, c = divmod(k, ncols)
        ax = axes[r * rows_per, c]
        for d, lab in zip(datasets, labels):
            ax.semilogy(d.f_hz, np.abs(d.response[:, i, j]), label=lab, lw=1.0)
        for lo, hi in shade_bands:
            ax.axvspan(lo, hi, color="tab:red", alpha=0.12, lw=0)
        ax.set_title(f"{ref.inputs[j]} -> {ref.outputs[i]}", fontsize=9)
        if phase:
            axp = axes[r * rows_per + 1, c]
            for d in datasets:
                axp.plot(d.f_hz, np.degrees(np.angle(d.response[:, i, j])), lw=0.8)
            axp.set_ylabel("phase (deg)", fontsize=8)
    for ax in axes[-1]:
        ax.set_xlabel("frequency (Hz)")
    for k in range(len(pairs), nrows * ncols):
        r, c = divmod(k, ncols)
        for rr in range(rows_per):
            axes[r * rows_per + rr, c].set_visible(False)
    axes[0, 0].legend(fontsize=7)
    if title:
        fig.suptitle(title)
    return fig
