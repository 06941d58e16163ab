"""Second-order sections of one SISO channel: a text file in scipy.signal's ``sos`` layout, with a
JSON metadata comment (sampling time, signal names, checks, provenance)."""

from __future__ import annotations

import json
import re
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import DataError
from .files import FORMAT_TAG, ControllerData, csv_value, header_dict

__all__ = ["write_sos", "read_sos", "read_sos_file", "sos_statespace_matrices"]


SOS_LAYOUT = (
    "# robustctl second-order sections, layout v1 (scipy.signal 'sos' convention), one section per line:\n"
    "# H(z) = prod_k (b0 + b1 z^-1 + b2 z^-2) / (a0 + a1 z^-1 + a2 z^-2), a0 = 1, overall gain in section 1\n"
)


def write_sos(ctrl: ControllerData, path: Path, sos: np.ndarray | None = None, **_: Any) -> None:
    meta = {
        **header_dict(ctrl),
        "input": ctrl.inputs[0],
        "output": ctrl.outputs[0],
        "units": dict(ctrl.units),
        **ctrl.meta,
    }
    meta.pop("n_states")
    meta.pop("equations")  # the sections are a transfer function, not the state-space update
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
            [csv_value(v, k, "coefficient") for v in r.split(",")]
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
