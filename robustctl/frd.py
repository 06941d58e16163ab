"""FrequencyData: the one container for measured or computed frequency responses.

Every FRF array in robustctl has the shape ``(n_freq, n_out, n_in)``; frequencies at the
surface are in Hz. The file formats (npz, csv, mat, UFF dataset 58) live in
:mod:`robustctl.frd_io` (:func:`robustctl.frd_io.load_frd`), which registers
:meth:`FrequencyData.save`; the figures register :meth:`FrequencyData.plot` (:data:`_METHODS`).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from dataclasses import fields as _dc_fields
from os import PathLike
from pathlib import Path
from typing import Any

import numpy as np

from .checks import band_data
from .errors import DataError

__all__ = ["FrequencyData", "as_frequency_data", "register_method", "Experiment", "combined_experiment",
           "INPUT_KINDS", "EXCITATIONS", "PLAIN_NOTE"]

#: Implementations of FrequencyData methods whose work belongs to a higher floor: ``"save"``
#: (the file formats, :mod:`robustctl.frd_io`), ``"plot"`` and ``"plot_sv"`` (the figures,
#: :mod:`robustctl.figures`). Those modules register them when they are imported, and
#: ``import robustctl`` (which runs before any submodule) imports both, so this module
#: imports nothing above it while ``data.save(...)`` and ``data.plot()`` keep working.
_METHODS: dict[str, Any] = {}


def register_method(name: str, implementation: Any) -> None:
    """Register the implementation of the FrequencyData method ``name`` (see :data:`_METHODS`).

    Parameters
    ----------
    name : {"save", "plot", "plot_sv"}
        The method.
    implementation : callable
        Called with the FrequencyData first, then the method's arguments.
    """
    _METHODS[name] = implementation


def _method(name: str) -> Any:
    try:
        return _METHODS[name]
    except KeyError:
        raise RuntimeError(
            f"FrequencyData.{name} is implemented by a module that has not been imported; import robustctl."
        ) from None


def _default_names(prefix: str, count: int) -> tuple[str, ...]:
    return tuple(f"{prefix}{k + 1}" for k in range(count))


def _check_names(names: Sequence[str] | None, count: int, what: str, prefix: str) -> tuple[str, ...]:
    if names is None:
        return _default_names(prefix, count)
    if isinstance(names, str):
        names = (names,)
    if not isinstance(names, Sequence) and not isinstance(names, np.ndarray):
        raise DataError(f"{what} must be a list of signal names (str); got {names!r}. Example: {what}=['F'].")
    if not all(isinstance(n, (str, np.str_)) for n in names):
        raise DataError(f"{what} names must be strings; got {list(names)!r}.")
    names = tuple(str(n) for n in names)
    bad = [n for n in names if "\x00" in n or not n]
    if bad:
        raise DataError(f"{what} names must be non-empty and hold no NUL characters; got {bad!r}.")
    if len(names) != count:
        raise DataError(
            f"{what} has {len(names)} names but the response has {count} {what}; "
            f"give one name per {what[:-1]}."
        )
    if len(set(names)) != len(names):
        dup = sorted({n for n in names if names.count(n) > 1})
        raise DataError(f"{what} names must be unique; repeated: {dup}.")
    return names


def _numeric_array(value: Any, name: str, kinds: str) -> np.ndarray:
    """``value`` as an array of numbers of the dtype kinds ``kinds`` ("iuf" real, "iufc" complex)."""
    try:
        arr = np.asarray(value)
    except (TypeError, ValueError) as exc:  # ragged nested lists
        raise DataError(f"{name} must be an array of numbers; got {type(value).__name__} ({exc}).") from None
    if arr.dtype.kind == "c" and "c" not in kinds:
        raise DataError(f"{name} must be real; got complex values. Pass its real part if that is meant.")
    if arr.dtype.kind not in kinds or arr.dtype.kind == "b":
        raise DataError(f"{name} must be an array of numbers; got an array of dtype {arr.dtype}.")
    return arr


def _as_response(response: Any) -> np.ndarray:
    arr = _numeric_array(response, "response", "iufc")
    if arr.ndim == 1:
        arr = arr[:, None, None]
    if arr.ndim != 3:
        raise DataError(
            f"response must have shape (n_freq, n_out, n_in); got an array of shape {arr.shape}."
        )
    if 0 in arr.shape[1:]:
        raise DataError(
            f"response of shape {arr.shape} has no channels; give at least one output and one input."
        )
    arr = arr.astype(complex)
    if not np.all(np.isfinite(arr)):
        raise DataError("response contains NaN or inf values; remove or repair those frequency points.")
    return arr


def as_frequencies(f_hz: Any) -> np.ndarray:
    """``f_hz`` as a checked float array: finite, positive (Hz) and strictly increasing, else a
    DataError."""
    f = _numeric_array(f_hz, "f_hz", "iuf").astype(float).reshape(-1)
    if f.size == 0:
        raise DataError("f_hz is empty; give at least one frequency in Hz.")
    if not np.all(np.isfinite(f)):
        raise DataError("f_hz contains NaN or inf; frequencies must be finite numbers in Hz.")
    if np.any(f <= 0):
        raise DataError(
            f"f_hz must be positive (Hz); the smallest value is {f.min():g}. Drop the DC point."
        )
    if f.size > 1 and np.any(np.diff(f) <= 0):
        raise DataError("f_hz must be strictly increasing; sort the data and remove duplicates.")
    return f


def _mapping(value: Any, name: str, example: str) -> dict:
    if value is None:
        return {}
    if not isinstance(value, Mapping):
        raise DataError(f"{name} must be a mapping (dict) or None; got {value!r}. Example: {name}={example}.")
    if name == "units" and not all(isinstance(k, str) and isinstance(v, str) for k, v in value.items()):
        raise DataError(f"units must map signal names (str) to unit names (str); got {dict(value)!r}.")
    return dict(value)


def _select_experiments(meta: Mapping[str, Any], n_in: int, columns: list[int]) -> dict:
    """``meta`` with ``experiment_of_input`` (the experiment each input column came from, for
    data joined by ``combine_experiments``) following a selection of input columns."""
    meta = dict(meta)
    subs = meta.get("experiments")
    if not isinstance(subs, (list, tuple)) or not subs:
        return meta
    owner = meta.get("experiment_of_input")
    if owner is None:
        owner = [k for k, m in enumerate(subs)
                 for _ in range(int(m.get("n_inputs", 1)) if isinstance(m, Mapping) else 1)]
    if len(owner) == n_in:
        meta["experiment_of_input"] = [int(owner[k]) for k in columns]
    return meta


#: How the input reached the structure: a measured force or voltage, or a DAC command through a
#: zero-order hold.
INPUT_KINDS = ("measured", "held")
#: The excitation signals an experiment description knows.
EXCITATIONS = ("random", "periodic", "burst", "impact", "stepped_sine")
#: The message every result carries when the data do not describe their experiment.
PLAIN_NOTE = "compared as the plain FRF: the data do not say how they were estimated"


def _opt_choice(value: Any, name: str, choices: tuple[str, ...]) -> str | None:
    if value is None:
        return None
    if not isinstance(value, str) or value not in choices:
        raise DataError(f"{name} must be one of {list(choices)} or None (unknown); got {value!r}.")
    return value


def _opt_int(value: Any, name: str, lo: int) -> int | None:
    if value is None:
        return None
    ok = isinstance(value, (int, np.integer)) or (isinstance(value, float) and float(value).is_integer())
    if not ok or isinstance(value, (bool, np.bool_)) or value < lo:
        raise DataError(f"{name} must be an integer >= {lo} or None (unknown); got {value!r}.")
    return int(value)


def _opt_seconds(value: Any, name: str, zero: bool = False) -> float | None:
    """A positive (with ``zero``: non-negative), finite duration in s, or None (unknown)."""
    if value is None:
        return None
    ok = isinstance(value, (int, float, np.integer, np.floating)) and not isinstance(value, (bool, np.bool_))
    if not ok or not (np.isfinite(value) and (value >= 0 if zero else value > 0)):
        sign = "non-negative" if zero else "positive"
        raise DataError(f"{name} must be a {sign}, finite time in s or None (unknown); got {value!r}.")
    return float(value)


def _tau_of_end(end: Any, record_s: Any, tau: Any) -> float:
    """The exponential window's time constant (s) from its value ``end`` at ``record_s`` after the
    hit: ``exp(-record_s / tau) = end``."""
    if end is None or record_s is None:
        raise DataError("give exp_window_end (the window's value at the record end, e.g. 0.01) together "
                        "with record_s (s from the hit to the record end), or exp_window_tau_s alone.")
    if tau is not None:
        raise DataError("give the exponential window once: exp_window_tau_s, or exp_window_end with "
                        "record_s.")
    ok = isinstance(end, (int, float, np.integer, np.floating)) and not isinstance(end, (bool, np.bool_))
    if not ok or not 0 < end < 1:
        raise DataError(f"exp_window_end must be the window's value at the record end, in (0, 1); "
                        f"got {end!r}.")
    return _opt_seconds(record_s, "record_s") / float(np.log(1.0 / end))


def _opt_window(value: Any) -> str | tuple | None:
    if value is None:
        return None
    if isinstance(value, list):
        value = tuple(value)
    named = isinstance(value, str) or (isinstance(value, tuple) and bool(value) and isinstance(value[0], str))
    items = value if isinstance(value, tuple) else ()
    if not named or not all(isinstance(v, (str, int, float)) for v in items):
        raise DataError(
            f"window must be a scipy.signal.get_window name ('hamming'), a (name, parameter) tuple or None; "
            f"got {value!r}."
        )
    return value


@dataclass(frozen=True, init=False)
class Experiment:
    """How frequency-response data were made; ``None`` in any field means "not known".

    The verdicts of ``compare``, ``diagnose`` and ``update`` see a model "as the estimator saw
    the structure" only as far as this description establishes (window leakage for random
    excitation with known settings, the zero-order hold for held inputs); a missing
    description leaves the plain FRF.

    Parameters
    ----------
    input_kind : {"measured", "held"} or None
        ``"measured"``: the input channel is a measured continuous signal (a load-cell force, a
        measured voltage), the usual modal test; ``"held"``: a DAC command held over each sample
        (zero-order hold), as :func:`robustctl.simulate_experiment` makes.
    excitation : {"random", "periodic", "burst", "impact", "stepped_sine"} or None
        The excitation signal.
    fs_hz : float or None
        Sampling frequency in Hz.
    window : str, tuple or None
        The ``scipy.signal.get_window`` spec of the Welch segments (``"user array"`` for a
        window given as values, which ``meta["window_values"]`` holds).
    nperseg, noverlap, n_averages : int or None
        Welch segment length and overlap (samples) and the number of averaged segments.
    whole_periods : bool or None
        Periodic excitation: each segment holds a whole number of periods (no leakage).
    hold_divided : bool
        The estimate was divided by the zero-order hold's response ``(1 - e^{-sT}) / (sT)``
        (:func:`robustctl.examples.make_experiment` does so for held inputs).
    exp_window_tau_s : float or None
        Impact tests: time constant ``tau`` (s) of the exponential window ``exp(-(t - t0)/tau)``
        applied from the hit on force and response (None: no exponential window, or not
        known). It adds ``1/tau`` to every pole's decay rate, so the model is compared at
        ``s + 1/tau`` (Fladung & Rost 1997; Ewins, *Modal Testing*, sec. 3.11).
    force_window_s : float or None
        Impact tests: length (s) of the force (transient) window kept after the end of each
        force pulse before it tapers to zero (None: no force window, or not known).
    pretrigger_s : float or None
        Impact tests: time (s) from the record start to the hit (the trigger's pre-trigger
        delay). With ``fs_hz`` and the record length (the DFT bins' spacing) it places the
        record end the model is seen through (eq. T1 of :mod:`robustctl.measure.impact_view`).
    fs : float or None
        The sampling frequency in Hz under the name :func:`robustctl.estimate_frf` uses (keyword
        only; stored as ``fs_hz``, which the attribute ``fs`` also reads).
    exp_window_end : float, optional
        Keyword only: the exponential window given as its value at the record end (a fraction
        in (0, 1), e.g. 0.01 for "1 % at the end", the way analysers state it) with
        ``record_s``; stored as ``exp_window_tau_s = record_s / ln(1 / exp_window_end)``.
    record_s : float, optional
        Keyword only, with ``exp_window_end``: the time (s) from the window's start (the hit)
        to the record end.
    """

    input_kind: str | None = None
    excitation: str | None = None
    fs_hz: float | None = None
    window: Any = None
    nperseg: int | None = None
    noverlap: int | None = None
    n_averages: int | None = None
    whole_periods: bool | None = None
    hold_divided: bool = False
    exp_window_tau_s: float | None = None
    force_window_s: float | None = None
    pretrigger_s: float | None = None

    def __init__(
        self,
        input_kind: str | None = None,
        excitation: str | None = None,
        fs_hz: float | None = None,
        window: Any = None,
        nperseg: int | None = None,
        noverlap: int | None = None,
        n_averages: int | None = None,
        whole_periods: bool | None = None,
        hold_divided: bool = False,
        exp_window_tau_s: float | None = None,
        force_window_s: float | None = None,
        pretrigger_s: float | None = None,
        *,
        fs: float | None = None,
        exp_window_end: float | None = None,
        record_s: float | None = None,
    ) -> None:
        if fs is not None:
            if fs_hz is not None and fs_hz != fs:
                raise DataError(f"give the sampling frequency once: fs={fs!r} and fs_hz={fs_hz!r} differ.")
            fs_hz = fs
        if exp_window_end is not None or record_s is not None:
            exp_window_tau_s = _tau_of_end(exp_window_end, record_s, exp_window_tau_s)
        values = dict(input_kind=input_kind, excitation=excitation, fs_hz=fs_hz, window=window,
                      nperseg=nperseg, noverlap=noverlap, n_averages=n_averages,
                      whole_periods=whole_periods, hold_divided=hold_divided,
                      exp_window_tau_s=exp_window_tau_s, force_window_s=force_window_s,
                      pretrigger_s=pretrigger_s)
        for name, value in values.items():
            object.__setattr__(self, name, value)
        self.__post_init__()

    @property
    def fs(self) -> float | None:
        """The sampling frequency in Hz (``fs_hz``)."""
        return self.fs_hz

    def __post_init__(self) -> None:
        object.__setattr__(self, "input_kind", _opt_choice(self.input_kind, "input_kind", INPUT_KINDS))
        object.__setattr__(self, "excitation", _opt_choice(self.excitation, "excitation", EXCITATIONS))
        fs = self.fs_hz
        if fs is not None:
            ok = isinstance(fs, (int, float, np.integer, np.floating))
            if not ok or isinstance(fs, (bool, np.bool_)) or not (np.isfinite(fs) and fs > 0):
                raise DataError(
                    f"fs_hz must be a positive, finite sampling frequency in Hz or None; got {fs!r}."
                )
            fs = float(fs)
        object.__setattr__(self, "fs_hz", fs)
        object.__setattr__(self, "window", _opt_window(self.window))
        n = _opt_int(self.nperseg, "nperseg", 2)
        nov = _opt_int(self.noverlap, "noverlap", 0)
        if n is not None and nov is not None and nov >= n:
            raise DataError(f"noverlap ({nov}) must be smaller than nperseg ({n}).")
        object.__setattr__(self, "nperseg", n)
        object.__setattr__(self, "noverlap", nov)
        object.__setattr__(self, "n_averages", _opt_int(self.n_averages, "n_averages", 1))
        for name in ("whole_periods", "hold_divided"):
            value = getattr(self, name)
            if value is not None and not isinstance(value, (bool, np.bool_)):
                raise DataError(f"{name} must be True, False{' or None' if name == 'whole_periods' else ''}; "
                                f"got {value!r}.")
        whole = None if self.whole_periods is None else bool(self.whole_periods)
        object.__setattr__(self, "whole_periods", whole)
        object.__setattr__(self, "hold_divided", bool(self.hold_divided))
        for name in ("exp_window_tau_s", "force_window_s"):
            object.__setattr__(self, name, _opt_seconds(getattr(self, name), name))
        object.__setattr__(self, "pretrigger_s", _opt_seconds(self.pretrigger_s, "pretrigger_s", zero=True))

    @property
    def described(self) -> bool:
        """True when both the input kind and the excitation are known."""
        return self.input_kind is not None and self.excitation is not None

    @property
    def welch_known(self) -> bool:
        """True when the Welch settings (fs_hz, nperseg, window) are known."""
        return self.fs_hz is not None and self.nperseg is not None and self.window is not None

    def replace(self, **changes: Any) -> Experiment:
        """A copy with some fields changed (validated again)."""
        return Experiment(**{**self.to_dict(), **changes})

    def fill(self, other: Experiment) -> Experiment:
        """This description with its unknown (None) fields taken from ``other``."""
        mine = self.to_dict()
        theirs = other.to_dict()
        merged = {k: (theirs[k] if mine[k] is None else mine[k]) for k in mine}
        merged["hold_divided"] = self.hold_divided or other.hold_divided
        return Experiment(**merged)

    def to_dict(self) -> dict[str, Any]:
        """The fields as a JSON-friendly dict (a window tuple as a list)."""
        out = {f.name: getattr(self, f.name) for f in _dc_fields(self)}
        if isinstance(out["window"], tuple):
            out["window"] = list(out["window"])
        return out

    @classmethod
    def from_dict(cls, value: Mapping[str, Any] | None) -> Experiment:
        """The description stored by :meth:`to_dict` (unknown keys are refused)."""
        if value is None:
            return cls()
        if isinstance(value, Experiment):
            return value
        if not isinstance(value, Mapping):
            raise DataError(f"an experiment description must be a mapping or an Experiment; got {value!r}.")
        names = {f.name for f in _dc_fields(cls)} | {"fs"}
        unknown = sorted(set(value) - names)
        if unknown:
            raise DataError(f"unknown experiment fields {unknown}; the fields are {sorted(names)}.")
        return cls(**dict(value))

    def describe(self) -> str:
        """One line, e.g. ``"measured input, random excitation, 2048-pt hamming at 200 Hz, 19 averages"``."""
        if self == Experiment():
            return "not described"
        excitation = (self.excitation or "unknown").replace("_", " ")
        parts = [f"{self.input_kind or 'unknown'} input", f"{excitation} excitation"]
        if self.whole_periods is not None and self.excitation == "periodic":
            parts.append(("" if self.whole_periods else "not ") + "whole periods per segment")
        if self.welch_known:
            win = self.window if isinstance(self.window, str) else str(self.window)
            parts.append(f"{self.nperseg}-pt {win} at {self.fs_hz:g} Hz")
        elif self.fs_hz is not None:
            parts.append(f"sampled at {self.fs_hz:g} Hz")
        if self.n_averages is not None:
            parts.append(f"{self.n_averages} averages")
        if self.hold_divided:
            parts.append("divided by the hold")
        if self.exp_window_tau_s is not None:
            parts.append(f"exponential window tau = {self.exp_window_tau_s:.4g} s")
        if self.force_window_s is not None:
            parts.append(f"force window {self.force_window_s:.4g} s after the pulse")
        if self.pretrigger_s is not None:
            parts.append(f"hit {self.pretrigger_s:.4g} s after the record start")
        return ", ".join(parts)


def combined_experiment(experiments: Sequence[Experiment]) -> Experiment:
    """One description of joined experiments: the fields on which they all agree (else None)."""
    exps = list(experiments)
    if not exps:
        return Experiment()
    dicts = [e.to_dict() for e in exps]
    merged = {k: (dicts[0][k] if all(d[k] == dicts[0][k] for d in dicts) else None) for k in dicts[0]}
    merged["hold_divided"] = all(e.hold_divided for e in exps)
    return Experiment(**merged)


@dataclass(frozen=True, eq=False)
class FrequencyData:
    """Frequency-response data of a multi-input, multi-output system.

    Parameters
    ----------
    f_hz : array_like, shape (n_freq,)
        Frequencies in Hz, strictly increasing, finite and positive.
    response : array_like, complex, shape (n_freq, n_out, n_in)
        The frequency response G(j 2 pi f); a 1-D array is read as SISO.
    inputs, outputs : sequence of str, optional
        Unique signal names; default ``u1, u2, ...`` and ``y1, y2, ...``.
    coherence : array_like, shape (n_freq, n_out, n_in), optional
        Ordinary (SISO) or multiple (MIMO) coherence in [0, 1] of each estimate.
    units : mapping, optional
        Units of the signals, e.g. ``{"u1": "V", "y1": "m/s^2"}``.
    meta : mapping, optional
        Free-form provenance (estimation settings, source file ...).
    experiment : Experiment or mapping, optional
        How the data were made (:class:`Experiment`); default: not described (every field
        unknown), so verdicts compare the plain FRF.
    """

    f_hz: np.ndarray
    response: np.ndarray
    inputs: tuple[str, ...] | None = None
    outputs: tuple[str, ...] | None = None
    coherence: np.ndarray | None = None
    units: Mapping[str, str] | None = field(default=None)
    meta: Mapping[str, Any] | None = field(default=None)
    experiment: Experiment | None = field(default=None)

    def __post_init__(self) -> None:
        f = as_frequencies(self.f_hz)
        g = _as_response(self.response)
        if g.shape[0] != f.size:
            raise DataError(
                f"response has {g.shape[0]} frequency points but f_hz has {f.size}; "
                "the first axis of response must run over f_hz."
            )
        outputs = _check_names(self.outputs, g.shape[1], "outputs", "y")
        inputs = _check_names(self.inputs, g.shape[2], "inputs", "u")
        coh = None
        if self.coherence is not None:
            coh = _numeric_array(self.coherence, "coherence", "iuf").astype(float)
            if coh.ndim == 1 and g.shape[1:] == (1, 1):
                coh = coh[:, None, None]
            if coh.shape != g.shape:
                raise DataError(
                    f"coherence has shape {coh.shape} but response has shape {g.shape}; "
                    "give one coherence value per response entry."
                )
            if not np.all(np.isfinite(coh)) or np.any(coh < 0) or np.any(coh > 1 + 1e-9):
                raise DataError("coherence must be finite and lie in [0, 1].")
            coh = np.clip(coh, 0.0, 1.0)
            coh.setflags(write=False)
        f.setflags(write=False)
        g.setflags(write=False)
        object.__setattr__(self, "f_hz", f)
        object.__setattr__(self, "response", g)
        object.__setattr__(self, "inputs", inputs)
        object.__setattr__(self, "outputs", outputs)
        object.__setattr__(self, "coherence", coh)
        object.__setattr__(self, "units", _mapping(self.units, "units", "{'u1': 'V'}"))
        object.__setattr__(self, "meta", _mapping(self.meta, "meta", "{'source': 'test 3'}"))
        experiment = Experiment.from_dict(self.experiment)
        if experiment.fs_hz is not None and f[-1] > experiment.fs_hz / 2 * (1 + 1e-9):
            fs = experiment.fs_hz
            raise DataError(
                f"the data reach {f[-1]:g} Hz, beyond the Nyquist frequency {fs / 2:g} Hz of the stated "
                f"sampling frequency {fs:g} Hz: are the frequencies in rad/s? f_hz must be in Hz (divide "
                f"rad/s by 2 pi: {f[-1] / (2 * np.pi):.4g} Hz), or correct fs_hz."
            )
        object.__setattr__(self, "experiment", experiment)

    # ------------------------------------------------------------------ basic views
    @property
    def shape(self) -> tuple[int, int, int]:
        """``(n_freq, n_out, n_in)``."""
        return self.response.shape  # type: ignore[return-value]

    @property
    def n_freq(self) -> int:
        return self.response.shape[0]

    @property
    def n_out(self) -> int:
        return self.response.shape[1]

    @property
    def n_in(self) -> int:
        return self.response.shape[2]

    @property
    def w(self) -> np.ndarray:
        """Angular frequencies in rad/s."""
        return 2.0 * np.pi * self.f_hz

    def replace(self, **changes: Any) -> FrequencyData:
        """A copy with some fields replaced (validated again)."""
        fields = dict(
            f_hz=self.f_hz,
            response=self.response,
            inputs=self.inputs,
            outputs=self.outputs,
            coherence=self.coherence,
            units=self.units,
            meta=self.meta,
            experiment=self.experiment,
        )
        fields.update(changes)
        return FrequencyData(**fields)

    def points(self, mask: Any) -> FrequencyData:
        """The data at the frequency points a boolean mask over ``f_hz`` selects.

        A subset of valid data is valid, so nothing is checked again (unlike :meth:`replace`):
        the data were checked once, where they entered.

        Parameters
        ----------
        mask : ndarray of bool, shape (n_freq,)
            True at the points to keep (at least one).

        Returns
        -------
        FrequencyData
            Same channels, names, units, meta and experiment description.

        Raises
        ------
        DataError
            ``mask`` is not a boolean array over ``f_hz`` selecting at least one point.
        """
        mask = np.asarray(mask)
        if mask.dtype != bool or mask.shape != (self.n_freq,) or not np.any(mask):
            raise DataError(
                f"points takes a boolean mask of shape ({self.n_freq},) over f_hz with at least one "
                f"True; got {mask.dtype} of shape {mask.shape}. Use data.band(lo_hz, hi_hz) for a band."
            )
        out = object.__new__(FrequencyData)
        arrays = (("f_hz", self.f_hz), ("response", self.response), ("coherence", self.coherence))
        for key, arr in arrays:
            if arr is not None:
                arr = arr[mask]
                arr.setflags(write=False)
            object.__setattr__(out, key, arr)
        for key in ("inputs", "outputs", "experiment"):
            object.__setattr__(out, key, getattr(self, key))
        object.__setattr__(out, "units", dict(self.units))
        object.__setattr__(out, "meta", dict(self.meta))
        return out

    def band(self, lo_hz: float | None = None, hi_hz: float | None = None) -> FrequencyData:
        """The data restricted to ``lo_hz <= f <= hi_hz`` (Hz); an open end (None) is the data's end.

        The band rule is :func:`robustctl.checks.check_band` (finite, ``lo_hz < hi_hz``, at
        least one data point), shared by every entry point that takes ``band=``.
        """
        lo = float(self.f_hz[0]) if lo_hz is None else lo_hz
        hi = float(self.f_hz[-1]) if hi_hz is None else hi_hz
        if lo_hz is None and hi_hz is None:
            return self
        return band_data(self, (lo, hi))

    def _indices(self, wanted: Sequence[str] | str | None, names: tuple[str, ...], what: str) -> list[int]:
        if wanted is None:
            return list(range(len(names)))
        if isinstance(wanted, (str, int, np.integer)):
            wanted = [wanted]
        idx = []
        for item in wanted:
            if isinstance(item, (int, np.integer)):
                if not -len(names) <= item < len(names):
                    raise DataError(f"{what} index {item} is out of range for {len(names)} {what}.")
                idx.append(int(item) % len(names))
            elif item in names:
                idx.append(names.index(item))
            else:
                raise DataError(f"unknown {what[:-1]} {item!r}; the data has {what} {list(names)}.")
        return idx

    def select(
        self,
        outputs: Sequence[str] | str | None = None,
        inputs: Sequence[str] | str | None = None,
    ) -> FrequencyData:
        """The sub-matrix of the named (or indexed) outputs and inputs, in the order given."""
        oi = self._indices(outputs, self.outputs, "outputs")
        ii = self._indices(inputs, self.inputs, "inputs")
        g = self.response[:, oi][:, :, ii]
        coh = None if self.coherence is None else self.coherence[:, oi][:, :, ii]
        return self.replace(
            response=g,
            coherence=coh,
            meta=_select_experiments(self.meta, self.n_in, ii),
            outputs=[self.outputs[k] for k in oi],
            inputs=[self.inputs[k] for k in ii],
        )

    # ------------------------------------------------------------------ python-control
    def to_control(self):
        """The data as a ``control.FrequencyResponseData`` (omega in rad/s)."""
        import control

        fresp = np.transpose(self.response, (1, 2, 0))
        return control.FrequencyResponseData(
            fresp, self.w, inputs=list(self.inputs), outputs=list(self.outputs)
        )

    @classmethod
    def from_control(cls, frd: Any) -> FrequencyData:
        """Build from a ``control.FrequencyResponseData`` (or anything with ``omega``/``fresp``)."""
        try:
            omega = np.asarray(frd.omega, dtype=float)
            fresp = np.asarray(frd.frdata if hasattr(frd, "frdata") else frd.fresp)
        except AttributeError as exc:
            raise DataError(
                "from_control needs a control.FrequencyResponseData; "
                f"got {type(frd).__name__}."
            ) from exc
        inputs = getattr(frd, "input_labels", None)
        outputs = getattr(frd, "output_labels", None)
        return cls(
            omega / (2.0 * np.pi),
            np.transpose(fresp, (2, 0, 1)),
            inputs=inputs,
            outputs=outputs,
        )

    # ------------------------------------------------------------------ files
    def save(self, path: str | PathLike, overwrite: bool = False) -> Path:
        """Write the data to ``path``; the format follows the extension.

        Parameters
        ----------
        path : str or path-like
            ``.npz`` (numpy, no pickles; everything kept), ``.mat`` (MATLAB: ``Frequency``
            in Hz, ``ResponseData`` n_out x n_in x n_freq as MATLAB's ``frd``, ``InputName``,
            ``OutputName``, ``Coherence``), ``.csv`` (long format
            ``f_hz,output,input,re,im[,coherence]``; numbers and names only; a first line
            ``# robustctl.FrequencyData csv: F frequencies x O outputs x I inputs = N rows``
            and a last line ``# end, N rows`` let :func:`load_frd` refuse a truncated file,
            see :mod:`robustctl.frd_io.csv_format`) or
            ``.uff``/``.unv`` (universal file dataset 58, one binary double-precision record
            per output/input pair, names in ID lines 4 and 5, coherence as function type 6).
            Every format keeps ``experiment`` (how the data were made): npz and MAT as JSON
            (MAT also as plain variables ``InputKind``, ``SampleRate`` ...), CSV as a
            ``# experiment: {...}`` header line, UFF in ID line 2 and a ``<file>.uff.json``
            sidecar (with ``meta``).
        overwrite : bool
            Replace an existing file. By default an existing file is never touched.

        Returns
        -------
        pathlib.Path
            The path written.
        """
        return _method("save")(self, path, overwrite)

    # ------------------------------------------------------------------ views
    def plot(self, *, phase: bool = True, coherence: bool | None = None, max_channels: int = 9):
        """Bode plot: magnitude, phase and coherence (when present) per channel, log frequency.

        See :func:`robustctl.figures.plot_frf`; returns a matplotlib Figure.
        """
        return _method("plot")(self, phase=phase, coherence=coherence, max_channels=max_channels)

    def plot_sv(self):
        """Singular values over frequency (:func:`robustctl.figures.plot_singular_values`)."""
        return _method("plot_sv")(self)

    def _repr_html_(self) -> str:
        import html

        units = ", ".join(f"{k}: {v}" for k, v in self.units.items()) or "none given"
        rows = [
            ("frequencies", f"{self.n_freq} points, {self.f_hz[0]:.4g}-{self.f_hz[-1]:.4g} Hz"),
            ("outputs", ", ".join(self.outputs)),
            ("inputs", ", ".join(self.inputs)),
            ("coherence", "yes" if self.coherence is not None else "no"),
            ("units", units),
            ("experiment", self.experiment.describe()),
        ]
        body = "".join(f"<tr><th>{html.escape(k)}</th><td>{html.escape(v)}</td></tr>" for k, v in rows)
        return f"<table><caption>FrequencyData</caption>{body}</table>"

    def __repr__(self) -> str:
        return (
            f"FrequencyData({self.n_freq} points, {self.f_hz[0]:.4g}-{self.f_hz[-1]:.4g} Hz, "
            f"outputs={list(self.outputs)}, inputs={list(self.inputs)}"
            f"{', with coherence' if self.coherence is not None else ''})"
        )


# ---------------------------------------------------------------------------- FrequencyData
def as_frequency_data(data: Any, name: str = "data"):
    """``data`` as a FrequencyData: a FrequencyData, a ``(f_hz, response)`` pair or a
    ``control.FrequencyResponseData`` (omega in rad/s)."""
    if isinstance(data, FrequencyData):
        return data
    if isinstance(data, tuple) and len(data) == 2:
        return FrequencyData(*data)
    if hasattr(data, "omega") and (hasattr(data, "frdata") or hasattr(data, "fresp")):
        return FrequencyData.from_control(data)
    raise DataError(
        f"{name} must be a FrequencyData, a control.FrequencyResponseData or a pair (f_hz, response); "
        f"got {type(data).__name__}."
    )
