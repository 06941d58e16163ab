"""FrequencyData in numpy ``.npz`` archives (no pickles: ``allow_pickle=False``)."""

from __future__ import annotations

import zipfile
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import DataError
from ..frd import FrequencyData
from ._common import FORMAT, build, json_dumps, json_loads

__all__ = ["read_npz", "write_npz"]

def write_npz(data: FrequencyData, path: Path) -> None:
    arrays = {
        "format": np.array(FORMAT),
        "version": np.array(1),
        "f_hz": data.f_hz,
        "response": data.response,
        "inputs": np.array(data.inputs, dtype=str),
        "outputs": np.array(data.outputs, dtype=str),
        "units_json": np.array(json_dumps(data.units)),
        "meta_json": np.array(json_dumps(data.meta)),
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


def read_npz(path: Path) -> FrequencyData:
    try:
        npz = np.load(path, allow_pickle=False)
    except (ValueError, OSError, zipfile.BadZipFile, EOFError) as exc:
        raise DataError(f"not a readable npz file ({exc}).") from None
    if not isinstance(npz, np.lib.npyio.NpzFile):
        raise DataError("the file holds a single array, not a FrequencyData npz archive.")
    with npz:
        try:
            fmt = str(_npz_array(npz, "format", "U"))
            if fmt != FORMAT:
                raise DataError(f"the npz archive is a {fmt!r}, not a {FORMAT!r}.")
            fields = dict(
                f_hz=_npz_array(npz, "f_hz", "fiu"),
                response=_npz_array(npz, "response", "fciu"),
                inputs=[str(n) for n in _npz_array(npz, "inputs", "U").reshape(-1)],
                outputs=[str(n) for n in _npz_array(npz, "outputs", "U").reshape(-1)],
                coherence=_npz_array(npz, "coherence", "fiu") if "coherence" in npz.files else None,
                units=json_loads(str(_npz_array(npz, "units_json", "U")), "units"),
                meta=json_loads(str(_npz_array(npz, "meta_json", "U")), "meta"),
            )
        except (zipfile.BadZipFile, OSError, EOFError) as exc:
            raise DataError(f"the npz archive is corrupt ({exc}).") from None
    return build("npz", **fields)
