"""The registry of controller file formats: extension -> writer and reader."""

from __future__ import annotations

from .c_header import read_header, write_header
from .files import read_csv, read_json, read_mat, write_csv, write_json, write_mat
from .sos_file import read_sos, write_sos

__all__ = ["WRITERS", "READERS", "FORMATS"]

#: ``writer(ctrl: ControllerData, path, **options)`` per extension
WRITERS = {".json": write_json, ".csv": write_csv, ".mat": write_mat, ".h": write_header, ".sos": write_sos}
#: ``reader(path) -> ControllerData`` per extension
READERS = {".json": read_json, ".csv": read_csv, ".mat": read_mat, ".h": read_header, ".sos": read_sos}
#: format names (extensions without the dot)
FORMATS = tuple(k[1:] for k in WRITERS)
