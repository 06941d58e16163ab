"""Index bookkeeping shared by the mu bounds: where each block sits in ``M`` and ``Delta``.

``M`` is ``n_out x n_in`` and ``Delta = diag(Delta_1, ...)`` is ``n_in x n_out`` (see
:mod:`robustctl.robust.uncertainty.blocks`). Block ``i`` owns the rows ``out[i]`` of ``M`` (its
``cols_i`` outputs) and the columns ``inp[i]`` of ``M`` (its ``rows_i`` inputs).

The D-scales commute with ``Delta`` (Packard & Doyle 1993, eq. 8.1): a full block gets
``d_i I`` (``d_i I_{cols_i}`` on the left of ``M``, ``d_i I_{rows_i}`` on the right), a
repeated scalar block of multiplicity ``r`` any invertible ``D_i`` (``r x r``, the same on
both sides). The G-scales (Fan, Tits & Doyle 1991, eq. 2.3) are Hermitian ``r x r``
blocks on the repeated real scalar blocks only, placed in the shape of ``Delta``.

The optimiser works in local coordinates: a parameter vector ``theta`` whose entries are
the coefficients of Hermitian generators ``E`` of the D-scales (``D <- exp(E) D``) and of
the G-scale increments. :class:`Layout` holds those generators as dense matrices.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np

from ..uncertainty.blocks import BlockStructure

__all__ = ["Layout", "layout_of", "hermitian_basis"]


def hermitian_basis(r: int) -> list[np.ndarray]:
    """A real basis of the ``r x r`` Hermitian matrices (``r^2`` elements).

    Diagonal units ``E_jj``, then ``E_jl + E_lj`` and ``j (E_jl - E_lj)`` for ``j < l``.
    """
    out = []
    for j in range(r):
        b = np.zeros((r, r), complex)
        b[j, j] = 1.0
        out.append(b)
    for j in range(r):
        for m in range(j + 1, r):
            b = np.zeros((r, r), complex)
            b[j, m] = b[m, j] = 1.0
            out.append(b)
            b = np.zeros((r, r), complex)
            b[j, m], b[m, j] = 1j, -1j
            out.append(b)
    return out


@dataclass(frozen=True)
class Layout:
    """Slices, scale sizes and generator matrices of a block structure.

    Attributes
    ----------
    n_out, n_in : int
        ``M`` is ``n_out x n_in``.
    out, inp : tuple of slice
        Rows / columns of ``M`` owned by each block.
    kinds : tuple of str
        ``"real"``, ``"complex"`` or ``"full"`` per block.
    dsize : tuple of int
        Size of the D-scale of each block: ``r`` for a repeated scalar block with ``r > 1``,
        1 otherwise (a scalar ``d_i``).
    gen_left, gen_right : ndarray, (n_d, n_out, n_out) and (n_d, n_in, n_in)
        Generators of the D parameters (left and right action on ``M``).
    gen_g : ndarray, (n_g, n_in, n_out)
        Generators of the G parameters (Hermitian basis on the real blocks).
    """

    n_out: int
    n_in: int
    out: tuple[slice, ...]
    inp: tuple[slice, ...]
    kinds: tuple[str, ...]
    dsize: tuple[int, ...]
    gen_left: np.ndarray
    gen_right: np.ndarray
    gen_g: np.ndarray

    @cached_property
    def ll_flat(self) -> np.ndarray:
        """``(L_a L_b)`` flattened to (n_d^2, n_out^2), for ``tr(L_a L_b P)`` as one product."""
        return _products(self.gen_left)

    @cached_property
    def rr_flat(self) -> np.ndarray:
        """``(R_a R_b)`` flattened to (n_d^2, n_in^2)."""
        return _products(self.gen_right)

    @cached_property
    def g_flat_t(self) -> np.ndarray:
        """``G_b^T`` flattened to (n_out n_in, n_g): ``tr(X G_b)`` as one product."""
        return np.swapaxes(self.gen_g, 1, 2).reshape(self.n_g, -1).T

    @cached_property
    def diagonal(self) -> tuple[np.ndarray, np.ndarray] | None:
        """The D generators as 0/1 vectors ``(l (n_d, n_out), r (n_d, n_in))`` when they are all
        diagonal (no repeated scalar block of multiplicity > 1), else None (fast path)."""
        if any(m > 1 for m in self.dsize):
            return None
        return (np.diagonal(self.gen_left, axis1=1, axis2=2).real.copy(),
                np.diagonal(self.gen_right, axis1=1, axis2=2).real.copy())

    @cached_property
    def param_slices(self) -> tuple[tuple[slice, slice], ...]:
        """(rows, columns) of ``M`` scaled by each D parameter (diagonal case)."""
        out = []
        for gl, gr in zip(*self.diagonal):
            rows, cols = np.flatnonzero(gl), np.flatnonzero(gr)
            out.append((slice(rows[0], rows[-1] + 1), slice(cols[0], cols[-1] + 1)))
        return tuple(out)

    @property
    def n_blocks(self) -> int:
        return len(self.kinds)

    @property
    def n_d(self) -> int:
        return self.gen_left.shape[0]

    @property
    def n_g(self) -> int:
        return self.gen_g.shape[0]

    @property
    def has_real(self) -> bool:
        return self.n_g > 0

    @property
    def square_scalar(self) -> bool:
        """True when every block is a repeated scalar (``M`` square, ``D_L = D_R``)."""
        return all(k != "full" for k in self.kinds)

    def assemble(self, dblocks: list[np.ndarray], inverse: bool = False) -> tuple[np.ndarray, np.ndarray]:
        """Left and right scaling matrices ``(D_L, D_R)`` (or their inverses) from per-block scales.

        ``dblocks[i]`` is ``(nf, m, m)`` with ``m = dsize[i]``.
        """
        nf = dblocks[0].shape[0]
        left = np.zeros((nf, self.n_out, self.n_out), complex)
        right = np.zeros((nf, self.n_in, self.n_in), complex)
        for d, o, i, m in zip(dblocks, self.out, self.inp, self.dsize):
            d = np.linalg.inv(d) if inverse and m > 1 else (1.0 / d if inverse else d)
            if m == 1:
                idx_o = np.arange(o.start, o.stop)
                idx_i = np.arange(i.start, i.stop)
                left[:, idx_o, idx_o] = d[:, :, 0]
                right[:, idx_i, idx_i] = d[:, :, 0]
            else:
                left[:, o, o] = d
                right[:, i, i] = d
        return left, right


def _products(gen: np.ndarray) -> np.ndarray:
    k, n = gen.shape[0], gen.shape[1]
    return np.einsum("aij,bjk->abik", gen, gen).reshape(k * k, n * n)


def layout_of(bs: BlockStructure) -> Layout:
    """The :class:`Layout` of a block structure.

    The last block's D-scale is fixed (``d = 1``) when it is a scalar, since the bound is
    invariant to a common factor of all D-scales.
    """
    out, inp = bs.row_slices(), bs.col_slices()
    n_out, n_in = bs.n_out, bs.n_in
    kinds = tuple(b.kind for b in bs.blocks)
    dsize = tuple(1 if (b.kind == "full" or b.rows == 1) else b.rows for b in bs.blocks)
    left, right, gens_g = [], [], []
    last = len(bs.blocks) - 1
    for k, (b, o, i, m) in enumerate(zip(bs.blocks, out, inp, dsize)):
        if m == 1 and k != last:
            gl, gr = np.zeros((n_out, n_out), complex), np.zeros((n_in, n_in), complex)
            gl[o, o] = np.eye(o.stop - o.start)
            gr[i, i] = np.eye(i.stop - i.start)
            left.append(gl)
            right.append(gr)
        elif m > 1:
            for basis in hermitian_basis(m):
                gl, gr = np.zeros((n_out, n_out), complex), np.zeros((n_in, n_in), complex)
                gl[o, o] = basis
                gr[i, i] = basis
                left.append(gl)
                right.append(gr)
        if b.kind == "real":
            for basis in hermitian_basis(b.rows):
                g = np.zeros((n_in, n_out), complex)
                g[i, o] = basis
                gens_g.append(g)
    gen_left = np.array(left).reshape(len(left), n_out, n_out)
    gen_right = np.array(right).reshape(len(right), n_in, n_in)
    gen_g = np.array(gens_g).reshape(len(gens_g), n_in, n_out)
    return Layout(n_out, n_in, tuple(out), tuple(inp), kinds, dsize, gen_left, gen_right, gen_g)
