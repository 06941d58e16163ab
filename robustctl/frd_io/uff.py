"""FrequencyData in universal files, dataset 58 (``.uff``/``.unv``, via pyuff).

How the data were made (:class:`~robustctl.frd.Experiment`) is kept twice: compactly in ID
line 2 of every record (``frf input=measured exc=random fs=200 nperseg=2048
window=hamming nov=1024 navg=19``; an impact test's ``tau=`` exponential-window time constant,
``fwin=`` force-window length and ``pretrig=`` hit time, s; read back from robustctl's own
files), and completely,
with ``meta``, in a sidecar ``<file>.uff.json`` that :func:`read_uff` reads when it is present
and matches the file's channels. A file without either loads as not described.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..errors import DataError
from ..frd import Experiment, FrequencyData
from ._common import MAX_FILE_BYTES, build, json_dumps, json_loads, read_limited

__all__ = ["read_uff", "write_uff", "sidecar_path", "write_sidecar"]

_SIDECAR = "robustctl.FrequencyData uff sidecar"
#: ID-line-2 keys of the compact experiment description and the Experiment fields they hold.
_ID2_KEYS = {
    "input": "input_kind", "exc": "excitation", "fs": "fs_hz", "nperseg": "nperseg", "window": "window",
    "whole": "whole_periods", "hold": "hold_divided", "nov": "noverlap", "navg": "n_averages",
    "tau": "exp_window_tau_s", "fwin": "force_window_s", "pretrig": "pretrigger_s",
}

_UFF_ID = "robustctl FrequencyData"
_SHAPE_TAG = "robustctl shape"
#: UFF "specific data type" codes of common SI units (dataset 58, ID-line 9/10 fields; unknown 0).
_DATA_TYPES = {"m": 8, "N": 13, "m/s": 11, "m/s^2": 12, "m/s2": 12, "Pa": 15, "kg": 16, "s": 17, "Hz": 18}
_TYPE_UNITS = {code: unit for unit, code in reversed(list(_DATA_TYPES.items()))}
_UNIT_LABEL_MAX = 20  # characters of an axis-unit label in dataset 58


def _uff_name_ok(name: str) -> bool:
    return 0 < len(name) <= 80 and name == name.strip() and name.isprintable()


def _uff_shape_id(data: FrequencyData) -> str:
    """ID line 3 of every record: the complete set, so a reader can tell a truncated file."""
    n_rec = data.n_out * data.n_in * (1 if data.coherence is None else 2)
    return f"{_SHAPE_TAG} {data.n_out}x{data.n_in} records={n_rec}"


def _uff_record(
    f: np.ndarray, values: np.ndarray, func_type: int, o: int, i: int, names: tuple[str, str],
    units: tuple[str, str] = ("", ""), id3: str = "NONE", experiment: Experiment | None = None,
):
    """One dataset-58 record; ``units`` (output, input) go to the ordinate numerator and
    denominator labels and data types (an FRF is output units per input unit); ``id3`` is
    :func:`_uff_shape_id`."""
    import pyuff

    out_u, in_u = units if func_type == 4 else ("", "")
    return pyuff.prepare_58(
        binary=1, id1=_UFF_ID, id2=id2_text("coherence" if func_type == 6 else "frf", experiment), id3=id3,
        id4=names[0], id5=names[1], func_type=func_type, rsp_node=o + 1, rsp_dir=0, ref_node=i + 1,
        ref_dir=0, data=values, x=f, abscissa_spacing=0, abscissa_spec_data_type=18,
        abscissa_axis_units_lab="Hz", ordinate_spec_data_type=_DATA_TYPES.get(out_u, 0),
        ordinate_axis_units_lab=out_u, orddenom_spec_data_type=_DATA_TYPES.get(in_u, 0),
        orddenom_axis_units_lab=in_u, z_axis_spec_data_type=0,
    )


def _signal_units(data: FrequencyData) -> dict[str, str]:
    units = {n: str(data.units.get(n, "")) for n in data.outputs + data.inputs}
    bad = {n: u for n, u in units.items() if len(u) > _UNIT_LABEL_MAX or not u.isprintable()}
    if bad:
        raise DataError(
            f"units {bad} do not fit a UFF axis label (printable, at most {_UNIT_LABEL_MAX} characters); "
            "shorten them (data.replace(units=...)) or save as .npz."
        )
    return units


def write_uff(data: FrequencyData, path: Path) -> None:
    import pyuff

    if data.n_freq < 2:
        raise DataError("UFF dataset 58 needs at least 2 frequencies; save single points as .npz or .csv.")
    bad = [n for n in data.outputs + data.inputs if not _uff_name_ok(n)]
    if bad:
        raise DataError(
            f"signal names {bad} cannot be stored in UFF ID lines (printable characters, 1-80 of them, no "
            "leading/trailing spaces); rename the signals or save as .npz."
        )
    units = _signal_units(data)
    records, id3 = [], _uff_shape_id(data)
    for o, out in enumerate(data.outputs):
        for i, inp in enumerate(data.inputs):
            records.append(
                _uff_record(
                    data.f_hz, data.response[:, o, i], 4, o, i, (out, inp), (units[out], units[inp]), id3,
                    data.experiment,
                )
            )
            if data.coherence is not None:
                coh = data.coherence[:, o, i].astype(float)
                records.append(_uff_record(data.f_hz, coh, 6, o, i, (out, inp), id3=id3,
                                           experiment=data.experiment))
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


def _uff_complete(path: Path) -> None:
    """Refuse a file whose last dataset is cut off (every dataset ends with a ``-1`` line)."""
    raw = read_limited(path, MAX_FILE_BYTES)
    if not raw.rstrip(b" \r\n").endswith(b"    -1"):
        raise DataError(
            "the universal file does not end with a dataset delimiter ('    -1'): it is truncated or "
            "corrupt, so it may not hold complete channels."
        )


def _uff_check_record(rec: dict) -> None:
    n_x, n_y = np.size(rec.get("x", [])), np.size(rec.get("data", []))
    n_pts = rec.get("num_pts", n_x)
    if not n_x == n_y == int(n_pts) or n_x == 0:
        raise DataError(
            f"a dataset 58 record holds {n_x} frequencies and {n_y} values but declares {n_pts}; "
            "the file is truncated or corrupt."
        )


def _uff_check_shape(sets: list[dict]) -> None:
    """For files written by robustctl: the records present are the complete set named in ID line 3."""
    for rec in sets:
        id3 = str(rec.get("id3", "")).strip()
        if str(rec.get("id1", "")).strip() != _UFF_ID or not id3.startswith(_SHAPE_TAG):
            continue
        want = id3.rsplit("records=", 1)[-1]
        if not want.isdigit() or int(want) != len(sets):
            raise DataError(
                f"the universal file holds {len(sets)} FRF/coherence records but was written with "
                f"{want} ({id3[len(_SHAPE_TAG):].strip()}); it is truncated or corrupt."
            )
        return


def _uff_sets(path: Path) -> list[dict]:
    import pyuff

    _uff_complete(path)
    try:
        uff = pyuff.UFF(str(path))
        idx = [k for k, t in enumerate(uff.get_set_types()) if int(t) == 58]
        sets = uff.read_sets(idx) if idx else []
    except Exception as exc:  # pyuff raises bare Exceptions
        raise DataError(f"not a readable universal file ({exc}).") from None
    sets = [sets] if isinstance(sets, dict) else list(sets)
    if len(sets) != len(idx):
        raise DataError(f"pyuff read {len(sets)} of the {len(idx)} dataset 58 records; the file is corrupt.")
    try:
        sets = [s for s in sets if int(s.get("func_type", -1)) in (4, 6)]
    except (TypeError, ValueError):
        raise DataError("a dataset 58 record has an unreadable function type; the file is corrupt.") from None
    for rec in sets:
        _uff_check_record(rec)
    _uff_check_shape(sets)
    return sets


def _record_unit(rec: dict, side: str) -> str:
    """The unit of the ordinate numerator (``side="ordinate"``) or denominator (``"orddenom"``):
    the axis label when given, else the SI unit of the specific data type."""
    label = str(rec.get(f"{side}_axis_units_lab", "") or "").strip()
    if label and label.upper() != "NONE":
        return label
    return _TYPE_UNITS.get(int(rec.get(f"{side}_spec_data_type", 0) or 0), "")


def _uff_units(sets: list[dict]) -> dict[str, str]:
    """Signal units from the FRF records (output: numerator, input: denominator); first one wins."""
    units: dict[str, str] = {}
    for rec in sets:
        if int(rec["func_type"]) != 4:
            continue
        out, inp = _uff_names(rec)
        for name, side in ((out, "ordinate"), (inp, "orddenom")):
            unit = _record_unit(rec, side)
            if unit and units.setdefault(name, unit) != unit:
                raise DataError(
                    f"signal {name!r} is in {units[name]!r} in one FRF record and in {unit!r} in another "
                    f"(record {out!r}/{inp!r}); convert the records to one unit per signal before loading."
                )
    return units


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
            how = (
                f"{x.size} points against {f_ref.size}" if x.shape != f_ref.shape
                else f"largest difference {np.max(np.abs(x - f_ref)):.6g} Hz"
            )
            raise DataError(
                f"record {out!r}/{inp!r} has a different frequency axis from the first record ({how}); "
                "all records must share one grid (export them with the same frequency lines)."
            )
        key = (int(rec["func_type"]), outs.setdefault(out, len(outs)), ins.setdefault(inp, len(ins)))
        if key in found:
            raise DataError(f"two records for output {out!r}, input {inp!r} (function type {key[0]}).")
        found[key] = np.asarray(rec["data"])
    return f_ref, list(outs), list(ins), found


def read_uff(path: Path) -> FrequencyData:
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
    units = _uff_units(sets)
    experiment, meta = _id2_experiment(sets), {}
    side = _read_sidecar(path, outs, ins, f.size)
    if side is not None:
        experiment, meta = side
    return build("UFF", f_hz=f, response=resp, outputs=outs, inputs=ins, coherence=coh, units=units,
                 meta=meta, experiment=experiment)


# ---------------------------------------------------------------------------- experiment
def id2_text(kind: str, experiment: Experiment | None) -> str:
    """ID line 2: ``kind`` and the compact experiment description (at most 80 characters)."""
    text = kind
    if experiment is None:
        return text
    values = experiment.to_dict()
    for key, name in _ID2_KEYS.items():
        value = values[name]
        if value is None or (name == "hold_divided" and not value):
            continue
        if isinstance(value, bool):
            value = int(value)
        if isinstance(value, float):
            value = f"{value:g}" if float(f"{value:g}") == value else repr(value)  # shortest exact text
        value = str(value)
        if name == "window" and (not isinstance(values[name], str) or " " in value):
            continue  # a tuple or user window: the sidecar keeps it
        token = f" {key}={value}"
        if len(text) + len(token) <= 80:
            text += token
    return text


def _id2_experiment(sets: list[dict]) -> Experiment | None:
    """The experiment described in ID line 2 of robustctl's records (the first FRF record's)."""
    for rec in sets:
        if str(rec.get("id1", "")).strip() != _UFF_ID or int(rec["func_type"]) != 4:
            continue
        tokens = str(rec.get("id2", "")).split()[1:]
        found: dict[str, object] = {}
        for token in tokens:
            key, sep, value = token.partition("=")
            if not sep or key not in _ID2_KEYS:
                continue
            name = _ID2_KEYS[key]
            try:
                if name in ("fs_hz", "exp_window_tau_s", "force_window_s", "pretrigger_s"):
                    found[name] = float(value)
                elif name in ("nperseg", "noverlap", "n_averages"):
                    found[name] = int(value)
                elif name in ("whole_periods", "hold_divided"):
                    found[name] = bool(int(value))
                else:
                    found[name] = value
            except ValueError:
                raise DataError(
                    f"ID line 2 {rec.get('id2')!r} holds an unreadable {key}={value!r}."
                ) from None
        return Experiment.from_dict(found)
    return None


def sidecar_path(path: Path) -> Path:
    """``<file>.uff.json`` next to a universal file."""
    return path.with_name(path.name + ".json")


def write_sidecar(data: FrequencyData, path: Path) -> None:
    """Write the sidecar of ``data`` (experiment, meta and the channels it belongs to) to ``path``."""
    doc = {
        "format": _SIDECAR, "outputs": list(data.outputs), "inputs": list(data.inputs),
        "n_freq": data.n_freq, "experiment": data.experiment.to_dict(), "meta": data.meta,
    }
    path.write_text(json_dumps(doc) + "\n", encoding="utf-8")


def _read_sidecar(path: Path, outs: list[str], ins: list[str], n_freq: int):
    """``(experiment, meta)`` from the sidecar of ``path``, or None when there is none.

    A sidecar written for other channels (a file renamed over another) is refused."""
    side = sidecar_path(path)
    if not side.is_file():
        return None
    try:
        doc = json_loads(read_limited(side, MAX_FILE_BYTES).decode("utf-8"), f"sidecar {side.name}")
    except UnicodeDecodeError:
        raise DataError(f"the sidecar {side.name} is not UTF-8 JSON; remove or repair it.") from None
    if doc.get("format") != _SIDECAR:
        raise DataError(f"{side.name} is not a robustctl UFF sidecar; remove it or rename it.")
    mine = (sorted(doc.get("outputs", [])), sorted(doc.get("inputs", [])), doc.get("n_freq"))
    if mine != (sorted(outs), sorted(ins), n_freq):
        raise DataError(
            f"the sidecar {side.name} describes outputs {doc.get('outputs')} x inputs {doc.get('inputs')} at "
            f"{doc.get('n_freq')} frequencies, not this file's {outs} x {ins} at {n_freq}; it belongs to "
            "another file. Remove it (the data then load as not described) or restore the right one."
        )
    meta = doc.get("meta") or {}
    if not isinstance(meta, dict):
        raise DataError(f"the sidecar {side.name} holds a meta that is not a JSON object.")
    return Experiment.from_dict(doc.get("experiment")), meta
