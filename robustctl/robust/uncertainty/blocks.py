"""Uncertainty block structures for mu-analysis and D-K iteration.

A block structure describes the admissible perturbations ``Delta = diag(Delta_1, ...,
Delta_k)`` in ``det(I - M Delta) = 0`` (Packard & Doyle 1993, "The complex structured
singular value", Automatica 29(1), eq. 3.1). Each block is one of

* a repeated real scalar ``delta I_r`` (``delta`` real),
* a repeated complex scalar ``delta I_r`` (``delta`` complex),
* a full complex ``rows x cols`` matrix.

Block ``i`` maps ``cols_i`` outputs of ``M`` to ``rows_i`` inputs of ``M``, so ``M`` has
``sum(cols_i)`` rows and ``sum(rows_i)`` columns (MATLAB ``mussv`` convention: a block
``[r, c]`` is an ``r x c`` perturbation and ``M`` is ``(sum c) x (sum r)``). Blocks appear
in order along the diagonal of ``Delta``.

The MATLAB ``mussv`` spelling is accepted: a list of rows ``[[-r, 0]]`` (repeated real
scalar of multiplicity ``r``), ``[[r, 0]]`` (repeated complex scalar), ``[[r, c]]`` (full
``r x c`` complex block).
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from typing import Any, Literal

import numpy as np

from ...errors import SynthesisError

__all__ = ["Block", "BlockStructure", "as_block_structure"]

BlockKind = Literal["real", "complex", "full"]
_KINDS = ("real", "complex", "full")


@dataclass(frozen=True)
class Block:
    """One diagonal block of ``Delta``.

    Parameters
    ----------
    kind : {"real", "complex", "full"}
        ``"real"``: repeated real scalar ``delta I``; ``"complex"``: repeated complex scalar;
        ``"full"``: full complex matrix.
    rows, cols : int
        Size of the block (``rows x cols``). Scalar blocks are square (``rows == cols`` is
        the multiplicity).
    name : str, optional
        A label (e.g. ``"additive"``, ``"performance"``) used in tables and plots.
    """

    kind: BlockKind
    rows: int
    cols: int
    name: str = ""

    def __post_init__(self) -> None:
        if not isinstance(self.kind, str) or self.kind not in _KINDS:
            raise SynthesisError(f"block kind must be one of {_KINDS}; got {self.kind!r}.")
        for what in ("rows", "cols"):
            v = getattr(self, what)
            if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or v < 1:
                raise SynthesisError(f"block {what} must be a positive integer; got {v!r}.")
        if self.kind != "full" and self.rows != self.cols:
            raise SynthesisError(
                f"a repeated {self.kind} scalar block is square (rows == cols); got rows={self.rows}, "
                f"cols={self.cols}. Use kind='full' for a rectangular block."
            )
        if not isinstance(self.name, str):
            raise SynthesisError(f"block name must be a str; got {self.name!r}.")

    @property
    def is_scalar(self) -> bool:
        """True for a repeated (real or complex) scalar block."""
        return self.kind != "full"

    def mussv_row(self) -> list[int]:
        """The block in MATLAB ``mussv`` spelling: ``[-r, 0]``, ``[r, 0]`` or ``[r, c]``."""
        if self.kind == "real":
            return [-self.rows, 0]
        if self.kind == "complex":
            return [self.rows, 0]
        return [self.rows, self.cols]


@dataclass(frozen=True)
class BlockStructure:
    """An ordered tuple of :class:`Block` s: the structure of ``Delta``.

    ``M`` (the matrix whose mu is sought) must be ``n_out x n_in`` with
    ``n_out = sum(cols)`` and ``n_in = sum(rows)``: ``Delta`` maps the ``n_out`` outputs of
    ``M`` back to its ``n_in`` inputs.

    Parameters
    ----------
    blocks : tuple of Block
        The blocks in order along the diagonal of ``Delta``; at least one.
    """

    blocks: tuple[Block, ...]

    def __post_init__(self) -> None:
        if not self.blocks:
            raise SynthesisError("a block structure needs at least one block.")
        if not all(isinstance(b, Block) for b in self.blocks):
            raise SynthesisError("every element of a BlockStructure must be a Block.")

    @classmethod
    def from_mussv(cls, rows: Any, names: Sequence[str] | None = None) -> BlockStructure:
        """Build from MATLAB ``mussv`` rows (``[[-r,0]]`` real, ``[[r,0]]`` complex, ``[[r,c]]`` full)."""
        arr = np.asarray(rows)
        if arr.ndim == 1 and arr.size == 2:
            arr = arr[None, :]
        if arr.ndim != 2 or arr.shape[1] != 2 or arr.shape[0] == 0:
            raise SynthesisError(
                f"mussv block rows must be a list of [r, c] pairs, e.g. [[2, 0], [1, 1]]; got {rows!r}."
            )
        if np.iscomplexobj(arr):
            raise SynthesisError(f"mussv block rows must be integers; got {rows!r}.")
        as_float = arr.astype(float)
        if not np.all(np.isfinite(as_float)) or np.any(as_float != np.round(as_float)):
            raise SynthesisError(f"mussv block rows must be integers; got {rows!r}.")
        arr = arr.astype(int)
        if names is not None and len(names) != arr.shape[0]:
            raise SynthesisError(f"give one name per block ({arr.shape[0]}); got {len(names)}.")
        out = []
        for i, (r, c) in enumerate(arr.tolist()):
            name = "" if names is None else str(names[i])
            if r < 0 and c == 0:
                out.append(Block("real", -r, -r, name))
            elif r > 0 and c == 0:
                out.append(Block("complex", r, r, name))
            elif r > 0 and c > 0:
                out.append(Block("full", r, c, name))
            else:
                raise SynthesisError(
                    f"mussv row {[int(r), int(c)]} is not a block: use [-r, 0] (repeated real scalar), "
                    "[r, 0] (repeated complex scalar) or [r, c] with r, c > 0 (full block)."
                )
        return cls(tuple(out))

    def mussv(self) -> np.ndarray:
        """The structure as a MATLAB ``mussv`` block array (k x 2 integers)."""
        return np.array([b.mussv_row() for b in self.blocks], dtype=int)

    @property
    def n_in(self) -> int:
        """Columns of ``M`` (= rows of ``Delta``): ``sum(rows)``."""
        return int(sum(b.rows for b in self.blocks))

    @property
    def n_out(self) -> int:
        """Rows of ``M`` (= columns of ``Delta``): ``sum(cols)``."""
        return int(sum(b.cols for b in self.blocks))

    @property
    def has_real(self) -> bool:
        """True when any block is a repeated real scalar (mixed mu)."""
        return any(b.kind == "real" for b in self.blocks)

    def row_slices(self) -> list[slice]:
        """Slices of ``M``'s rows (``Delta``'s columns) that belong to each block."""
        return _slices([b.cols for b in self.blocks])

    def col_slices(self) -> list[slice]:
        """Slices of ``M``'s columns (``Delta``'s rows) that belong to each block."""
        return _slices([b.rows for b in self.blocks])

    def check_matrix_shape(self, shape: tuple[int, ...]) -> None:
        """Refuse an ``M`` whose last two dimensions do not fit the structure."""
        if len(shape) < 2 or shape[-2:] != (self.n_out, self.n_in):
            raise SynthesisError(
                f"M must be {self.n_out} x {self.n_in} for blocks {self.mussv().tolist()} "
                f"(rows = sum of block columns, columns = sum of block rows); got shape {tuple(shape)}."
            )

    def __len__(self) -> int:
        return len(self.blocks)

    def __iter__(self):
        return iter(self.blocks)

    def __getitem__(self, i: int) -> Block:
        return self.blocks[i]


def _slices(sizes: Iterable[int]) -> list[slice]:
    out, start = [], 0
    for n in sizes:
        out.append(slice(start, start + n))
        start += n
    return out


def as_block_structure(blocks: Any) -> BlockStructure:
    """Coerce ``blocks`` to a :class:`BlockStructure`.

    Parameters
    ----------
    blocks : BlockStructure, Block, sequence of Block or array_like (n, 2)
        A structure, one block, blocks, or MATLAB ``mussv`` rows (``[-r, 0]`` a repeated real
        scalar, ``[r, 0]`` a repeated complex scalar, ``[r, c]`` a full complex block).

    Returns
    -------
    BlockStructure

    Raises
    ------
    SynthesisError
        Anything else, or malformed rows.
    """
    if isinstance(blocks, BlockStructure):
        return blocks
    if isinstance(blocks, Block):
        return BlockStructure((blocks,))
    if isinstance(blocks, (list, tuple)) and blocks and all(isinstance(b, Block) for b in blocks):
        return BlockStructure(tuple(blocks))
    if blocks is None or isinstance(blocks, (str, bytes, dict)):
        raise SynthesisError(
            f"blocks must be a BlockStructure, a list of Block, or mussv rows like [[1, 1], [-2, 0]]; "
            f"got {blocks!r}."
        )
    try:
        return BlockStructure.from_mussv(blocks)
    except (TypeError, ValueError) as exc:
        if isinstance(exc, SynthesisError):
            raise
        raise SynthesisError(
            f"blocks must be a BlockStructure, a list of Block, or mussv rows like [[1, 1], [-2, 0]]; "
            f"got {blocks!r}."
        ) from exc
