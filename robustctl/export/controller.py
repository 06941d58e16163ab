"""Write a discretised, checked controller to a coefficient file, and read it back."""

from __future__ import annotations

import datetime
import warnings
from os import PathLike
from pathlib import Path
from typing import Any

import control
import numpy as np

from .._version import __version__
from ..errors import DataError, ModelError, RobustctlWarning
from ..frd_io._common import jsonable as _jsonable
from ..frd_io._common import write_atomically
from . import files, formats
from .arguments import choice, flag, is_discrete, positive, unwrap
from .c_header import c_prefix
from .realization import (
    balance_diagonal,
    balance_gramian,
    dynamic_range,
    select_channel,
    sos_sections,
    spectral_radius,
)
from .report import ExportReport
from .sampling import METHODS, discretization_error, discretize, peak_gain_hz

__all__ = ["export_controller", "load_controller"]

#: relative discretisation error at the crossover above which export_controller warns
ERROR_WARN = 0.1
#: stability margin: |z| of the largest discrete pole must stay below this
MAX_SPECTRAL_RADIUS = 1.0
#: relative response deviation of second-order sections above which export_controller warns
SOS_WARN = 1e-6
_BALANCE = ("diagonal", "balanced")


class ExportWarning(RobustctlWarning, RuntimeWarning):
    """The exported controller differs from ``K`` beyond a tolerance (discretisation error above
    :data:`ERROR_WARN`, second-order sections above :data:`SOS_WARN`) or is unstable with
    ``on_unstable="warn"``: the file is written and the caveat is shown."""


def _format(path: Path, format: str | None) -> str:
    """The format named by ``format``, else by the file's extension."""
    if format is not None:
        return choice(format, "format", formats.FORMATS)
    suffix = path.suffix.lower()
    if suffix[1:] not in formats.FORMATS:
        raise DataError(
            f"cannot tell the format of path {path.name!r} from its extension; use one of "
            f"{', '.join('.' + f for f in formats.FORMATS)} or pass format= (one of {formats.FORMATS})."
        )
    return suffix[1:]


def _provenance(user: Any) -> dict:
    if user is not None and not isinstance(user, dict):
        raise DataError(f"provenance must be a dict of JSON-able values; got {type(user).__name__}.")
    prov = {
        "software": f"robustctl {__version__}",
        "date_utc": datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds"),
    }
    user = _jsonable(user or {})
    if not _finite_json(user):
        raise DataError("provenance holds NaN or inf, which JSON cannot store; give finite numbers or text.")
    return {**prov, **user}


def _finite_json(value: Any) -> bool:
    """True when no float in a JSON-able tree is NaN or inf."""
    if isinstance(value, dict):
        return all(_finite_json(v) for v in value.values())
    if isinstance(value, list):
        return all(_finite_json(v) for v in value)
    return not isinstance(value, float) or bool(np.isfinite(value))


def export_controller(
    K: Any,
    path: str | PathLike,
    fs: float | None = None,
    format: str | None = None,
    *,
    method: str = "tustin",
    prewarp_hz: float | None = None,
    overwrite: bool = False,
    provenance: dict | None = None,
    crossover_hz: float | None = None,
    balance: bool | str = False,
    on_unstable: str = "warn",
    units: dict | None = None,
    channel: tuple | None = None,
    prefix: str | None = None,
) -> ExportReport:
    """Discretise ``K``, check it, and write it as a coefficient file.

    Parameters
    ----------
    K : control.StateSpace, a synthesis result with ``.K`` (its ``gamma`` / ``mu_peak`` are
        recorded), or anything :func:`robustctl.lti.as_statespace` accepts
        Continuous (discretised with ``fs``, ``method``, ``prewarp_hz``) or already discrete.
    path : str or path-like
        Output file; an existing file is never replaced unless ``overwrite=True``. Written to a
        temporary file in the same folder and moved into place (no partial files).
    fs : float, optional
        Sample rate in Hz (required for a continuous K).
    format : {"json", "csv", "h", "mat", "sos"}, optional
        Default: from the extension (pass the same ``format`` to :func:`load_controller` for a
        file named otherwise, e.g. ``coeffs.txt`` with ``format="sos"``).

        * ``json``: matrices, ``fs``, names, units, method, design figures, checks, provenance;
        * ``csv``: one coefficient per line (layout in the file's comment header);
        * ``h``: C header with double and float arrays, size macros and an inline step function;
        * ``mat``: MATLAB ``A, B, C, D, Ts, InputName, OutputName`` (``ss(A,B,C,D,Ts)``);
        * ``sos``: second-order sections (scipy.signal layout) of one SISO channel.
    method, prewarp_hz
        See :func:`discretize`.
    overwrite : bool
        Replace an existing file.
    provenance : dict, optional
        Your information (project, plant version, author...), stored with ``software`` and
        ``date_utc``.
    crossover_hz : float, optional
        Where to evaluate the discretisation error (Hz, below fs/2). Default: the frequency of
        the controller's largest gain. A relative error above 10 % warns.
    balance : bool or {"diagonal", "balanced"}
        Rescale the states before writing (the transfer function is unchanged). ``True`` or
        ``"diagonal"``: an exact power-of-two diagonal similarity equalising the row/column
        norms of ``[[A, B], [C, 0]]``; ``"balanced"``: the balanced realisation (equal diagonal
        discrete Gramians; stable and minimal K only). Both reported as coefficient dynamic range.
    on_unstable : {"warn", "raise", "ignore"}
        What to do when a discrete pole has ``|z| >= 1`` (an integrator or an unstable design).
    units : dict, optional
        Signal name -> unit (e.g. ``{"accel_1": "m/s^2", "force_1": "N"}``).
    channel : (output, input), optional
        SOS only: the channel of a MIMO controller to export (names or indices).
    prefix : str, optional
        C header only: prefix of the macros and arrays (default: the file stem, upper case).

    Returns
    -------
    ExportReport

    Raises
    ------
    DataError
        Bad argument, existing file, MIMO controller for ``sos`` without ``channel``.
    ModelError
        Unstable discrete controller with ``on_unstable="raise"``; Tustin singular.
    """
    path = _as_path(path)
    fmt = _format(path, format)
    overwrite = flag(overwrite, "overwrite")
    on_unstable = choice(on_unstable, "on_unstable", ("warn", "raise", "ignore"))
    method = choice(method, "method", METHODS)
    balance = _balance_choice(balance)
    _format_options(fmt, channel, prefix)
    ss, design = unwrap(K)
    was_continuous = not is_discrete(ss)
    Kd = discretize(ss, fs, method, prewarp_hz)
    units = _units(units, Kd)
    if fmt == "sos":
        o, i = select_channel(Kd, channel)
        ss, Kd = ss[o, i], Kd[o, i]
        units = {k: v for k, v in units.items() if k in (Kd.input_labels[0], Kd.output_labels[0])}
    rho = spectral_radius(np.asarray(Kd.A, dtype=float))
    _stability(rho, on_unstable)
    f_err, err = _error_check(ss, Kd, crossover_hz, was_continuous, method)
    mats = [np.asarray(m, dtype=float) for m in (Kd.A, Kd.B, Kd.C, Kd.D)]
    if balance is not None:
        mats = [*(balance_diagonal if balance == "diagonal" else balance_gramian)(*mats[:3]), mats[3]]
    sos, sos_err = sos_sections(_with(Kd, mats)) if fmt == "sos" else (None, None)
    if sos_err is not None and sos_err > SOS_WARN:
        warnings.warn(
            f"the second-order sections deviate from the controller by {sos_err:.3g} (relative to its peak "
            "gain); prefer the state-space formats (json, h, mat) for this channel.",
            ExportWarning,
            stacklevel=2,
        )
    _finite_range(Kd, mats)
    checks = {
        "spectral_radius": rho,
        "stable": rho < MAX_SPECTRAL_RADIUS,
        "error_at_hz": f_err,
        "relative_discretization_error": err,
        "dynamic_range": dynamic_range(Kd.A, Kd.B, Kd.C, Kd.D),
        "balance": balance,
        "dynamic_range_balanced": dynamic_range(*mats) if balance else None,
        "sos_max_relative_error": sos_err,
    }
    discretization = {"method": method, "prewarp_hz": prewarp_hz} if was_continuous else {}
    meta = {
        "discretization": {"method": None, "prewarp_hz": None, **discretization},
        "design": design,
        "checks": checks,
        "provenance": _provenance(provenance),
    }
    names = (tuple(Kd.input_labels), tuple(Kd.output_labels), tuple(Kd.state_labels))
    ctrl = files.ControllerData(*mats, Kd.dt, *names, units=units, meta=_jsonable(meta))
    writer = formats.WRITERS["." + fmt]
    prefix = c_prefix(path, prefix) if fmt == "h" else None  # from the final name, not the temp file
    write_atomically(path, lambda tmp: writer(ctrl, tmp, prefix=prefix, sos=sos), overwrite)
    return ExportReport(
        path=path,
        format=fmt,
        fs_hz=1.0 / Kd.dt,
        method=meta["discretization"]["method"],
        prewarp_hz=meta["discretization"]["prewarp_hz"],
        n_states=mats[0].shape[0],
        n_inputs=mats[3].shape[1],
        n_outputs=mats[3].shape[0],
        spectral_radius=rho,
        stable=checks["stable"],
        crossover_hz=f_err,
        discretization_error=err,
        dynamic_range=checks["dynamic_range"],
        dynamic_range_balanced=checks["dynamic_range_balanced"],
        balance=balance,
        sos_error=sos_err,
        channel=(Kd.output_labels[0], Kd.input_labels[0]) if fmt == "sos" else None,
        gamma=design.get("gamma"),
        mu=design.get("mu"),
        controller=ctrl.statespace(),
    )


def _finite_range(Kd: Any, mats: list[np.ndarray]) -> None:
    """Refuse coefficients whose largest-to-smallest ratio overflows float64 (e.g. a 1e-310 entry):
    no file could state their dynamic range, and no real-time computer could use the smallest."""
    values = np.abs(np.concatenate([np.asarray(m, float).ravel() for m in (Kd.A, Kd.B, Kd.C, Kd.D, *mats)]))
    values = values[values > 0]
    if values.size and not np.isfinite(dynamic_range(values)):
        raise ModelError(
            f"the controller's coefficients span {values.min():.3g} to {values.max():.3g}, more than the "
            "float64 range; the smallest are numerical noise: set them to zero (or rescale the signals) "
            "before exporting."
        )


def _format_options(fmt: str, channel: Any, prefix: Any) -> None:
    if channel is not None and fmt != "sos":
        raise DataError(f"channel applies to format 'sos' only; got format {fmt!r}.")
    if prefix is not None and fmt != "h":
        raise DataError(f"prefix applies to format 'h' (C header) only; got format {fmt!r}.")


def _units(units: Any, Kd: Any) -> dict[str, str]:
    """``units`` checked against the controller's signal names (those of the exported channel kept)."""
    if units is None:
        return {}
    if not isinstance(units, dict) or not all(isinstance(v, str) for v in units.values()):
        raise DataError(f"units must be a dict mapping signal names to unit strings; got {units!r}.")
    signals = [*Kd.input_labels, *Kd.output_labels]
    unknown = [k for k in units if k not in signals]
    if unknown:
        raise DataError(
            f"units name(s) {unknown!r} are not signals of the controller (inputs "
            f"{list(Kd.input_labels)}, outputs {list(Kd.output_labels)}); fix the names."
        )
    return {str(k): v for k, v in units.items()}


def _as_path(path: Any) -> Path:
    try:
        path = Path(path)
    except TypeError:
        raise DataError(f"path must be a file name (str or path-like); got {type(path).__name__}.") from None
    if "\x00" in str(path):
        raise DataError(f"path must not contain NUL characters; got {str(path)!r}.")
    return path


def _balance_choice(balance: Any) -> str | None:
    if isinstance(balance, (bool, np.bool_)):
        return "diagonal" if balance else None
    return choice(balance, "balance", _BALANCE)


def _stability(rho: float, on_unstable: str) -> None:
    if rho < MAX_SPECTRAL_RADIUS or on_unstable == "ignore":
        return
    msg = (
        f"the discrete controller has a pole with |z| = {rho:.6g} >= 1 (not asymptotically stable); "
        "check the design, or pass on_unstable='ignore' if that is intended (e.g. an integrator)."
    )
    if on_unstable == "raise":
        raise ModelError(msg)
    warnings.warn(msg, ExportWarning, stacklevel=3)


def _error_check(K, Kd, crossover_hz: Any, was_continuous: bool, method: str):
    fs_hz = 1.0 / Kd.dt
    if crossover_hz is not None:
        crossover_hz = positive(crossover_hz, "crossover_hz", "Give the loop's crossover in Hz.")
        if crossover_hz >= fs_hz / 2:
            raise DataError(
                f"crossover_hz = {crossover_hz:g} Hz must lie below the Nyquist frequency "
                f"{fs_hz / 2:g} Hz; raise fs."
            )
    if not was_continuous:
        return crossover_hz, None
    f = crossover_hz if crossover_hz is not None else peak_gain_hz(K, fs_hz)
    err = discretization_error(K, Kd, f)
    if err > ERROR_WARN:
        fix = (
            "raise fs or prewarp there (prewarp_hz=)"
            if method == "tustin"
            else "raise fs or use method='tustin'"
        )
        warnings.warn(
            f"the discretised controller differs from K by {100 * err:.3g} % at {f:.4g} Hz; {fix}.",
            ExportWarning,
            stacklevel=3,
        )
    return f, err


def _with(Kd: Any, mats: list[np.ndarray]):
    return control.ss(*mats, Kd.dt, inputs=list(Kd.input_labels), outputs=list(Kd.output_labels))


def load_controller(path: str | PathLike, format: str | None = None):
    """Read a controller written by :func:`export_controller` (or a user's ``.mat`` with A, B, C, D, Ts).

    Parameters
    ----------
    path : str or path-like
        ``.json``, ``.csv``, ``.mat``, ``.h`` (the header layout written by
        :func:`export_controller`) or ``.sos`` (returned as a cascade realisation of the sections).
    format : {"json", "csv", "h", "mat", "sos"}, optional
        For a file whose extension does not say (default: from the extension).

    Returns
    -------
    control.StateSpace
        Discrete with ``dt = 1/fs`` (continuous, dt = 0, when a ``.mat``/``.json`` says Ts = 0),
        with the stored signal names.

    Raises
    ------
    DataError
        Missing file, unknown extension, or content that is corrupt or inconsistent (the
        message names the field).
    """
    path = _as_path(path)
    reader = formats.READERS["." + _format(path, format)]
    if not path.is_file():
        raise DataError(f"cannot load {str(path)!r}: no such file.")
    try:
        return reader(path).statespace()
    except DataError as exc:
        raise DataError(f"{path.name}: {exc}") from exc
