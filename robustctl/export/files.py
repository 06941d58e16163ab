"""Coefficient files of a discrete controller: the shared container and the JSON, CSV and MATLAB
.mat layouts (the C header is in :mod:`.c_header`, second-order sections in :mod:`.sos_file`).

Every format holds the update equations

    x[k+1] = A x[k] + B u[k],        y[k] = C x[k] + D u[k],        t = k / fs,

with ``u`` the controller's inputs (the plant's measurements) and ``y`` its outputs (the
plant's controls). Floats are written with the shortest decimal text that reads back to the
same double (``repr``), so JSON, CSV, .mat and the double arrays of the C header reload
bit-exact. :mod:`robustctl.export.controller` discretises, checks and calls the writers
(registered in :mod:`.formats`); these modules only know the layouts.
"""

from __future__ import annotations

import csv
import io
import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import control
import numpy as np

from ..errors import DataError
from ..frd_io.mat import cellstr, mat_names, mat_string

__all__ = [
    "ControllerData",
    "from_dict",
    "header_dict",
    "csv_value",
    "read_json",
    "write_json",
    "read_csv",
    "write_csv",
    "read_mat",
    "write_mat",
]

FORMAT_TAG = "robustctl.controller"
FORMAT_VERSION = 1
EQUATIONS = "x[k+1] = A x[k] + B u[k]; y[k] = C x[k] + D u[k]"


@dataclass(frozen=True, eq=False)
class ControllerData:
    """A discrete (or, as read from a user's file, continuous) realisation and its metadata.

    ``dt`` in s (0 for continuous); names one per signal; ``units`` maps signal names to unit
    strings; ``meta`` holds discretisation, design figures, checks and provenance (JSON types).
    """

    A: np.ndarray
    B: np.ndarray
    C: np.ndarray
    D: np.ndarray
    dt: float
    inputs: tuple[str, ...]
    outputs: tuple[str, ...]
    states: tuple[str, ...]
    units: dict = field(default_factory=dict)
    meta: dict = field(default_factory=dict)

    def __post_init__(self) -> None:
        mats = [np.array(m, dtype=float) for m in (self.A, self.B, self.C, self.D)]
        n, m, p = mats[0].shape[0], mats[3].shape[1], mats[3].shape[0]
        expected = {"A": (n, n), "B": (n, m), "C": (p, n), "D": (p, m)}
        for (key, shape), mat in zip(expected.items(), mats):
            if mat.shape != shape:
                raise DataError(
                    f"{key} has shape {mat.shape}; the sizes (states {n}, inputs {m}, "
                    f"outputs {p}) need {shape}."
                )
            if not np.all(np.isfinite(mat)):
                raise DataError(f"{key} contains NaN or inf; every coefficient must be a finite number.")
            object.__setattr__(self, key, mat)
        for what, names, count in (
            ("inputs", self.inputs, m),
            ("outputs", self.outputs, p),
            ("states", self.states, n),
        ):
            if len(names) != count or not all(isinstance(x, str) for x in names):
                raise DataError(f"{what} must be {count} names (text); got {list(names)!r}.")
            object.__setattr__(self, what, tuple(names))
        if not (np.isfinite(self.dt) and self.dt >= 0) or isinstance(self.dt, bool):
            raise DataError(f"the sampling time must be a finite number >= 0 s; got {self.dt!r}.")
        object.__setattr__(self, "dt", float(self.dt))

    def statespace(self):
        """The realisation as a named ``control.StateSpace``."""
        return control.ss(
            self.A,
            self.B,
            self.C,
            self.D,
            self.dt,
            inputs=list(self.inputs),
            outputs=list(self.outputs),
            states=list(self.states),
        )


def default_names(what: str, count: int) -> list[str]:
    """python-control's default signal names: ``u[i]`` inputs, ``y[i]`` outputs, ``x[i]`` states."""
    letter = {"inputs": "u", "outputs": "y", "states": "x"}[what]
    return [f"{letter}[{i}]" for i in range(count)]


def _sizes(ctrl: ControllerData) -> dict[str, int]:
    return {"n_states": ctrl.A.shape[0], "n_inputs": ctrl.D.shape[1], "n_outputs": ctrl.D.shape[0]}


def header_dict(ctrl: ControllerData) -> dict[str, Any]:
    return {
        "format": FORMAT_TAG,
        "version": FORMAT_VERSION,
        "equations": EQUATIONS,
        "dt_s": ctrl.dt,
        "fs_hz": 1.0 / ctrl.dt if ctrl.dt > 0 else None,
        **_sizes(ctrl),
    }


def _number(value: Any, what: str, integer: bool = False) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise DataError(f"{what} must be a number; got {value!r}.")
    if integer and (not isinstance(value, int) or value < 0):
        raise DataError(f"{what} must be a whole number >= 0; got {value!r}.")
    return value


def _matrix(value: Any, shape: tuple[int, int], key: str) -> np.ndarray:
    try:
        arr = np.array(value, dtype=float)
    except (TypeError, ValueError):
        raise DataError(f"{key} must be a matrix of numbers (a list of equal-length rows).") from None
    if arr.size == 0 and 0 in shape:
        return np.zeros(shape)
    if arr.shape != shape:
        raise DataError(f"{key} has shape {arr.shape}; the stated sizes need {shape}.")
    return arr


# ---------------------------------------------------------------------------- json
def write_json(ctrl: ControllerData, path: Path, **_: Any) -> None:
    doc = header_dict(ctrl)
    doc.update(
        inputs=list(ctrl.inputs),
        outputs=list(ctrl.outputs),
        states=list(ctrl.states),
        units=dict(ctrl.units),
        A=ctrl.A.tolist(),
        B=ctrl.B.tolist(),
        C=ctrl.C.tolist(),
        D=ctrl.D.tolist(),
        **ctrl.meta,
    )
    with open(path, "w", encoding="utf-8") as fh:
        json.dump(doc, fh, indent=1, allow_nan=False)  # floats via repr: shortest exact text
        fh.write("\n")


def from_dict(doc: Any, what: str) -> ControllerData:
    if not isinstance(doc, dict) or doc.get("format") != FORMAT_TAG:
        raise DataError(f"not a robustctl controller {what}: the 'format' field must be {FORMAT_TAG!r}.")
    version = doc.get("version", FORMAT_VERSION)
    if not isinstance(version, int) or isinstance(version, bool) or version > FORMAT_VERSION:
        raise DataError(
            f"layout version {version!r} is newer than this robustctl reads ({FORMAT_VERSION}); "
            "update robustctl."
        )
    missing = [k for k in ("dt_s", "n_states", "n_inputs", "n_outputs", "A", "B", "C", "D") if k not in doc]
    if missing:
        raise DataError(f"the {what} lacks the field(s) {', '.join(missing)}.")
    n, m, p = (int(_number(doc[k], k, integer=True)) for k in ("n_states", "n_inputs", "n_outputs"))
    dt = float(_number(doc["dt_s"], "dt_s"))
    fs = doc.get("fs_hz")
    if fs is not None and dt > 0 and abs(float(_number(fs, "fs_hz")) * dt - 1.0) > 1e-12:
        raise DataError(f"fs_hz = {fs!r} and dt_s = {dt!r} disagree (fs must be 1/dt); fix one of them.")
    names = {k: doc.get(k, default_names(k, c)) for k, c in (("inputs", m), ("outputs", p), ("states", n))}
    for k, v in names.items():
        if not isinstance(v, list):
            raise DataError(f"{k} must be a list of names; got {v!r}.")
    units = doc.get("units", {})
    if not isinstance(units, dict):
        raise DataError(f"units must be an object mapping signal names to units; got {units!r}.")
    shapes = {"A": (n, n), "B": (n, m), "C": (p, n), "D": (p, m)}
    mats = {k: _matrix(doc[k], s, k) for k, s in shapes.items()}
    skip = (
        set(shapes)
        | set(names)
        | {"units", "dt_s", "fs_hz", "format", "version", "equations", "n_states", "n_inputs", "n_outputs"}
    )
    meta = {k: v for k, v in doc.items() if k not in skip}
    return ControllerData(dt=dt, units=units, meta=meta, **mats, **names)


def read_json(path: Path) -> ControllerData:
    try:
        doc = json.loads(path.read_text(encoding="utf-8"))
    except (UnicodeDecodeError, ValueError) as exc:
        raise DataError(f"not valid JSON ({exc}).") from None
    return from_dict(doc, "JSON file")


# ---------------------------------------------------------------------------- csv
CSV_HEADER = ["field", "row", "col", "value"]
CSV_LAYOUT = (
    "# robustctl controller, csv layout v1: " + EQUATIONS + "\n"
    "# one value per line: field,row,col,value (0-based row/col). Fields: dt_s, fs_hz, n_states, n_inputs,\n"
    "# n_outputs; input/output/state (row = index, value = name); unit (col = signal name);\n"
    "# A, B, C, D (one coefficient per line, exact decimal); meta (value = JSON object).\n"
)


def write_csv(ctrl: ControllerData, path: Path, **_: Any) -> None:
    rows: list[list[Any]] = [
        [k, "", "", repr(v) if isinstance(v, float) else v]
        for k, v in header_dict(ctrl).items()
        if k.startswith(("dt", "fs", "n_"))
    ]
    for key in ("inputs", "outputs", "states"):
        rows += [[key[:-1], i, "", name] for i, name in enumerate(getattr(ctrl, key))]
    rows += [["unit", "", name, unit] for name, unit in ctrl.units.items()]
    for key in "ABCD":
        mat = getattr(ctrl, key)
        rows += [[key, i, j, repr(float(mat[i, j]))] for i, j in np.ndindex(*mat.shape)]
    rows.append(["meta", "", "", json.dumps(ctrl.meta, allow_nan=False)])
    with open(path, "w", newline="", encoding="utf-8") as fh:
        fh.write(CSV_LAYOUT)
        writer = csv.writer(fh, lineterminator="\n")
        writer.writerow(CSV_HEADER)
        writer.writerows([[str(c) for c in r] for r in rows])


def csv_value(text: str, line: int, what: str) -> float:
    try:
        return float(text)
    except ValueError:
        raise DataError(f"line {line}: {what} {text!r} is not a number.") from None


def _csv_index(text: str, line: int, size: int, what: str) -> int:
    if not text.isdigit() or int(text) >= size:
        raise DataError(f"line {line}: {what} index {text!r} is not in 0..{size - 1}.")
    return int(text)


def read_csv(path: Path) -> ControllerData:
    try:
        lines = path.read_text(encoding="utf-8").splitlines(keepends=True)
        skip = next((k for k, ln in enumerate(lines) if not ln.startswith("#")), len(lines))
        reader = csv.reader(io.StringIO("".join(lines[skip:]), newline=""))
        rows = [(skip + reader.line_num, r) for r in reader]  # (line number in the file, fields)
    except (UnicodeDecodeError, csv.Error) as exc:
        raise DataError(f"not a readable text CSV file ({exc}).") from None
    if not rows or [h.strip() for h in rows[0][1]] != CSV_HEADER:
        raise DataError(f"the first line after the # comments must be the header {','.join(CSV_HEADER)}.")
    body = [(k, r) for k, r in rows[1:] if r]
    for line, r in body:
        if len(r) != 4:
            raise DataError(f"line {line} has {len(r)} fields; expected 4 ({','.join(CSV_HEADER)}).")
    scalars = {
        r[0]: csv_value(r[3], line, r[0])
        for line, r in body
        if r[0] in ("dt_s", "fs_hz") or r[0].startswith("n_")
    }
    doc: dict[str, Any] = {"format": FORMAT_TAG, "units": {}}
    for key, value in scalars.items():
        doc[key] = int(value) if key.startswith("n_") and value == int(value) and value >= 0 else value
    sizes = {k: doc.get(f"n_{k}") for k in ("states", "inputs", "outputs")}
    if any(not isinstance(v, int) for v in sizes.values()):
        raise DataError(
            f"the CSV file must state n_states, n_inputs and n_outputs as whole numbers; got {sizes}."
        )
    n, m, p = sizes["states"], sizes["inputs"], sizes["outputs"]
    shapes = {"A": (n, n), "B": (n, m), "C": (p, n), "D": (p, m)}
    mats = {k: np.full(s, np.nan) for k, s in shapes.items()}
    names: dict[str, list[Any]] = {"input": [None] * m, "output": [None] * p, "state": [None] * n}
    for line, (key, row, col, value) in body:
        if key in mats:
            i = _csv_index(row, line, shapes[key][0], f"{key} row")
            j = _csv_index(col, line, shapes[key][1], f"{key} column")
            mats[key][i, j] = csv_value(value, line, key)
        elif key in names:
            names[key][_csv_index(row, line, len(names[key]), key)] = value
        elif key == "unit":
            doc["units"][col] = value
        elif key == "meta":
            try:
                doc.update(json.loads(value))
            except ValueError as exc:
                raise DataError(f"line {line}: the meta field is not a JSON object ({exc}).") from None
        elif key not in scalars:
            raise DataError(f"line {line}: unknown field {key!r}.")
    for key, mat in mats.items():
        if np.isnan(mat).any():
            i, j = np.argwhere(np.isnan(mat))[0]
            raise DataError(f"{key}[{i},{j}] is missing (or NaN); every coefficient needs a line.")
        doc[key] = mat
    for key, vals in names.items():
        if None in vals:
            raise DataError(f"{key} {vals.index(None)} has no name line.")
        doc[key + "s"] = vals
    return from_dict(doc, "CSV file")


# ---------------------------------------------------------------------------- mat
def write_mat(ctrl: ControllerData, path: Path, **_: Any) -> None:
    from scipy.io import savemat

    mdict = {
        "A": ctrl.A,
        "B": ctrl.B,
        "C": ctrl.C,
        "D": ctrl.D,
        "Ts": ctrl.dt,
        "InputName": cellstr(ctrl.inputs),
        "OutputName": cellstr(ctrl.outputs),
        "StateName": cellstr(ctrl.states),
        "InputUnit": cellstr([ctrl.units.get(x, "") for x in ctrl.inputs]),
        "OutputUnit": cellstr([ctrl.units.get(x, "") for x in ctrl.outputs]),
        "robustctl_format": FORMAT_TAG,
        "robustctl_meta": json.dumps(ctrl.meta, allow_nan=False),
    }
    with open(path, "wb") as fh:
        savemat(fh, mdict, do_compression=True)


def _mat_matrix(mdict: dict, key: str, shape: tuple[int, int]) -> np.ndarray:
    if key not in mdict:
        raise DataError(f"the MAT file has no variable {key} (expected A, B, C, D and Ts).")
    arr = np.asarray(mdict[key])
    if arr.dtype.kind not in "fiu":
        raise DataError(f"{key} must be a real numeric matrix; got dtype {arr.dtype}.")
    if arr.size == 0 and 0 in shape:
        return np.zeros(shape)
    if arr.shape != shape:
        raise DataError(
            f"{key} has shape {arr.shape}; with D {shape[0] if key != 'B' else ''} the sizes need {shape}."
        )
    return arr.astype(float)


def read_mat(path: Path) -> ControllerData:
    from scipy.io import loadmat

    try:
        mdict = loadmat(path)
    except Exception as exc:  # scipy raises several types for corrupt files
        raise DataError(f"not a readable MAT file ({exc}).") from None
    d = np.atleast_2d(_mat_matrix(mdict, "D", np.shape(mdict.get("D", np.zeros((0, 0))))))
    a = np.asarray(mdict.get("A", np.zeros((0, 0))))
    n = a.shape[0] if a.ndim == 2 else -1
    p, m = d.shape
    mats = {
        k: _mat_matrix(mdict, k, s) for k, s in (("A", (n, n)), ("B", (n, m)), ("C", (p, n)), ("D", (p, m)))
    }
    if "Ts" not in mdict:  # read as continuous before: a discrete design saved without Ts was re-discretised
        raise DataError(
            "the MAT file has no Ts; add Ts = 0 for a continuous controller or its sampling time in s "
            "(save('K.mat', 'A', 'B', 'C', 'D', 'Ts'))."
        )
    try:
        ts = np.asarray(mdict["Ts"], dtype=float).reshape(-1)
    except (TypeError, ValueError):
        raise DataError(f"Ts must be a number (s; 0 for continuous); got {mdict['Ts']!r}.") from None
    if ts.size != 1:
        raise DataError(f"Ts must be one number (s; 0 for continuous); got {ts.size} values.")
    if ts[0] == -1:
        raise DataError(
            "Ts = -1 (MATLAB's unspecified sampling time) cannot be exported or simulated; set Ts to the "
            "controller's sampling time in s."
        )
    names = {
        k: mat_names(mdict, v)
        for k, v in (("inputs", "InputName"), ("outputs", "OutputName"), ("states", "StateName"))
    }
    for key, count in (("inputs", m), ("outputs", p), ("states", n)):
        if names[key] is None:
            names[key] = default_names(key, count)
    units = {}
    for key, var in (("inputs", "InputUnit"), ("outputs", "OutputUnit")):
        got = mat_names(mdict, var) or []
        units.update({name: u for name, u in zip(names[key], got) if u})
    meta = {}
    if "robustctl_meta" in mdict:
        try:
            meta = json.loads(mat_string(mdict["robustctl_meta"]) or "{}")
        except ValueError as exc:
            raise DataError(f"robustctl_meta is not valid JSON ({exc}).") from None
    return ControllerData(dt=float(ts[0]), units=units, meta=meta, **mats, **names)
