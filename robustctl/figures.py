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

from .correlate.comparison import statespace_modes
from .cost import _model_response
from .errors import DataError
from .frd import FrequencyData, as_frequency_data, register_method
from .frd_io.geometry import ModeShapes
from .lti import as_statespace, freqresp
from .measure.estimator import model_view, resolve_view, split_hold
from .modes import Mode, mac
from .plots import annotated_matrix, bode_grid, colorbar, log_frequency_axis, new_figure, shown_channels_title

__all__ = [
    "fit_percent",
    "mac_matrix",
    "plot_compare",
    "plot_frf",
    "plot_mac",
    "plot_mode_shapes",
    "plot_singular_values",
    "animate_mode_shape",
    "ModeAnimation",
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
    channels: Sequence[tuple[str, str]] | None = None,
    max_channels: int = 12,
    estimator: Any = "auto",
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
        Restrict data, models, fit % and the frequency axis to this band.
    channels : sequence of (output, input), optional
        The channels to draw, by name (default: every channel, up to ``max_channels``).
    max_channels : int
        At most this many channels are drawn (output-major); when channels are left out the
        title says so (``"9 of 12 channels shown: pass channels= for others"``).
    estimator : "auto", True, False or EstimatorSettings
        Draw each model as the data's estimator sees it, by the rule of :func:`robustctl.compare`
        (:func:`robustctl.measure.estimator.resolve_view`): with ``"auto"``, the window leakage of
        a described random-excitation H1 estimate (a 2 %-damped mode's peak at a 0.25 Hz line
        spacing is drawn as the estimate shows it, not twice as high), a held input's hold, an
        impact test's window; the title says what was applied. False: the plain FRF.

    Returns
    -------
    matplotlib.figure.Figure
        The legend of each channel gives each model's :func:`fit_percent` there;
        ``fig.fit_percent`` holds ``{name: ndarray (n_out, n_in)}``.
    """
    data = as_frequency_data(data)
    if band is not None:
        data = data.band(*band)
    if not isinstance(models, Mapping):
        models = list(models) if isinstance(models, (list, tuple)) else [models]
        models = {getattr(m, "name", None) or f"model {k + 1}": m for k, m in enumerate(models)}
    if not models:
        raise DataError("plot_compare needs at least one model; got none.")
    seen = {name: _seen(data, m, estimator) for name, m in models.items()}
    responses = {name: _model_response(data, _cut_to_data(data, r)) for name, (r, _) in seen.items()}
    views = sorted({note for _, note in seen.values() if note})
    fits = {name: fit_percent(data, r) for name, r in responses.items()}
    total = data.n_out * data.n_in
    if channels is not None:
        picked = [(data.outputs.index(o), data.inputs.index(i)) for o, i in _named_channels(data, channels)]
    else:
        picked = [(i, j) for i in range(data.n_out) for j in range(data.n_in)]
    pairs = picked[:max_channels]
    notes = [[]] + [[f"fit {fits[name][i, j]:.0f}%" for i, j in pairs] for name in responses]
    title = "fit % = 100 (1 - ||G_data - G_model|| / ||G_data - mean||) per channel"
    if views:
        title += "\n" + "; ".join(views)
    shown = shown_channels_title(len(pairs), total)
    fig = bode_grid(
        [data, *responses.values()],
        ["data", *responses],
        channels=pairs,
        phase=phase,
        channel_notes=notes,
        title=f"{shown}\n{title}" if shown else title,
    )
    fig.fit_percent = fits
    return fig


def _seen(data: FrequencyData, model: Any, estimator: Any) -> tuple[Any, str]:
    """``(model or its response as the estimator sees it, note)``; the note is empty when the model is
    drawn as given (a FrequencyData, ``estimator=False``, or data that describe no estimator)."""
    if isinstance(model, FrequencyData):
        return model, ""
    settings, note = resolve_view(estimator, data, model)
    if settings is None:
        return model, ""
    bare, hold = split_hold(model)
    sys = as_statespace(bare)
    g = model_view(sys, hold, data.f_hz, settings)
    return FrequencyData(data.f_hz, g, inputs=list(sys.input_labels), outputs=list(sys.output_labels)), (
        note.replace("model seen", "models seen")
    )


def _named_channels(data: FrequencyData, channels: Sequence[tuple[str, str]]) -> list[tuple[str, str]]:
    """``channels`` as (output, input) name pairs of ``data``; DataError naming an unknown one."""
    out = []
    for pair in channels:
        if not isinstance(pair, (tuple, list)) or len(pair) != 2:
            raise DataError(f"channels= takes (output, input) name pairs, e.g. [('S1', 'A1')]; got {pair!r}.")
        o, i = str(pair[0]), str(pair[1])
        if o not in data.outputs or i not in data.inputs:
            raise DataError(
                f"channel ({o!r}, {i!r}) is not in the data (outputs {list(data.outputs)}, inputs "
                f"{list(data.inputs)})."
            )
        out.append((o, i))
    return out


def _cut_to_data(data: FrequencyData, model: Any) -> Any:
    """The model's response on the data's grid, restricted to the data's channels when the model
    has more (a single-shaker test against a multi-input model); other models unchanged."""
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
    im = annotated_matrix(ax, values, rows, cols, fmt=".2f", max_cells=400)
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
    geometry: Any = None,
    outputs: Sequence[str] | None = None,
    *,
    band: Sequence[float] | None = None,
    max_modes: int = 12,
    pair_with: Any = None,
    labels: tuple[str, str] = ("test", "FE"),
    scale: float = 0.15,
):
    """Mode shapes: bars at the sensors, or the deformed structure in 3-D over the undeformed one.

    The shape of a mode is the output column of its residue (``C v`` of the state space, or
    ``output_shape`` of an identified mode; Caltech eq. 10), rotated to real and scaled so its
    largest entry is 1; :class:`~robustctl.frd_io.geometry.ModeShapes` give every node's motion.

    Parameters
    ----------
    model : result with ``.modes`` (MeasurementModel), sequence of Mode, a system, or ModeShapes
        A system (PhysicalModel, StateSpace) gives its eigenmodes in ``band``.
    geometry : Geometry, optional
        Draw each mode as a deformed wireframe (matplotlib 3-D axes, several modes in a grid).
        Channel shapes move their sensor's node along the sensor's direction
        (``geometry.sensors`` or ``"node:direction"`` channel names); ModeShapes move every node.
        Without it: one bar chart per mode, a bar per sensor.
    outputs : sequence of str, optional
        Sensor names (default: the model's output names, else ``y1..``).
    band : (lo_hz, hi_hz), optional
        Which modes (default all).
    max_modes : int
        At most this many modes (lowest first); the figure says so when modes are left out.
    pair_with : same kinds as ``model``, optional
        A second mode set (FE shapes beside test shapes): each mode of ``model`` is drawn next to
        the mode of ``pair_with`` with the largest MAC over the sensors (Allemang & Brown 1982),
        the MAC and both frequencies in the titles. Needs ``geometry``.
    labels : (str, str)
        Names of ``model`` and ``pair_with`` in the titles.
    scale : float
        Largest drawn displacement as a fraction of the structure's size.

    Returns
    -------
    matplotlib.figure.Figure

    See Also
    --------
    animate_mode_shape, plot_mac, robustctl.load_uff_geometry, robustctl.load_bdf_geometry

    References
    ----------
    Allemang, R. J. & Brown, D. L. (1982), "A correlation coefficient for modal vector
    analysis", Proc. 1st IMAC (the MAC pairing test and FE shapes).
    """
    if geometry is not None:
        return _plot_shapes_3d(model, geometry, band, max_modes, pair_with, labels, scale, outputs)
    if isinstance(model, ModeShapes):
        raise DataError(
            "mode shapes over nodes are drawn on the structure: pass geometry= (rc.load_uff_geometry, "
            "rc.load_bdf_geometry or rc.load_ansys_geometry)."
        )
    if pair_with is not None:
        raise DataError(
            "pair_with= draws test and FE shapes side by side on a structure; give geometry= too."
        )
    modes, names = _modes_and_sensors(model, band)
    modes = sorted(modes, key=lambda m: m.f_hz)
    if not modes:
        raise DataError("no modes to plot; widen band= or check the model.")
    total = len(modes)
    modes = modes[:max_modes]
    shapes = [_real_shape(m.output_shape[:, 0] if m.output_shape is not None else _column(m)) for m in modes]
    n_out = shapes[0].size
    outputs = list(outputs) if outputs is not None else (names or [f"y{k + 1}" for k in range(n_out)])
    if len(outputs) != n_out:
        raise DataError(f"outputs has {len(outputs)} names but the modes have {n_out} sensors.")
    # one bar slot must hold a vertical 7-point label: ~0.13 inch per sensor
    ax_w = max(2.6, 0.13 * n_out + 0.7)
    ncols = max(1, min(4, len(modes), int(16.0 // ax_w)))
    nrows = int(np.ceil(len(modes) / ncols))
    label_h = 0.07 * max(len(o) for o in outputs)
    fig = new_figure(ax_w * ncols + 0.4, (1.7 + label_h) * nrows + 0.6)
    axes = fig.subplots(nrows, ncols, squeeze=False, sharey=True)
    rotation = 90 if n_out > 8 else 45
    for k, ax in enumerate(axes.flat):
        if k >= len(modes):
            fig.delaxes(ax)
            continue
        ax.bar(range(n_out), shapes[k], color=["C0" if s >= 0 else "C3" for s in shapes[k]])
        ax.axhline(0.0, color="k", lw=0.6)
        ax.set_xticks(range(n_out), outputs, rotation=rotation, ha="center" if rotation == 90 else "right",
                      fontsize=7 if n_out <= 16 else 6)
        ax.set_xlim(-0.6, n_out - 0.4)
        ax.set_title(f"{modes[k].f_hz:.4g} Hz, {modes[k].damping_pct:.2g}% damping", fontsize=8)
        ax.set_ylabel("shape (peak = 1)", fontsize=8)
        ax.set_xlabel("sensor", fontsize=8)
    _say_left_out(fig, total, len(modes), max_modes)
    return fig


def _say_left_out(fig, total: int, shown: int, max_modes: int) -> None:
    if total > shown:
        fig.suptitle(f"the {shown} lowest of {total} modes (max_modes={max_modes}; raise it to see all)",
                     fontsize=9, color="C3")


class _NodeShapes:
    """Mode frequencies, damping and real node displacements (n_modes, n_nodes, 3) over a geometry,
    plus the shapes at the sensor channels (for the MAC)."""

    def __init__(self, f_hz, zeta, disp, at_sensors, channels, full_field=False):
        self.f_hz, self.zeta, self.disp = np.asarray(f_hz), np.asarray(zeta), disp
        self.at_sensors, self.channels, self.full_field = at_sensors, channels, full_field


def _node_shapes(source: Any, geometry: Any, band, outputs=None) -> _NodeShapes:
    """Shapes of ``source`` (ModeShapes or anything with modes at channels) on ``geometry``'s nodes."""
    lo, hi = (0.0, np.inf) if band is None else band
    channels = list(geometry.sensors)
    if isinstance(source, ModeShapes):
        keep = np.flatnonzero((source.f_hz >= lo) & (source.f_hz <= hi))
        keep = keep[np.argsort(source.f_hz[keep], kind="stable")]
        where = {int(n): k for k, n in enumerate(source.node_ids)}
        rows = [where.get(int(n)) for n in geometry.node_ids]
        if all(r is None for r in rows):
            raise DataError(
                f"none of the geometry's nodes has a mode shape ({source.name or 'ModeShapes'} holds nodes "
                f"{list(source.node_ids[:5])}...); use the geometry of the same model."
            )
        disp = np.zeros((keep.size, geometry.n_nodes, 3))
        for j, r in enumerate(rows):
            if r is not None:
                disp[:, j] = np.real([_real_rotate(source.shapes[k]) for k in keep])[:, r, :3]
        sel = source.select(keep)
        sens = sel.at(channels, geometry=geometry, mass_normalized=False) if channels else None
        return _NodeShapes(source.f_hz[keep], source.zeta[keep], disp, sens, channels, full_field=True)
    modes, names = _modes_and_sensors(source, band)
    modes = sorted(modes, key=lambda m: m.f_hz)
    if not modes:
        raise DataError("no modes to plot; widen band= or check the model.")
    cols = np.array([m.output_shape[:, 0] if m.output_shape is not None else _column(m) for m in modes]).T
    if outputs is not None:
        if len(outputs) != cols.shape[0]:
            raise DataError(f"outputs has {len(outputs)} names but the modes have {cols.shape[0]} sensors.")
        names = [str(o) for o in outputs]
    names = names or [f"y{k + 1}" for k in range(cols.shape[0])]
    rows, dirs = geometry.channel_map(names)
    disp = np.zeros((len(modes), geometry.n_nodes, 3))
    for k in range(len(modes)):
        shape = _real_shape(cols[:, k])
        np.add.at(disp[k], rows, shape[:, None] * dirs)
    return _NodeShapes([m.f_hz for m in modes], [m.zeta for m in modes], disp, cols, list(names))


def _real_rotate(shape: np.ndarray) -> np.ndarray:
    """A (n_nodes, 6) complex shape turned to the phase of its largest entry (real shapes unchanged)."""
    if not np.iscomplexobj(shape):
        return shape
    flat = shape.ravel()
    k = int(np.argmax(np.abs(flat)))
    return (shape * np.exp(-1j * np.angle(flat[k]))).real


def _pairs(first: _NodeShapes, second: _NodeShapes) -> tuple[list[int], list[float]]:
    """Index of the mode of ``second`` with the largest MAC against each mode of ``first``: over
    the sensor channels both have, else (two node-shape sets, no sensors) over every node's
    translation."""
    common = [c for c in first.channels if c in second.channels]
    if common and first.at_sensors is not None and second.at_sensors is not None:
        a = first.at_sensors[[first.channels.index(c) for c in common]]
        b = second.at_sensors[[second.channels.index(c) for c in common]]
    elif first.full_field and second.full_field:
        a = first.disp.reshape(first.disp.shape[0], -1).T
        b = second.disp.reshape(second.disp.shape[0], -1).T
    else:
        raise DataError(
            f"the two mode sets share no sensor channel (first {first.channels[:4]}, second "
            f"{second.channels[:4]}); pairing by MAC needs shapes at the same sensors: place them "
            "with geometry.with_sensors({...})."
        )
    best, values = [], []
    for k in range(a.shape[1]):
        m = [mac(a[:, k], b[:, j]) for j in range(b.shape[1])]
        best.append(int(np.argmax(m)))
        values.append(float(np.max(m)))
    return best, values


def _plot_shapes_3d(model, geometry, band, max_modes, pair_with, labels, scale, outputs=None):
    from matplotlib.ticker import MaxNLocator

    first = _node_shapes(model, geometry, band, outputs)
    total = first.f_hz.size
    shown = min(total, max_modes)
    panels = []  # (shapes, mode index, title)
    if pair_with is None:
        for k in range(shown):
            panels.append((first, k, _shape_title(first, k, "")))
    else:
        second = _node_shapes(pair_with, geometry, band)
        if second.f_hz.size == 0:
            raise DataError("pair_with has no modes in band=; widen the band.")
        best, macs = _pairs(first, second)
        for k in range(shown):
            panels.append((first, k, _shape_title(first, k, labels[0])))
            title = _shape_title(second, best[k], labels[1]) + f"\nMAC {macs[k]:.2f}"
            panels.append((second, best[k], title))
    ncols = 4 if pair_with is not None else min(3, len(panels))
    nrows = int(np.ceil(len(panels) / ncols))
    fig = new_figure(3.2 * ncols, 3.0 * nrows + 0.5)
    size = float(np.max(np.ptp(geometry.xyz, axis=0))) if geometry.n_nodes > 1 else 1.0
    size = size if size > 0 else 1.0
    for p, (shapes, k, title) in enumerate(panels):
        ax = fig.add_subplot(nrows, ncols, p + 1, projection="3d")
        d = shapes.disp[k]
        peak = float(np.max(np.linalg.norm(d, axis=1)))
        deformed = geometry.xyz + (scale * size / peak if peak > 0 else 0.0) * d
        _wireframe(ax, geometry, geometry.xyz, color="0.5", lw=0.8, ls="--", gid="undeformed")
        colour = "C0" if shapes is first else "C1"
        _wireframe(ax, geometry, deformed, color=colour, lw=1.4, ls="-", gid="deformed")
        dot = float(np.clip(400.0 / max(geometry.n_nodes, 1), 0.3, 4.0))  # many nodes: small dots
        ax.scatter(*deformed.T, s=dot, color="k", depthshade=False)
        ax.set_title(title, fontsize=8)
        _equal_box(ax, np.vstack([geometry.xyz, deformed]))
        ax.tick_params(labelsize=6, pad=0)
        for axis in (ax.xaxis, ax.yaxis, ax.zaxis):
            axis.set_major_locator(MaxNLocator(3))
        unit = geometry.unit
        ax.set_xlabel(f"x ({unit})", fontsize=7, labelpad=-4)
        ax.set_ylabel(f"y ({unit})", fontsize=7, labelpad=-4)
        ax.set_zlabel(f"z ({unit})", fontsize=7, labelpad=-4)
    _say_left_out(fig, total, shown, max_modes)
    return fig


class ModeAnimation:
    """Frames of one mode shape swinging through a cycle, shown as an animated GIF in Jupyter.

    Attributes
    ----------
    frames : list of ndarray (height, width, 3), uint8
    f_hz : float
        Frequency of the mode, Hz.
    backend : str
        ``"pyvista"`` or ``"matplotlib"`` (what drew the frames).
    duration_ms : int
        Time each frame is shown in the GIF, ms.
    """

    def __init__(self, frames: list, f_hz: float, backend: str, duration_ms: int) -> None:
        self.frames, self.f_hz, self.backend = frames, float(f_hz), backend
        self.duration_ms = int(duration_ms)

    def __repr__(self) -> str:
        return f"ModeAnimation({self.f_hz:.4g} Hz, {len(self.frames)} frames, {self.backend})"

    def gif(self) -> bytes:
        """The animation as GIF bytes (Pillow)."""
        import io

        from PIL import Image

        images = [Image.fromarray(np.asarray(f, dtype=np.uint8)) for f in self.frames]
        buf = io.BytesIO()
        images[0].save(buf, format="GIF", save_all=True, append_images=images[1:], duration=self.duration_ms,
                       loop=0)
        return buf.getvalue()

    def save(self, path) -> None:
        """Write the animation as a GIF file."""
        from pathlib import Path

        Path(path).write_bytes(self.gif())

    def _repr_html_(self) -> str:
        import base64

        data = base64.b64encode(self.gif()).decode("ascii")
        return f'<img src="data:image/gif;base64,{data}" alt="mode at {self.f_hz:.4g} Hz"/>'


def animate_mode_shape(
    model: Any,
    geometry: Any,
    mode: int = 1,
    *,
    band: Sequence[float] | None = None,
    frames: int = 16,
    scale: float = 0.15,
    size: tuple[int, int] = (360, 300),
    backend: str = "auto",
) -> ModeAnimation:
    """One mode swinging on the structure: ``x(t) = x0 + a phi cos(2 pi t / T)`` over one cycle.

    Parameters
    ----------
    model, geometry, band, scale :
        As for :func:`plot_mode_shapes`.
    mode : int
        Which mode, 1-based in ascending frequency.
    frames : int
        Frames per cycle.
    size : (int, int)
        Width and height in pixels.
    backend : {"auto", "pyvista", "matplotlib"}
        pyvista (off-screen VTK rendering, the ``ansys`` extra installs it) when available, else
        matplotlib's 3-D axes.

    Returns
    -------
    ModeAnimation
        ``.save("mode.gif")``; displays as an animated GIF in Jupyter.
    """
    import importlib.util

    shapes = _node_shapes(model, geometry, band)
    n = shapes.f_hz.size
    if not isinstance(mode, (int, np.integer)) or not 1 <= mode <= n:
        raise DataError(f"mode must be an integer from 1 to {n} (the modes in band={band}); got {mode!r}.")
    if not isinstance(frames, (int, np.integer)) or frames < 2:
        raise DataError(f"frames must be an integer >= 2; got {frames!r}.")
    if backend not in ("auto", "pyvista", "matplotlib"):
        raise DataError(f"backend must be 'auto', 'pyvista' or 'matplotlib'; got {backend!r}.")
    if backend == "auto":
        backend = "pyvista" if importlib.util.find_spec("pyvista") else "matplotlib"
    d = shapes.disp[mode - 1]
    peak = float(np.max(np.linalg.norm(d, axis=1)))
    extent = float(np.max(np.ptp(geometry.xyz, axis=0))) if geometry.n_nodes > 1 else 1.0
    amp = scale * (extent or 1.0) / peak if peak > 0 else 0.0
    phases = np.cos(2 * np.pi * np.arange(frames) / frames)
    draw = _frames_pyvista if backend == "pyvista" else _frames_matplotlib
    images = draw(geometry, [geometry.xyz + amp * c * d for c in phases], size,
                  f"mode {mode}: {shapes.f_hz[mode - 1]:.4g} Hz")
    return ModeAnimation(images, shapes.f_hz[mode - 1], backend, duration_ms=max(20, 1000 // frames))


def _frames_pyvista(geometry, positions, size, title):
    try:
        import pyvista as pv
    except ImportError:
        raise DataError(
            "backend='pyvista' needs pyvista; pip install pyvista or use backend='matplotlib'."
        ) from None
    idx = {int(n): k for k, n in enumerate(geometry.node_ids)}
    cells = np.array([[2, idx[a], idx[b]] for a, b in geometry.lines.tolist()], dtype=np.int64).ravel()
    out = []
    plotter = pv.Plotter(off_screen=True, window_size=size)
    try:
        plotter.set_background("white")
        def poly(xyz):
            return pv.PolyData(xyz.copy(), lines=cells) if cells.size else pv.PolyData(xyz.copy())

        base = poly(geometry.xyz)
        plotter.add_mesh(base, color="gray", line_width=1, opacity=0.5)
        moving = poly(positions[0])
        plotter.add_mesh(moving, color="tab:blue", line_width=3, render_points_as_spheres=True, point_size=4)
        plotter.add_text(title, font_size=9, color="black")
        plotter.view_isometric()
        plotter.reset_camera(bounds=np.ravel([np.min(positions, axis=(0, 1)), np.max(positions, axis=(0, 1))],
                                             order="F"))
        for xyz in positions:
            moving.points = xyz
            plotter.render()
            out.append(np.asarray(plotter.screenshot(return_img=True))[..., :3])
    finally:
        plotter.close()
    return out


def _frames_matplotlib(geometry, positions, size, title):
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    fig = new_figure(size[0] / 100, size[1] / 100)
    canvas = FigureCanvasAgg(fig)
    ax = fig.add_subplot(projection="3d")
    lo, hi = np.min(positions, axis=(0, 1)), np.max(positions, axis=(0, 1))
    out = []
    for xyz in positions:
        ax.clear()
        _wireframe(ax, geometry, geometry.xyz, color="0.5", lw=0.8, ls="--", gid="undeformed")
        _wireframe(ax, geometry, xyz, color="C0", lw=1.4, ls="-", gid="deformed")
        _equal_box(ax, np.vstack([lo, hi]))
        ax.set_title(title, fontsize=8)
        ax.set_axis_off()
        canvas.draw()
        out.append(np.asarray(canvas.buffer_rgba())[..., :3].copy())
    return out


def _shape_title(shapes: _NodeShapes, k: int, label: str) -> str:
    z = shapes.zeta[k]
    damp = f", {100 * z:.2g}%" if np.isfinite(z) else ""
    return f"{label + ' ' if label else ''}mode {k + 1}: {shapes.f_hz[k]:.4g} Hz{damp}"


def _wireframe(ax, geometry, xyz, *, gid: str, **style) -> None:
    from mpl_toolkits.mplot3d.art3d import Line3DCollection

    if len(geometry.lines) == 0:
        ax.scatter(*xyz.T, s=8, color=style.get("color"), gid=gid)
        return
    idx = {int(n): k for k, n in enumerate(geometry.node_ids)}
    segs = [(xyz[idx[a]], xyz[idx[b]]) for a, b in geometry.lines.tolist()]
    coll = Line3DCollection(segs, colors=style["color"], linewidths=style["lw"], linestyles=style["ls"])
    coll.set_gid(gid)
    ax.add_collection3d(coll)


def _equal_box(ax, pts: np.ndarray) -> None:
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    centre, half = (lo + hi) / 2, max(float(np.max(hi - lo)) / 2, 1e-12)
    for setter, c in zip((ax.set_xlim, ax.set_ylim, ax.set_zlim), centre):
        setter(c - half, c + half)
    ax.set_box_aspect((1, 1, 1))


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
    sys = as_statespace(model)
    lo, hi = (0.0, np.inf) if band is None else band
    return statespace_modes(sys, (lo, hi)), list(sys.output_labels)


def _plot_data_sv(data: FrequencyData):
    return plot_singular_values(data, labels=["data"])


register_method("plot", plot_frf)
register_method("plot_sv", _plot_data_sv)
