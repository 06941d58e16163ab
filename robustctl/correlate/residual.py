"""The complex-log residual of a model against measured data and its sensitivities.

MACE (Glaese & Miller) compare a model with measured transfer functions through the cost

    J = sum over frequencies, sensors, actuators of | log(G_data(jw) / G_model(jw)) |^2   (eq. 5)

written as ``J = j^T j`` with ``j`` the stacked per-point errors (eq. 6). The real part of
``log(G_data / G_model)`` is the log-magnitude error (natural-log units; x 20/ln 10 for dB),
the imaginary part the phase error (rad, principal value in (-pi, pi]). Poles and zeros
count alike, and so does phase.

:class:`Residual` holds the real vector ``j`` (real and imaginary parts stacked) of a
:class:`~robustctl.physical.model.PhysicalModel` against
:class:`~robustctl.frd.FrequencyData` on a band, and :func:`sensitivities` its
finite-difference derivatives with respect to named parameters (eqs. 7-8).

The data are coerced and checked once, where they enter: :func:`check_data` makes them a
FrequencyData (with its experiment description), checks the response and the band and builds
the noise model on the band; the resulting :class:`CheckedData` travels inward
(``Residual.of_checked``) and nothing behind ``rc.compare``, ``rc.diagnose`` and
``rc.update`` checks the data again.
"""

from __future__ import annotations

import warnings
from collections.abc import Mapping, Sequence
from concurrent.futures import Executor
from typing import Any

import numpy as np

from ..checks import (
    UNSET,
    band_data,
    check_band,
    checked_band_mask,
    finite_number,
    match_channels,
    renamed_keyword,
    user_stacklevel,
)
from ..checks import point_weights as point_weights_of
from ..errors import DataError, DataWarning, FitError, ModelError, RobustctlError, RobustctlWarning
from ..executors import parallel_map_shared
from ..frd import FrequencyData, as_frequency_data
from ..lti import as_statespace, freqresp, log_ratio
from ..measure.estimator import model_view, resolve_estimator, resolve_view, split_hold
from ..measure.noise import (
    NoiseModel,
    checked_averages,
    checked_noise_model,
    own_coherence_weights,
    point_weight_bias,
)

__all__ = [
    "Residual",
    "CheckedData",
    "check_data",
    "Sensitivities",
    "sensitivities",
    "log_ratio",
    "alignment",
    "orthogonality",
    "normalized",
    "NEGLIGIBLE_DB",
    "as_model",
    "physical_model",
    "check_complex_response",
    "resolve_estimator",
    "check_determined",
    "check_sampled_model",
    "UnitWarning",
]


class UnitWarning(RobustctlWarning):
    """A band or frequency that looks like rad/s where Hz is meant."""

#: Default level (dB) below which a channel counts as negligible (decoupled) and gets weight 0
#: in compare, update and diagnose (one rule, so they report one cost).
NEGLIGIBLE_DB = -80.0


class _FixedSystem:
    """A system without parameters (StateSpace, transfer function, MeasurementModel, fit) seen
    through the two PhysicalModel methods a :class:`Residual` uses."""

    def __init__(self, sys: Any) -> None:
        self.sys = as_statespace(sys)
        self.source = sys
        self.name = getattr(sys, "name", None) or type(sys).__name__
        self.param_names: tuple[str, ...] = ()

    def statespace(self, **overrides: float):
        if overrides:
            raise ModelError(f"a {self.name} has no parameters to override; got {sorted(overrides)}.")
        return self.sys

    def freqresp(self, f_hz: Any, **overrides: float) -> FrequencyData:
        return freqresp(self.statespace(**overrides), f_hz)


def as_model(model: Any) -> Any:
    """A PhysicalModel as is; any other system (see :func:`robustctl.as_statespace`) wrapped."""
    if hasattr(model, "param_names") and hasattr(model, "freqresp") and hasattr(model, "statespace"):
        return model
    return _FixedSystem(model)


def physical_model(model: Any, func: str) -> Any:
    """``model`` if it is a PhysicalModel (it has parameters to change); else a ModelError."""
    if hasattr(model, "param_names") and hasattr(model, "with_values") and hasattr(model, "statespace"):
        return model
    raise ModelError(
        f"{func} changes a model's physical parameters, so it needs a PhysicalModel; got "
        f"{type(model).__name__}. Use rc.compare for a model without parameters."
    )


def _channel_rms(response: np.ndarray) -> np.ndarray:
    """RMS magnitude over frequency of each channel of ``response`` (n_freq, n_out, n_in)."""
    return np.sqrt(np.mean(np.abs(response) ** 2, axis=0))


def _negligible_channels(
    response: np.ndarray, outputs: tuple[str, ...], inputs: tuple[str, ...], min_db: float
) -> list[tuple[str, str, float]]:
    """Channels whose rms response is ``min_db`` below the largest of their row and column."""
    rms = _channel_rms(response)
    ref = np.sqrt(np.outer(rms.max(axis=1), rms.max(axis=0)))
    with np.errstate(divide="ignore"):
        level = 20.0 * np.log10(np.where(ref > 0, rms / np.where(ref > 0, ref, 1.0), 0.0))
    return [(outputs[o], inputs[i], float(level[o, i])) for o, i in np.argwhere(level < float(min_db))]


def _check_no_zero_channel(data: FrequencyData) -> None:
    rms = _channel_rms(data.response)
    if np.any(rms == 0):
        o, i = np.argwhere(rms == 0)[0]
        raise DataError(
            f"data channel {data.outputs[o]} <- {data.inputs[i]} is identically zero on the band; its "
            "log error is undefined. Drop it with data.select(...), weight it 0, or let "
            "min_channel_db drop negligible channels."
        )


def _warn_dead_channels(data: FrequencyData) -> None:
    """Warn (:class:`~robustctl.errors.DataWarning`) about channels that are identically zero in
    the data: a disconnected sensor or actuator, not a decoupled axis (whose noise is never
    exactly zero). They are left out of the cost like negligible channels, but the user is told."""
    rms = _channel_rms(data.response)
    dead = np.argwhere(rms == 0)
    if dead.size == 0:
        return
    rows = [data.outputs[o] for o in range(rms.shape[0]) if np.all(rms[o] == 0)]
    cols = [data.inputs[i] for i in range(rms.shape[1]) if np.all(rms[:, i] == 0)]
    where = ([f"output {o} (every input)" for o in rows] + [f"input {i} (every output)" for i in cols])
    where = where or [f"{data.outputs[o]} <- {data.inputs[i]}" for o, i in dead]
    warnings.warn(
        f"the data are identically zero in {len(dead)} channel(s): {', '.join(where)}. That is a dead or "
        "disconnected sensor or actuator (a cable, a channel not recorded), not a decoupled axis: those "
        "channels are left out of the cost. Check the cable or drop them with data.select(...).",
        DataWarning, stacklevel=4,
    )


def check_complex_response(data: FrequencyData, name: str = "data") -> None:
    """Refuse "FRFs" that cannot be complex responses: magnitude only, or levels in dB.

    A measured frequency response has a phase; an array whose imaginary part is zero at every
    point is a magnitude (non-negative) or a level in dB (signed) and would give meaningless
    complex-log errors.
    """
    g = data.response
    if np.any(g.imag != 0):
        return
    if np.all(g.real >= 0):
        raise DataError(
            f"{name} is real and non-negative at every point: a magnitude without phase, not a frequency "
            "response. Give the complex response G(j 2 pi f) (e.g. magnitude * exp(1j * phase_rad))."
        )
    raise DataError(
        f"{name} is real-valued with negative values ({g.real.min():.3g} to {g.real.max():.3g}): it looks "
        "like a level in dB, not a complex response. Convert it: 10 ** (dB / 20) * exp(1j * phase_rad)."
    )


class CheckedData:
    """Data checked once, at a public entry point, and passed inward as this object.

    Made by :func:`check_data`; :class:`Residual` (``Residual.of_checked``) and everything
    behind ``rc.compare``, ``rc.diagnose`` and ``rc.update`` take it as it is, without
    coercing or checking the data again.

    Parameters
    ----------
    full : FrequencyData
        Every data point (with its experiment description, ``full.experiment``), Hz.
    band : (float, float) or None
        The checked band, Hz (None: every point).
    mask : ndarray of bool (n_freq,)
        The band's points in ``full``.
    noise : "auto", NoiseModel or None
        As for :func:`check_data`.
    measurement_model : system, optional
        As for :func:`check_data`.

    Attributes
    ----------
    data : FrequencyData
        The data on the band.
    noise : NoiseModel or None
        The noise model on the band.
    averages : ndarray (n_in,) or None
        Effective number of averages per input column (computed when first asked for).
    """

    def __init__(self, full: FrequencyData, band: tuple[float, float] | None, mask: np.ndarray,
                 noise: Any = "auto", measurement_model: Any = None) -> None:
        self.full, self.band, self.mask = full, band, mask
        self.data = band_data(full, band, mask=mask)
        self._averages: Any = UNSET
        self.noise: NoiseModel | None = _band_noise(noise, self, measurement_model)

    @property
    def averages(self) -> np.ndarray | None:
        if self._averages is UNSET:
            self._averages = None if self.full.coherence is None else checked_averages(self.full)
        return self._averages


def check_data(
    data: Any, band: Any = None, noise: Any = "auto", measurement_model: Any = None
) -> CheckedData:
    """Coerce and check the data of a public entry point once: FrequencyData, complex response,
    band, and the noise model on the band.

    Parameters
    ----------
    data : FrequencyData, (f_hz, response) pair or control.FrequencyResponseData
        Measured responses, Hz (:func:`robustctl.frd.as_frequency_data`).
    band : (f_lo_hz, f_hi_hz), optional
        :func:`robustctl.checks.check_band`; a band far beyond the data warns (rad/s?).
    noise : "auto", NoiseModel or None
        ``"auto"``: :func:`robustctl.measure.noise.noise_model` of the data (with
        ``measurement_model`` for data without coherence); a NoiseModel made on the data's
        grid or on the band's; None: no noise model.
    measurement_model : system, optional
        Gives the noise from its residual when the data carry no coherence.

    Returns
    -------
    CheckedData

    Raises
    ------
    DataError
        Data that cannot be a complex frequency response, a bad band, a bad ``noise``.
    """
    full = as_frequency_data(data)
    check_complex_response(full)
    band = check_band(band)
    _warn_band_units(band, full)
    return CheckedData(full, band, checked_band_mask(full.f_hz, band), noise, measurement_model)


def _band_noise(spec: Any, checked: CheckedData, measurement_model: Any) -> NoiseModel | None:
    """The noise model on the band: ``spec`` (a NoiseModel on the data's grid or the band's, with
    the data's channels; DataError otherwise), or ``"auto"``, from the data
    (:func:`robustctl.measure.noise.checked_noise_model`)."""
    mask = checked.mask
    if isinstance(spec, str) and spec == "auto":
        nm = checked_noise_model(checked.full, checked.averages, measurement_model)
        return None if nm is None else nm.band(mask)
    if isinstance(spec, NoiseModel):
        nm = spec.on(checked.full.f_hz[mask])
        shape = checked.full.response.shape[1:]
        if nm.sigma.shape[1:] != shape:
            raise DataError(
                f"the noise model has {nm.sigma.shape[1]} x {nm.sigma.shape[2]} channels (outputs x inputs) "
                f"but the data have {shape[0]} x {shape[1]}; build it on the same data "
                "(rc.noise_model(data)) or give sigma the shape (n_freq, n_out, n_in) of the data's response."
            )
        return nm
    if spec is None:
        return None
    raise DataError(f"noise must be 'auto', a NoiseModel or None; got {type(spec).__name__}.")


class Residual:
    """Weighted complex-log residual of a model against data on a band (MACE eqs. 5-6).

    Parameters
    ----------
    model : PhysicalModel
        The model; its output and input names must match the data's (any order).
    data : FrequencyData
        Measured (or simulated) responses, shape (n_freq, n_out, n_in), Hz.
    band : (float, float), optional
        Frequency band ``(lo_hz, hi_hz)`` in Hz; default: every data point.
    point_weights : "auto", None, "coherence" or array_like, optional
        Data-point weights ``W`` on the squared log error (:func:`robustctl.checks.point_weights`),
        so the cost is ``sum W |log ratio|^2``, the number ``rc.log_cost(m, d, point_weights=W)``
        gives. ``"auto"`` (default): coherence weights ``W = g2 / (1 - g2)`` (inverse variance
        of the log estimate, g2 clipped at 0.999, normalised to mean 1) when the data carry
        coherence; else the inverse variance ``1 / sigma^2`` of a given noise model (data
        without coherence, noise from a measurement model's residual); else uniform. The
        residual vector carries ``sqrt(W)``. With coherence weights and a known number of
        averages the real part of each log error is first lowered by
        :func:`robustctl.measure.noise.coherence_weight_bias` (``bias``): what the bin's own
        coherence in ``W`` adds to it on average.
    min_channel_db : float or None
        Channels whose RMS magnitude on the band, in the data or in the nominal model, lies
        more than this many dB below the geometric mean of the largest channel in their row
        and in their column are given weight 0 (listed in ``dropped``): decoupled axes of a
        symmetric structure measure noise against a numerically zero model, a log error no
        physical parameter can explain, and it would swamp the cost. ``None`` keeps every
        channel and refuses identically zero ones.
    estimator : "auto", True, False or EstimatorSettings
        See the model "as the H1 estimator sees it" (:func:`robustctl.measure.estimator.estimator_view`)
        as far as the data's experiment description (``data.experiment``) establishes it
        (``"auto"``, default; :func:`robustctl.measure.estimator.experiment_view`): window leakage for
        random excitation with known settings, the sampled zero-order hold for held inputs,
        nothing for undescribed data (the plain FRF, said so in every result). ``False``:
        compare ``G(jw)`` itself.
    noise : "auto", NoiseModel or None
        The noise model of the data (:func:`robustctl.measure.noise.noise_model`); ``"auto"``: from
        coherence and the recorded number of averages when possible, else None.

    Attributes
    ----------
    n : int
        Length of the real residual vector, ``2 * n_freq_band * n_out * n_in``.
    data : FrequencyData
        The banded data, channels in data order.
    weights : ndarray, shape (n_freq_band, n_out, n_in)
        ``sqrt(W)``: the factor on each complex log error in :meth:`complex`.
    point_weights : ndarray, shape (n_freq_band, n_out, n_in)
        ``W``, the weights on the squared error (zero on dropped channels).
    bias : ndarray (n_freq_band, n_out, n_in) or None
        The offset subtracted from ``Re log(G_data / G_model)`` before weighting
        (:func:`robustctl.measure.noise.point_weight_bias`), nepers; None with uniform or given weights
        or without a known number of averages.
    dropped : list of (output, input, level_db)
        Channels given weight 0 as negligible, with their relative level in dB.

    Notes
    -----
    ``vector()`` stacks ``Re`` then ``Im`` of ``w * (log(G_data / G_model(theta)) - bias)``, each
    flattened in (frequency, output, input) C order, so ``cost() = vector() @ vector()``
    is MACE's J (eq. 5) and ``vector()`` its j (eq. 6).
    """

    def __init__(
        self,
        model: Any,
        data: FrequencyData,
        band: Sequence[float] | None = None,
        point_weights: Any = "auto",
        min_channel_db: float | None = NEGLIGIBLE_DB,
        *,
        weights: Any = UNSET,
        estimator: Any = "auto",
        noise: Any = "auto",
    ) -> None:
        point_weights = renamed_keyword(point_weights, weights, "point_weights", "weights", default="auto")
        self._setup(as_model(model), check_data(data, band, noise), point_weights, min_channel_db, estimator)

    @classmethod
    def of_checked(
        cls,
        model: Any,
        checked: CheckedData,
        point_weights: Any = "auto",
        min_channel_db: float | None = NEGLIGIBLE_DB,
        estimator: Any = "auto",
    ) -> Residual:
        """The residual of data checked once at a public entry point (:func:`check_data`): the
        data, band and noise model are taken as they are; the arguments as for the class."""
        res = cls.__new__(cls)
        res._setup(as_model(model), checked, point_weights, min_channel_db, estimator)
        return res

    def _setup(
        self, model: Any, checked: CheckedData, point_weights: Any, min_channel_db: float | None,
        estimator: Any,
    ) -> None:
        data, mask = checked.full, checked.mask
        self.model = model
        self.band = checked.band
        self.data = checked.data
        self.estimator, self._view_note = resolve_view(estimator, data, model)
        self.noise = checked.noise
        sys0 = model.statespace()
        check_sampled_model(sys0, data)
        self._out_idx = match_channels(sys0.output_labels, self.data.outputs, "outputs")
        self._in_idx = match_channels(sys0.input_labels, self.data.inputs, "inputs")
        self.weights = self._point_weights(point_weights, data, mask)
        self.bias = None
        if own_coherence_weights(point_weights, data):
            coherent = self.noise is not None and self.noise.kind == "coherence"
            nd = self.noise.averages if coherent else checked.averages
            if nd is not None:
                self.bias = point_weight_bias(point_weights, data, mask, n_averages=nd)
        self.dropped = self._negligible(min_channel_db)
        for o, i, _level in self.dropped:
            self.weights[:, self.data.outputs.index(o), self.data.inputs.index(i)] = 0.0
        if not np.any(self.weights > 0):
            raise DataError("every channel has zero weight; nothing is left to compare.")
        self.n = 2 * self.data.response.size

    def _without_hold(self) -> tuple[Any, bool]:
        """The model without its zero-order-hold stage (cached per model) and whether it had one.

        With the hold added deliberately (``electronics.zero_order_hold_stage``), the estimator
        view samples the bare model through an exact hold instead of the stage's rational
        approximation (aliasing and the feedthrough's timing included).
        """
        model = self.model
        cached = getattr(self, "_bare_cache", None)
        if cached is not None and cached[0] is model:
            return cached[1], cached[2]
        bare, has = split_hold(model)
        self._bare_cache = (model, bare, has)
        return bare, has

    def _point_weights(self, spec: Any, data: FrequencyData, mask: np.ndarray) -> np.ndarray:
        """``sqrt(W)`` by the shared rule (:func:`robustctl.checks.point_weights`), except that
        ``"auto"`` on data without coherence but with a noise model (e.g. from a measurement
        model's residual) uses the inverse noise variance ``1 / sigma^2`` (mean 1) -- what
        coherence weights are for data with coherence -- instead of falling back to uniform."""
        auto = isinstance(spec, str) and spec == "auto"
        if auto and data.coherence is None and self.noise is not None:
            w = 1.0 / self.noise.sigma**2
            return np.sqrt(w / float(np.mean(w)))
        return point_weights_of(spec, data, mask, amplitude=True)

    def describe_estimator(self) -> str:
        """How the model was seen: ``"model seen through the H1 estimator: 4096-pt hamming at 200 Hz"``,
        or why as the plain FRF (``"compared as the plain FRF: the data do not say how they were
        estimated"``, :func:`robustctl.measure.estimator.experiment_view`)."""
        return self._view_note

    @property
    def point_weights(self) -> np.ndarray:
        """``W`` on the squared log error (zero on dropped channels), shape of the banded data."""
        return self.weights**2

    def _negligible(self, min_db: float | None) -> list[tuple[str, str, float]]:
        """Channels negligible in the data or in the nominal model (decoupled by symmetry)."""
        if min_db is None:
            _check_no_zero_channel(self.data)
            return []
        min_db = finite_number(min_db, "min_channel_db", DataError)
        d = self.data
        _warn_dead_channels(d)
        found = {(o, i): lvl for o, i, lvl in _negligible_channels(d.response, d.outputs, d.inputs, min_db)}
        model_level = _negligible_channels(self.model_response(), d.outputs, d.inputs, min_db)
        for o, i, lvl in model_level:
            found[(o, i)] = min(lvl, found.get((o, i), lvl))
        return [(o, i, lvl) for (o, i), lvl in found.items()]

    def informative_frequencies(self) -> int:
        """The number of band frequencies at which some channel carries weight."""
        return int(np.count_nonzero(np.any(self.weights > 0, axis=(1, 2))))

    # ------------------------------------------------------------------ evaluation
    @property
    def f_hz(self) -> np.ndarray:
        """Band frequencies in Hz."""
        return self.data.f_hz

    def model_response(self, **overrides: float) -> np.ndarray:
        """Model response (n_freq_band, n_out, n_in) on the band, in data channel order.

        With estimator settings this is the expected H1 estimate of the model without the
        hold (:func:`robustctl.measure.estimator.estimator_view`), else ``G(j 2 pi f)``.
        """
        if self.estimator is not None:
            bare, hold = self._without_hold()
            g = model_view(bare, hold, self.data.f_hz, self.estimator, **overrides)
        else:
            g = self.model.freqresp(self.data.f_hz, **overrides).response
        return g[:, self._out_idx][:, :, self._in_idx]

    def error(self, g_model: np.ndarray | None = None, **overrides: float) -> np.ndarray:
        """The log error the cost sees, ``log(G_data / G_model) - bias`` (unweighted), shape
        (n_freq_band, n_out, n_in); ``g_model`` (on the band, data channel order) if known."""
        g = self.model_response(**overrides) if g_model is None else g_model
        e = log_ratio(self.data.response, g)
        return e if self.bias is None else e - self.bias

    def complex(self, **overrides: float) -> np.ndarray:
        """Weighted complex log error ``w * (log(G_data / G_model) - bias)``, shape (n_freq_band,
        n_out, n_in)."""
        return self.weights * self.error(**overrides)

    def vector(self, **overrides: float) -> np.ndarray:
        """Real residual vector j (MACE eq. 6): ``[Re(e).ravel(), Im(e).ravel()]``, length ``n``."""
        e = self.complex(**overrides).ravel()
        return np.concatenate([e.real, e.imag])

    def cost(self, **overrides: float) -> float:
        """MACE's cost ``J = j^T j`` (eq. 5), dimensionless."""
        j = self.vector(**overrides)
        return float(j @ j)

    def unstack(self, j: np.ndarray) -> np.ndarray:
        """Invert :meth:`vector`: a real vector of length ``n`` back to the complex (nf, no, ni) array."""
        j = np.asarray(j)
        half = self.n // 2
        return (j[:half] + 1j * j[half:]).reshape(self.data.shape)

    def __repr__(self) -> str:
        band = "all" if self.band is None else f"{self.band[0]:g}-{self.band[1]:g} Hz"
        return (
            f"Residual(model={getattr(self.model, 'name', '?')!r}, band={band}, "
            f"{self.data.n_freq} points x {self.data.n_out} x {self.data.n_in} channels, n={self.n})"
        )


# ---------------------------------------------------------------------- sensitivities
class Sensitivities(tuple):
    """``(j0, dJ)`` from :func:`sensitivities`, with the scaling used as attributes.

    Unpacks as a pair: ``j0, dJ = sensitivities(...)``.

    Attributes
    ----------
    j0 : ndarray (n,)
        Residual vector at the base point.
    dJ : ndarray (n, p)
        Scaled sensitivity columns (MACE eq. 8).
    names : tuple of str
    base : dict
        Parameter values at the base point (``at`` with ``origin`` applied).
    trial : ndarray (p,)
        The perturbed value of each parameter.
    delta : ndarray (p,)
        ``trial - base`` per parameter (signed finite-difference step).
    scale : ndarray (p,)
        The scale ``s_i`` with ``dJ[:, i] = (j_i - j0) * s_i / delta_i``.
    kind : tuple of str
        ``"relative"`` (s_i = alpha_i), ``"unit"`` (s_i = 1) or ``"secant"`` (s_i = delta_i).
    n_evals : int
        Residual evaluations spent (including j0 unless it was given).
    """

    def __new__(cls, j0: np.ndarray, dJ: np.ndarray, **attrs: Any) -> Sensitivities:
        obj = super().__new__(cls, (j0, dJ))
        obj.j0 = j0
        obj.dJ = dJ
        for key, value in attrs.items():
            setattr(obj, key, value)
        return obj

    def jacobian(self) -> np.ndarray:
        """Derivative ``d j / d alpha`` per unit of each parameter, shape (n, p)."""
        return self.dJ / self.scale

    def __reduce__(self):  # keep attributes through pickling
        return (_rebuild_sensitivities, (self.j0, self.dJ, dict(self.__dict__)))


def _rebuild_sensitivities(j0: np.ndarray, dJ: np.ndarray, attrs: dict) -> Sensitivities:
    attrs = {k: v for k, v in attrs.items() if k not in ("j0", "dJ")}
    return Sensitivities(j0, dJ, **attrs)


def _check_names(model: Any, names: Sequence[str]) -> tuple[str, ...]:
    if isinstance(names, str):
        names = (names,)
    names = tuple(names)
    if not names:
        raise ModelError("give at least one parameter name.")
    known = set(model.param_names)
    unknown = [n for n in names if n not in known]
    if unknown:
        raise ModelError(f"unknown parameter(s) {unknown}; the model has {list(model.param_names)}.")
    if len(set(names)) != len(names):
        raise ModelError(f"parameter names repeat: {list(names)}.")
    return names


def _trial_value(param: Any, base: float, step: float) -> float:
    lo, hi = param.bounds
    up, down = base + step, base - step
    if up <= hi:
        return up
    if down >= lo:
        return down
    raise ModelError(
        f"parameter {param.name!r}: the finite-difference step {step:g} leaves its bounds "
        f"[{lo:g}, {hi:g}] in both directions at {base:g}; give a smaller step."
    )


def _evaluate(residual: Residual, overrides: dict[str, float]) -> np.ndarray | RobustctlError:
    """The residual vector, or the RobustctlError the model build raised (so a batch survives)."""
    try:
        return residual.vector(**overrides)
    except RobustctlError as exc:
        return exc


def sensitivities(
    residual: Residual,
    names: Sequence[str],
    *,
    at: Mapping[str, float] | None = None,
    steps: Mapping[str, float] | None = None,
    origin: Mapping[str, float] | None = None,
    j0: np.ndarray | None = None,
    executor: Executor | None = None,
    progress: bool = False,
) -> Sensitivities:
    """Finite-difference sensitivities of the residual vector (MACE eqs. 7-8).

    Parameters
    ----------
    residual : Residual
    names : sequence of str
        Parameters to differentiate with respect to.
    at : mapping, optional
        Parameter values (any of the model's) of the base point; default the model's values.
    steps : mapping, optional
        Step ``d alpha_i`` (parameter units) per name; default ``Parameter.step(alpha_i)``
        (``max(rel_step*|alpha|, abs_step)``). The step is taken upwards unless that
        leaves the parameter's bounds, then downwards.
    origin : mapping, optional
        ``{name: value}`` for parameters whose sensitivity is a secant from ``value``
        (e.g. an effect at its neutral value, where the derivative may vanish): the
        base point has the parameter at ``origin``; the trial value is its ``at`` value
        (or model value), or ``origin + step`` when those coincide.
    j0 : ndarray, optional
        The residual vector at the base point if already known (saves one evaluation).
    executor : concurrent.futures.Executor, optional
        Runs the perturbed evaluations in parallel (a ProcessPoolExecutor needs a
        picklable model).
    progress : bool
        Show a tqdm bar (only when stderr is a terminal).

    Returns
    -------
    Sensitivities
        Unpacks as ``(j0, dJ)``; ``dJ[:, i] = (j_i - j0) * s_i / delta_i`` with
        ``delta_i = trial_i - base_i`` and scale ``s_i``:

        * ``alpha_i`` (base value) when it is nonzero: the relative sensitivity
          ``dj / d ln alpha`` of MACE eq. 7;
        * ``1`` when ``alpha_i == 0``: the sensitivity per unit of the parameter;
        * ``delta_i`` for a parameter in ``origin``: ``dJ[:, i] = j_i - j0``, the whole
          secant change from the origin to the trial value.

        In every case the linear model is ``j(base + s * c) ~ j0 + dJ @ c``; ``.scale``,
        ``.delta``, ``.trial``, ``.base`` and ``.kind`` record what was used.
    """
    model = residual.model
    names = _check_names(model, names)
    base = dict(model.values)
    for key, value in dict(at or {}).items():
        if key not in base:
            raise ModelError(f"unknown parameter {key!r} in at=; the model has {list(base)}.")
        base[key] = float(value)
    origin = dict(origin or {})
    steps = dict(steps or {})
    for key in list(origin) + list(steps):
        if key not in names:
            raise ModelError(f"origin/steps name {key!r} is not among the parameters {list(names)}.")
    trial_of = {n: base[n] for n in names}
    for key, value in origin.items():
        base[key] = float(value)
    trials, kinds, scales = [], [], []
    for n in names:
        par = model.param(n)
        a = base[n]
        if n in origin and trial_of[n] != a:
            t = trial_of[n]
        else:
            step = float(steps[n]) if n in steps else par.step(a)
            if not step > 0:
                raise ModelError(f"step for {n!r} must be positive; got {step!r}.")
            t = _trial_value(par, a, step)
        trials.append(t)
        if n in origin:
            kinds.append("secant")
            scales.append(t - a)
        elif a != 0.0:
            kinds.append("relative")
            scales.append(a)
        else:
            kinds.append("unit")
            scales.append(1.0)
    points = [{**_diff(base, model.values), n: t} for n, t in zip(names, trials)]
    base_point = _diff(base, model.values)
    n_evals = len(points)
    if j0 is None:
        points = [base_point] + points
        n_evals += 1
    vectors = parallel_map_shared(
        _evaluate, residual, points, executor, desc="sensitivities", progress=progress
    )
    if j0 is None:
        j0, vectors = vectors[0], vectors[1:]
        if isinstance(j0, RobustctlError):
            raise j0
    j0 = np.asarray(j0, dtype=float)
    for k, v in enumerate(vectors):
        if isinstance(v, RobustctlError):
            vectors[k], trials[k] = _retry_mirrored(residual, names[k], base, trials[k], kinds[k], v)
            n_evals += 1
    trial = np.array(trials)
    delta = trial - np.array([base[n] for n in names])
    scale = np.array(scales)
    dJ = np.column_stack([(v - j0) * (s / d) for v, s, d in zip(vectors, scale, delta)])
    return Sensitivities(
        j0,
        dJ,
        names=names,
        base=base,
        trial=trial,
        delta=delta,
        scale=scale,
        kind=tuple(kinds),
        n_evals=n_evals,
    )


def _retry_mirrored(
    residual: Residual, name: str, base: dict[str, float], trial: float, kind: str, exc: Exception
) -> tuple[np.ndarray, float]:
    """Evaluate at the step mirrored about the base value after a failed evaluation."""
    par = residual.model.param(name)
    mirrored = 2.0 * base[name] - trial
    if kind != "secant" and par.bounds[0] <= mirrored <= par.bounds[1]:
        v = _evaluate(residual, {**_diff(base, residual.model.values), name: mirrored})
        if not isinstance(v, RobustctlError):
            return v, mirrored
    raise FitError(
        f"the model cannot be evaluated for the finite difference of {name!r} at {trial:g} "
        f"{par.unit}: {exc} Give a different step (steps={{{name!r}: ...}}) or leave {name!r} out."
    ) from exc


def _diff(theta: Mapping[str, float], values: Mapping[str, float]) -> dict[str, float]:
    """Only the entries of ``theta`` that differ from the model's ``values`` (short overrides)."""
    return {k: v for k, v in theta.items() if values.get(k) != v}


def alignment(j0: np.ndarray, dJ: np.ndarray) -> np.ndarray:
    """MACE test 1: ``|j0^T dJ|`` per parameter (eq. 8), in the units of ``J``.

    Large values mark parameters the initial cost is sensitive to.
    """
    return np.abs(np.asarray(j0) @ np.asarray(dJ))


def normalized(dJ: np.ndarray) -> np.ndarray:
    """Columns of ``dJ`` scaled to unit length (MACE eq. 9); zero columns stay zero."""
    dJ = np.asarray(dJ, dtype=float)
    norms = np.linalg.norm(dJ, axis=0)
    return dJ / np.where(norms > 0, norms, 1.0)


def orthogonality(dJ: np.ndarray) -> np.ndarray:
    """MACE test 2: ``|dJn^T dJn|`` (eq. 9, Fig. 4); unit diagonal, off-diagonals in [0, 1].

    An off-diagonal near 1 means two parameters move the residual the same way (a
    superparameter candidate); a zero column (no sensitivity) gives a 0 diagonal.
    """
    n = normalized(dJ)
    out = np.abs(n.T @ n)
    return np.clip(out, 0.0, 1.0)


# ---------------------------------------------------------------------- sanity of the set-up
def _warn_band_units(band: tuple[float, float] | None, data: FrequencyData) -> None:
    """Warn when a band reaches far beyond the data (Hz): it was probably given in rad/s."""
    if band is None:
        return
    import warnings

    top = float(data.f_hz[-1])
    if band[1] > 1.5 * top:
        warnings.warn(
            f"band ({band[0]:g}, {band[1]:g}) reaches {band[1] / top:.3g} x beyond the data's highest "
            f"frequency ({top:g} Hz): bands are in Hz, not rad/s (in rad/s this band would be "
            f"{band[0] / (2 * np.pi):.4g}-{band[1] / (2 * np.pi):.4g} Hz).",
            UnitWarning,
            stacklevel=user_stacklevel(),
        )


def check_sampled_model(sys: Any, data: FrequencyData) -> None:
    """Refuse a sampled model (``dt > 0``) that cannot describe the data.

    A sampled model is evaluated at ``z = exp(j 2 pi f dt)`` (:func:`robustctl.freqresp`); its
    frequencies end at ``1 / (2 dt)``, and its sampling time must be the data's when the data
    state their sampling frequency (``data.experiment.fs_hz``).
    """
    dt = getattr(sys, "dt", None)
    if dt in (None, 0) or dt is False:
        return
    if dt is True:
        raise ModelError(
            "the model is discrete with an unspecified sampling time (dt=True); give its sampling time "
            "in s (control.ss(A, B, C, D, dt)) or pass the continuous model."
        )
    nyquist = 0.5 / float(dt)
    if data.f_hz[-1] > nyquist * (1 + 1e-9):
        raise ModelError(
            f"the model is sampled (dt = {dt:g} s, Nyquist {nyquist:g} Hz) but the data reach "
            f"{data.f_hz[-1]:g} Hz; restrict the band below {nyquist:g} Hz, or are the data's frequencies "
            "in rad/s (f_hz must be in Hz)?"
        )
    fs = getattr(getattr(data, "experiment", None), "fs_hz", None)
    if fs is not None and abs(fs * float(dt) - 1.0) > 1e-6:
        raise ModelError(
            f"the model is sampled at {1 / float(dt):g} Hz (dt = {dt:g} s) but the data were sampled at "
            f"{fs:g} Hz; discretise the model at the data's rate (control.c2d(sys, {1 / fs:g})) or pass the "
            "continuous model."
        )


def check_determined(residual: Residual, n_params: int, func: str) -> None:
    """Refuse a fit of more parameters than the band has informative frequencies.

    Every parameter needs at least one frequency of its own (a band holding one point fits any
    one-mode change exactly, and reports a 100 % cost reduction that means nothing).

    Raises
    ------
    DataError
        Naming the counts and the fix.
    """
    n_f = residual.informative_frequencies()
    if n_f < n_params:
        band = "the data"
        if residual.band is not None:
            band = f"the band {residual.band[0]:g}-{residual.band[1]:g} Hz"
        raise DataError(
            f"{func} fits {n_params} free parameters but {band} holds {n_f} informative frequencies (with "
            f"weight in some channel); the fit would be undetermined. Widen the band or fix parameters "
            f"(params=[...] naming at most {max(n_f, 1)})."
        )
