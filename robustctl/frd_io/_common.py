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

__all__ = [
    "FORMAT", "MAX_FILE_BYTES", "jsonable", "json_dumps", "json_loads", "write_atomically", "build",
    "read_limited",
]

FORMAT = "robustctl.FrequencyData"
#: Largest FrequencyData file read (bytes); a larger one is refused before it is read.
MAX_FILE_BYTES = 1 << 30


def read_limited(path: Path, limit: int) -> bytes:
    """The bytes of ``path``; refuses a file larger than ``limit`` or one that cannot be read."""
    try:
        size = path.stat().st_size
        if size > limit:
            raise DataError(f"the file has {size} bytes, more than the {limit} read; is it the right file?")
        with open(path, "rb") as fh:
            return fh.read(limit + 1)
    except OSError as exc:
        raise DataError(f"cannot read the file ({type(exc).__name__}: {exc.strerror or exc}).") from None


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
        The folder does not exist, ``path`` is a folder or a read-only file, ``path`` exists and
        ``overwrite`` is False, or the write fails (permissions, full disk: the cause is named and
        an existing file is left unchanged).
    """
    if not path.parent.is_dir():
        raise DataError(f"cannot save to {str(path)!r}: the directory {str(path.parent)!r} does not exist.")
    if path.is_dir():
        raise DataError(f"cannot save to {str(path)!r}: it is a directory; give a file name.")
    if path.exists() and not overwrite:
        raise DataError(
            f"{str(path)!r} already exists; pass overwrite=True to replace it or choose another name."
        )
    if path.exists() and not os.access(path, os.W_OK):
        raise DataError(
            f"cannot save to {str(path)!r}: the file is read-only; make it writable to replace it "
            "or choose another name."
        )
    try:
        _write_via_temporary(path, write, overwrite)
    except OSError as exc:  # read-only folder or file, disk full, quota, ...
        reason = exc.strerror or str(exc)
        raise DataError(
            f"cannot save to {str(path)!r}: {reason} ({type(exc).__name__}); the existing file, if any, "
            "is unchanged. Check the folder's permissions and free space, or choose another path."
        ) from exc
    return path


def _write_via_temporary(path: Path, write: Callable[[Path], None], overwrite: bool) -> None:
    fd, tmp_name = tempfile.mkstemp(prefix=f".{path.stem}-", suffix=path.suffix, dir=path.parent)
    os.close(fd)
    tmp = Path(tmp_name)
    try:
        write(tmp)
        _default_permissions(tmp)
        if overwrite:
            os.replace(tmp, path)
        else:
            move_no_clobber(tmp, path)
    finally:
        if tmp.exists():
            tmp.unlink()


def _default_permissions(tmp: Path) -> None:
    """``mkstemp`` makes the file private (0600); give it the mode a plain ``open`` would (umask)."""
    os.chmod(tmp, 0o666 & ~_current_umask())


def _current_umask() -> int:
    """The process umask, read without changing it (``os.umask`` would race with other threads)."""
    try:
        with open("/proc/self/status", encoding="ascii") as fh:
            for line in fh:
                if line.startswith("Umask:"):
                    return int(line.split()[1], 8)
    except (OSError, ValueError):
        pass
    return 0o022


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
