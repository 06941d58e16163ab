"""Argument checks shared by every public entry point: one rule, one error class, one wording.

Like python-control's ``_process_indices``/``_process_labels``, each check is written once
here and imported by ``frd``, ``estimate``, ``lti``, ``correlate`` and ``identify``. It
imports only :mod:`robustctl.errors` (the coercion to FrequencyData is
:func:`robustctl.frd.as_frequency_data`; the coherence-weight bias, which needs the noise
model, is :func:`robustctl.measure.noise.coherence_weight_bias`):

* :func:`check_band`, :func:`band_mask`, :func:`band_data` -- a frequency band
  ``(f_lo_hz, f_hi_hz)``: a pair of finite numbers in Hz with ``f_lo < f_hi`` that holds at
  least one data point. Always a :class:`~robustctl.errors.DataError`.
* :func:`point_weights` -- data-point weights ``W`` on the *squared* complex-log error
  (MACE eq. 5 weighted: ``J = sum W |log(G_data / G_model)|^2``). ``None`` = uniform,
  ``"auto"`` = coherence weights when the data carry coherence (else uniform),
  ``"coherence"`` = coherence weights (refused without coherence), or an array. The one
  coherence formula is :func:`coherence_weights`. Always a ``DataError``. These are not the
  robust half's uncertainty/performance weights, which are LTI systems; hence the name.
* :func:`match_channels` -- model signal names against data signal names (see there for the
  one policy). Always a ``DataError``.
* generic validators (:func:`finite_number`, :func:`positive_number`, :func:`integer`,
  :func:`flag`, :func:`probability`, :func:`real_array`, :func:`optional_text`): the wording is
  fixed here; the error class follows the stage that owns the argument (``DataError`` for data
  and signal settings, ``FitError`` for fit and update settings, ``ModelError`` for model
  settings, ``SynthesisError`` for synthesis and robustness analysis), given by the caller.
* systems: :func:`robustctl.lti.as_statespace` (``name=`` the argument) is the one system
  check: it names the argument and refuses what cannot be converted and NaN/inf matrices.
"""

from __future__ import annotations

import math
import numbers
import warnings
from collections.abc import Sequence
from typing import Any

import numpy as np

from .errors import DataError, RobustctlDeprecationWarning, RobustctlError

__all__ = [
    "COHERENCE_CAP",
    "check_band",
    "band_mask",
    "checked_band_mask",
    "band_data",
    "coherence_weights",
    "neighbour_coherence",
    "point_weights",
    "match_channels",
    "is_default_names",
    "is_real_number",
    "is_whole_number",
    "finite_number",
    "positive_number",
    "integer",
    "flag",
    "probability",
    "choice",
    "check_seed",
    "real_array",
    "optional_text",
    "renamed_keyword",
    "UNSET",
    "user_stacklevel",
]

#: Coherence above this counts as this in :func:`coherence_weights` (a floor on the error
#: variance: no data point is trusted more than ``0.999 / 0.001 = 999`` times a coherence-0.5 one).
COHERENCE_CAP = 0.999

#: bins next to each bin left out of its neighbour coherence (:func:`neighbour_coherence`):
#: the H1 errors of bins one apart are correlated (0.39 for a Hamming window), two apart hardly
#: (0.018; :func:`robustctl.measure.estimator.bin_correlation`)
NEIGHBOUR_SKIP = 1
#: bins averaged on each side beyond them (so bins 2 and 3 away: local next to a resonance)
NEIGHBOUR_HALF = 2


# ---------------------------------------------------------------------------- numbers
def is_real_number(value: Any) -> bool:
    """True for a real number (Python or numpy int/float), False for bools, strings and arrays."""
    return isinstance(value, (numbers.Real, np.floating, np.integer)) and not isinstance(
        value, (bool, np.bool_)
    )


def is_whole_number(value: Any) -> bool:
    """True for an integer or an integral real number (``2``, ``np.int64(2)``, ``2.0``); False for
    booleans, strings, fractions, NaN and inf."""
    return is_real_number(value) and math.isfinite(float(value)) and float(value) == int(value)


def finite_number(value: Any, name: str, error: type[RobustctlError] = DataError) -> float:
    """``value`` as a float; refuses non-numbers, booleans, NaN and inf."""
    if not is_real_number(value) or not np.isfinite(float(value)):
        raise error(f"{name} must be a finite real number; got {value!r}.")
    return float(value)


def positive_number(
    value: Any,
    name: str,
    error: type[RobustctlError] = DataError,
    *,
    allow_zero: bool = False,
    unit: str = "",
) -> float:
    """``value`` as a float ``> 0`` (``>= 0`` with ``allow_zero``), finite."""
    what = "non-negative" if allow_zero else "positive"
    unit = f" ({unit})" if unit else ""
    if not is_real_number(value) or not np.isfinite(float(value)):
        raise error(f"{name} must be {what} and finite{unit}; got {value!r}.")
    v = float(value)
    if v < 0 or (v == 0 and not allow_zero):
        raise error(f"{name} must be {what} and finite{unit}; got {value!r}.")
    return v


def integer(
    value: Any,
    name: str,
    error: type[RobustctlError] = DataError,
    *,
    lo: int | None = None,
    hi: int | None = None,
    alternative: str = "",
) -> int:
    """``value`` as an int in ``[lo, hi]`` (either end open when None); refuses bools and floats.

    ``alternative`` names what else the argument accepts (e.g. ``"None for automatic"``); the
    error then says ``(or ...)`` after the range.
    """
    ok = isinstance(value, (int, np.integer)) and not isinstance(value, (bool, np.bool_))
    if ok and (lo is None or value >= lo) and (hi is None or value <= hi):
        return int(value)
    if lo is not None and hi is not None:
        rng = f"in [{lo}, {hi}]"
    elif lo is not None:
        rng = f">= {lo}"
    elif hi is not None:
        rng = f"<= {hi}"
    else:
        rng = "(any)"
    alt = f" (or {alternative})" if alternative else ""
    raise error(f"{name} must be an integer {rng}{alt}; got {value!r}.")


def flag(value: Any, name: str, error: type[RobustctlError] = DataError) -> bool:
    """A real boolean (``True``/``False``, numpy bools included); refuses strings and numbers
    (``overwrite="False"`` would otherwise be truthy)."""
    if isinstance(value, (bool, np.bool_)):
        return bool(value)
    raise error(f"{name} must be True or False; got {value!r}.")


def choice(value: Any, name: str, options: tuple[str, ...], error: type[RobustctlError] = DataError) -> str:
    """One of ``options`` (case-insensitive), lower case; anything else raises ``error``."""
    if not isinstance(value, str) or value.lower() not in options:
        raise error(f"{name} must be one of {', '.join(map(repr, options))}; got {value!r}.")
    return value.lower()


def probability(value: Any, name: str, error: type[RobustctlError] = DataError) -> float:
    """A finite number in [0, 1]."""
    if not is_real_number(value) or not 0.0 <= float(value) <= 1.0:
        raise error(f"{name} must be a number in [0, 1]; got {value!r}.")
    return float(value)


def real_array(value: Any, name: str, error: type[RobustctlError] = DataError) -> np.ndarray:
    """``value`` as a float ndarray; refuses None, text, objects, complex and ragged lists.

    NaN and inf pass (the caller says what is allowed and names the point).
    """
    try:
        complex_given = np.iscomplexobj(value)
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        complex_given, arr = False, None
    if arr is None or complex_given or value is None or isinstance(value, (str, bytes)):
        raise error(f"{name} must be an array of real numbers; got {_short(value)}.")
    return arr


def optional_text(value: Any, name: str, error: type[RobustctlError] = DataError) -> str | None:
    """``value`` as a str without NUL characters, or None."""
    if value is None or (isinstance(value, str) and "\x00" not in value):
        return value
    raise error(f"{name} must be a str (or None); got {value!r}.")


def _short(value: Any) -> str:
    text = repr(value)
    return text if len(text) <= 80 else text[:77] + "..."


def check_seed(seed: Any, name: str = "seed", error: type[RobustctlError] = DataError) -> Any:
    """A seed ``numpy.random.default_rng`` accepts: None, an int >= 0, a SeedSequence or a
    Generator (returned unchanged); refuses negatives, floats, strings and bools."""
    if seed is None or isinstance(
        seed, (np.random.Generator, np.random.SeedSequence, np.random.BitGenerator)
    ):
        return seed
    return integer(seed, name, error, lo=0)


class _Unset:
    """The default of a deprecated keyword: tells "not given" apart from an explicit None."""

    def __repr__(self) -> str:
        return "<not given>"

    def __reduce__(self):
        return "UNSET"


#: Default of deprecated keywords (``weights=``, ``update_params=``).
UNSET: Any = _Unset()


def renamed_keyword(new: Any, old: Any, new_name: str, old_name: str, default: Any = None) -> Any:
    """Resolve a renamed keyword: ``old`` (deprecated, warns) or ``new``; refuses both at once.

    ``old`` is :data:`UNSET` when not given.
    """
    if old is UNSET:
        return new
    if new is not default and not (isinstance(new, str) and isinstance(default, str) and new == default):
        raise DataError(f"give {new_name}= only; {old_name}= is its deprecated old name.")
    what = " (data-point weights on the squared log error)" if new_name == "point_weights" else ""
    warnings.warn(
        f"{old_name}= is deprecated; call it {new_name}={what}.",
        RobustctlDeprecationWarning,
        stacklevel=user_stacklevel(),
    )
    return old


def user_stacklevel() -> int:
    """The ``stacklevel`` of ``warnings.warn`` that points at the first caller outside robustctl."""
    import os
    import sys

    package = os.path.dirname(os.path.abspath(__file__))
    frame, level = sys._getframe(1), 1
    while frame is not None and os.path.abspath(frame.f_code.co_filename).startswith(package):
        frame, level = frame.f_back, level + 1
    return level


# ---------------------------------------------------------------------------- band
def check_band(band: Any, name: str = "band") -> tuple[float, float] | None:
    """The band ``(f_lo_hz, f_hi_hz)`` as two floats, or None for the whole data.

    Raises
    ------
    DataError
        Not a pair of real numbers, not finite, ``f_lo >= f_hi`` or ``f_lo < 0``.
    """
    if band is None:
        return None
    try:
        items = list(band)
    except TypeError:
        items = []
    if isinstance(band, (str, bytes)) or len(items) != 2 or not all(is_real_number(b) for b in items):
        raise DataError(
            f"{name} must be a pair (f_lo_hz, f_hi_hz) of finite frequencies in Hz; got {band!r}."
        )
    lo, hi = float(items[0]), float(items[1])
    if not (np.isfinite(lo) and np.isfinite(hi)) or not lo < hi:
        raise DataError(
            f"{name} ({lo:g}, {hi:g}) Hz is empty or not finite; give finite f_lo_hz < f_hi_hz in Hz."
        )
    if lo < 0:
        raise DataError(
            f"{name} ({lo:g}, {hi:g}) Hz starts below 0 Hz: frequency responses are one-sided here, so "
            f"a negative edge selects nothing more than 0 Hz would; give 0 <= f_lo_hz < f_hi_hz in Hz."
        )
    return lo, hi


def band_mask(f_hz: np.ndarray, band: Any, name: str = "band") -> np.ndarray:
    """Boolean mask of ``lo <= f <= hi`` over ``f_hz``; refuses a band holding no point."""
    return checked_band_mask(f_hz, check_band(band, name), name)


def checked_band_mask(f_hz: np.ndarray, band: tuple[float, float] | None, name: str = "band") -> np.ndarray:
    """:func:`band_mask` of a band :func:`check_band` has already checked (not checked again).

    Parameters
    ----------
    f_hz : ndarray (n_freq,)
        The data's frequencies, Hz.
    band : (float, float) or None
        What :func:`check_band` returned; None: every point.
    name : str
        The argument's name in the message.

    Returns
    -------
    ndarray of bool, shape (n_freq,)

    Raises
    ------
    DataError
        The band holds no data point.
    """
    f = np.asarray(f_hz, dtype=float)
    if band is None:
        return np.ones(f.size, dtype=bool)
    lo, hi = band
    mask = (f >= lo) & (f <= hi)
    if not np.any(mask):
        raise DataError(
            f"{name} ({lo:g}, {hi:g}) Hz holds 0 data points; the data span {f[0]:g}-{f[-1]:g} Hz. "
            "Choose a band that overlaps the measured range."
        )
    return mask


def band_data(data: Any, band: Any, name: str = "band", mask: np.ndarray | None = None):
    """``data`` (a FrequencyData) restricted to the band (itself when every point is in it).

    ``mask``: the band's :func:`band_mask` when the caller has it already (``band`` is then
    not checked again). The banded data are not validated again (``FrequencyData.points``)."""
    if mask is None:
        mask = band_mask(data.f_hz, band, name)
    if np.all(mask):
        return data
    return data.points(mask)


# ---------------------------------------------------------------------------- point weights
def neighbour_coherence(
    coherence: np.ndarray, skip: int = NEIGHBOUR_SKIP, half: int = NEIGHBOUR_HALF
) -> np.ndarray:
    """The coherence at each bin from its neighbours alone: the mean over bins ``skip + 1`` to
    ``skip + half`` away on either side (fewer at the ends), the bin itself and its ``skip``
    correlated neighbours left out.

    A bin's estimated coherence is correlated with its own estimation error: where the noise
    happens to add in phase with the response, ``|G_yu|`` and hence ``g2`` come out larger
    (``g2 / (1 - g2) = |H1|^2 G_uu / G_nn`` with the residual spectrum ``G_nn`` independent of
    ``H1``, so ``ln(g2 / (1 - g2))`` carries ``2 Re`` of the bin's own log error). Anything chosen
    or weighted on a bin's own coherence therefore favours the bins whose ``ln |H1|`` came out
    high. The neighbours' coherence carries the same information about the true coherence (a
    smooth function of frequency) without that correlation (Hamming windows: bin correlation
    0.39 at one bin, 0.018 at two, :func:`robustctl.measure.estimator.bin_correlation`). Used by the
    noise model's choice of the bins to test (:func:`robustctl.measure.noise.noise_model`).

    Parameters
    ----------
    coherence : ndarray (nf, ...)
        Ordinary (or multiple) coherence along axis 0 (frequency), dimensionless.
    skip, half : int
        Bins left out next to each bin, and bins averaged on each side beyond them.

    Returns
    -------
    ndarray, same shape
    """
    g2 = np.asarray(coherence, dtype=float)
    n = g2.shape[0]
    acc, cnt = np.zeros_like(g2), np.zeros((n,) + (1,) * (g2.ndim - 1))
    for lag in range(skip + 1, skip + half + 1):
        if lag >= n:
            break
        acc[lag:] += g2[:-lag]
        cnt[lag:] += 1
        acc[:-lag] += g2[lag:]
        cnt[:-lag] += 1
    return np.where(cnt > 0, acc / np.maximum(cnt, 1), g2)


def coherence_weights(coherence: np.ndarray, amplitude: bool = False) -> np.ndarray:
    """The one coherence weighting: ``W = g2 / (1 - g2)`` normalised to ``mean(W) = 1``.

    The variance of ``ln H1`` of an H1 (Welch) estimate is ``(1 - g2) / (2 n_d g2)`` in its real
    and in its imaginary part (Bendat & Piersol, *Random Data*, 4th ed., sec. 9.2.3, Table 9.6;
    Pintelon & Schoukens), so ``W`` weights each squared log error by its inverse variance.
    ``g2`` is clipped at :data:`COHERENCE_CAP`. The normalisation keeps the cost in units of an
    unweighted cost per point. With ``amplitude`` the square root ``sqrt(W)`` is returned (the
    factor on the complex error in a residual vector), computed as ``s / rms(s)``,
    ``s = sqrt(g2 / (1 - g2))``.

    Each bin's *own* estimated coherence is correlated with that bin's log error
    (``g2 / (1 - g2) = |H1|^2 G_uu / G_nn``, the residual spectrum ``G_nn`` independent of
    ``H1``, so ``W`` carries a factor ``|1 + eps|^2`` of the bin's own relative error ``eps``):
    a least-squares fit with these weights sees ``Re ln H1`` as raised (by about one standard
    error in E and the masses of the true Caltech truss over 10 seeds). Every complex-log
    residual weighted by ``W`` therefore subtracts :func:`coherence_weight_bias` from its real
    part (:func:`point_weight_bias` says where it applies), which removes that bias exactly for
    Gaussian errors. The neighbours' coherence (:func:`neighbour_coherence`) would avoid the
    correlation but not as weights on lightly damped data: the Caltech resonances are 0.7-1.6
    bins wide and the coherence dips at the peaks, so the neighbours' mean mis-weights peak
    and flank bins by up to 6-8x and the standard errors grew 1.3-1.9x.

    Raises
    ------
    DataError
        The coherence is zero everywhere.
    """
    g2 = np.clip(np.asarray(coherence, dtype=float), 0.0, COHERENCE_CAP)
    s = np.sqrt(g2 / (1.0 - g2))
    ms = float(np.mean(s**2)) if s.size else 0.0
    if not ms > 0:
        raise DataError(
            "the coherence is zero at every point in the band, so coherence weights are all zero; "
            "pass point_weights=None (uniform)."
        )
    s = s / np.sqrt(ms)
    return s if amplitude else s**2


def point_weights(
    spec: Any, data: Any, mask: np.ndarray | None = None, name: str = "point_weights", amplitude: bool = False
) -> np.ndarray:
    """Data-point weights ``W`` on the squared complex-log error, shape of the banded data.

    Parameters
    ----------
    spec : None, "auto", "coherence" or array_like
        ``None``: uniform (``W = 1``). ``"auto"``: :func:`coherence_weights` when ``data``
        carries coherence, else uniform. ``"coherence"``: coherence weights, refused when the
        data carry none. An array: ``W`` itself, broadcast to ``(n_freq, n_out, n_in)``; a
        1-D array of length ``n_freq`` weights frequencies. With ``mask``, an array may be
        given on the banded points or on the full grid of ``data``.
    data : FrequencyData
        The full data (``mask`` selects the band) or the banded data (``mask`` None).
    mask : ndarray of bool, optional
        Band mask over ``data.f_hz``.
    amplitude : bool
        Return ``sqrt(W)`` (the factor on the complex error of a residual vector) instead.

    Returns
    -------
    ndarray, shape (n_band, n_out, n_in)
        Finite, non-negative, with at least one positive entry.
    """
    mask = np.ones(data.n_freq, dtype=bool) if mask is None else np.asarray(mask, dtype=bool)
    shape = (int(mask.sum()),) + tuple(data.shape[1:])
    if isinstance(spec, str):
        if spec not in ("auto", "coherence"):
            raise DataError(
                f"{name} must be None, 'auto', 'coherence' or an array of weights on the squared log "
                f"error; got {spec!r}."
            )
        if data.coherence is None:
            if spec == "coherence":
                raise DataError(
                    f"{name}='coherence' but the data carry no coherence; estimate the FRF with "
                    f"rc.estimate_frf (which returns coherence) or pass {name}=None."
                )
            return np.ones(shape)
        return coherence_weights(data.coherence[mask], amplitude=amplitude)
    if spec is None:
        return np.ones(shape)
    w = _array_weights(spec, data.n_freq, mask, shape, name)
    return np.sqrt(w) if amplitude else w


def _array_weights(spec: Any, n_full: int, mask: np.ndarray, shape: tuple, name: str) -> np.ndarray:
    try:
        w = np.asarray(spec, dtype=float)
    except (TypeError, ValueError):
        w = np.full(1, np.nan)
    if w.ndim >= 1 and w.shape[0] == n_full != shape[0]:
        w = w[mask]
    if w.ndim == 1 and w.size == shape[0]:
        w = w[:, None, None]
    try:
        w = np.array(np.broadcast_to(w, shape), dtype=float)
    except ValueError:
        raise DataError(
            f"{name} of shape {np.shape(spec)} do not fit the banded data of shape {shape} "
            "(n_freq, n_out, n_in); give one weight per frequency (n_freq,) or per entry."
        ) from None
    if not np.all(np.isfinite(w)) or np.any(w < 0) or not np.any(w > 0):
        raise DataError(
            f"{name} must be finite and non-negative with at least one positive weight in the band; "
            "remove NaN/inf or negative weights."
        )
    return w


# ---------------------------------------------------------------------------- channel names
def is_default_names(names: Sequence[str], prefix: str) -> bool:
    """True for python-control's default names ``u[0], u[1], ...`` (prefix ``"u"``) or
    ``y[0], y[1], ...`` (prefix ``"y"``): signals nobody named."""
    names = tuple(names)
    return names == tuple(f"{prefix}[{k}]" for k in range(len(names)))


def match_channels(
    model_names: Sequence[str],
    data_names: Sequence[str],
    what: str,
    sides: tuple[str, str] = ("model", "data"),
) -> list[int]:
    """Index of each data channel among the model's channels: the one matching policy.

    1. The counts must agree.
    2. The same names (in any order) match by name: the model is reordered to the data's order.
    3. Otherwise, when either side carries python-control's default names (``u[0], u[1], ...``
       or ``y[0], y[1], ...``: a system nobody named), they match by position.
    4. Anything else is refused. (FrequencyData's own defaults ``u1``/``y1`` are names: data
       built without names must be named, or the model renamed, to match a named model.)

    Parameters
    ----------
    model_names, data_names : sequence of str
    what : {"inputs", "outputs"}
    sides : (str, str)
        What the two sides are called in the message (default ``("model", "data")``).

    Raises
    ------
    DataError
        Counts or names that do not match; the message says how to rename.
    """
    model_names, data_names = [str(n) for n in model_names], [str(n) for n in data_names]
    a, b = sides
    if len(model_names) != len(data_names):
        if set(data_names) < set(model_names):
            fix = f"select the {a}'s matching {what} with {a}.select({what}={data_names!r})"
        elif set(model_names) < set(data_names):
            fix = f"select the {b}'s matching {what} with {b}.select({what}={model_names!r})"
        else:
            fix = f"select matching channels with {a}.select(...) or {b}.select(...)"
        raise DataError(
            f"the {a} has {len(model_names)} {what} {model_names} but the {b} has "
            f"{len(data_names)} {data_names}; {fix}."
        )
    if set(model_names) == set(data_names) and len(set(model_names)) == len(model_names):
        return [model_names.index(n) for n in data_names]
    prefix = "u" if what == "inputs" else "y"
    if is_default_names(model_names, prefix) or is_default_names(data_names, prefix):
        return list(range(len(data_names)))
    raise DataError(
        f"the {a}'s {what} {model_names} do not match the {b}'s {data_names}; rename the model's "
        f"signals (rc.as_statespace(sys, {what}=[...])) or the data's (data.replace({what}=[...]))."
    )
