"""Assembly kernels of the frame FEM: stacked element matrices, triplets, constraints, signals.

The element matrices of a :class:`~robustctl.physical.fem.Frame` are built in vectorised
stacks per element kind (:mod:`.elements`) and summed sparsely as (row, column, value)
triplets with four value columns (elastic stiffness, mass, dashpot damping, geometric
stiffness per newton); rigid links and supports become a transformation ``q_full = T q``
(slave nodes follow their master rigidly, fixed DOFs are dropped); inputs and outputs become
pointing matrices over the full DOFs.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from ..errors import ModelError
from . import elements as el
from .frame_parts import _Signal, _skew, _Spring
from .structure_base import Structure


@dataclass
class _ElementStacks:
    dofs_beam: np.ndarray
    dofs_rod: np.ndarray
    K_beam: np.ndarray
    M_beam: np.ndarray
    G_beam: np.ndarray
    K_rod: np.ndarray
    M_rod: np.ndarray
    G_rod: np.ndarray
    beam_idx: np.ndarray  # position of each beam in the frame's element order
    rod_idx: np.ndarray
    axis: np.ndarray  # (ne, 3) unit axes, frame element order
    EA_L: np.ndarray  # (ne,) axial stiffness, N/m
    n1: np.ndarray
    n2: np.ndarray
    R: np.ndarray  # (nb, 3, 3) beam axes
    length: np.ndarray


def _element_stacks(frame: Structure, index: dict[str, int], X: np.ndarray) -> _ElementStacks:
    """Element matrices in global axes, stacked per kind, for the frame's elements in order."""
    elems = list(frame._elements.values())
    scale = np.array([frame._group_scale.get(e.group, 1.0) for e in elems])
    n1 = np.array([index[e.n1] for e in elems], dtype=int)
    n2 = np.array([index[e.n2] for e in elems], dtype=int)
    is_beam = np.array([e.kind == "beam" for e in elems], dtype=bool)
    prop = {
        k: np.array([getattr(e, k) for e in elems], dtype=float)
        for k in ("E", "G", "A", "rho", "Iy", "Iz", "J")
    }
    prop["E"], prop["G"] = prop["E"] * scale, prop["G"] * scale
    d = X[n2] - X[n1] if elems else np.zeros((0, 3))
    L = np.linalg.norm(d, axis=1)
    bi, ri = np.flatnonzero(is_beam), np.flatnonzero(~is_beam)
    R, K_b, M_b, G_b, dofs_b = _beam_blocks(elems, bi, X, n1[bi], n2[bi], {k: v[bi] for k, v in prop.items()})
    K_r, M_r, G_r, dofs_r = _rod_blocks(elems, ri, X, n1[ri], n2[ri], {k: v[ri] for k, v in prop.items()})
    safe_L = np.where(L > 0, L, 1.0)
    return _ElementStacks(
        dofs_b, dofs_r, K_b, M_b, G_b, K_r, M_r, G_r, bi, ri, d / safe_L[:, None],
        prop["E"] * prop["A"] / safe_L, n1, n2, R, L,
    )  # fmt: skip


def _beam_blocks(elems, idx, X, n1, n2, p):
    """Axes, stiffness, mass, unit geometric stiffness (global) and DOFs of the beams."""
    if idx.size == 0:
        empty = np.zeros((0, 12, 12))
        return np.zeros((0, 3, 3)), empty, empty, empty, np.zeros((0, 12), dtype=int)
    orient = el.default_orient(X[n1], X[n2])
    for j, i in enumerate(idx):
        if elems[i].orient is not None:
            orient[j] = elems[i].orient
    R = el.beam_axes(X[n1], X[n2], orient)
    L = np.linalg.norm(X[n2] - X[n1], axis=1)
    kl = el.beam_local_stiffness(L, p["E"], p["G"], p["A"], p["Iy"], p["Iz"], p["J"])
    ml = el.beam_local_mass(L, p["rho"], p["A"], p["Iy"], p["Iz"])
    rot = np.array([elems[i].rotary_inertia for i in idx])
    if rot.any():
        ml[rot] = el.beam_local_mass(
            L[rot], p["rho"][rot], p["A"][rot], p["Iy"][rot], p["Iz"][rot], rotary_inertia=True
        )
    dofs = np.concatenate([6 * n1[:, None] + np.arange(6), 6 * n2[:, None] + np.arange(6)], axis=1)
    geo = el.beam_local_geometric(L)
    return R, el.beam_to_global(kl, R), el.beam_to_global(ml, R), el.beam_to_global(geo, R), dofs


def _rod_blocks(elems, idx, X, n1, n2, p):
    """Stiffness, mass, unit geometric stiffness (global) and translational DOFs of the rods."""
    if idx.size == 0:
        empty = np.zeros((0, 6, 6))
        return empty, empty, empty, np.zeros((0, 6), dtype=int)
    lumped = np.array([elems[i].lumped for i in idx])
    K, M, G = el.rod_matrices(X[n1], X[n2], p["E"], p["A"], p["rho"], lumped=lumped)
    dofs = np.concatenate([6 * n1[:, None] + np.arange(3), 6 * n2[:, None] + np.arange(3)], axis=1)
    return K, M, G, dofs


class _Pattern:
    """A fixed sparsity pattern: sums values given at (row, col) triplets into a CSR matrix
    with one ``bincount`` (the pattern is sorted once, the values change per call)."""

    def __init__(self, rows: np.ndarray, cols: np.ndarray, n: int) -> None:
        lin = rows.astype(np.int64) * n + cols
        uniq, self.pos = np.unique(lin, return_inverse=True)
        self.n, self.nnz = n, uniq.size
        self.indices = (uniq % n).astype(np.int32)
        self.indptr = np.concatenate([[0], np.cumsum(np.bincount(uniq // n, minlength=n))]).astype(np.int32)

    def matrix(self, vals: np.ndarray) -> sp.csr_matrix:
        """The matrix with ``vals`` (one per triplet) summed into the pattern."""
        data = np.bincount(self.pos, weights=vals, minlength=self.nnz)
        return sp.csr_matrix((data, self.indices, self.indptr), shape=(self.n, self.n))


#: Columns of :class:`_Trip` values: elastic stiffness, mass, dashpot damping, geometric
#: stiffness per newton of axial force.
_K, _M, _C, _G = range(4)


@dataclass
class _Trip:
    """Matrix entries as triplets with four value columns (K, M, C, G per unit N);
    ``tag`` is the element index of the geometric stiffness entry (or 0 when there is none)."""

    rows: np.ndarray
    cols: np.ndarray
    vals: np.ndarray  # (m, 4)
    tag: np.ndarray

    @staticmethod
    def cat(parts: list[_Trip]) -> _Trip:
        if not parts:
            z = np.zeros(0, dtype=int)
            return _Trip(z, z, np.zeros((0, 4)), z)
        return _Trip(
            *(np.concatenate([getattr(p, a) for p in parts]) for a in ("rows", "cols", "vals", "tag"))
        )

    @staticmethod
    def from_blocks(dofs: np.ndarray, mats: dict[int, np.ndarray], tag: np.ndarray | None = None) -> _Trip:
        """Element matrices ``mats[column] (ne, d, d)`` at DOF indices ``dofs (ne, d)``."""
        ne, d = dofs.shape
        rows = np.repeat(dofs, d, axis=1).ravel()
        cols = np.tile(dofs, (1, d)).ravel()
        vals = np.zeros((rows.size, 4))
        for column, mat in mats.items():
            vals[:, column] = mat.reshape(-1)
        t = np.zeros(rows.size, dtype=int) if tag is None else np.repeat(tag, d * d)
        return _Trip(rows, cols, vals, t)

    def reduce(self, T: sp.csr_matrix, new_index: np.ndarray) -> _Trip:
        """Entries of ``T^T A T`` restricted to the kept reduced DOFs (``new_index >= 0``)."""
        counts = np.diff(T.indptr)
        if counts.max(initial=0) <= 1 and np.all(T.data == 1.0):  # supports only: a renumbering
            col = -np.ones(T.shape[0] + 1, dtype=int)
            col[np.flatnonzero(counts == 1)] = new_index[T.indices]
            r, c = col[self.rows], col[self.cols]
            ok = (r >= 0) & (c >= 0)
            return _Trip(r[ok], c[ok], self.vals[ok], self.tag[ok])
        out = self
        for axis in ("rows", "cols"):
            idx = getattr(out, axis)
            cnt = counts[idx]
            src = np.repeat(np.arange(idx.size), cnt)
            k = np.repeat(T.indptr[idx] - (np.cumsum(cnt) - cnt), cnt) + np.arange(src.size)
            parts = {a: getattr(out, a)[src] for a in ("rows", "cols", "tag")}
            parts[axis] = new_index[T.indices[k]]
            out = _Trip(parts["rows"], parts["cols"], out.vals[src] * T.data[k][:, None], parts["tag"])
        ok = (out.rows >= 0) & (out.cols >= 0)
        return _Trip(out.rows[ok], out.cols[ok], out.vals[ok], out.tag[ok])


def _point_triplets(frame: Structure, index: dict[str, int]) -> _Trip:
    """Lumped masses, springs and dashpots as triplets over the full DOFs (stacked per run of
    like components, in the frame's order)."""
    parts: list[_Trip] = []
    if frame._masses:
        blocks = np.zeros((len(frame._masses), 6, 6))
        blocks[:, :3, :3] = np.array([m.mass for m in frame._masses])[:, None, None] * np.eye(3)
        blocks[:, 3:, 3:] = np.array([m.inertia for m in frame._masses])
        dofs = 6 * np.array([index[m.node] for m in frame._masses])[:, None] + np.arange(6)
        parts.append(_Trip.from_blocks(dofs, {_M: blocks}))
    run: list[_Spring] = []
    for s in frame._springs:
        if run and ((s.node2 is None) != (run[0].node2 is None) or s.kind != run[0].kind):
            parts.append(_spring_triplets(run, index))
            run = []
        run.append(s)
    if run:
        parts.append(_spring_triplets(run, index))
    return _Trip.cat(parts)


def _spring_triplets(run: list[_Spring], index: dict[str, int]) -> _Trip:
    """Springs or dashpots of one kind, all grounded or all between two nodes (``k v v^T``)."""
    dofs = 6 * np.array([index[s.node] for s in run])[:, None] + np.arange(6)
    vec = np.array([s.vec for s in run], dtype=float)
    if run[0].node2 is not None:
        dofs2 = 6 * np.array([index[s.node2] for s in run])[:, None] + np.arange(6)
        dofs = np.concatenate([dofs, dofs2], axis=1)
        vec = np.concatenate([vec, -vec], axis=1)
    value = np.array([s.value for s in run], dtype=float)
    blocks = value[:, None, None] * (vec[:, :, None] * vec[:, None, :])
    return _Trip.from_blocks(dofs, {_K if run[0].kind == "spring" else _C: blocks})


def _link_roots(frame: Structure) -> dict[str, str]:
    """Each rigid-link slave's ultimate master (chains of links resolved)."""
    master_of = {lk.slave: lk.master for lk in frame._links}
    partial = {lk.slave for lk in frame._links if lk.released}
    root = {}
    for s in master_of:
        m, seen = master_of[s], {s}
        while m in master_of:
            if m in seen:
                raise ModelError(
                    f"rigid links form a loop through node {m!r}; a chain of links must end at a master."
                )
            if m in partial:
                raise ModelError(
                    f"node {m!r} follows its master only partly (a flexible joint's twin), so node {s!r} "
                    "cannot be linked to it; link it to the joint's node instead."
                )
            seen.add(m)
            m = master_of[m]
        root[s] = m
    return root


def _link_pairs(frame: Structure, index: dict[str, int], X: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(root master, slave) node indices of the rigid links with an offset."""
    pairs = [(index[m], index[s]) for s, m in _link_roots(frame).items()]
    pairs = [(m, s) for m, s in pairs if np.linalg.norm(X[s] - X[m]) > 0]
    arr = np.array(pairs, dtype=int).reshape(-1, 2)
    return arr[:, 0], arr[:, 1]


def _constraint_transform(
    frame: Structure, index: dict[str, int], X: np.ndarray
) -> tuple[sp.csr_matrix, np.ndarray]:
    """``q_full = T q``: rigid-link slaves follow their (root) master, but for the DOFs a link
    releases (a hinge's rotations, which stay the slave's own); fixed DOFs dropped.

    Returns ``T`` and, per column, the full DOF it stands for."""
    n_full = 6 * len(index)
    root = _link_roots(frame)
    released = {lk.slave: set(lk.released) for lk in frame._links}
    fixed = np.zeros(n_full, dtype=bool)
    for f in frame._fixes:
        if f.node in root:
            raise ModelError(
                f"node {f.node!r} is the slave of a rigid link and cannot be fixed; fix its master "
                f"{root[f.node]!r} instead."
            )
        fixed[6 * index[f.node] + np.array(f.dofs, dtype=int)] = True
    is_slave = np.zeros(n_full, dtype=bool)
    for s in root:
        is_slave[6 * index[s] : 6 * index[s] + 6] = True
        is_slave[[6 * index[s] + d for d in released[s]]] = False
    indep = ~fixed & ~is_slave
    col = -np.ones(n_full, dtype=int)
    col[indep] = np.arange(indep.sum())
    rows = list(np.flatnonzero(indep))
    cols = list(col[indep])
    vals = [1.0] * len(rows)
    for s, m in root.items():
        si, mi = 6 * index[s], 6 * index[m]
        link = np.eye(6)
        link[:3, 3:] = -_skew(X[index[s]] - X[index[m]])
        for i in range(6):
            if i in released[s]:
                continue
            for j in range(6):
                if link[i, j] != 0 and col[mi + j] >= 0:
                    rows.append(si + i)
                    cols.append(col[mi + j])
                    vals.append(link[i, j])
    T = sp.csr_matrix((vals, (rows, cols)), shape=(n_full, int(indep.sum())))
    return T, np.flatnonzero(indep)


def _signal_matrix(
    frame: Structure, signals: dict[str, _Signal], index, stacks: _ElementStacks, n_full: int
) -> np.ndarray:
    """Pointing vectors of the signals over the full DOFs, shape (n_full, n_sig)."""
    P = np.zeros((n_full, len(signals)))
    elem_pos = {name: i for i, name in enumerate(frame._elements)}
    for j, sig in enumerate(signals.values()):
        for node, vec in sig.terms:
            if node not in index:
                raise ModelError(
                    f"signal {sig.name!r} acts at node {node!r}, which this structure no longer has "
                    "(removed by without()); tag the signal like the component it sits on."
                )
            P[6 * index[node] : 6 * index[node] + 6, j] += vec
        if sig.strain is not None:
            P[:, j] = _strain_row(frame, sig, elem_pos, stacks, n_full)
    return P


def _strain_row(frame: Structure, sig: _Signal, elem_pos, stacks: _ElementStacks, n_full: int) -> np.ndarray:
    names, pos, kind, fiber = sig.strain
    missing = [e for e in names if e not in elem_pos]
    if missing:
        raise ModelError(f"strain output {sig.name!r} reads element {missing[0]!r}, which was removed.")
    idx = np.array([elem_pos[e] for e in names])
    lengths = stacks.length[idx]
    s = pos * lengths.sum()
    k = int(min(np.searchsorted(np.cumsum(lengths), s, side="left"), len(idx) - 1))
    xi = float(np.clip((s - (np.cumsum(lengths)[k] - lengths[k])) / lengths[k], 0.0, 1.0))
    e = idx[k]
    L = stacks.length[e]
    row = np.zeros(n_full)
    a, b = 6 * stacks.n1[e], 6 * stacks.n2[e]
    if kind == "axial":
        row[a : a + 3] -= stacks.axis[e] / L
        row[b : b + 3] += stacks.axis[e] / L
        return row
    j = int(np.flatnonzero(stacks.beam_idx == e)[0])
    local = -fiber * el.hermite_curvature_row(L, xi, "v" if kind == "bending_z" else "w")
    R = stacks.R[j]
    glob = (local.reshape(4, 3) @ R).ravel()  # u_local = R u_global per 3-block
    row[a : a + 6] += glob[:6]
    row[b : b + 6] += glob[6:]
    return row


def _link_geometric_triplets(X: np.ndarray, links, offset: int) -> _Trip:
    """Unit geometric stiffness of each rigid link as a rod from master to slave."""
    masters, slaves = links
    if masters.size == 0:
        return _Trip.cat([])
    ones = np.ones(masters.size)
    _, _, G = el.rod_matrices(X[masters], X[slaves], ones, ones, ones)
    dofs = np.concatenate([6 * masters[:, None] + np.arange(3), 6 * slaves[:, None] + np.arange(3)], axis=1)
    return _Trip.from_blocks(dofs, {_G: G}, offset + np.arange(masters.size))
