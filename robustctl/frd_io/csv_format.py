"""FrequencyData in long-format ``.csv`` files (``f_hz,output,input,re,im[,coherence]``).

Layout written by :func:`write_csv` (``N = n_freq * n_out * n_in`` data rows)::

    # robustctl.FrequencyData csv: 16 frequencies x 2 outputs x 2 inputs = 64 rows
    # experiment: {"input_kind": "measured", "excitation": "random", "fs_hz": 200.0, ...}
    # units: {"F": "N", "a1": "m/s^2"}
    # meta: {"method": "H1 (Welch averaged cross-spectra)", ...}
    f_hz,output,input,re,im,coherence
    1.0,y1,u1,0.25,-0.5,0.9            <- frequency-major: every (output, input) pair of
    ...                                   one frequency, then the next frequency
    # end, 64 rows

The ``# experiment``, ``# units`` and ``# meta`` lines (one JSON object each, written when
there is something to keep, optional on reading; a file without ``# experiment`` loads as not
described) keep how the data were made
(:class:`~robustctl.frd.Experiment`), the signal units and the provenance.
The first and last lines are the completeness markers. A file cut anywhere -- even exactly
between two frequency blocks, where every row left is whole -- lacks the ``# end`` line (or
holds fewer rows than it announces) and :func:`read_csv` refuses it with a
:class:`~robustctl.errors.DataError` naming the truncation, instead of loading fewer
frequencies. Files without the markers (written before they existed, or by hand: the column
header line and the rows) are still read; then every frequency must hold every
(output, input) pair exactly once, which catches a block cut short but cannot tell a file
that ends between two frequency blocks from a shorter one.
"""

from __future__ import annotations

import csv
import io
import re
from pathlib import Path

import numpy as np

from ..errors import DataError
from ..frd import Experiment, FrequencyData
from ._common import MAX_FILE_BYTES, build, json_dumps, json_loads, read_limited

__all__ = ["read_csv", "write_csv"]

_CSV_HEADER = ["f_hz", "output", "input", "re", "im"]
_PREAMBLE = "# robustctl.FrequencyData csv: {} frequencies x {} outputs x {} inputs = {} rows"
_PREAMBLE_RE = re.compile(
    r"# robustctl\.FrequencyData csv: (\d+) frequencies x (\d+) outputs x (\d+) inputs = (\d+) rows\s*"
)
_FIELD_RE = re.compile(r"# (experiment|units|meta): (.*)")
_END = "# end, {} rows"
_END_RE = re.compile(r"# end, (\d+) rows\s*")


def write_csv(data: FrequencyData, path: Path) -> None:
    """Write ``data`` with the completeness markers (module docstring)."""
    has_coh = data.coherence is not None
    n_rows = data.n_freq * data.n_out * data.n_in
    with open(path, "w", newline="", encoding="utf-8") as fh:
        fh.write(_PREAMBLE.format(data.n_freq, data.n_out, data.n_in, n_rows) + "\n")
        if data.experiment != Experiment():  # the layout of undescribed data is unchanged
            fh.write(f"# experiment: {json_dumps(data.experiment.to_dict())}\n")
        if data.units:
            fh.write(f"# units: {json_dumps(data.units)}\n")
        if data.meta:
            fh.write(f"# meta: {json_dumps(data.meta)}\n")
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
        fh.write(_END.format(n_rows) + "\n")


def _csv_float(text: str, line: int, column: str) -> float:
    try:
        return float(text)
    except ValueError:
        pass
    hint = ""
    if "," in text and _parses(text.replace(",", ".")):
        hint = " It has a decimal comma; write numbers with a decimal point ('1.5', not '1,5')."
    elif _parses(text, complex):
        hint = " It is a complex number; write its real and imaginary parts in the columns re and im."
    raise DataError(f"line {line}: {column} {text!r} is not a number.{hint}")


def _parses(text: str, kind: type = float) -> bool:
    try:
        kind(text.strip().replace(" ", ""))
    except ValueError:
        return False
    return True


def _decode(raw: bytes) -> str:
    """The text of a CSV file: UTF-8 (an Excel byte-order mark is dropped), classic-Mac CR line ends
    read as newlines; UTF-16 and other encodings are refused with the fix."""
    if raw.startswith((b"\xff\xfe", b"\xfe\xff")):
        raise DataError(
            "the CSV file is UTF-16 text (Excel's 'Unicode Text'); save it as UTF-8 CSV "
            "('CSV UTF-8 (comma delimited)')."
        )
    try:
        text = raw.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        raise DataError(
            f"the CSV file is not UTF-8 text (byte {raw[exc.start]:#04x} at position {exc.start}); save "
            "it with UTF-8 encoding."
        ) from None
    if "\n" not in text and "\r" in text:  # old Mac line ends: CR only
        text = text.replace("\r", "\n")
    return text


def _header_error(fields: list[str]) -> DataError:
    hint = ""
    first = fields[0] if fields else ""
    if len(fields) == 1 and (";" in first or "\t" in first):
        sep = "semicolons" if ";" in first else "tabs"
        hint = (
            f" The columns are separated by {sep}: write comma-separated values with decimal points "
            "(a spreadsheet's 'CSV (comma delimited)' in an English locale)."
        )
    elif fields and _parses(first):
        hint = f" The first line holds data; add the column header line {','.join(_CSV_HEADER)} above it."
    elif len(fields) == 4:
        hint = " Complex values go in two columns, re and im."
    return DataError(
        f"the CSV header is {fields}; expected {','.join(_CSV_HEADER)}[,coherence] (long format).{hint}"
    )


def _header_fields(text: str, first: int) -> tuple[dict[str, dict], str, int]:
    """The ``# experiment|units|meta: {json}`` lines at the start of ``text``, the rest, its first line."""
    found: dict[str, dict] = {}
    while text.startswith("# "):
        line, _, rest = text.partition("\n")
        match = _FIELD_RE.fullmatch(line.rstrip("\r"))
        if match is None:
            break
        if match.group(1) in found:
            raise DataError(f"line {first}: a second '# {match.group(1)}:' line; the file is damaged.")
        found[match.group(1)] = json_loads(match.group(2).strip(), f"CSV '# {match.group(1)}' line {first}")
        text, first = rest, first + 1
    return found, text, first


def _markers(text: str) -> tuple[tuple[int, ...] | None, int | None, str, int]:
    """``(announced (n_freq, n_out, n_in, n_rows) or None, footer rows or None, body, body's first line)``.

    The preamble is the first line when it starts with ``#`` (and is not a field line); the
    footer the last line when it starts with ``# end``. A preamble that is not robustctl's is
    refused (a damaged marker).
    """
    announced, first = None, 1
    if text.startswith("#") and _FIELD_RE.fullmatch(text.partition("\n")[0].rstrip("\r")) is None:
        line, _, text = text.partition("\n")
        match = _PREAMBLE_RE.fullmatch(line)
        if match is None:
            raise DataError(
                f"line 1 {line[:80]!r} is not robustctl's CSV preamble ('# robustctl.FrequencyData csv: "
                "F frequencies x O outputs x I inputs = N rows'); the file is damaged. Remove the line to "
                "read the rows without the completeness check."
            )
        announced, first = tuple(int(g) for g in match.groups()), 2
    footer = None
    body, _, last = text.rstrip("\n").rpartition("\n")
    if last.startswith("# end"):
        match = _END_RE.fullmatch(last)
        if match is None:
            raise DataError(f"the last line {last[:40]!r} is a damaged '# end, N rows' marker.")
        footer, text = int(match.group(1)), body + "\n"
    return announced, footer, text, first


def _csv_rows(
    path: Path,
) -> tuple[bool, list[list[str]], tuple[int, ...] | None, int | None, int, dict[str, dict]]:
    text = _decode(read_limited(path, MAX_FILE_BYTES))
    if not text:
        raise DataError("the CSV file is empty.")
    if not text.endswith("\n"):
        raise DataError(
            "the CSV file does not end with a line break: it is truncated (the last row may be cut "
            "short); write it again or add the missing end."
        )
    announced, footer, body, first = _markers(text)
    extra, body, first = _header_fields(body, first)
    try:
        rows = list(csv.reader(io.StringIO(body)))
    except csv.Error as exc:
        raise DataError(f"not a readable text CSV file ({exc}).") from None
    if not rows:
        if announced is not None:
            raise DataError(
                f"the CSV file is truncated: its first line announces {announced[3]} data rows but the file "
                "ends after it. Write the file again."
            )
        raise DataError("the CSV file has no column header line (f_hz,output,input,re,im[,coherence]).")
    header = [h.strip().lower() for h in rows[0]]
    if header not in (_CSV_HEADER, _CSV_HEADER + ["coherence"]):
        raise _header_error(rows[0])
    return len(header) == 6, rows, announced, footer, first, extra


def _check_complete(announced: tuple[int, ...] | None, footer: int | None, n_rows: int) -> None:
    """Refuse a file whose rows do not match its completeness markers."""
    if announced is not None and footer is None:
        raise DataError(
            f"the CSV file is truncated: its first line announces {announced[3]} data rows "
            f"({announced[0]} frequencies) but it ends after {n_rows} rows without the '# end, N rows' "
            "line. Write the file again."
        )
    first = None if announced is None else announced[3]
    for what, count in (("first line", first), ("'# end' line", footer)):
        if count is not None and count != n_rows:
            raise DataError(
                f"the CSV file is truncated or damaged: its {what} says {count} data rows but it holds "
                f"{n_rows}. Write the file again."
            )


def read_csv(path: Path) -> FrequencyData:
    """Read a long-format CSV file, checking its completeness markers when it has them."""
    has_coh, rows, announced, footer, first, extra = _csv_rows(path)
    freqs: dict[float, int] = {}
    outs: dict[str, int] = {}
    ins: dict[str, int] = {}
    entries: dict[tuple[int, int, int], tuple[complex, float]] = {}
    for line, row in enumerate(rows[1:], start=first + 1):
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
    _check_complete(announced, footer, len(entries))
    if not entries:
        raise DataError("the CSV file has a header but no data rows.")
    shape = (len(freqs), len(outs), len(ins))
    if announced is not None and shape != announced[:3]:
        raise DataError(
            f"the CSV file holds {shape[0]} frequencies x {shape[1]} outputs x {shape[2]} inputs but its "
            f"first line announces {announced[0]} x {announced[1]} x {announced[2]}; it is damaged."
        )
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
    return build("CSV", f_hz=list(freqs), response=resp, outputs=list(outs), inputs=list(ins), coherence=coh,
                 units=extra.get("units"), meta=extra.get("meta"), experiment=extra.get("experiment"))
