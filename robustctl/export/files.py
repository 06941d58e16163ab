"""Coefficient files of a discrete controller: JSON, CSV, C header, MATLAB .mat, second-order sections.

Every format holds the update equations

    x[k+1] = A x[k] + B u[k],        y[k] = C x[k] + D u[k],        t = k / fs,

with ``u`` the controller's inputs (the plant's measurements) and ``y`` its outputs (the
plant's controls). Floats are written with the shortest decimal text that reads back to the
same double (``repr``), so JSON, CSV, .mat and the double arrays of the C header reload
bit-exact. :mod:`robustctl.export` discretises, checks and calls these writers; this module
only knows the layouts.
"""

from __future__ import annotations

import contextlib
import csv
import io
import json
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import DataError
from ..frd import _cell, _mat_names, _mat_string

__all__ = ["ControllerData", "WRITERS", "READERS", "FORMATS"]

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
        import control

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


def _sizes(ctrl: ControllerData) -> dict[str, int]:
    return {"n_states": ctrl.A.shape[0], "n_inputs": ctrl.D.shape[1], "n_outputs": ctrl.D.shape[0]}


def _header_dict(ctrl: ControllerData) -> dict[str, Any]:
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
    doc = _header_dict(ctrl)
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


def _from_dict(doc: Any, what: str) -> ControllerData:
    if not isinstance(doc, dict) or doc.get("format") != FORMAT_TAG:
        raise DataError(f"not a robustctl controller {what}: the 'format' field must be {FORMAT_TAG!r}.")
    missing = [k for k in ("dt_s", "n_states", "n_inputs", "n_outputs", "A", "B", "C", "D") if k not in doc]
    if missing:
        raise DataError(f"the {what} lacks the field(s) {', '.join(missing)}.")
    n, m, p = (int(_number(doc[k], k, integer=True)) for k in ("n_states", "n_inputs", "n_outputs"))
    dt = float(_number(doc["dt_s"], "dt_s"))
    fs = doc.get("fs_hz")
    if fs is not None and dt > 0 and abs(float(_number(fs, "fs_hz")) * dt - 1.0) > 1e-12:
        raise DataError(f"fs_hz = {fs!r} and dt_s = {dt!r} disagree (fs must be 1/dt); fix one of them.")
    names = {
        k: doc.get(k, [f"{k[0]}[{i}]" for i in range(c)])
        for k, c in (("inputs", m), ("outputs", p), ("states", n))
    }
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
    return _from_dict(doc, "JSON file")


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
        for k, v in _header_dict(ctrl).items()
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


def _csv_value(text: str, line: int, what: str) -> float:
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
        r[0]: _csv_value(r[3], line, r[0])
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
            mats[key][i, j] = _csv_value(value, line, key)
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
    return _from_dict(doc, "CSV file")


# ---------------------------------------------------------------------------- mat
def write_mat(ctrl: ControllerData, path: Path, **_: Any) -> None:
    from scipy.io import savemat

    mdict = {
        "A": ctrl.A,
        "B": ctrl.B,
        "C": ctrl.C,
        "D": ctrl.D,
        "Ts": ctrl.dt,
        "InputName": _cell(ctrl.inputs),
        "OutputName": _cell(ctrl.outputs),
        "StateName": _cell(ctrl.states),
        "InputUnit": _cell([ctrl.units.get(x, "") for x in ctrl.inputs]),
        "OutputUnit": _cell([ctrl.units.get(x, "") for x in ctrl.outputs]),
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
    ts = np.asarray(mdict.get("Ts", 0.0), dtype=float).reshape(-1)
    if ts.size != 1:
        raise DataError(f"Ts must be one number (s; 0 for continuous); got {ts.size} values.")
    names = {
        k: _mat_names(mdict, v)
        for k, v in (("inputs", "InputName"), ("outputs", "OutputName"), ("states", "StateName"))
    }
    for key, count in (("inputs", m), ("outputs", p), ("states", n)):
        if names[key] is None:
            names[key] = [f"{key[0]}[{i}]" for i in range(count)]
    units = {}
    for key, var in (("inputs", "InputUnit"), ("outputs", "OutputUnit")):
        got = _mat_names(mdict, var) or []
        units.update({name: u for name, u in zip(names[key], got) if u})
    meta = {}
    if "robustctl_meta" in mdict:
        try:
            meta = json.loads(_mat_string(mdict["robustctl_meta"]) or "{}")
        except ValueError as exc:
            raise DataError(f"robustctl_meta is not valid JSON ({exc}).") from None
    return ControllerData(dt=float(ts[0]), units=units, meta=meta, **mats, **names)


# ---------------------------------------------------------------------------- C header
def c_prefix(path: Path, prefix: str | None) -> str:
    """The macro/array prefix: ``prefix`` or the file stem, upper case, a valid C identifier."""
    if prefix is not None and not isinstance(prefix, str):
        raise DataError(f"prefix must be text (a C identifier); got {prefix!r}.")
    text = path.stem if prefix is None else prefix
    ident = re.sub(r"[^A-Za-z0-9_]", "_", text).upper().strip("_") or "CONTROLLER"
    if prefix is not None and ident != prefix.upper():
        raise DataError(
            f"prefix {prefix!r} is not a C identifier; use letters, digits and '_' "
            "(not starting with a digit or '_')."
        )
    return "K_" + ident if ident[0].isdigit() else ident


def _c_string(text: str) -> str:
    return '"' + text.replace("\\", "\\\\").replace('"', '\\"').replace("\n", "\\n") + '"'


def _c_array(ctype: str, name: str, size: str, values: np.ndarray) -> str:
    if ctype == "float":
        items = [np.format_float_scientific(np.float32(v), unique=True, trim="0") + "f" for v in values]
    else:
        items = [repr(float(v)) for v in values]
    items = items or ["0.0f" if ctype == "float" else "0.0"]  # C has no empty arrays
    body = ",\n    ".join(", ".join(items[k : k + 4]) for k in range(0, len(items), 4))
    return f"static const {ctype} {name}[{size}] = {{\n    {body}\n}};\n"


_C_STEP = """
/* One sample of the controller: y = C x + D u, then x <- A x + B u (x holds NX states, zero at start). */
static inline void {fn}({t} x[], const {t} u[], {t} y[])
{{
    {t} xn[{P}_NX_ALLOC];
    int i, j;
    for (i = 0; i < {P}_NY; ++i) {{
        {t} s = ({t})0;
        for (j = 0; j < {P}_NX; ++j) s += {P}_C{sfx}[i * {P}_NX + j] * x[j];
        for (j = 0; j < {P}_NU; ++j) s += {P}_D{sfx}[i * {P}_NU + j] * u[j];
        y[i] = s;
    }}
    for (i = 0; i < {P}_NX; ++i) {{
        {t} s = ({t})0;
        for (j = 0; j < {P}_NX; ++j) s += {P}_A{sfx}[i * {P}_NX + j] * x[j];
        for (j = 0; j < {P}_NU; ++j) s += {P}_B{sfx}[i * {P}_NU + j] * u[j];
        xn[i] = s;
    }}
    for (i = 0; i < {P}_NX; ++i) x[i] = xn[i];
}}
"""


def write_header(ctrl: ControllerData, path: Path, prefix: str | None = None, **_: Any) -> None:
    P = prefix if prefix is not None else c_prefix(path, None)
    n, m, p = ctrl.A.shape[0], ctrl.D.shape[1], ctrl.D.shape[0]
    comment = json.dumps(ctrl.meta, indent=1, allow_nan=False).replace("*/", "* /")
    names = json.dumps({"u": list(ctrl.inputs), "y": list(ctrl.outputs)}).replace("*/", "* /")
    big = max((float(np.max(np.abs(getattr(ctrl, k)), initial=0.0)) for k in "ABCD"), default=0.0)
    if big > float(np.finfo(np.float32).max):
        raise DataError(
            f"a coefficient of magnitude {big:.3g} exceeds the float range of the header's _F "
            "arrays; rescale the controller's states (balance=True) or its signals."
        )
    out = [
        f"/* Discrete controller exported by robustctl (C header layout v1).\n"
        f" * {EQUATIONS}; sample rate {P}_FS_HZ.\n"
        f" * Signals (u = inputs, y = outputs): {names}.\n"
        f" * Arrays are row-major: {P}_A[i * {P}_NX + j] = A(i, j). Double arrays reproduce the exported\n"
        f" * coefficients exactly; the _F arrays are the same values rounded to float.\n"
        f" * Metadata:\n{comment}\n */\n",
        f"#ifndef {P}_H_\n#define {P}_H_\n\n",
        f"#define {P}_NX {n}\n#define {P}_NU {m}\n#define {P}_NY {p}\n#define {P}_NX_ALLOC {max(n, 1)}\n",
        f"#define {P}_DT_S {ctrl.dt!r}\n#define {P}_FS_HZ {1.0 / ctrl.dt!r}\n\n",
    ]
    for key, (rows, cols) in zip("ABCD", (("NX", "NX"), ("NX", "NU"), ("NY", "NX"), ("NY", "NU"))):
        size = f"{getattr(ctrl, key).size or 1}"
        values = getattr(ctrl, key).reshape(-1)
        out.append(f"/* {key}: {rows} x {cols} */\n" + _c_array("double", f"{P}_{key}", size, values))
        out.append(_c_array("float", f"{P}_{key}_F", size, values))
    for key, names in (("INPUT", ctrl.inputs), ("OUTPUT", ctrl.outputs)):
        items = ", ".join(_c_string(x) for x in names) or '""'
        out.append(f"static const char *const {P}_{key}_NAMES[{max(len(names), 1)}] = {{{items}}};\n")
    out.append(_C_STEP.format(fn=f"{P.lower()}_step", t="double", P=P, sfx=""))
    out.append(_C_STEP.format(fn=f"{P.lower()}_step_f", t="float", P=P, sfx="_F"))
    out.append(f"\n#endif /* {P}_H_ */\n")
    path.write_text("".join(out), encoding="utf-8")


def _c_define(text: str, name: str) -> str:
    match = re.search(rf"^#define\s+\w+_{name}\s+(\S+)\s*$", text, re.M)
    if not match:
        raise DataError(f"the header has no #define <PREFIX>_{name}.")
    return match.group(1)


def read_header(path: Path) -> ControllerData:
    try:
        text = path.read_text(encoding="utf-8")
    except UnicodeDecodeError as exc:
        raise DataError(f"not a text file ({exc}).") from None
    if "exported by robustctl" not in text:
        raise DataError("not a header written by robustctl.export_controller (only that layout is read).")
    doc: dict[str, Any] = {"format": FORMAT_TAG}
    for key, name in (("n_states", "NX"), ("n_inputs", "NU"), ("n_outputs", "NY")):
        value = _c_define(text, name)
        if not value.isdigit():
            raise DataError(f"<PREFIX>_{name} must be a whole number; got {value!r}.")
        doc[key] = int(value)
    doc["dt_s"] = _csv_value(_c_define(text, "DT_S"), 0, "DT_S")
    for key in "ABCD":
        match = re.search(rf"static const double \w+_{key}\[\d+\] = \{{([^}}]*)\}};", text)
        if not match:
            raise DataError(f"the header has no double array <PREFIX>_{key}.")
        try:
            doc[key] = [float(v) for v in match.group(1).split(",") if v.strip()]
        except ValueError as exc:
            raise DataError(f"array {key}: {exc}.") from None
    n, m, p = doc["n_states"], doc["n_inputs"], doc["n_outputs"]
    for key, shape in (("A", (n, n)), ("B", (n, m)), ("C", (p, n)), ("D", (p, m))):
        size = int(np.prod(shape))
        if len(doc[key]) != max(size, 1):  # an empty matrix is stored as one placeholder 0.0
            raise DataError(f"array {key} holds {len(doc[key])} values; the sizes need {size}.")
        doc[key] = np.array(doc[key][:size], dtype=float).reshape(shape)
    for key, name in (("inputs", "INPUT"), ("outputs", "OUTPUT")):
        match = re.search(rf"\w+_{name}_NAMES\[\d+\] = \{{(.*)\}};", text)
        if match:
            names = [json.loads(s) for s in re.findall(r'"(?:[^"\\]|\\.)*"', match.group(1))]
            doc[key] = names if doc[f"n_{key}"] else []
    meta = re.search(r" \* Metadata:\n(.*)\n \*/", text, re.S)
    if meta:
        with contextlib.suppress(ValueError):  # the comment informs; the arrays are the contract
            doc.update(json.loads(meta.group(1).replace("* /", "*/")))
    return _from_dict(doc, "C header")


# ---------------------------------------------------------------------------- second-order sections
SOS_LAYOUT = (
    "# robustctl second-order sections, layout v1 (scipy.signal 'sos' convention), one section per line:\n"
    "# H(z) = prod_k (b0 + b1 z^-1 + b2 z^-2) / (a0 + a1 z^-1 + a2 z^-2), a0 = 1, overall gain in section 1\n"
)


def write_sos(ctrl: ControllerData, path: Path, sos: np.ndarray | None = None, **_: Any) -> None:
    meta = {
        **_header_dict(ctrl),
        "input": ctrl.inputs[0],
        "output": ctrl.outputs[0],
        "units": dict(ctrl.units),
        **ctrl.meta,
    }
    meta.pop("n_states")
    lines = [SOS_LAYOUT, f"# meta: {json.dumps(meta, allow_nan=False)}\n", "b0,b1,b2,a0,a1,a2\n"]
    lines += [",".join(repr(float(v)) for v in row) + "\n" for row in np.asarray(sos)]
    path.write_text("".join(lines), encoding="utf-8")


def read_sos_file(path: Path) -> tuple[np.ndarray, dict]:
    """The sections (n_sections, 6) and the metadata of a ``.sos`` file."""
    try:
        text = path.read_text(encoding="utf-8")
    except UnicodeDecodeError as exc:
        raise DataError(f"not a text file ({exc}).") from None
    meta_line = re.search(r"^# meta: (.*)$", text, re.M)
    if not meta_line:
        raise DataError("the '# meta: {...}' line (sampling time, names) is missing.")
    try:
        meta = json.loads(meta_line.group(1))
    except ValueError as exc:
        raise DataError(f"the meta line is not valid JSON ({exc}).") from None
    if not isinstance(meta, dict) or meta.get("format") != FORMAT_TAG:
        raise DataError(f"the meta line must be a JSON object with format {FORMAT_TAG!r}.")
    rows = [ln for ln in text.splitlines() if ln.strip() and not ln.startswith("#")]
    if not rows or rows[0].replace(" ", "") != "b0,b1,b2,a0,a1,a2":
        raise DataError("the first non-comment line must be the header b0,b1,b2,a0,a1,a2.")
    sos = np.array(
        [
            [_csv_value(v, k, "coefficient") for v in r.split(",")]
            for k, r in enumerate(rows[1:], 2)
            if len(r.split(",")) == 6 or _bad_row(r, k)
        ]
    )
    if sos.size == 0:
        raise DataError("the file holds no sections.")
    if not np.all(np.isfinite(sos)) or np.any(sos[:, 3] == 0):
        raise DataError("every coefficient must be finite and every a0 nonzero.")
    return sos, meta


def _bad_row(row: str, line: int) -> bool:
    raise DataError(f"section line {line} has {len(row.split(','))} values; expected 6 (b0,b1,b2,a0,a1,a2).")


def sos_statespace_matrices(sos: np.ndarray) -> tuple[np.ndarray, ...]:
    """A cascade realisation of the sections (controller canonical form per section, in series)."""
    from scipy.signal import tf2ss

    A, B, C, D = np.zeros((0, 0)), np.zeros((0, 1)), np.zeros((1, 0)), np.ones((1, 1))
    for row in sos:
        b, a = row[:3] / row[3], row[3:] / row[3]
        order = 2 if a[2] != 0 or b[2] != 0 else (1 if a[1] != 0 or b[1] != 0 else 0)
        a2, b2 = a[: order + 1], b[: order + 1]
        if order:
            As, Bs, Cs, Ds = tf2ss(b2, a2)
        else:
            As, Bs, Cs, Ds = np.zeros((0, 0)), np.zeros((0, 1)), np.zeros((1, 0)), np.array([[b2[0]]])
        # series: section input = previous output
        n1, n2 = A.shape[0], As.shape[0]
        A = np.block([[A, np.zeros((n1, n2))], [Bs @ C, As]])
        B = np.vstack([B, Bs @ D])
        C = np.hstack([Ds @ C, Cs])
        D = Ds @ D
    return A, B, C, D


def read_sos(path: Path) -> ControllerData:
    sos, meta = read_sos_file(path)
    dt = meta.get("dt_s")
    if not isinstance(dt, (int, float)) or isinstance(dt, bool) or not dt > 0:
        raise DataError(f"dt_s in the meta line must be a positive number (s); got {dt!r}.")
    A, B, C, D = sos_statespace_matrices(sos)
    names = {
        "inputs": [str(meta.get("input", "u[0]"))],
        "outputs": [str(meta.get("output", "y[0]"))],
        "states": [f"x[{i}]" for i in range(A.shape[0])],
    }
    skip = {
        "format",
        "version",
        "equations",
        "dt_s",
        "fs_hz",
        "n_inputs",
        "n_outputs",
        "input",
        "output",
        "units",
    }
    return ControllerData(
        A,
        B,
        C,
        D,
        float(dt),
        units=meta.get("units") or {},
        meta={k: v for k, v in meta.items() if k not in skip},
        **names,
    )


WRITERS = {".json": write_json, ".csv": write_csv, ".mat": write_mat, ".h": write_header, ".sos": write_sos}
READERS = {".json": read_json, ".csv": read_csv, ".mat": read_mat, ".h": read_header, ".sos": read_sos}
FORMATS = tuple(k[1:] for k in WRITERS)
