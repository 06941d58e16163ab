"""File formats of FrequencyData: npz, csv, MATLAB mat and UFF dataset 58, one module each.

:func:`load_frd` reads, :func:`save_frd` (behind :meth:`FrequencyData.save`) writes; the
format follows the file extension. Every reader treats the file as untrusted input and
refuses inconsistent content with a :class:`~robustctl.errors.DataError`.
"""

from __future__ import annotations

from os import PathLike
from pathlib import Path
from typing import Any

from ..checks import flag
from ..errors import DataError
from ..frd import Experiment, FrequencyData, register_method
from ._common import write_atomically
from .csv_format import read_csv, write_csv
from .mat import read_mat, write_mat
from .npz import read_npz, write_npz
from .uff import read_uff, sidecar_path, write_sidecar, write_uff

__all__ = ["load_frd", "save_frd", "SUPPORTED_FORMATS"]

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
        CSV files written by robustctl carry completeness markers (a first line with the
        frequency, output, input and row counts, a last line ``# end, N rows``), so a cut
        file is refused; a CSV without them (a user's own) is read when every frequency holds
        every output/input pair (:mod:`robustctl.frd_io.csv_format`).

    Returns
    -------
    FrequencyData

    Raises
    ------
    DataError
        Unknown extension, missing file, corrupt, truncated or inconsistent content.
    """
    if isinstance(path, (str, PathLike)) and Path(path).is_dir():
        raise DataError(f"cannot load {str(path)!r}: it is a directory, not a file; give the file's path.")
    path = _check_path(path)
    if path.is_dir():
        raise DataError(f"cannot load {str(path)!r}: it is a directory, not a file; give the file's path.")
    if not path.is_file():
        raise DataError(f"cannot load {str(path)!r}: no such file.")
    try:
        return _READERS[path.suffix.lower()](path)
    except DataError as exc:
        raise DataError(f"{path.name}: {exc}") from exc


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


def save_frd(data: FrequencyData, path: Any, overwrite: bool = False) -> Path:
    """Write ``data`` to ``path`` (format from the extension; see :meth:`FrequencyData.save`).

    Writes to a temporary file next to ``path`` and moves it into place
    (:func:`~robustctl.frd_io._common.write_atomically`), never clobbering an existing file
    unless ``overwrite`` is True (a real boolean).
    """
    overwrite = flag(overwrite, "overwrite")
    path = _check_path(path)
    writer = _WRITERS[path.suffix.lower()]
    written = write_atomically(path, lambda tmp: writer(data, tmp), overwrite)
    side = sidecar_path(path)
    if writer is write_uff and (data.experiment != Experiment() or data.meta):
        # the sidecar belongs to the file just written: replace any old one
        write_atomically(side, lambda tmp: write_sidecar(data, tmp), True)
    elif writer is write_uff and side.is_file():
        side.unlink()  # an old file's description must not be read with this one
    return written


_WRITERS = {".npz": write_npz, ".mat": write_mat, ".csv": write_csv, ".uff": write_uff, ".unv": write_uff}
_READERS = {".npz": read_npz, ".mat": read_mat, ".csv": read_csv, ".uff": read_uff, ".unv": read_uff}

register_method("save", save_frd)
