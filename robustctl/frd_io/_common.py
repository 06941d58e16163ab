"""Helpers shared by the FrequencyData file formats: paths, JSON fields, validation, atomic writes."""

from __future__ import annotations

import json
import os
import tempfile
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import DataError
from ..frd import FrequencyData

__all__ = ["FORMAT", "jsonable", "json_dumps", "json_loads", "write_atomically", "build"]

FORMAT = "robustctl.FrequencyData"


def jsonable(obj: Any) -> Any:
    """A JSON-serialisable copy of ``obj`` (numpy values to Python, others to repr)."""
    if isinstance(obj, Mapping):
        return {str(k): jsonable(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [jsonable(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return jsonable(obj.tolist())
    if isinstance(obj, np.generic):
        obj = obj.item()
    if obj is None or isinstance(obj, (str, bool, int, float)):
        return obj
    return repr(obj)


def json_dumps(obj: Any) -> str:
    return json.dumps(jsonable(obj))


def json_loads(text: str, what: str) -> dict:
    try:
        value = json.loads(text) if text else {}
    except ValueError as exc:
        raise DataError(f"the stored {what} is not valid JSON ({exc}).") from None
    if not isinstance(value, dict):
        raise DataError(f"the stored {what} must be a JSON object; got {type(value).__name__}.")
    return value


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
            move_no_clobber(tmp, path)
    finally:
        if tmp.exists():
            tmp.unlink()
    return path


def move_no_clobber(tmp: Path, path: Path) -> None:
    try:
        os.link(tmp, path)  # atomic: fails if path appeared meanwhile
    except FileExistsError:
        raise DataError(f"{str(path)!r} already exists; pass overwrite=True to replace it.") from None
    except OSError:  # a file system without hard links
        if path.exists():
            raise DataError(f"{str(path)!r} already exists; pass overwrite=True to replace it.") from None
        os.replace(tmp, path)


def build(what: str, **fields: Any) -> FrequencyData:
    try:
        return FrequencyData(**fields)
    except DataError as exc:
        raise DataError(f"the {what} content is inconsistent: {exc}") from None
