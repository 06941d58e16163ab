"""Structural check of a MAT-5 file before ``scipy.io.loadmat`` sees it.

``scipy.io.loadmat`` (scipy 1.17, ``_mio5_utils.pyx``) trusts the element tags of a MAT-5
file: a byte inserted or a few bits flipped in a valid file can make its Cython reader
index past a buffer (sizes in a tag or in a matrix's dimensions that disagree with the
bytes that follow), and the interpreter dies with SIGSEGV/SIGBUS instead of raising.
(Observed: every crash in a mutation run of 400 files was one byte inserted inside a
miCOMPRESSED variable. Its tag's byte count no longer reaches the end of the zlib stream;
scipy inflates the truncated stream without asking for its end, so the next variable's tag
is read one byte off and the Cython reader, ``VarReader5`` called from ``_mio5.py``
``read_var_array``, acts on garbage sizes. A precedent is scipy issue #6072, a segfault on
truncated files.) So every file is walked here first, with only ``struct`` and ``zlib``, against the layout of
the MAT-File Format reference (MathWorks, "MAT-File Format", 2024, ch. 1: 128-byte header,
8-byte tags, small data elements, miMATRIX sub-elements, miCOMPRESSED zlib streams):

* the header's version is 0x0100 and its endian indicator ``IM``/``MI``;
* every tag's byte count fits inside its parent (the file, a matrix or a decompressed
  stream);
* miCOMPRESSED streams inflate completely, under :data:`MAX_INFLATED_BYTES`, and their
  content is checked recursively;
* every miMATRIX has array flags, dimensions (non-negative, product under
  :data:`MAX_ELEMENTS`) and a name, and its data agree with its class: numeric real (and
  imaginary) parts of exactly ``prod(dims)`` values, char data of ``prod(dims)``
  characters, ``prod(dims)`` cells, ``prod(dims) * n_fields`` struct fields, each a
  checked miMATRIX. Sparse, object, function and opaque classes are refused (FrequencyData
  files never hold them).

Anything else is a :class:`~robustctl.errors.DataError`; only a file that passes is read
by scipy, from the very bytes that were checked.
"""

from __future__ import annotations

import struct
import zlib

from ..errors import DataError

__all__ = ["check_mat5", "MAX_INFLATED_BYTES", "MAX_ELEMENTS"]

#: Cap on the bytes a miCOMPRESSED element may inflate to (a zip bomb is refused).
MAX_INFLATED_BYTES = 256 * 2**20
#: Cap on the number of values in one array.
MAX_ELEMENTS = 2**27
_MAX_DEPTH = 16

_MI_INT8, _MI_UINT8, _MI_INT16, _MI_UINT16, _MI_INT32, _MI_UINT32 = 1, 2, 3, 4, 5, 6
_MI_MATRIX, _MI_COMPRESSED, _MI_UTF8, _MI_UTF16, _MI_UTF32 = 14, 15, 16, 17, 18
#: Bytes per value of the numeric element types (miINT8 ... miUINT64).
_ITEMSIZE = {1: 1, 2: 1, 3: 2, 4: 2, 5: 4, 6: 4, 7: 4, 9: 8, 12: 8, 13: 8}
_CHAR_ITEMSIZE = {_MI_INT8: 1, _MI_UINT8: 1, _MI_INT16: 2, _MI_UINT16: 2, _MI_UTF16: 2, _MI_UTF32: 4}
_NUMERIC_CLASSES = range(6, 16)  # mxDOUBLE ... mxUINT64
_CELL, _STRUCT, _CHAR = 1, 2, 4


#: What to do with a file that is not MAT-5 at all (MATLAB's v4 or v7.3 formats, or not MATLAB).
_RESAVE = (
    "; robustctl reads MAT-5 files (MATLAB save -v7 or -v6, scipy.io.savemat): re-save a v4 or "
    "v7.3 file with save(name, '-v7')"
)


def _bad(what: str) -> DataError:
    return DataError(f"not a readable MAT file (corrupt MAT-5 structure: {what}).")


def check_mat5(raw: bytes) -> None:
    """Walk the whole MAT-5 structure of ``raw``; raise :class:`DataError` on any inconsistency."""
    if len(raw) < 128:
        raise _bad(f"{len(raw)} bytes, shorter than the 128-byte header{_RESAVE}")
    order = {b"IM": "<", b"MI": ">"}.get(raw[126:128])
    if order is None:
        raise _bad(f"endian indicator {raw[126:128]!r} is neither b'IM' nor b'MI'{_RESAVE}")
    if struct.unpack(order + "H", raw[124:126])[0] != 0x0100:
        raise _bad(f"the header's version is not 0x0100 (only MAT-5, not v7.3/HDF5, is read){_RESAVE}")
    _Walker(order).top_level(memoryview(raw)[128:], depth=0)


class _Walker:
    def __init__(self, order: str) -> None:
        self.order = order
        self.inflated = 0

    def tag(self, buf: memoryview, pos: int) -> tuple[int, int, int, int]:
        """``(type, nbytes, data_start, next_pos)`` of the element at ``pos`` (8-byte padded)."""
        if pos + 8 > len(buf):
            raise _bad(f"an element tag at offset {pos} runs past the end of its parent")
        first, second = struct.unpack(self.order + "II", buf[pos : pos + 8])
        if first >> 16:  # small data element: type and size in the first word, data in the second
            nbytes, mtype = first >> 16, first & 0xFFFF
            if nbytes > 4:
                raise _bad(f"a small data element claims {nbytes} bytes (at most 4)")
            return mtype, nbytes, pos + 4, pos + 8
        end = pos + 8 + second
        if end > len(buf):
            raise _bad(f"an element at offset {pos} claims {second} bytes; only {len(buf) - pos - 8} follow")
        return first, second, pos + 8, min(len(buf), pos + 8 + -(-second // 8) * 8)

    def top_level(self, buf: memoryview, depth: int) -> None:
        pos = 0
        if len(buf) == 0 and depth == 0:
            raise _bad("no variables after the header")
        while pos < len(buf):
            mtype, nbytes, start, _ = self.tag(buf, pos)
            if mtype == _MI_COMPRESSED and depth == 0:
                self.compressed(buf[start : start + nbytes], depth)
            elif mtype == _MI_MATRIX:
                self.matrix(buf[start : start + nbytes], depth)
            else:
                raise _bad(f"a variable of element type {mtype} (expected miMATRIX or miCOMPRESSED)")
            pos = start + nbytes

    def compressed(self, data: memoryview, depth: int) -> None:
        inflater = zlib.decompressobj()
        try:
            inner = inflater.decompress(bytes(data), MAX_INFLATED_BYTES - self.inflated + 1)
        except zlib.error as exc:
            raise _bad(f"a compressed variable does not inflate ({exc})") from None
        self.inflated += len(inner)
        if self.inflated > MAX_INFLATED_BYTES:
            raise _bad(f"compressed variables inflate to more than {MAX_INFLATED_BYTES} bytes")
        if not inflater.eof or inflater.unused_data or inflater.unconsumed_tail:
            raise _bad("a compressed variable is truncated or followed by stray bytes")
        self.top_level(memoryview(inner), depth + 1)

    def matrix(self, buf: memoryview, depth: int) -> None:
        if depth > _MAX_DEPTH:
            raise _bad(f"cells/structs nested deeper than {_MAX_DEPTH}")
        if len(buf) == 0:  # an empty miMATRIX is an empty array
            return
        mtype, nbytes, start, pos = self.tag(buf, 0)
        if mtype != _MI_UINT32 or nbytes != 8:
            raise _bad("an array does not start with its 8-byte array flags")
        cls = struct.unpack(self.order + "I", buf[start : start + 4])[0]
        is_complex, cls = bool(cls & 0x800), cls & 0xFF
        mtype, nbytes, start, pos = self.tag(buf, pos)
        if mtype != _MI_INT32 or nbytes % 4 or nbytes < 8:
            raise _bad("an array's dimensions are not at least two int32 values")
        dims = struct.unpack(f"{self.order}{nbytes // 4}i", buf[start : start + nbytes])
        count = 1
        for d in dims:
            if d < 0:
                raise _bad(f"an array has a negative dimension {dims}")
            count *= d
        if count > MAX_ELEMENTS:
            raise _bad(f"an array of dimensions {dims} exceeds {MAX_ELEMENTS} values")
        mtype, nbytes, start, pos = self.tag(buf, pos)
        if mtype not in (_MI_INT8, _MI_UINT8):
            raise _bad("an array's name is not int8 text")
        pos = self.content(buf, pos, cls, is_complex, count, depth)
        if any(buf[pos:]):
            raise _bad("an array has stray bytes after its data")

    def content(self, buf: memoryview, pos: int, cls: int, is_complex: bool, count: int, depth: int) -> int:
        if cls in _NUMERIC_CLASSES:
            for _ in range(2 if is_complex else 1):
                mtype, nbytes, _, pos = self.tag(buf, pos)
                if mtype not in _ITEMSIZE or nbytes != count * _ITEMSIZE[mtype]:
                    raise _bad(f"numeric data of {nbytes} bytes (type {mtype}) do not hold {count} values")
            return pos
        if cls == _CHAR:
            mtype, nbytes, start, pos = self.tag(buf, pos)
            if mtype == _MI_UTF8:
                text = bytes(buf[start : start + nbytes]).decode("utf-8", errors="replace")
                ok = len(text) == count
            else:
                ok = mtype in _CHAR_ITEMSIZE and nbytes == count * _CHAR_ITEMSIZE[mtype]
            if not ok:
                raise _bad(f"char data of {nbytes} bytes (type {mtype}) do not hold {count} characters")
            return pos
        if cls == _CELL:
            return self.children(buf, pos, count, depth)
        if cls == _STRUCT:
            mtype, nbytes, start, pos = self.tag(buf, pos)
            if mtype != _MI_INT32 or nbytes != 4:
                raise _bad("a struct's field-name length is not one int32")
            name_len = struct.unpack(self.order + "i", buf[start : start + 4])[0]
            mtype, nbytes, start, pos = self.tag(buf, pos)
            if mtype not in (_MI_INT8, _MI_UINT8) or name_len <= 0 or nbytes % name_len:
                raise _bad("a struct's field names do not match their length")
            return self.children(buf, pos, count * (nbytes // name_len), depth)
        raise _bad(f"array class {cls} (sparse, object, function or unknown) is not read")

    def children(self, buf: memoryview, pos: int, count: int, depth: int) -> int:
        for _ in range(count):
            mtype, nbytes, start, pos = self.tag(buf, pos)
            if mtype != _MI_MATRIX:
                raise _bad(f"a cell or field of element type {mtype} (expected miMATRIX)")
            self.matrix(buf[start : start + nbytes], depth + 1)
        return pos
