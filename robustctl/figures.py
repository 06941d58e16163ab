"""The modal engineer's figures: FRF Bode/coherence, MIMO singular values, model overlays with
fit %, MAC/AutoMAC matrices and mode-shape bars at the sensors.

Every function returns a ``matplotlib.figure.Figure`` built by :func:`robustctl.plots.new_figure`
(so it displays in Jupyter and leaks nothing in scripts); frequency axes are logarithmic over
the data's full range, every axis is labelled with its units, and channels are named
``"output <- input"``.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from .errors import DataError
from .frd import FrequencyData, as_frequency_data, register_method
from .modes import Mode
from .plots import bode_grid, colorbar, log_frequency_axis, new_figure

__all__ = [
    "fit_percent",
    "mac_matrix",
    "plot_compare",
    "plot_frf",
    "plot_mac",
    "plot_mode_shapes",
    "plot_singular_values",
]


# ---------------------------------------------------------------------------- FRF
def plot_frf(
    data: FrequencyData, *, phase: bool = True, coherence: bool | None = None, max_channels: int = 9
):
    """Bode plot of measured or computed FRFs: magnitude, phase and (when present) coherence.

    Parameters
    ----------
    data : FrequencyData
    phase : bool
        Draw the phase row (deg).
    coherence : bool, optional
        Draw the coherence row; default: when ``data.coherence`` is present.
    max_channels : int
        At most this many channels (output/input pairs).

    Returns
    -------
    matplotlib.figure.Figure
        ``1 + phase + coherence`` stacked axes per channel, log-frequency axes.
    """
    data = as_frequency_data(data)
    coherence = data.coherence is not None if coherence is None else bool(coherence)
    if coherence and data.coherence is None:
        raise DataError("coherence=True but the data carry no coherence; pass coherence=None or False.")
    return bode_grid([data], ["data"], max_channels=max_channels, phase=phase, coherence=coherence)


# ---------------------------------------------------------------------------- singular values
def _as_response(system: Any, f_hz: Any = None) -> FrequencyData:
    if isinstance(system, FrequencyData):
        return system
    if isinstance(system, tuple) or hasattr(system, "omega"):
        return as_frequency_data(system, "system")
    from .lti import freqresp

    if f_hz is None:
        raise DataError("a system needs f_hz (Hz) for its singular values; pass f_hz=np.logspace(...).")
    return freqresp(system, f_hz)


def plot_singular_values(systems: Any, f_hz: Any = None, labels: Sequence[str] | None = None):
    """Singular values ``sigma_k(G(j 2 pi f))`` of MIMO responses (Skogestad-Postlethwaite sec. 3.3).

    Parameters
    ----------
    systems : FrequencyData, system, or a sequence / mapping of them
        Data or anything :func:`robustctl.freqresp` evaluates (then ``f_hz`` is needed).
    f_hz : array_like, optional
        Frequencies (Hz) for systems given as state spaces or models.
    labels : sequence of str, optional
        Legend names (keys when ``systems`` is a mapping).

    Returns
    -------
    matplotlib.figure.Figure
        One axis: every singular value of every set against log frequency; largest solid,
        the others dashed.
    """
    if isinstance(systems, Mapping):
        labels, systems = list(systems), list(systems.values())
    elif isinstance(systems, (FrequencyData, tuple)) or not isinstance(systems, Sequence):
        systems = [systems]
    sets = [_as_response(s, f_hz) for s in systems]
    labels = list(labels) if labels is not None else [f"set {k + 1}" for k in range(len(sets))]
    fig = new_figure(7.0, 4.2)
    ax = fig.subplots()
    for n, (d, lab) in enumerate(zip(sets, labels)):
        sv = np.linalg.svd(d.response, compute_uv=False)
        for k in range(sv.shape[1]):
            ax.loglog(
                d.f_hz,
                sv[:, k],
                color=f"C{n}",
                lw=1.2 if k == 0 else 0.8,
                ls="-" if k == 0 else "--",
                label=f"{lab}: sigma_max" if k == 0 else (f"{lab}: other sigma" if k == 1 else None),
            )
    units = sets[0].units or {}
    unit = "" if not units else f" ({'/'.join(sorted(set(units.values())))})"
    ax.set_ylabel(f"singular value{unit}")
    log_frequency_axis(ax, np.array([min(d.f_hz[0] for d in sets), max(d.f_hz[-1] for d in sets)]))
    ax.set_title(f"singular values ({sets[0].n_out} outputs x {sets[0].n_in} inputs)")
    ax.legend(fontsize=8)
    return fig


# ---------------------------------------------------------------------------- compare
def fit_percent(data: FrequencyData, model: FrequencyData) -> np.ndarray:
    """Normalised-RMSE fit per channel, ``100 (1 - ||G_d - G_m|| / ||G_d - mean(G_d)||)`` (%).

    The norms run over frequency (complex 2-norm), as MATLAB's ``compare`` reports for
    frequency-domain data: 100 % is a perfect fit, 0 % no better than the mean response, and
    the value is negative when worse than that.

    Parameters
    ----------
    data, model : FrequencyData
        Same frequencies and channel order.

    Returns
    -------
    ndarray, shape (n_out, n_in)
    """
    if data.shape != model.shape:
        raise DataError(f"model response shape {model.shape} differs from the data's {data.shape}.")
    gd, gm = data.response, model.response
    num = np.linalg.norm(gd - gm, axis=0)
    den = np.linalg.norm(gd - gd.mean(axis=0, keepdims=True), axis=0)
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(den > 0, 100.0 * (1.0 - num / den), np.nan)


def plot_compare(
    data: Any,
    models: Any,
    *,
    phase: bool = False,
    band: Sequence[float] | None = None,
    max_channels: int = 9,
):
    """Data and several models on one axis per channel, with each model's fit % (MATLAB ``compare``).

    Parameters
    ----------
    data : FrequencyData
        Measured responses.
    models : mapping name -> system, or sequence of systems
        Anything :func:`robustctl.freqresp` evaluates (PhysicalModel, StateSpace, MeasurementModel
        ...) or a FrequencyData on the data's grid; channels are matched to the data by name, and
        a model with more channels than the data is cut to the data's.
    phase : bool
        Add a phase row (deg).
    band : (lo_hz, hi_hz), optional
        Restrict data and fit % to this band.
    max_channels : int

    Returns
    -------
    matplotlib.figure.Figure
        The legend of each channel gives each model's :func:`fit_percent` there;
        ``fig.fit_percent`` holds ``{name: ndarray (n_out, n_in)}``.
    """
    from .cost import _model_response

    data = as_frequency_data(data)
    if band is not None:
        data = data.band(*band)
    if not isinstance(models, Mapping):
        models = list(models) if isinstance(models, (list, tuple)) else [models]
        models = {getattr(m, "name", None) or f"model {k + 1}": m for k, m in enumerate(models)}
    if not models:
        raise DataError("plot_compare needs at least one model; got none.")
    responses = {name: _model_response(data, _cut_to_data(data, m)) for name, m in models.items()}
    fits = {name: fit_percent(data, r) for name, r in responses.items()}
    pairs = [(i, j) for i in range(data.n_out) for j in range(data.n_in)][:max_channels]
    notes = [[]] + [[f"fit {fits[name][i, j]:.0f}%" for i, j in pairs] for name in responses]
    fig = bode_grid(
        [data, *responses.values()],
        ["data", *responses],
        max_channels=max_channels,
        phase=phase,
        channel_notes=notes,
        title="fit % = 100 (1 - ||G_data - G_model|| / ||G_data - mean||) per channel",
    )
    fig.fit_percent = fits
    return fig


def _cut_to_data(data: FrequencyData, model: Any) -> Any:
    """The model's response on the data's grid, restricted to the data's channels when the model
    has more (a single-shaker test against a multi-input model); other models unchanged."""
    from .lti import freqresp

    response = model if isinstance(model, FrequencyData) else freqresp(model, data.f_hz)
    if set(data.outputs) <= set(response.outputs) and set(data.inputs) <= set(response.inputs):
        return response.select(outputs=list(data.outputs), inputs=list(data.inputs))
    return response


# ---------------------------------------------------------------------------- MAC
def _shapes(modes: Any) -> tuple[list[np.ndarray], list[str]]:
    if hasattr(modes, "modes"):
        modes = modes.modes
    if isinstance(modes, np.ndarray) and modes.ndim == 2:
        return [modes[:, k] for k in range(modes.shape[1])], [f"{k + 1}" for k in range(modes.shape[1])]
    shapes, names = [], []
    for k, m in enumerate(modes):
        if isinstance(m, Mode):
            if m.shape is None:
                raise DataError(f"mode {k + 1} ({m!r}) has no shape (residue); MAC needs shapes.")
            shapes.append(m.shape)
            names.append(f"{m.f_hz:.3g} Hz")
        else:
            shapes.append(np.asarray(m).ravel())
            names.append(f"{k + 1}")
    if not shapes:
        raise DataError("no mode shapes given; pass Modes, a (n_dof, n_modes) array or a model with .modes.")
    return shapes, names


def mac_matrix(a: Any, b: Any = None) -> np.ndarray:
    """MAC between every shape of ``a`` and of ``b`` (AutoMAC of ``a`` when ``b`` is None).

    ``MAC_kl = |a_k^H b_l|^2 / ((a_k^H a_k)(b_l^H b_l))`` (Allemang & Brown 1982), in [0, 1].

    Parameters
    ----------
    a, b : sequence of Mode, ndarray (n_dof, n_modes), or a result with ``.modes``
    """
    from .modes import mac

    sa, _ = _shapes(a)
    sb, _ = _shapes(a if b is None else b)
    if len({s.size for s in sa + sb}) != 1:
        raise DataError(
            f"mode shapes have different lengths {sorted({s.size for s in sa + sb})}; "
            "use shapes over the same channels."
        )
    return np.array([[mac(x, y) for y in sb] for x in sa])


def plot_mac(a: Any, b: Any = None, labels: tuple[str, str] = ("model", "data")):
    """MAC matrix (AutoMAC when ``b`` is None) as a coloured grid with values written in.

    Parameters
    ----------
    a, b : sequence of Mode, ndarray (n_dof, n_modes), or a result with ``.modes``
    labels : (str, str)
        Names of the two mode sets (rows, columns).

    Returns
    -------
    matplotlib.figure.Figure
    """
    values = mac_matrix(a, b)
    _, rows = _shapes(a)
    _, cols = _shapes(a if b is None else b)
    n, m = values.shape
    fig = new_figure(max(4.0, 0.45 * m + 2.5), max(3.5, 0.4 * n + 1.5))
    ax = fig.subplots()
    im = ax.imshow(values, vmin=0.0, vmax=1.0, cmap="viridis")
    ax.set_xticks(range(m), cols, rotation=60, ha="right", fontsize=7)
    ax.set_yticks(range(n), rows, fontsize=7)
    if n * m <= 400:
        for i in range(n):
            for k in range(m):
                ax.text(
                    k,
                    i,
                    f"{values[i, k]:.2f}",
                    ha="center",
                    va="center",
                    fontsize=6,
                    color="w" if values[i, k] < 0.6 else "k",
                )
    second = labels[0] if b is None else labels[1]
    ax.set_xlabel(f"{second} mode")
    ax.set_ylabel(f"{labels[0]} mode")
    ax.set_title("AutoMAC" if b is None else "MAC")
    colorbar(fig, im, ax, "MAC (-)")
    return fig


# ---------------------------------------------------------------------------- mode shapes
def _real_shape(vector: np.ndarray) -> np.ndarray:
    """A complex shape rotated to its largest component's phase, real part, peak scaled to 1."""
    v = np.asarray(vector, dtype=complex)
    k = int(np.argmax(np.abs(v)))
    if abs(v[k]) == 0:
        return np.zeros(v.size)
    r = (v * np.exp(-1j * np.angle(v[k]))).real
    return r / np.max(np.abs(r))


def plot_mode_shapes(
    model: Any,
    outputs: Sequence[str] | None = None,
    *,
    band: Sequence[float] | None = None,
    max_modes: int = 12,
):
    """Mode shapes at the sensors: one bar chart per mode, a bar per output.

    The shape of a mode is the output column of its residue (``C v`` of the state space, or
    ``output_shape`` of an identified mode; Caltech eq. 10), rotated to real and scaled so its
    largest entry is 1.

    Parameters
    ----------
    model : result with ``.modes`` (MeasurementModel), sequence of Mode, or a system
        A system (PhysicalModel, StateSpace) gives its eigenmodes in ``band``.
    outputs : sequence of str, optional
        Sensor names (default: the model's output names, else ``y1..``).
    band : (lo_hz, hi_hz), optional
        For a system: which modes (default 0-inf Hz).
    max_modes : int
        At most this many modes (lowest first).

    Returns
    -------
    matplotlib.figure.Figure
    """
    modes, names = _modes_and_sensors(model, band)
    modes = sorted(modes, key=lambda m: m.f_hz)[:max_modes]
    if not modes:
        raise DataError("no modes to plot; widen band= or check the model.")
    shapes = [_real_shape(m.output_shape[:, 0] if m.output_shape is not None else _column(m)) for m in modes]
    n_out = shapes[0].size
    outputs = list(outputs) if outputs is not None else (names or [f"y{k + 1}" for k in range(n_out)])
    if len(outputs) != n_out:
        raise DataError(f"outputs has {len(outputs)} names but the modes have {n_out} sensors.")
    ncols = min(4, len(modes))
    nrows = int(np.ceil(len(modes) / ncols))
    fig = new_figure(2.6 * ncols + 0.4, 2.2 * nrows + 0.4)
    axes = fig.subplots(nrows, ncols, squeeze=False, sharey=True)
    for k, ax in enumerate(axes.flat):
        if k >= len(modes):
            fig.delaxes(ax)
            continue
        ax.bar(range(n_out), shapes[k], color=["C0" if s >= 0 else "C3" for s in shapes[k]])
        ax.axhline(0.0, color="k", lw=0.6)
        ax.set_xticks(range(n_out), outputs, rotation=45, ha="right", fontsize=7)
        ax.set_title(f"{modes[k].f_hz:.4g} Hz, {modes[k].damping_pct:.2g}% damping", fontsize=8)
        ax.set_ylabel("shape (peak = 1)", fontsize=8)
        ax.set_xlabel("sensor", fontsize=8)
    return fig


def _column(mode: Mode) -> np.ndarray:
    """The residue column of the input that excites the mode most."""
    res = np.asarray(mode.residue)
    return res[:, int(np.argmax(np.linalg.norm(res, axis=0)))]


def _modes_and_sensors(model: Any, band: Sequence[float] | None) -> tuple[list[Mode], list[str] | None]:
    if hasattr(model, "modes") and not callable(model.modes):
        sys = getattr(model, "sys", None)
        names = list(sys.output_labels) if sys is not None else None
        return list(model.modes), names
    if isinstance(model, Sequence) and all(isinstance(m, Mode) for m in model):
        return list(model), None
    from .correlate.comparison import statespace_modes
    from .lti import as_statespace

    sys = as_statespace(model)
    lo, hi = (0.0, np.inf) if band is None else band
    return statespace_modes(sys, (lo, hi)), list(sys.output_labels)


def _plot_data_sv(data: FrequencyData):
    return plot_singular_values(data, labels=["data"])


register_method("plot", plot_frf)
register_method("plot_sv", _plot_data_sv)
