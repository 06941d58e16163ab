"""FrequencyData in long-format ``.csv`` files (``f_hz,output,input,re,im[,coherence]``)."""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np

from ..errors import DataError
from ..frd import FrequencyData
from ._common import build

__all__ = ["read_csv", "write_csv"]

_CSV_HEADER = ["f_hz", "output", "input", "re", "im"]


def write_csv(data: FrequencyData, path: Path) -> None:
    has_coh = data.coherence is not None
    with open(path, "w", newline="", encoding="utf-8") as fh:
        writer = csv.writer(fh, lineterminator="\n")
        writer.writerow(_CSV_HEADER + (["coherence"] if has_coh else []))
        for k, f in enumerate(data.f_hz.tolist()):
            for o, out in enumerate(data.outputs):
                for i, inp in enumerate(data.inputs):
                    g = complex(data.response[k, o, i])
                    row = [repr(f), out, inp, repr(g.real), repr(g.imag)]
                    if has_coh:
                        row.append(repr(float(data.coherence[k, o, i])))
                    writer.writerow(row)


def _csv_float(text: str, line: int, column: str) -> float:
    try:
        return float(text)
    except ValueError:
        raise DataError(f"line {line}: {column} {text!r} is not a number.") from None


def _csv_rows(path: Path) -> tuple[bool, list[list[str]]]:
    try:
        with open(path, newline="", encoding="utf-8") as fh:
            rows = list(csv.reader(fh))
    except (UnicodeDecodeError, csv.Error) as exc:
        raise DataError(f"not a readable text CSV file ({exc}).") from None
    if not rows:
        raise DataError("the CSV file is empty.")
    header = [h.strip() for h in rows[0]]
    if header not in (_CSV_HEADER, _CSV_HEADER + ["coherence"]):
        raise DataError(
            f"the CSV header is {rows[0]}; expected {','.join(_CSV_HEADER)}[,coherence] (long format)."
        )
    return len(header) == 6, rows


def read_csv(path: Path) -> FrequencyData:
    has_coh, rows = _csv_rows(path)
    freqs: dict[float, int] = {}
    outs: dict[str, int] = {}
    ins: dict[str, int] = {}
    entries: dict[tuple[int, int, int], tuple[complex, float]] = {}
    for line, row in enumerate(rows[1:], start=2):
        if not row:
            continue
        if len(row) != 5 + has_coh:
            raise DataError(f"line {line} has {len(row)} fields; the header has {5 + has_coh}.")
        f = _csv_float(row[0], line, "f_hz")
        key = (
            freqs.setdefault(f, len(freqs)),
            outs.setdefault(row[1], len(outs)),
            ins.setdefault(row[2], len(ins)),
        )
        if key in entries:
            raise DataError(f"line {line} repeats f_hz={row[0]}, output {row[1]!r}, input {row[2]!r}.")
        g = complex(_csv_float(row[3], line, "re"), _csv_float(row[4], line, "im"))
        entries[key] = (g, _csv_float(row[5], line, "coherence") if has_coh else 0.0)
    if not entries:
        raise DataError("the CSV file has a header but no data rows.")
    shape = (len(freqs), len(outs), len(ins))
    missing = [k for k in np.ndindex(*shape) if k not in entries][:1]
    if missing:
        k, o, i = missing[0]
        raise DataError(
            f"{int(np.prod(shape)) - len(entries)} entries are missing, e.g. f_hz={list(freqs)[k]!r}, "
            f"output {list(outs)[o]!r}, input {list(ins)[i]!r}; every frequency needs every pair."
        )
    resp = np.empty(shape, complex)
    coh = np.empty(shape) if has_coh else None
    for (k, o, i), (g, c) in entries.items():
        resp[k, o, i] = g
        if coh is not None:
            coh[k, o, i] = c
    return build("CSV", f_hz=list(freqs), response=resp, outputs=list(outs), inputs=list(ins), coherence=coh)
