"""FrequencyData in MATLAB ``.mat`` files (the layout of MATLAB's ``frd``: Frequency, ResponseData)."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import DataError
from ..frd import FrequencyData
from ._common import FORMAT, MAX_FILE_BYTES, build, json_dumps, json_loads, read_limited
from .mat5_check import check_mat5

__all__ = ["read_mat", "write_mat"]

_CONTENTS = "robustctl_contents"
#: Plain MAT variables of the experiment description (:class:`~robustctl.frd.Experiment`), written
#: beside the complete JSON record and read when a file (e.g. MATLAB's) has only them.
_MAT_EXPERIMENT = {
    "InputKind": "input_kind", "Excitation": "excitation", "SampleRate": "fs_hz", "Window": "window",
    "NPerSeg": "nperseg", "NOverlap": "noverlap", "NAverages": "n_averages", "WholePeriods": "whole_periods",
    "HoldDivided": "hold_divided", "ExpWindowTau": "exp_window_tau_s", "ForceWindow": "force_window_s",
    "PreTrigger": "pretrigger_s",
}

def cellstr(names: Sequence[str]) -> np.ndarray:
    """Names as a MATLAB cell column (an (n, 1) object array), as ``savemat`` writes a cellstr."""
    cell = np.empty((len(names), 1), dtype=object)
    for k, name in enumerate(names):
        cell[k, 0] = name
    return cell


def write_mat(data: FrequencyData, path: Path) -> None:
    from scipy.io import savemat

    mdict = {
        "Frequency": data.f_hz[:, None],
        "FrequencyUnit": "Hz",
        "ResponseData": np.transpose(data.response, (1, 2, 0)),
        "InputName": cellstr(data.inputs),
        "OutputName": cellstr(data.outputs),
        "robustctl_format": FORMAT,
        "robustctl_units": json_dumps(data.units),
        "robustctl_meta": json_dumps(data.meta),
        "robustctl_experiment": json_dumps(data.experiment.to_dict()),
    }
    for key, name in _MAT_EXPERIMENT.items():  # plain fields a MATLAB user reads (and may write)
        value = getattr(data.experiment, name)
        if value is not None and not (name == "hold_divided" and not value) and not isinstance(value, tuple):
            mdict[key] = float(value) if isinstance(value, (bool, int, float)) else str(value)
    if data.coherence is not None:
        mdict["Coherence"] = np.transpose(data.coherence, (1, 2, 0))
    # written first: the list of every variable, so a file cut at a variable boundary is refused
    mdict = {_CONTENTS: ",".join(mdict), **mdict}
    with open(path, "wb") as fh:
        savemat(fh, mdict, do_compression=True)


def mat_string(value: Any) -> str:
    """The text of a MAT-file char array or a cell holding one (DataError for anything else)."""
    arr = np.asarray(value)
    while arr.dtype == object and arr.size == 1:
        arr = np.asarray(arr.reshape(-1)[0])
    if arr.size == 0:
        return ""
    if arr.dtype.kind != "U":
        raise DataError(f"expected text in the MAT file, got an array of dtype {arr.dtype}.")
    return "".join(str(x) for x in arr.reshape(-1))


def mat_names(mdict: dict, key: str) -> list[str] | None:
    """The names stored under ``key`` (cellstr or char matrix), or None when the key is absent."""
    if key not in mdict:
        return None
    cell = np.asarray(mdict[key])
    if cell.dtype.kind == "U":  # a char matrix: one name per row
        return [str(x).rstrip() for x in cell.reshape(-1)]
    if cell.dtype != object:
        raise DataError(f"{key} must be a cell array of names; got an array of dtype {cell.dtype}.")
    return [mat_string(c) for c in cell.reshape(-1, order="F")]


def _vector_like(arr: np.ndarray) -> bool:
    """True when at most one dimension of ``arr`` exceeds 1 (a row, a column or a 1 x 1 x N array)."""
    return sum(d > 1 for d in arr.shape) <= 1


def _mat_array(mdict: dict, key: str, shape: tuple[int, ...]) -> np.ndarray:
    """``mdict[key]`` as an array of ``shape`` (n_out, n_in, n_freq), MATLAB's ``frd`` order.

    Accepted: exactly ``shape``; ``(n_out, n_in)`` for one frequency (MATLAB drops a trailing
    singleton dimension); ``(n_out, n_freq)`` or ``(n_in, n_freq)`` when the other count is 1
    (``squeeze``); any vector of n_freq values for a SISO response. Any other layout with the
    right number of values would be read with outputs, inputs and frequencies mixed up, so it is
    refused.
    """
    arr = np.asarray(mdict[key])
    if arr.dtype.kind not in "fciu":
        raise DataError(f"{key} must be numeric; got an array of dtype {arr.dtype}.")
    n_out, n_in, n_f = shape
    layouts = {shape}
    if n_f == 1:
        layouts.add((n_out, n_in))
    if n_in == 1:
        layouts.add((n_out, n_f))
    if n_out == 1:
        layouts.add((n_in, n_f))
    if n_out == n_in == 1:
        layouts |= {(n_f,), (n_f, 1)}
    if arr.shape not in layouts:
        hint = ""
        if arr.ndim == 3 and arr.shape[0] == n_f and arr.shape[2] != n_f:
            hint = (
                " It looks like (n_freq, n_out, n_in), the Python order; store it as MATLAB's frd does "
                "(permute(ResponseData, [2 3 1]) in MATLAB, np.transpose(g, (1, 2, 0)) in Python)."
            )
        raise DataError(
            f"{key} has shape {arr.shape} but the names and frequencies need {shape} "
            f"(n_out x n_in x n_freq, as MATLAB's frd stores it); check OutputName, InputName and "
            f"Frequency against it.{hint}"
        )
    return arr.reshape(shape, order="F")


def read_mat(path: Path) -> FrequencyData:
    import io

    from scipy.io import loadmat

    raw = read_limited(path, MAX_FILE_BYTES)
    check_mat5(raw)  # scipy's reader can crash the interpreter on a corrupt file
    try:
        mdict = loadmat(io.BytesIO(raw), squeeze_me=False, chars_as_strings=True)
    except Exception as exc:  # scipy raises ValueError, TypeError, MatReadError, ...
        raise DataError(f"not a readable MAT file ({type(exc).__name__}: {exc}).") from None
    if _CONTENTS in mdict:
        missing = [k for k in mat_string(mdict[_CONTENTS]).split(",") if k and k not in mdict]
        if missing:
            raise DataError(f"the MAT file lacks {missing}, listed in its {_CONTENTS}; it is truncated.")
    for key in ("Frequency", "ResponseData"):
        if key not in mdict:
            found = sorted(k for k in mdict if not k.startswith("__"))
            raise DataError(
                f"the MAT file has no {key!r} variable; it holds {found}. Store the frequencies as "
                "'Frequency' (with 'FrequencyUnit', 'Hz' or 'rad/s') and the responses as 'ResponseData' "
                "(n_out x n_in x n_freq), as MATLAB's frd does (names are case-sensitive)."
            )
    f = np.asarray(mdict["Frequency"])
    if f.dtype.kind not in "fiu":
        raise DataError(f"Frequency must be real numbers; got dtype {f.dtype}.")
    if not _vector_like(f):
        raise DataError(
            f"Frequency must be a vector (1 x N or N x 1); got an array of shape {f.shape}."
        )
    f = f.astype(float).reshape(-1)
    unit = mat_string(mdict["FrequencyUnit"]).strip().lower() if "FrequencyUnit" in mdict else "rad/s"
    if unit in ("rad/s", "rad/sec", "rad/second"):
        f = f / (2.0 * np.pi)
    elif unit != "hz":
        raise DataError(f"FrequencyUnit {unit!r} is not supported; use 'Hz' or 'rad/s'.")
    g = np.asarray(mdict["ResponseData"])
    outputs, inputs = mat_names(mdict, "OutputName"), mat_names(mdict, "InputName")
    siso = g.size == f.size and _vector_like(g)  # a vector of one value per frequency
    n_out = len(outputs) if outputs is not None else (1 if siso or g.ndim < 2 else g.shape[0])
    n_in = len(inputs) if inputs is not None else (1 if siso or g.ndim < 3 else g.shape[1])
    shape = (n_out, n_in, f.size)
    resp = np.transpose(_mat_array(mdict, "ResponseData", shape), (2, 0, 1))
    coh = None
    if "Coherence" in mdict:
        coh = np.transpose(_mat_array(mdict, "Coherence", shape), (2, 0, 1))
        if np.iscomplexobj(coh):
            if np.any(coh.imag != 0):
                raise DataError("Coherence holds complex values; coherence is real, in [0, 1].")
            coh = coh.real
    units = json_loads(mat_string(mdict["robustctl_units"]), "units") if "robustctl_units" in mdict else {}
    meta = json_loads(mat_string(mdict["robustctl_meta"]), "meta") if "robustctl_meta" in mdict else {}
    experiment = None
    if "robustctl_experiment" in mdict:
        experiment = json_loads(mat_string(mdict["robustctl_experiment"]), "experiment")
    elif any(key in mdict for key in _MAT_EXPERIMENT):
        experiment = _plain_experiment(mdict)
    return build(
        "MAT", f_hz=f, response=resp, inputs=inputs, outputs=outputs, coherence=coh, units=units, meta=meta,
        experiment=experiment,
    )


def _plain_experiment(mdict: dict) -> dict:
    """The experiment description from the plain variables (``InputKind``, ``SampleRate`` ...)."""
    found: dict[str, Any] = {}
    for key, name in _MAT_EXPERIMENT.items():
        if key not in mdict:
            continue
        raw = np.asarray(mdict[key])
        if raw.dtype.kind in "US" or raw.dtype == object:
            found[name] = mat_string(raw).strip()
            continue
        if raw.size != 1 or raw.dtype.kind not in "fiub":
            raise DataError(f"{key} must be one number or text; got an array of shape {raw.shape}.")
        value = raw.reshape(-1)[0].item()
        if name in ("whole_periods", "hold_divided"):
            value = bool(value)
        elif name in ("nperseg", "noverlap", "n_averages"):
            if float(value) != int(value):
                raise DataError(f"{key} must be a whole number; got {value!r}.")
            value = int(value)
        found[name] = value
    return found
