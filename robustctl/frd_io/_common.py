"""Helpers shared by the FrequencyData file formats: paths, JSON fields, validation, atomic writes."""

from __future__ import annotations

import json
import os
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import DataError
from ..frd import FrequencyData

__all__ = ["FORMAT", "json_dumps", "json_loads", "move_no_clobber", "build"]

FORMAT = "robustctl.FrequencyData"


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


def json_dumps(obj: Any) -> str:
    return json.dumps(_jsonable(obj))


def json_loads(text: str, what: str) -> dict:
    try:
        value = json.loads(text) if text else {}
    except ValueError as exc:
        raise DataError(f"the stored {what} is not valid JSON ({exc}).") from None
    if not isinstance(value, dict):
        raise DataError(f"the stored {what} must be a JSON object; got {type(value).__name__}.")
    return value


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
