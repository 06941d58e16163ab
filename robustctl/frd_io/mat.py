"""FrequencyData in MATLAB ``.mat`` files (the layout of MATLAB's ``frd``: Frequency, ResponseData)."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import DataError
from ..frd import FrequencyData
from ._common import FORMAT, build, json_dumps, json_loads

__all__ = ["read_mat", "write_mat"]

def _cell(names: Sequence[str]) -> np.ndarray:
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
        "InputName": _cell(data.inputs),
        "OutputName": _cell(data.outputs),
        "robustctl_format": FORMAT,
        "robustctl_units": json_dumps(data.units),
        "robustctl_meta": json_dumps(data.meta),
    }
    if data.coherence is not None:
        mdict["Coherence"] = np.transpose(data.coherence, (1, 2, 0))
    with open(path, "wb") as fh:
        savemat(fh, mdict, do_compression=True)


def _mat_string(value: Any) -> str:
    arr = np.asarray(value)
    while arr.dtype == object and arr.size == 1:
        arr = np.asarray(arr.reshape(-1)[0])
    if arr.size == 0:
        return ""
    if arr.dtype.kind != "U":
        raise DataError(f"expected text in the MAT file, got an array of dtype {arr.dtype}.")
    return "".join(str(x) for x in arr.reshape(-1))


def _mat_names(mdict: dict, key: str) -> list[str] | None:
    if key not in mdict:
        return None
    cell = np.asarray(mdict[key])
    if cell.dtype.kind == "U":  # a char matrix: one name per row
        return [str(x).rstrip() for x in cell.reshape(-1)]
    if cell.dtype != object:
        raise DataError(f"{key} must be a cell array of names; got an array of dtype {cell.dtype}.")
    return [_mat_string(c) for c in cell.reshape(-1, order="F")]


def _mat_array(mdict: dict, key: str, shape: tuple[int, ...]) -> np.ndarray:
    arr = np.asarray(mdict[key])
    if arr.dtype.kind not in "fciu":
        raise DataError(f"{key} must be numeric; got an array of dtype {arr.dtype}.")
    if arr.size != int(np.prod(shape)):
        raise DataError(
            f"{key} holds {arr.size} values but the names and frequencies need shape {shape} "
            "(n_out x n_in x n_freq)."
        )
    return arr.reshape(shape, order="F")


def read_mat(path: Path) -> FrequencyData:
    from scipy.io import loadmat

    try:
        mdict = loadmat(path, squeeze_me=False, chars_as_strings=True)
    except Exception as exc:  # scipy raises ValueError, TypeError, MatReadError, ...
        raise DataError(f"not a readable MAT file ({type(exc).__name__}: {exc}).") from None
    for key in ("Frequency", "ResponseData"):
        if key not in mdict:
            raise DataError(f"the MAT file has no {key!r} variable (expected Frequency, ResponseData).")
    f = np.asarray(mdict["Frequency"])
    if f.dtype.kind not in "fiu":
        raise DataError(f"Frequency must be real numbers; got dtype {f.dtype}.")
    f = f.astype(float).reshape(-1)
    unit = _mat_string(mdict["FrequencyUnit"]).strip().lower() if "FrequencyUnit" in mdict else "rad/s"
    if unit in ("rad/s", "rad/sec", "rad/second"):
        f = f / (2.0 * np.pi)
    elif unit != "hz":
        raise DataError(f"FrequencyUnit {unit!r} is not supported; use 'Hz' or 'rad/s'.")
    g = np.asarray(mdict["ResponseData"])
    outputs, inputs = _mat_names(mdict, "OutputName"), _mat_names(mdict, "InputName")
    n_out = len(outputs) if outputs is not None else (g.shape[0] if g.ndim >= 2 else 1)
    n_in = len(inputs) if inputs is not None else (g.shape[1] if g.ndim >= 3 else 1)
    shape = (n_out, n_in, f.size)
    resp = np.transpose(_mat_array(mdict, "ResponseData", shape), (2, 0, 1))
    coh = None
    if "Coherence" in mdict:
        coh = np.transpose(_mat_array(mdict, "Coherence", shape), (2, 0, 1)).real
    units = json_loads(_mat_string(mdict["robustctl_units"]), "units") if "robustctl_units" in mdict else {}
    meta = json_loads(_mat_string(mdict["robustctl_meta"]), "meta") if "robustctl_meta" in mdict else {}
    return build(
        "MAT", f_hz=f, response=resp, inputs=inputs, outputs=outputs, coherence=coh, units=units, meta=meta
    )
