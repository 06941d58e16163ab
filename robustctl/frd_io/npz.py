"""FrequencyData in numpy ``.npz`` archives (no pickles: ``allow_pickle=False``)."""

from __future__ import annotations

import zipfile
import zlib
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import DataError
from ..frd import FrequencyData
from ._common import FORMAT, build, json_dumps, json_loads

__all__ = ["read_npz", "write_npz"]

_NPZ_KEYS = {
    "format", "version", "f_hz", "response", "inputs", "outputs", "units_json", "meta_json", "coherence",
    "experiment_json",
}

#: Format version written and read.
_VERSION = 1


def write_npz(data: FrequencyData, path: Path) -> None:
    arrays = {
        "format": np.array(FORMAT),
        "version": np.array(_VERSION),
        "f_hz": data.f_hz,
        "response": data.response,
        "inputs": np.array(data.inputs, dtype=str),
        "outputs": np.array(data.outputs, dtype=str),
        "units_json": np.array(json_dumps(data.units)),
        "meta_json": np.array(json_dumps(data.meta)),
        "experiment_json": np.array(json_dumps(data.experiment.to_dict())),
    }
    if data.coherence is not None:
        arrays["coherence"] = data.coherence
    with open(path, "wb") as fh:
        np.savez(fh, **arrays)


_OWN_ARRAYS = (
    " To load arrays of your own, build rc.FrequencyData(f_hz, response, inputs=..., outputs=...) from "
    "them (np.load) and save that."
)


def _npz_array(npz: Any, key: str, kinds: str) -> np.ndarray:
    if key not in npz.files:
        raise DataError(
            f"the npz file has no {key!r} array; it was not written by FrequencyData.save.{_OWN_ARRAYS}"
        )
    try:
        arr = npz[key]
    except ValueError as exc:
        if "allow_pickle" in str(exc):  # object arrays need pickle, which is refused
            raise DataError(
                f"array {key!r} holds pickled Python objects, which robustctl never loads "
                "(allow_pickle=False)."
            ) from None
        raise DataError(f"array {key!r} has a corrupt .npy header or data ({exc}).") from None
    except (NotImplementedError, RuntimeError, EOFError, OSError, zlib.error, zipfile.BadZipFile) as exc:
        # NotImplementedError: zipfile meets an unknown compression method (a flipped bit in its field)
        raise DataError(
            f"the npz archive is corrupt: array {key!r} cannot be read ({type(exc).__name__}: {exc})."
        ) from None
    if arr.dtype.kind not in kinds:
        raise DataError(f"array {key!r} has dtype {arr.dtype}, expected kind {kinds!r}.")
    return arr


def read_npz(path: Path) -> FrequencyData:
    try:
        npz = np.load(path, allow_pickle=False)
    except (ValueError, OSError, zipfile.BadZipFile, EOFError, NotImplementedError, RuntimeError) as exc:
        raise DataError(f"not a readable npz file ({type(exc).__name__}: {exc}).") from None
    if not isinstance(npz, np.lib.npyio.NpzFile):
        raise DataError("the file holds a single array, not a FrequencyData npz archive.")
    with npz:
        unexpected = sorted(set(npz.files) - _NPZ_KEYS)
        if unexpected:
            raise DataError(
                f"the npz archive holds unexpected arrays {unexpected}; it is corrupt or was not "
                f"written by FrequencyData.save.{_OWN_ARRAYS}"
            )
        try:
            fmt = str(_npz_array(npz, "format", "U"))
            if fmt != FORMAT:
                raise DataError(f"the npz archive is a {fmt!r}, not a {FORMAT!r}.")
            version = _npz_array(npz, "version", "iu") if "version" in npz.files else None
            if version is not None and (version.shape != () or int(version) != _VERSION):
                raise DataError(
                    f"the npz archive has format version {version.tolist()!r}; this robustctl reads version "
                    f"{_VERSION}. Load it with the robustctl that wrote it (a newer one?) and save it again."
                )
            fields = dict(
                f_hz=_npz_array(npz, "f_hz", "fiu"),
                response=_npz_array(npz, "response", "fciu"),
                inputs=[str(n) for n in _npz_array(npz, "inputs", "U").reshape(-1)],
                outputs=[str(n) for n in _npz_array(npz, "outputs", "U").reshape(-1)],
                coherence=_npz_array(npz, "coherence", "fiu") if "coherence" in npz.files else None,
                units=json_loads(str(_npz_array(npz, "units_json", "U")), "units"),
                meta=json_loads(str(_npz_array(npz, "meta_json", "U")), "meta"),
                experiment=json_loads(str(_npz_array(npz, "experiment_json", "U")), "experiment")
                if "experiment_json" in npz.files else None,
            )
        except (zipfile.BadZipFile, OSError, EOFError) as exc:
            raise DataError(f"the npz archive is corrupt ({exc}).") from None
    return build("npz", **fields)
