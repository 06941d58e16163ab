"""Uncertainty weights that cover measured and modelled errors (the MATLAB ``ucover`` idea).

A nominal model ``G0`` and a set of plants it should stand for -- measured responses (the
residual ``rc.compare`` shows) and/or models (e.g. ``UpdateResult.sample_models``, the
spread of the updated parameters) -- define, frequency by frequency, the error to cover:

* additive (Caltech seed eqs. 1-2, ``G = G0 + W_a Delta``): ``sigma_max(G - G0)``;
* input multiplicative (``G = G0 (I + W Delta)``): ``sigma_max(G0^+ (G - G0))``;
* output multiplicative (``G = (I + W Delta) G0``, seed eq. 3 in the SISO case):
  ``sigma_max((G - G0) G0^+)``;

``G0^+`` is the Moore-Penrose pseudo-inverse (the inverse for a square, non-singular
``G0``; for a non-square ``G0`` the relative error is measured in the range of ``G0``).
The weight is a stable, minimum-phase ``W`` with ``|W(j 2 pi f)| >= envelope(f)`` at
every grid frequency, the smallest such of its order in the log-Chebyshev sense
(:func:`~robustctl.robust.uncertainty.magfit.fit_magnitude` with ``upper_bound=True``) fitted to the
envelope's running maximum over a fraction of an octave (a low-order weight cannot follow
the notches of a lightly damped structure's error; the running maximum keeps the cover
and drops them). The covering margin ``min_f |W| / envelope`` is reported; >= 1 means
every point is covered (Zhou-Doyle-Glover sec. 8.1; Skogestad-Postlethwaite sec. 7.4).
"""

from __future__ import annotations

import inspect
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ...budget import Deadline
from ...checks import check_band, match_channels, positive_number
from ...errors import DataError, FitError, RobustctlError
from ...frd import FrequencyData, as_frequencies
from ...lti import align_channels, as_statespace, freqresp, freqresp_array
from ...measure.noise import noise_model
from ...physical.uncertain import UncertainModel
from ...plots import single_axes
from ...table import Table, result_html
from .magfit import DB_PER_NEPER, fit_magnitude_details

__all__ = ["UncertaintyCover", "cover_additive", "cover_multiplicative", "cover_remainder", "error_envelope"]

_KINDS = ("additive", "input multiplicative", "output multiplicative")
#: Points the weight is fitted on (log bins of the bound's running maximum); every grid point is checked.
MAX_FIT_POINTS = 160


# ---------------------------------------------------------------------------- result
@dataclass(frozen=True, eq=False)
class UncertaintyCover:
    """A weight covering the error between a nominal model and a set of plants.

    Attributes
    ----------
    weight : control.StateSpace
        SISO, stable, minimum phase; ``|W| >= envelope`` at every grid frequency.
    kind : str
        ``"additive"``, ``"input multiplicative"`` or ``"output multiplicative"``.
    order : int
        Number of states of ``weight``.
    f_hz : ndarray (nf,)
        Grid, Hz.
    envelope : ndarray (nf,)
        Largest error over the sources (max singular value), per frequency.
    bound : ndarray (nf,)
        What the weight was fitted to: the envelope's running maximum over
        ``smooth_octaves`` (floored at ``floor`` times its peak).
    weight_mag : ndarray (nf,)
        ``|W(j 2 pi f)|``.
    sources : tuple of str
        Labels of the covered plants (``"data"``, ``"model 1"``, ...).
    source_errors : ndarray (n_sources, nf)
        Each source's error (max singular value).
    margin : float
        ``min_f |W| / envelope``; >= 1 means covered at every grid point.
    f_margin_hz : float
        Where the margin is smallest (Hz).
    overbound_db : float
        Largest ``20 log10(|W| / bound)`` (dB): how conservative the weight is at its worst.
    median_overbound_db : float
        Median ``20 log10(|W| / envelope)`` over the grid (dB).
    fit_time_s : float
        Time of the magnitude fit (s).
    notes : tuple of str
    stopped_by_budget : bool
        A ``time_budget_s`` ended the weight fit early (see :mod:`robustctl.budget`).
    """

    weight: Any
    kind: str
    order: int
    f_hz: np.ndarray
    envelope: np.ndarray
    bound: np.ndarray
    weight_mag: np.ndarray
    sources: tuple[str, ...]
    source_errors: np.ndarray = field(repr=False)
    margin: float = 0.0
    f_margin_hz: float = 0.0
    overbound_db: float = 0.0
    median_overbound_db: float = 0.0
    fit_time_s: float = 0.0
    notes: tuple[str, ...] = ()
    stopped_by_budget: bool = False

    @property
    def covered(self) -> bool:
        """True when ``|W| >= envelope`` at every grid frequency."""
        return self.margin >= 1.0

    def statespace(self):
        """The weight (so a cover is accepted wherever a system is, e.g. ``generalized_plant``)."""
        return self.weight

    def table(self) -> Table:
        """The envelope, the bound and ``|W|`` at log-spaced frequencies (about 20 rows)."""
        idx = np.unique(np.round(np.geomspace(1, self.f_hz.size, min(20, self.f_hz.size)) - 1).astype(int))
        rows = [
            (
                float(self.f_hz[k]),
                float(self.envelope[k]),
                float(self.bound[k]),
                float(self.weight_mag[k]),
                float(DB_PER_NEPER * np.log(self.weight_mag[k] / self.envelope[k])),
            )
            for k in idx
        ]
        return Table(
            ("f (Hz)", "error envelope", "fitted bound", "|W|", "|W| / envelope (dB)"),
            rows,
            title=f"{self.kind} uncertainty cover: order {self.order}, margin {self.margin:.4g}",
        )

    def summary(self) -> str:
        """The cover in plain words."""
        word = "covers" if self.covered else "does NOT cover"
        names = ", ".join(self.sources[:4]) + (", ..." if len(self.sources) > 4 else "")
        lines = [
            f"{self.kind.capitalize()} weight of order {self.order} {word} the error of "
            f"{len(self.sources)} plant(s) ({names}) at all {self.f_hz.size} grid points from "
            f"{self.f_hz[0]:.4g} to {self.f_hz[-1]:.4g} Hz: covering "
            f"margin {self.margin:.4g} (smallest |W| / error, at {self.f_margin_hz:.4g} Hz).",
            f"Error envelope {self.envelope.min():.3g} to {self.envelope.max():.3g}; |W| exceeds the "
            f"smoothed bound by at most {self.overbound_db:.1f} dB and the raw envelope by "
            f"{self.median_overbound_db:.1f} dB at the median frequency.",
        ]
        lines += [f"Note: {n}" for n in self.notes]
        return "\n".join(lines)

    def _repr_html_(self) -> str:
        return result_html(self.summary(), self.table())

    def __repr__(self) -> str:
        return (
            f"UncertaintyCover(kind={self.kind!r}, order={self.order}, margin={self.margin:.4g}, "
            f"sources={len(self.sources)})"
        )

    def plot(
        self, fig: Any = None, *, reference: Any = None, reference_label: str = "reference weight"
    ) -> Any:
        """Each source's error, the envelope, the fitted bound and ``|W|`` on log axes.

        Parameters
        ----------
        fig : matplotlib Figure, optional
        reference : system, optional
            Another weight to draw for comparison (e.g. the seed's eq. 14 weight).
        reference_label : str

        Returns
        -------
        matplotlib.figure.Figure
        """
        fig, ax = single_axes(fig, 8.0, 4.5)
        f = self.f_hz
        for k, (label, err) in enumerate(zip(self.sources, self.source_errors)):
            kw = dict(color="0.65", lw=0.6)
            if label.startswith("data"):
                kw = dict(color="k", lw=0.8)
            ax.loglog(f, err, label=label if (k < 3 or label.startswith("data")) else None, **kw)
        ax.loglog(f, self.bound, "C1--", lw=1.0, label="fitted bound (running max)")
        ax.loglog(f, self.weight_mag, "C0-", lw=2.0, label=f"|W| (order {self.order})")
        if reference is not None:
            ax.loglog(f, np.abs(freqresp_array(reference, f)[:, 0, 0]), "C3-.", lw=1.5, label=reference_label)
        ax.set_xlabel("frequency (Hz)")
        ylabel = "sigma_max(G - G0)" if self.kind == "additive" else "sigma_max(relative error)"
        ax.set_ylabel(ylabel)
        ax.set_title(f"{self.kind} uncertainty cover: margin {self.margin:.3g}")
        ax.legend(fontsize=7)
        ax.grid(True, which="both", alpha=0.3)
        return fig


# ---------------------------------------------------------------------------- sources
def _sources(
    data_or_models: Any, f_hz: Any, band: Sequence[float] | None
) -> tuple[np.ndarray, list[tuple[str, Any]]]:
    """The grid (Hz) and the labelled sources (FrequencyData or systems)."""
    items = list(data_or_models) if isinstance(data_or_models, (list, tuple)) else [data_or_models]
    if not items:
        raise FitError("data_or_models is empty; give measured FrequencyData and/or a list of models.")
    many = isinstance(data_or_models, (list, tuple))
    items = [d if isinstance(d, FrequencyData) else as_statespace(
        d, name=f"data_or_models[{k}]" if many else "data_or_models") for k, d in enumerate(items)]
    datas = [d for d in items if isinstance(d, FrequencyData)]
    if f_hz is not None:
        f = as_frequencies(f_hz)
    elif datas:
        f = datas[0].f_hz
    else:
        raise FitError("data_or_models holds only models: pass f_hz=... (Hz) to evaluate them on.")
    band = check_band(band)
    if band is not None:
        lo, hi = band
        keep = (f >= lo) & (f <= hi)
        if keep.sum() < 2:
            raise DataError(f"band {tuple(band)} Hz holds {int(keep.sum())} grid points; give a wider band.")
        f = f[keep]
    labelled, n_data, n_model = [], 0, 0
    for item in items:
        if isinstance(item, FrequencyData):
            n_data += 1
            labelled.append((f"data {n_data}" if len(datas) > 1 else "data", item))
        else:
            n_model += 1
            labelled.append((f"model {n_model}", item))
    return f, labelled


def _on_grid(data: FrequencyData, f: np.ndarray, label: str) -> np.ndarray:
    idx = np.searchsorted(data.f_hz, f)
    idx = np.clip(idx, 0, data.n_freq - 1)
    if not np.allclose(data.f_hz[idx], f, rtol=1e-9, atol=0):
        raise DataError(
            f"{label} is not measured on the cover's grid ({f[0]:g}-{f[-1]:g} Hz, {f.size} points); give "
            "every FrequencyData on one grid, or f_hz= a subset of the data's frequencies."
        )
    return data.response[idx]


def _responses(
    nominal: Any, f: np.ndarray, sources: list[tuple[str, Any]]
) -> tuple[np.ndarray, list[np.ndarray], list[np.ndarray | None]]:
    """Nominal response, each source's response and, for measured data, the 1-sigma random
    error bound ``||G eps_r||_F`` per frequency (None when unknown)."""
    g0 = freqresp(nominal, f)
    out, noise = [], []
    for label, src in sources:
        if isinstance(src, FrequencyData):
            coh = None if src.coherence is None else _on_grid_values(src, src.coherence, f, label)
            fd = FrequencyData(
                f, _on_grid(src, f, label), inputs=src.inputs, outputs=src.outputs, coherence=coh,
                meta=src.meta,
            )
            noise.append(_random_error(fd))  # a Frobenius norm: channel order is moot
            fd = align_channels(g0, fd)  # (drops the coherence)
        else:
            fd = align_channels(g0, freqresp(src, f))
            noise.append(None)
        out.append(fd.response)
    return g0.response, out, noise


def _on_grid_values(data: FrequencyData, values: np.ndarray, f: np.ndarray, label: str) -> np.ndarray:
    idx = np.clip(np.searchsorted(data.f_hz, f), 0, data.n_freq - 1)
    return values[idx]


def _random_error(data: FrequencyData) -> np.ndarray | None:
    """``||G o sigma||_F`` per frequency: the H1 estimate's random error, ``sigma`` the noise
    model's normalised error ``sqrt(1 - g^2) / (|g| sqrt(2 n_d))`` (Bendat-Piersol, *Random
    Data*, Table 9.6; :func:`robustctl.measure.noise.noise_model`: Welch's effective number of
    averages, one per input column). It bounds the max singular value of the estimate's
    error. None without coherence or a known number of averages."""
    model = noise_model(data)  # from coherence and averages, or None (no measurement model given)
    if model is None:
        return None
    return np.linalg.norm(np.abs(data.response) * model.sigma, axis=(1, 2))


def _sigma_max(e: np.ndarray) -> np.ndarray:
    return np.linalg.svd(e, compute_uv=False)[:, 0]


def error_envelope(
    nominal: Any,
    data_or_models: Any,
    kind: str = "additive",
    *,
    f_hz: Any = None,
    band=None,
    data_sigmas: float = 3.0,
):
    """Each source's error (max singular value) against ``nominal`` on the grid.

    Parameters
    ----------
    nominal : system
        Anything :func:`robustctl.lti.as_statespace` accepts.
    data_or_models : FrequencyData, system, or a list of them
    kind : {"additive", "input multiplicative", "output multiplicative"}
    f_hz : array_like, optional
        Grid (Hz); default the first FrequencyData's.
    band : (lo_hz, hi_hz), optional
    data_sigmas : float
        Measured data's error is raised by this many standard deviations of the H1
        estimate's random error (from its coherence and number of averages; see
        :func:`_random_error`), so the cover holds for the true plant, not only for the
        estimate. 0 covers the estimate as measured. No term without coherence.

    Returns
    -------
    f_hz : ndarray (nf,)
    labels : tuple of str
    errors : ndarray (n_sources, nf)
    """
    if not isinstance(kind, str) or kind not in _KINDS:
        raise FitError(f"kind must be one of {_KINDS}; got {kind!r}.")
    data_sigmas = positive_number(data_sigmas, "data_sigmas", FitError, allow_zero=True)
    nominal = as_statespace(nominal, name="nominal")
    f, sources = _sources(data_or_models, f_hz, band)
    g0, gs, noise = _responses(nominal, f, sources)
    if kind == "additive":
        errs = [_sigma_max(g - g0) for g in gs]
        gain = np.ones(f.size)
    else:
        if not np.all(np.isfinite(g0)) or np.any(np.linalg.norm(g0, axis=(1, 2)) == 0):
            raise FitError(
                "the nominal response is zero at some frequency; a relative error is undefined there."
            )
        pinv = np.linalg.pinv(g0)
        gain = _sigma_max(pinv)
        if kind == "input multiplicative":
            errs = [_sigma_max(pinv @ (g - g0)) for g in gs]
        else:
            errs = [_sigma_max((g - g0) @ pinv) for g in gs]
    errs = [e if r is None else e + data_sigmas * gain * r for e, r in zip(errs, noise)]
    return f, tuple(label for label, _ in sources), np.array(errs)


# ---------------------------------------------------------------------------- fit
def _running_max(f: np.ndarray, v: np.ndarray, octaves: float) -> np.ndarray:
    if octaves <= 0:
        return v.copy()
    lf = np.log2(f)
    lo = np.searchsorted(lf, lf - 0.5 * octaves, side="left")
    hi = np.searchsorted(lf, lf + 0.5 * octaves, side="right")
    return np.array([v[a:b].max() for a, b in zip(lo, hi)])


def _fit_points(f: np.ndarray, bound: np.ndarray) -> np.ndarray:
    """At most MAX_FIT_POINTS indices: the bound's largest point in each log-frequency bin."""
    if f.size <= MAX_FIT_POINTS:
        return np.arange(f.size)
    edges = np.geomspace(f[0], f[-1] * (1 + 1e-12), MAX_FIT_POINTS + 1)
    bins = np.clip(np.searchsorted(edges, f, side="right") - 1, 0, MAX_FIT_POINTS - 1)
    picks = [np.flatnonzero(bins == b) for b in range(MAX_FIT_POINTS)]
    return np.array(sorted(int(p[np.argmax(bound[p])]) for p in picks if p.size))


def _fit_cover(
    f: np.ndarray, bound: np.ndarray, idx: np.ndarray, order: int, kind: str, objective: str,
    deadline: Deadline,
) -> tuple[Any, np.ndarray, float]:
    """Fit on the points ``idx``; points left uncovered join the fit (up to 4 rounds)."""
    t0 = time.perf_counter()
    for _ in range(4):
        fit = fit_magnitude_details(
            f[idx],
            bound[idx],
            order,
            upper_bound=True,
            objective=objective,
            time_budget_s=deadline,
            name=f"W_{kind.split()[0]}",
        )
        mag = np.abs(freqresp_array(fit.system, f)[:, 0, 0])
        short = bound / mag
        bad = np.flatnonzero(short > 1.0 + 1e-6)
        if bad.size == 0 or deadline.expired():
            break
        worst = bad[np.argsort(short[bad])[::-1][:20]]
        idx = np.union1d(idx, worst)
    return fit.system, mag, time.perf_counter() - t0


def _check_options(order: Any, smooth_octaves: Any, floor: Any, time_budget_s: Any, objective: Any) -> None:
    if isinstance(order, bool) or not isinstance(order, (int, np.integer)) or not 0 <= order <= 20:
        raise FitError(f"order must be an integer from 0 to 20; got {order!r}.")
    positive_number(smooth_octaves, "smooth_octaves (0: no smoothing)", FitError, allow_zero=True)
    if not (positive_number(floor, "floor", FitError) < 1):
        raise FitError(f"floor must lie in (0, 1) (a fraction of the envelope's peak); got {floor!r}.")
    if not isinstance(objective, str) or objective not in ("max", "mean"):
        raise FitError(f'objective must be "max" or "mean"; got {objective!r}.')


def _cover(
    kind: str,
    nominal: Any,
    data_or_models: Any,
    order: int = 3,
    *,
    f_hz: Any = None,
    band: Sequence[float] | None = None,
    smooth_octaves: float = 0.25,
    floor: float = 1e-3,
    objective: str = "max",
    data_sigmas: float = 3.0,
    time_budget_s: float | None = None,
) -> UncertaintyCover:
    """The cover of the ``kind`` error (``"additive"``, ``"input multiplicative"`` or ``"output
    multiplicative"``); the one parameter list of :func:`cover_additive` and
    :func:`cover_multiplicative` (:func:`_public_signature`)."""
    _check_options(order, smooth_octaves, floor, time_budget_s, objective)
    deadline = Deadline(time_budget_s, error=FitError)
    f, labels, errs = error_envelope(
        nominal, data_or_models, kind, f_hz=f_hz, band=band, data_sigmas=data_sigmas
    )
    envelope = errs.max(axis=0)
    if not np.all(np.isfinite(envelope)):
        raise FitError(f"the {kind} error is not finite on the grid; check the nominal model and the data.")
    peak = float(envelope.max())
    if peak <= 0:
        raise FitError("every source equals the nominal model: there is no error to cover.")
    notes = []
    if np.any(envelope < floor * peak):
        notes.append(
            f"the error was floored at {floor:g} x its peak ({floor * peak:.3g}) where it was smaller."
        )
    bound = _running_max(f, np.maximum(envelope, floor * peak), float(smooth_octaves))
    idx = _fit_points(f, bound)
    W, mag, fit_time = _fit_cover(f, bound, idx, int(order), kind, objective, deadline)
    if deadline.hit:
        notes.append(f"the time budget ({deadline.budget_s:g} s) stopped the weight fit early.")
        deadline.warn(f"the {kind} cover's weight fit", stacklevel=4)
    short = float(np.max(bound / mag))
    if short > 1.0:  # still short between fit points: raise the gain until every point is covered
        W = W * (short * (1.0 + 1e-9))
        mag = np.abs(freqresp_array(W, f)[:, 0, 0])
        notes.append(
            f"the gain was raised by {DB_PER_NEPER * np.log(short):.2g} dB to cover every grid point."
        )
    ratio = mag / envelope
    k = int(np.argmin(ratio))
    if kind != "additive":
        notes.append(
            "relative errors use the pseudo-inverse of the nominal response (exact for a square, "
            "invertible G0)."
        )
    return UncertaintyCover(
        weight=W,
        kind=kind,
        order=int(W.nstates),
        f_hz=f,
        envelope=envelope,
        bound=bound,
        weight_mag=mag,
        sources=labels,
        source_errors=errs,
        margin=float(ratio[k]),
        f_margin_hz=float(f[k]),
        overbound_db=float(DB_PER_NEPER * np.max(np.log(mag / bound))),
        median_overbound_db=float(DB_PER_NEPER * np.median(np.log(ratio))),
        fit_time_s=fit_time,
        notes=tuple(notes),
        stopped_by_budget=deadline.hit,
    )


def cover_additive(nominal: Any, data_or_models: Any, order: int = 3, **options: Any) -> UncertaintyCover:
    """An additive uncertainty weight covering ``sigma_max(G - G0)`` at every grid frequency.

    The set ``{G0 + W_a Delta : ||Delta||_inf <= 1}`` (Caltech seed eqs. 1-2; MATLAB
    ``ucover`` for additive uncertainty) then holds every given plant on the grid.

    Parameters
    ----------
    nominal : system
        The nominal model ``G0`` (anything :func:`robustctl.lti.as_statespace` accepts).
    data_or_models : FrequencyData, system, or a list mixing both
        Measured responses (channels matched to the nominal's by name) and/or models
        (e.g. ``upd.sample_models(50)``), evaluated on the grid.
    order : int
        States of the weight (0: a constant).
    f_hz : array_like, optional
        Grid (Hz); default the first FrequencyData's. Every FrequencyData must hold these
        frequencies. Needed when only models are given.
    band : (lo_hz, hi_hz), optional
        Restrict the grid (Hz).
    smooth_octaves : float
        Width of the running maximum applied to the envelope before fitting (octaves;
        0 fits the raw envelope, notches included).
    floor : float
        The envelope is floored at this fraction of its peak (a log fit needs > 0).
    objective : {"mean", "max"}
        ``"mean"``: the cover with the smallest mean log overbound (tight over most of the
        band); ``"max"``: the smallest worst-case overbound (log-Chebyshev, MATLAB
        ``fitmagfrd``). See :func:`~robustctl.robust.uncertainty.magfit.fit_magnitude`.
    data_sigmas : float
        Measured residuals are raised by this many standard deviations of the H1
        estimate's random error (coherence, number of averages; Bendat-Piersol eq. 9.90),
        so the cover bounds the true plant's error, not only the estimate's; 0 covers the
        estimate as measured.
    time_budget_s : float or None
        Optional wall-clock cap on the magnitude fit (s), by :mod:`robustctl.budget`'s policy:
        None (default) bounds the fit by its iteration counts only.

    Returns
    -------
    UncertaintyCover

    Raises
    ------
    FitError, DataError
        Bad order or options, a grid mismatch, channels that do not match, no error.

    Examples
    --------
    >>> import robustctl as rc
    >>> data, _ = rc.examples.caltech_truss_experiment(seed=0)   # doctest: +SKIP
    >>> cov = rc.cover_additive(rc.examples.caltech_truss(), data, order=3, band=(0.3, 60))  # doctest: +SKIP
    >>> cov.margin >= 1  # doctest: +SKIP
    True
    """
    return _cover("additive", nominal, data_or_models, order, **options)


def cover_multiplicative(
    nominal: Any, data_or_models: Any, order: int = 3, side: str = "input", **options: Any
) -> UncertaintyCover:
    """A multiplicative uncertainty weight covering the relative error at every grid frequency.

    ``side="input"``: ``G = G0 (I + W Delta)``, covering ``sigma_max(G0^+ (G - G0))``;
    ``side="output"``: ``G = (I + W Delta) G0``, covering ``sigma_max((G - G0) G0^+)``
    (seed eq. 3 in the SISO case, ``W_m = W_a / G0``). ``G0^+`` is the pseudo-inverse of the
    nominal response, exact for a square, invertible ``G0``.

    Parameters
    ----------
    nominal : system
        The nominal model ``G0`` (anything :func:`robustctl.lti.as_statespace` accepts).
    data_or_models : FrequencyData, system, or a list mixing both
        Measured responses and/or models, as for :func:`cover_additive`.
    order : int
        States of the weight (0: a constant).
    side : {"input", "output"}
        Where the relative error acts.
    f_hz : array_like, optional
        Grid (Hz), as for :func:`cover_additive`.
    band : (lo_hz, hi_hz), optional
        Restrict the grid (Hz).
    smooth_octaves : float
        Width of the running maximum applied to the envelope before fitting (octaves).
    floor : float
        The envelope is floored at this fraction of its peak.
    objective : {"mean", "max"}
        Mean or worst-case log overbound, as for :func:`cover_additive`.
    data_sigmas : float
        Measured residuals are raised by this many standard deviations of the H1 estimate's
        random error (Bendat-Piersol eq. 9.90); 0 covers the estimate as measured.
    time_budget_s : float
        Cap on the magnitude fit (s).

    Returns
    -------
    UncertaintyCover
    """
    if side not in ("input", "output"):
        raise FitError(f'side must be "input" or "output"; got {side!r}.')
    return _cover(f"{side} multiplicative", nominal, data_or_models, order, **options)



def _stands_for(um: Any, src: Any, f: np.ndarray, label: str) -> tuple[np.ndarray, np.ndarray]:
    """``(G_src, Fu(M, delta_src))`` on ``f``: a model's own LFT member (:meth:`UncertainModel.delta_of`,
    clipped to the box), the nominal for measured data."""
    g0 = freqresp(um.nominal, f)
    if isinstance(src, FrequencyData):
        measured = FrequencyData(f, _on_grid(src, f, label), inputs=src.inputs, outputs=src.outputs)
        fd = align_channels(g0, measured)
        return fd.response, g0.response
    try:
        delta = um.delta_of(src)
    except (RobustctlError, AttributeError, TypeError) as exc:  # a model the LFT cannot place
        raise FitError(f"{label} cannot be placed in the uncertain model ({exc}); give models with the "
                       "LFT's parameters (e.g. upd.sample_models) or measured FrequencyData.") from exc
    return align_channels(g0, freqresp(src, f)).response, freqresp(um.statespace(delta), f).response


def cover_remainder(
    um: Any,
    data_or_models: Any,
    order: int = 4,
    kind: str = "additive",
    *,
    f_hz: Any = None,
    band: Sequence[float] | None = None,
    smooth_octaves: float = 0.25,
    floor: float = 1e-3,
    objective: str = "max",
    data_sigmas: float = 3.0,
    time_budget_s: float | None = None,
    fold: float = 0.0,
):
    """A complex weight covering what a parametric LFT misses, attached to it as its remainder.

    Each model ``G_s`` (e.g. ``upd.sample_models(n)``, at full order) stands in the LFT for
    ``Fu(M, delta_s)`` with ``delta_s = um.delta_of(G_s)`` clipped to [-1, 1] (its own
    parameters, or its modes' movement for ``form="modes"``); measured data stand for the
    nominal (``delta = 0``). The weight covers ``G_s - Fu(M, delta_s)`` (``"additive"``) or
    the relative error ``Fu^+ (G_s - Fu)`` / ``(G_s - Fu) Fu^+`` (``"input"`` / ``"output
    multiplicative"``) at every grid frequency, so every source is a member of ``{Fu(M,
    Delta_real) + W Delta_c}`` on the grid (the mixed real/complex set of Young 1996; the
    cover as :func:`cover_additive`, Zhou-Doyle-Glover sec. 8.1). The cover's ``sources`` and
    ``source_errors`` then state the LFT's error against each sampled model.

    Parameters
    ----------
    um : UncertainModel
        The parametric LFT (``upd.uncertain(...)``).
    data_or_models : FrequencyData, system, or a list mixing both
        Measured responses (channels matched by name) and models with the LFT's parameters.
    order : int
        States of the weight.
    kind : {"additive", "input multiplicative", "output multiplicative"}
        How the remainder enters (``rc.generalized_plant`` places it accordingly).
    f_hz : array_like, optional
        Grid (Hz); default the first FrequencyData's, else 200 points of the LFT's check grid.
    band : (lo_hz, hi_hz), optional
        Restrict the grid (Hz).
    smooth_octaves, floor, objective : float, float, str
        As for :func:`cover_additive`.
    data_sigmas : float
        Measured residuals are raised by this many standard deviations of the H1 estimate's
        random error (as :func:`cover_additive`).
    time_budget_s : float or None
        Optional cap on the magnitude fit (s).
    fold : float
        Fold into the remainder every real block whose whole effect
        (:meth:`~robustctl.physical.uncertain.UncertainModel.block_effect`) stays below ``fold``
        times the remainder's weight at every grid frequency (then refit the remainder on the
        LFT without them, so the cover still holds every source): a block that small changes
        the uncertainty set by less than that fraction of the remainder but adds channels and a
        scale to every D-K iteration. 0 (default) keeps every block.

    Returns
    -------
    UncertainModel
        ``um.with_remainder(cover)`` (less the folded blocks); the cover is ``.remainder``.

    Raises
    ------
    FitError
        Not an UncertainModel, an unknown ``kind``, a model the LFT cannot place, or a bad fit option.

    See Also
    --------
    robustctl.physical.uncertain.parametric_lft, cover_additive

    References
    ----------
    P. M. Young, "Controller design with real parametric uncertainty", Int. J. Control 65(3),
    1996 (the mixed real/complex set); Balas & Doyle (Caltech seed), eqs. 1-3.
    """
    if not isinstance(um, UncertainModel):
        raise FitError(f"um must be an UncertainModel (upd.uncertain()); got {type(um).__name__}.")
    if kind not in _KINDS:
        raise FitError(f"kind must be one of {list(_KINDS)}; got {kind!r}.")
    if f_hz is None and not any(isinstance(d, FrequencyData) for d in (
            data_or_models if isinstance(data_or_models, (list, tuple)) else [data_or_models])):
        f_hz = um.check_f_hz
    positive_number(fold, "fold (0: keep every real block)", FitError, allow_zero=True)
    f, sources = _sources(data_or_models, f_hz, band)
    fit = (order, kind, smooth_octaves, floor, time_budget_s, objective, data_sigmas)
    out = _remainder(um, f, sources, fit)
    if fold > 0:
        small = out.block_effect(f) <= fold * out.remainder.weight_mag[None, :]
        folded = [nm for nm, low in zip(out.names, small.all(axis=1)) if low]
        if folded:  # (all of them: an LFT without real blocks, the remainder a plain complex cover)
            out = _remainder(um.without(folded), f, sources, fit)
    return out


def _remainder(um: Any, f: np.ndarray, sources: list, fit: tuple) -> Any:
    """``um`` with the remainder cover of ``sources`` on ``f`` (see :func:`cover_remainder`)."""
    order, kind, smooth_octaves, floor, time_budget_s, objective, data_sigmas = fit
    g0 = freqresp(um.nominal, f)
    G0 = g0.response
    stand_ins = []
    for label, src in sources:
        G, Fu = _stands_for(um, src, f, label)
        E = G - Fu
        if kind == "input multiplicative":
            E = G0 @ np.linalg.pinv(Fu) @ E
        elif kind == "output multiplicative":
            E = E @ np.linalg.pinv(Fu) @ G0
        meta = src.meta if isinstance(src, FrequencyData) else {}
        coh = None
        if isinstance(src, FrequencyData) and src.coherence is not None:
            coh = _on_grid_values(src, src.coherence, f, label)
            coh = _align_values(g0, src, coh)
        # a stand-in with the nominal's channels whose error against the nominal is the remainder
        stand_ins.append(FrequencyData(f, G0 + E, inputs=g0.inputs, outputs=g0.outputs, coherence=coh,
                                       meta=meta))
    cover = _cover(kind, um.nominal, stand_ins, order, f_hz=f, band=None, smooth_octaves=smooth_octaves,
                   floor=floor, time_budget_s=time_budget_s, objective=objective, data_sigmas=data_sigmas)
    return um.with_remainder(cover)


def _align_values(g0: Any, src: FrequencyData, values: np.ndarray) -> np.ndarray:
    """``values`` (on ``src``'s channels) reordered to ``g0``'s channels, as :func:`robustctl.lti._align`."""
    out_idx = match_channels(src.outputs, g0.outputs, "outputs")
    in_idx = match_channels(src.inputs, g0.inputs, "inputs")
    return values[:, out_idx][:, :, in_idx]


def _public_signature(side: bool) -> inspect.Signature:
    """:func:`_cover`'s parameters without ``kind`` (and with ``side`` after ``order`` for the
    multiplicative cover): what ``help`` and ``inspect.signature`` show of the two covers."""
    params = list(inspect.signature(_cover).parameters.values())[1:]
    if side:
        kind = inspect.Parameter.POSITIONAL_OR_KEYWORD
        params.insert(3, inspect.Parameter("side", kind, default="input", annotation="str"))
    return inspect.Signature(params, return_annotation="UncertaintyCover")


cover_additive.__signature__ = _public_signature(False)  # type: ignore[attr-defined]
cover_multiplicative.__signature__ = _public_signature(True)  # type: ignore[attr-defined]
