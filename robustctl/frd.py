"""FrequencyData: the one container for measured or computed frequency responses.

Every FRF array in robustctl has the shape ``(n_freq, n_out, n_in)``; frequencies at the
surface are in Hz. File I/O (npz, csv, mat, UFF dataset 58) lives here too.
"""

from __future__ import annotations

import csv
import json
import os
import tempfile
import zipfile
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from os import PathLike
from pathlib import Path
from typing import Any

import numpy as np

from .errors import DataError

__all__ = ["FrequencyData", "load_frd", "SUPPORTED_FORMATS"]


def _default_names(prefix: str, count: int) -> tuple[str, ...]:
    return tuple(f"{prefix}{k + 1}" for k in range(count))


def _check_names(names: Sequence[str] | None, count: int, what: str, prefix: str) -> tuple[str, ...]:
    if names is None:
        return _default_names(prefix, count)
    if isinstance(names, str):
        names = (names,)
    names = tuple(str(n) for n in names)
    if len(names) != count:
        raise DataError(
            f"{what} has {len(names)} names but the response has {count} {what}; "
            f"give one name per {what[:-1]}."
        )
    if len(set(names)) != len(names):
        dup = sorted({n for n in names if names.count(n) > 1})
        raise DataError(f"{what} names must be unique; repeated: {dup}.")
    return names


def _as_response(response: Any) -> np.ndarray:
    arr = np.asarray(response)
    if arr.ndim == 1:
        arr = arr[:, None, None]
    if arr.ndim != 3:
        raise DataError(
            f"response must have shape (n_freq, n_out, n_in); got an array of shape {arr.shape}."
        )
    arr = arr.astype(complex)
    if not np.all(np.isfinite(arr)):
        raise DataError("response contains NaN or inf values; remove or repair those frequency points.")
    return arr


def _as_frequencies(f_hz: Any) -> np.ndarray:
    f = np.asarray(f_hz, dtype=float).reshape(-1)
    if f.size == 0:
        raise DataError("f_hz is empty; give at least one frequency in Hz.")
    if not np.all(np.isfinite(f)):
        raise DataError("f_hz contains NaN or inf; frequencies must be finite numbers in Hz.")
    if np.any(f <= 0):
        raise DataError(
            f"f_hz must be positive (Hz); the smallest value is {f.min():g}. Drop the DC point."
        )
    if f.size > 1 and np.any(np.diff(f) <= 0):
        raise DataError("f_hz must be strictly increasing; sort the data and remove duplicates.")
    return f


@dataclass(frozen=True, eq=False)
class FrequencyData:
    """Frequency-response data of a multi-input, multi-output system.

    Parameters
    ----------
    f_hz : array_like, shape (n_freq,)
        Frequencies in Hz, strictly increasing, finite and positive.
    response : array_like, complex, shape (n_freq, n_out, n_in)
        The frequency response G(j 2 pi f); a 1-D array is read as SISO.
    inputs, outputs : sequence of str, optional
        Unique signal names; default ``u1, u2, ...`` and ``y1, y2, ...``.
    coherence : array_like, shape (n_freq, n_out, n_in), optional
        Ordinary (SISO) or multiple (MIMO) coherence in [0, 1] of each estimate.
    units : mapping, optional
        Units of the signals, e.g. ``{"u1": "V", "y1": "m/s^2"}``.
    meta : mapping, optional
        Free-form provenance (estimation settings, source file ...).
    """

    f_hz: np.ndarray
    response: np.ndarray
    inputs: tuple[str, ...] | None = None
    outputs: tuple[str, ...] | None = None
    coherence: np.ndarray | None = None
    units: Mapping[str, str] | None = field(default=None)
    meta: Mapping[str, Any] | None = field(default=None)

    def __post_init__(self) -> None:
        f = _as_frequencies(self.f_hz)
        g = _as_response(self.response)
        if g.shape[0] != f.size:
            raise DataError(
                f"response has {g.shape[0]} frequency points but f_hz has {f.size}; "
                "the first axis of response must run over f_hz."
            )
        outputs = _check_names(self.outputs, g.shape[1], "outputs", "y")
        inputs = _check_names(self.inputs, g.shape[2], "inputs", "u")
        coh = None
        if self.coherence is not None:
            coh = np.asarray(self.coherence, dtype=float)
            if coh.ndim == 1 and g.shape[1:] == (1, 1):
                coh = coh[:, None, None]
            if coh.shape != g.shape:
                raise DataError(
                    f"coherence has shape {coh.shape} but response has shape {g.shape}; "
                    "give one coherence value per response entry."
                )
            if not np.all(np.isfinite(coh)) or np.any(coh < 0) or np.any(coh > 1 + 1e-9):
                raise DataError("coherence must be finite and lie in [0, 1].")
            coh = np.clip(coh, 0.0, 1.0)
            coh.setflags(write=False)
        f.setflags(write=False)
        g.setflags(write=False)
        object.__setattr__(self, "f_hz", f)
        object.__setattr__(self, "response", g)
        object.__setattr__(self, "inputs", inputs)
        object.__setattr__(self, "outputs", outputs)
        object.__setattr__(self, "coherence", coh)
        object.__setattr__(self, "units", dict(self.units or {}))
        object.__setattr__(self, "meta", dict(self.meta or {}))

    # ------------------------------------------------------------------ basic views
    @property
    def shape(self) -> tuple[int, int, int]:
        """``(n_freq, n_out, n_in)``."""
        return self.response.shape  # type: ignore[return-value]

    @property
    def n_freq(self) -> int:
        return self.response.shape[0]

    @property
    def n_out(self) -> int:
        return self.response.shape[1]

    @property
    def n_in(self) -> int:
        return self.response.shape[2]

    @property
    def w(self) -> np.ndarray:
        """Angular frequencies in rad/s."""
        return 2.0 * np.pi * self.f_hz

    def replace(self, **changes: Any) -> FrequencyData:
        """A copy with some fields replaced (validated again)."""
        fields = dict(
            f_hz=self.f_hz,
            response=self.response,
            inputs=self.inputs,
            outputs=self.outputs,
            coherence=self.coherence,
            units=self.units,
            meta=self.meta,
        )
        fields.update(changes)
        return FrequencyData(**fields)

    def band(self, lo_hz: float | None = None, hi_hz: float | None = None) -> FrequencyData:
        """The data restricted to ``lo_hz <= f <= hi_hz`` (Hz)."""
        lo = -np.inf if lo_hz is None else float(lo_hz)
        hi = np.inf if hi_hz is None else float(hi_hz)
        if lo >= hi:
            raise DataError(f"band ({lo_hz}, {hi_hz}) is empty; give lo_hz < hi_hz in Hz.")
        keep = (self.f_hz >= lo) & (self.f_hz <= hi)
        if not np.any(keep):
            raise DataError(
                f"band ({lo_hz}, {hi_hz}) Hz holds no data points; the data span "
                f"{self.f_hz[0]:g}-{self.f_hz[-1]:g} Hz."
            )
        return self.replace(
            f_hz=self.f_hz[keep],
            response=self.response[keep],
            coherence=None if self.coherence is None else self.coherence[keep],
        )

    def _indices(self, wanted: Sequence[str] | str | None, names: tuple[str, ...], what: str) -> list[int]:
        if wanted is None:
            return list(range(len(names)))
        if isinstance(wanted, (str, int, np.integer)):
            wanted = [wanted]
        idx = []
        for item in wanted:
            if isinstance(item, (int, np.integer)):
                if not -len(names) <= item < len(names):
                    raise DataError(f"{what} index {item} is out of range for {len(names)} {what}.")
                idx.append(int(item) % len(names))
            elif item in names:
                idx.append(names.index(item))
            else:
                raise DataError(f"unknown {what[:-1]} {item!r}; the data has {what} {list(names)}.")
        return idx

    def select(
        self,
        outputs: Sequence[str] | str | None = None,
        inputs: Sequence[str] | str | None = None,
    ) -> FrequencyData:
        """The sub-matrix of the named (or indexed) outputs and inputs, in the order given."""
        oi = self._indices(outputs, self.outputs, "outputs")
        ii = self._indices(inputs, self.inputs, "inputs")
        g = self.response[:, oi][:, :, ii]
        coh = None if self.coherence is None else self.coherence[:, oi][:, :, ii]
        return self.replace(
            response=g,
            coherence=coh,
            outputs=[self.outputs[k] for k in oi],
            inputs=[self.inputs[k] for k in ii],
        )

    # ------------------------------------------------------------------ python-control
    def to_control(self):
        """The data as a ``control.FrequencyResponseData`` (omega in rad/s)."""
        import control

        fresp = np.transpose(self.response, (1, 2, 0))
        return control.FrequencyResponseData(
            fresp, self.w, inputs=list(self.inputs), outputs=list(self.outputs)
        )

    @classmethod
    def from_control(cls, frd: Any) -> FrequencyData:
        """Build from a ``control.FrequencyResponseData`` (or anything with ``omega``/``fresp``)."""
        try:
            omega = np.asarray(frd.omega, dtype=float)
            fresp = np.asarray(frd.frdata if hasattr(frd, "frdata") else frd.fresp)
        except AttributeError as exc:
            raise DataError(
                "from_control needs a control.FrequencyResponseData; "
                f"got {type(frd).__name__}."
            ) from exc
        inputs = getattr(frd, "input_labels", None)
        outputs = getattr(frd, "output_labels", None)
        return cls(
            omega / (2.0 * np.pi),
            np.transpose(fresp, (2, 0, 1)),
            inputs=inputs,
            outputs=outputs,
        )

    # ------------------------------------------------------------------ files
    def save(self, path: str | PathLike, overwrite: bool = False) -> Path:
        """Write the data to ``path``; the format follows the extension.

        Parameters
        ----------
        path : str or path-like
            ``.npz`` (numpy, no pickles; everything kept), ``.mat`` (MATLAB: ``Frequency``
            in Hz, ``ResponseData`` n_out x n_in x n_freq as MATLAB's ``frd``, ``InputName``,
            ``OutputName``, ``Coherence``), ``.csv`` (long format
            ``f_hz,output,input,re,im[,coherence]``; numbers and names only) or
            ``.uff``/``.unv`` (universal file dataset 58, one binary double-precision record
            per output/input pair, names in ID lines 4 and 5, coherence as function type 6).
        overwrite : bool
            Replace an existing file. By default an existing file is never touched.

        Returns
        -------
        pathlib.Path
            The path written.
        """
        return _save(self, path, overwrite)

    def __repr__(self) -> str:
        return (
            f"FrequencyData({self.n_freq} points, {self.f_hz[0]:.4g}-{self.f_hz[-1]:.4g} Hz, "
            f"outputs={list(self.outputs)}, inputs={list(self.inputs)}"
            f"{', with coherence' if self.coherence is not None else ''})"
        )


SUPPORTED_FORMATS = (".npz", ".mat", ".csv", ".uff", ".unv")


def load_frd(path: str | PathLike) -> FrequencyData:
    """Read a FrequencyData written by :meth:`FrequencyData.save` (or by another tool).

    Parameters
    ----------
    path : str or path-like
        A ``.npz``, ``.mat``, ``.csv``, ``.uff`` or ``.unv`` file (see
        :meth:`FrequencyData.save`). npz files are read with ``allow_pickle=False``: a file
        holding pickled objects is refused, never executed. MAT files may also come from
        MATLAB (``Frequency``, ``ResponseData``, optional ``FrequencyUnit``); UFF files from
        other modal-test software (dataset 58 FRF records, names from node and direction).

    Returns
    -------
    FrequencyData

    Raises
    ------
    DataError
        Unknown extension, missing file, corrupt or inconsistent content.
    """
    path = _check_path(path)
    if not path.is_file():
        raise DataError(f"cannot load {str(path)!r}: no such file.")
    try:
        return _READERS[path.suffix.lower()](path)
    except DataError as exc:
        raise DataError(f"{path.name}: {exc}") from exc


# ---------------------------------------------------------------------------- file helpers
_FORMAT = "robustctl.FrequencyData"


def _check_path(path: Any) -> Path:
    try:
        path = Path(path)
    except TypeError:
        raise DataError(f"path must be a file name (str or path-like); got {type(path).__name__}.") from None
    if path.suffix.lower() not in SUPPORTED_FORMATS:
        raise DataError(
            f"unknown file extension {path.suffix!r} of {path.name!r}; supported: "
            f"{', '.join(SUPPORTED_FORMATS)}."
        )
    return path


def _jsonable(obj: Any) -> Any:
    """A JSON-serialisable copy of ``obj`` (numpy values to Python, others to repr)."""
    if isinstance(obj, Mapping):
        return {str(k): _jsonable(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_jsonable(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return _jsonable(obj.tolist())
    if isinstance(obj, np.generic):
        obj = obj.item()
    if obj is None or isinstance(obj, (str, bool, int, float)):
        return obj
    return repr(obj)


def _json_dumps(obj: Any) -> str:
    return json.dumps(_jsonable(obj))


def _json_loads(text: str, what: str) -> dict:
    try:
        value = json.loads(text) if text else {}
    except ValueError as exc:
        raise DataError(f"the stored {what} is not valid JSON ({exc}).") from None
    if not isinstance(value, dict):
        raise DataError(f"the stored {what} must be a JSON object; got {type(value).__name__}.")
    return value


def _save(data: FrequencyData, path: Any, overwrite: bool) -> Path:
    """Write to a temporary file next to ``path`` and move it into place (never clobbering)."""
    path = _check_path(path)
    writer = _WRITERS[path.suffix.lower()]
    return write_atomically(path, lambda tmp: writer(data, tmp), overwrite)


def write_atomically(path: Path, write: Callable[[Path], None], overwrite: bool) -> Path:
    """Call ``write(tmp)`` on a temporary file in ``path``'s folder, then move it to ``path``.

    The move is ``os.replace`` (``overwrite=True``) or a hard link that fails if ``path``
    appeared meanwhile, so a reader never sees a partial file and an existing file is only
    replaced when asked. The temporary file is removed if ``write`` raises.

    Raises
    ------
    DataError
        The folder does not exist, or ``path`` exists and ``overwrite`` is False.
    """
    if not path.parent.is_dir():
        raise DataError(f"cannot save to {str(path)!r}: the directory {str(path.parent)!r} does not exist.")
    if path.exists() and not overwrite:
        raise DataError(
            f"{str(path)!r} already exists; pass overwrite=True to replace it or choose another name."
        )
    fd, tmp_name = tempfile.mkstemp(prefix=f".{path.stem}-", suffix=path.suffix, dir=path.parent)
    os.close(fd)
    tmp = Path(tmp_name)
    try:
        write(tmp)
        if overwrite:
            os.replace(tmp, path)
        else:
            _move_no_clobber(tmp, path)
    finally:
        if tmp.exists():
            tmp.unlink()
    return path


def _move_no_clobber(tmp: Path, path: Path) -> None:
    try:
        os.link(tmp, path)  # atomic: fails if path appeared meanwhile
    except FileExistsError:
        raise DataError(f"{str(path)!r} already exists; pass overwrite=True to replace it.") from None
    except OSError:  # a file system without hard links
        if path.exists():
            raise DataError(f"{str(path)!r} already exists; pass overwrite=True to replace it.") from None
        os.replace(tmp, path)


def _build(what: str, **fields: Any) -> FrequencyData:
    try:
        return FrequencyData(**fields)
    except DataError as exc:
        raise DataError(f"the {what} content is inconsistent: {exc}") from None


# ---------------------------------------------------------------------------- npz
def _write_npz(data: FrequencyData, path: Path) -> None:
    arrays = {
        "format": np.array(_FORMAT),
        "version": np.array(1),
        "f_hz": data.f_hz,
        "response": data.response,
        "inputs": np.array(data.inputs, dtype=str),
        "outputs": np.array(data.outputs, dtype=str),
        "units_json": np.array(_json_dumps(data.units)),
        "meta_json": np.array(_json_dumps(data.meta)),
    }
    if data.coherence is not None:
        arrays["coherence"] = data.coherence
    with open(path, "wb") as fh:
        np.savez(fh, **arrays)


def _npz_array(npz: Any, key: str, kinds: str) -> np.ndarray:
    if key not in npz.files:
        raise DataError(f"the npz file has no {key!r} array; it was not written by FrequencyData.save.")
    try:
        arr = npz[key]
    except ValueError as exc:  # object arrays need pickle, which is refused
        raise DataError(
            f"array {key!r} holds pickled Python objects, which robustctl never loads "
            f"(allow_pickle=False): {exc}"
        ) from None
    if arr.dtype.kind not in kinds:
        raise DataError(f"array {key!r} has dtype {arr.dtype}, expected kind {kinds!r}.")
    return arr


def _read_npz(path: Path) -> FrequencyData:
    try:
        npz = np.load(path, allow_pickle=False)
    except (ValueError, OSError, zipfile.BadZipFile, EOFError) as exc:
        raise DataError(f"not a readable npz file ({exc}).") from None
    if not isinstance(npz, np.lib.npyio.NpzFile):
        raise DataError("the file holds a single array, not a FrequencyData npz archive.")
    with npz:
        try:
            fmt = str(_npz_array(npz, "format", "U"))
            if fmt != _FORMAT:
                raise DataError(f"the npz archive is a {fmt!r}, not a {_FORMAT!r}.")
            fields = dict(
                f_hz=_npz_array(npz, "f_hz", "fiu"),
                response=_npz_array(npz, "response", "fciu"),
                inputs=[str(n) for n in _npz_array(npz, "inputs", "U").reshape(-1)],
                outputs=[str(n) for n in _npz_array(npz, "outputs", "U").reshape(-1)],
                coherence=_npz_array(npz, "coherence", "fiu") if "coherence" in npz.files else None,
                units=_json_loads(str(_npz_array(npz, "units_json", "U")), "units"),
                meta=_json_loads(str(_npz_array(npz, "meta_json", "U")), "meta"),
            )
        except (zipfile.BadZipFile, OSError, EOFError) as exc:
            raise DataError(f"the npz archive is corrupt ({exc}).") from None
    return _build("npz", **fields)


# ---------------------------------------------------------------------------- mat
def _cell(names: Sequence[str]) -> np.ndarray:
    cell = np.empty((len(names), 1), dtype=object)
    for k, name in enumerate(names):
        cell[k, 0] = name
    return cell


def _write_mat(data: FrequencyData, path: Path) -> None:
    from scipy.io import savemat

    mdict = {
        "Frequency": data.f_hz[:, None],
        "FrequencyUnit": "Hz",
        "ResponseData": np.transpose(data.response, (1, 2, 0)),
        "InputName": _cell(data.inputs),
        "OutputName": _cell(data.outputs),
        "robustctl_format": _FORMAT,
        "robustctl_units": _json_dumps(data.units),
        "robustctl_meta": _json_dumps(data.meta),
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


def _read_mat(path: Path) -> FrequencyData:
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
    units = _json_loads(_mat_string(mdict["robustctl_units"]), "units") if "robustctl_units" in mdict else {}
    meta = _json_loads(_mat_string(mdict["robustctl_meta"]), "meta") if "robustctl_meta" in mdict else {}
    return _build(
        "MAT", f_hz=f, response=resp, inputs=inputs, outputs=outputs, coherence=coh, units=units, meta=meta
    )


# ---------------------------------------------------------------------------- csv
_CSV_HEADER = ["f_hz", "output", "input", "re", "im"]


def _write_csv(data: FrequencyData, path: Path) -> None:
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


def _read_csv(path: Path) -> FrequencyData:
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
    return _build("CSV", f_hz=list(freqs), response=resp, outputs=list(outs), inputs=list(ins), coherence=coh)


# ---------------------------------------------------------------------------- uff 58
_UFF_ID = "robustctl FrequencyData"


def _uff_name_ok(name: str) -> bool:
    return 0 < len(name) <= 80 and name == name.strip() and name.isprintable()


def _uff_record(f: np.ndarray, values: np.ndarray, func_type: int, o: int, i: int, names: tuple[str, str]):
    import pyuff

    return pyuff.prepare_58(
        binary=1, id1=_UFF_ID, id2="coherence" if func_type == 6 else "frf", id3="NONE",
        id4=names[0], id5=names[1], func_type=func_type, rsp_node=o + 1, rsp_dir=0, ref_node=i + 1,
        ref_dir=0, data=values, x=f, abscissa_spacing=0, abscissa_spec_data_type=18,
        abscissa_axis_units_lab="Hz", ordinate_spec_data_type=0, orddenom_spec_data_type=0,
        z_axis_spec_data_type=0,
    )


def _write_uff(data: FrequencyData, path: Path) -> None:
    import pyuff

    if data.n_freq < 2:
        raise DataError("UFF dataset 58 needs at least 2 frequencies; save single points as .npz or .csv.")
    bad = [n for n in data.outputs + data.inputs if not _uff_name_ok(n)]
    if bad:
        raise DataError(
            f"signal names {bad} cannot be stored in UFF ID lines (printable characters, 1-80 of them, no "
            "leading/trailing spaces); rename the signals or save as .npz."
        )
    records = []
    for o, out in enumerate(data.outputs):
        for i, inp in enumerate(data.inputs):
            records.append(_uff_record(data.f_hz, data.response[:, o, i], 4, o, i, (out, inp)))
            if data.coherence is not None:
                coh = data.coherence[:, o, i].astype(float)
                records.append(_uff_record(data.f_hz, coh, 6, o, i, (out, inp)))
    path.unlink()  # pyuff opens the file itself; "add" mode (its binary "overwrite" truncates the header)
    try:
        pyuff.UFF(str(path)).write_sets(records, mode="add")
    except Exception as exc:  # pyuff raises bare Exceptions
        raise DataError(f"pyuff could not write the universal file ({exc}).") from None


def _uff_names(rec: dict) -> tuple[str, str]:
    if str(rec.get("id1", "")).strip() == _UFF_ID:
        return str(rec["id4"]), str(rec["id5"])
    out = f"{rec.get('rsp_node', 0)}:{rec.get('rsp_dir', 0)}"
    return out, f"{rec.get('ref_node', 0)}:{rec.get('ref_dir', 0)}"


def _uff_sets(path: Path) -> list[dict]:
    import pyuff

    try:
        uff = pyuff.UFF(str(path))
        idx = [k for k, t in enumerate(uff.get_set_types()) if int(t) == 58]
        sets = uff.read_sets(idx) if idx else []
    except Exception as exc:  # pyuff raises bare Exceptions
        raise DataError(f"not a readable universal file ({exc}).") from None
    sets = [sets] if isinstance(sets, dict) else list(sets)
    return [s for s in sets if int(s.get("func_type", -1)) in (4, 6)]


def _uff_collect(sets: list[dict]):
    f_ref = None
    outs: dict[str, int] = {}
    ins: dict[str, int] = {}
    found: dict[tuple[int, int, int], np.ndarray] = {}
    for rec in sets:
        out, inp = _uff_names(rec)
        x = np.asarray(rec["x"], dtype=float)
        if "rad" in str(rec.get("abscissa_axis_units_lab", "")).lower():
            x = x / (2.0 * np.pi)
        if f_ref is None:
            f_ref = x
        elif x.shape != f_ref.shape or not np.array_equal(x, f_ref):
            raise DataError(
                f"record {out!r}/{inp!r} has a different frequency axis ({x.size} points) from the first "
                f"({f_ref.size} points); all records must share one grid."
            )
        key = (int(rec["func_type"]), outs.setdefault(out, len(outs)), ins.setdefault(inp, len(ins)))
        if key in found:
            raise DataError(f"two records for output {out!r}, input {inp!r} (function type {key[0]}).")
        found[key] = np.asarray(rec["data"])
    return f_ref, list(outs), list(ins), found


def _read_uff(path: Path) -> FrequencyData:
    sets = _uff_sets(path)
    if not any(int(s["func_type"]) == 4 for s in sets):
        raise DataError("the universal file has no dataset 58 frequency-response (function type 4) records.")
    f, outs, ins, found = _uff_collect(sets)
    shape = (f.size, len(outs), len(ins))
    resp = np.empty(shape, complex)
    coh = np.empty(shape) if any(k[0] == 6 for k in found) else None
    for o, i in np.ndindex(shape[1], shape[2]):
        if (4, o, i) not in found:
            raise DataError(f"no FRF record for output {outs[o]!r}, input {ins[i]!r}; every pair is needed.")
        resp[:, o, i] = found[(4, o, i)]
        if coh is not None:
            if (6, o, i) not in found:
                raise DataError(f"coherence is given for some pairs but not for {outs[o]!r}/{ins[i]!r}.")
            coh[:, o, i] = np.real(found[(6, o, i)])
    return _build("UFF", f_hz=f, response=resp, outputs=outs, inputs=ins, coherence=coh)


_WRITERS = {
    ".npz": _write_npz, ".mat": _write_mat, ".csv": _write_csv, ".uff": _write_uff, ".unv": _write_uff
}
_READERS = {".npz": _read_npz, ".mat": _read_mat, ".csv": _read_csv, ".uff": _read_uff, ".unv": _read_uff}
