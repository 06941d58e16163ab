"""The C header layout of an exported controller: size macros, ``static const`` double and float
arrays (row-major), signal names, and an inline step function per precision.

The step computes ``y = C x + D u`` from the current state, then ``x <- A x + B u``
(the update equations of :mod:`robustctl.export.files`); the double arrays hold the exact
coefficients (shortest round-trip decimals), the ``_F`` arrays the same values rounded to float.
"""

from __future__ import annotations

import contextlib
import json
import re
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import DataError
from .files import EQUATIONS, FORMAT_TAG, ControllerData, csv_value, from_dict

__all__ = ["c_prefix", "write_header", "read_header"]


def c_prefix(path: Path, prefix: str | None) -> str:
    """The macro/array prefix: ``prefix`` or the file stem, upper case, a valid C identifier."""
    if prefix is not None and not isinstance(prefix, str):
        raise DataError(f"prefix must be text (a C identifier); got {prefix!r}.")
    text = path.stem if prefix is None else prefix
    ident = re.sub(r"[^A-Za-z0-9_]", "_", text).upper().strip("_") or "CONTROLLER"
    if prefix is not None and (ident != prefix.upper() or ident[0].isdigit()):
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
    signals = {"u": list(ctrl.inputs), "y": list(ctrl.outputs), "units": dict(ctrl.units)}
    names = json.dumps(signals).replace("*/", "* /")
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
    doc["dt_s"] = csv_value(_c_define(text, "DT_S"), 0, "DT_S")
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
    signals = re.search(r"^ \* Signals \(u = inputs, y = outputs\): (.*)\.$", text, re.M)
    with contextlib.suppress(ValueError, AttributeError):  # comments inform; the arrays are the contract
        doc.update(json.loads(meta.group(1).replace("* /", "*/")))
    with contextlib.suppress(ValueError, AttributeError, KeyError, TypeError):
        doc["units"] = dict(json.loads(signals.group(1).replace("* /", "*/"))["units"])
    return from_dict(doc, "C header")
