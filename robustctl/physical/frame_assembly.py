"""The frame FEM's assembly: from a :class:`~robustctl.physical.fem.Frame` to its matrices.

The geometry part comes from :mod:`.frame_cache`; point masses and springs are added as
triplets; DOFs with neither mass nor stiffness are dropped (an input or output on one is an
error); with gravity on, the preload iteration (:func:`~robustctl.physical.gravity.preload_iteration`)
gives the member axial forces and ``K + K_g(N)``; DOFs with stiffness but no mass are condensed
statically (Guyan) with the input and output pointing matrices.
"""

from __future__ import annotations

import hashlib

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp

from ..errors import ModelError
from ..threads import limit_blas
from .frame_cache import _GEOMETRY_LOCK, _PRELOADS, _full_triplets, _Geometry, _geometry, _Kept, _reduced
from .frame_kernels import _C, _G, _K, _M, _point_triplets, _Trip
from .frame_parts import _DOF_NAMES, _Assembly
from .gravity import PreloadResult, preload_iteration
from .structure_base import StructuralMatrices, Structure


@limit_blas
def _assemble(frame: Structure) -> _Assembly:
    if not frame._nodes:
        raise ModelError("the frame has no nodes; add nodes and elements first.")
    geo = _geometry(frame)
    names, X, st, links = geo.names, geo.X, geo.st, geo.links
    n_full = 6 * len(names)
    points = _point_triplets(frame, geo.index)
    full = _full_triplets(geo, points)
    # DOFs with neither mass nor stiffness (nor damping, nor geometric stiffness) are dropped
    weight_full = np.bincount(full.rows, weights=np.abs(full.vals).sum(axis=1), minlength=n_full)
    keep = abs(geo.T).T @ weight_full > 0
    kept = _kept(frame, geo, keep)
    new_index = np.append(-np.ones(geo.T.shape[1], dtype=int), -1)
    new_index[np.flatnonzero(keep)] = np.arange(keep.sum())
    red, pattern = _reduced(geo, points, keep, new_index)
    T, B1, Cy1 = kept.T, kept.B1.copy(), kept.Cy1.copy()
    K1, M1, C1 = (pattern.matrix(red.vals[:, j]) for j in (_K, _M, _C))

    def kg_red(N: np.ndarray) -> sp.csr_matrix:
        return pattern.matrix(red.vals[:, _G] * N[red.tag])

    tension = np.array([frame._group_tension.get(e.group, 0.0) for e in frame._elements.values()])
    tension = np.concatenate([tension, np.zeros(links[0].size)])  # rigid links: from equilibrium
    preload, axial = None, tension.copy()
    if frame._gravity_on and (len(frame._elements) or links[0].size):
        key = _preload_key(frame, geo, points, keep, tension)
        found = _PRELOADS.get(key)  # (geometry, preload): the geometry's id is only valid with it
        if found is not None and found[0] is geo:
            preload = found[1]
        else:
            preload = _gravity_preload(frame, st, T, full, K1, M1, kg_red, tension, links, X)
            _PRELOADS.put(key, (geo, preload))
        axial = preload.axial_forces
    Kt = (K1 + kg_red(axial)).tocsr() if np.any(axial) else K1
    mats = _condense(Kt, M1, C1, B1, Cy1, list(kept.labels), frame)
    link_names = tuple(f"{names[m]}->{names[k]}" for m, k in zip(*links))
    return _Assembly(mats, names, tuple(frame._elements) + link_names, T, preload, axial)


def _preload_key(
    frame: Structure, geo: _Geometry, points: _Trip, keep: np.ndarray, tension: np.ndarray
) -> tuple:
    """Everything the gravity preload reads besides the geometry: the point masses and springs
    (not the dashpots, which it ignores), the kept DOFs, tensions and the gravity settings."""
    h = hashlib.blake2b(digest_size=20)
    stiff_or_mass = (points.vals[:, _K] != 0) | (points.vals[:, _M] != 0)
    for a in (points.rows[stiff_or_mass], points.cols[stiff_or_mass], points.vals[stiff_or_mass][:, [_K, _M]],
              keep, tension, np.asarray(frame._gdir, float)):
        h.update(np.ascontiguousarray(a).tobytes() + b"|")
    h.update(repr((frame._g, frame.gravity_tol, frame.max_gravity_iterations)).encode())
    return id(geo), h.digest()


def _gravity_preload(frame, st, T, full: _Trip, K1, M1, kg_red, tension, links, X) -> PreloadResult:
    """Gravity load ``T^T M a_g`` (masses of supported DOFs load the free ones through the
    consistent mass coupling) and MACE's stress-stiffening iteration.

    Rigid links carry the force that holds their slave node in equilibrium; its component
    along the link (tension positive) gives the link the geometric stiffness of a rod, so a
    body hanging below its suspension point is a compound pendulum (restoring moment
    ``m g h``), as with a stiff beam in place of the link."""
    n_full = 6 * X.shape[0]
    accel = np.zeros(n_full)
    for i in range(3):
        accel[i::6] = frame._g * frame._gdir[i]
    f_full = np.bincount(full.rows, weights=full.vals[:, _M] * accel[full.cols], minlength=n_full)
    f = T.T @ f_full
    masters, slaves = links
    ne = st.EA_L.size
    rows = _SlaveRows(full, (6 * slaves[:, None] + np.arange(3)).ravel(), n_full) if masters.size else None
    e_link = (X[slaves] - X[masters]) / np.linalg.norm(X[slaves] - X[masters], axis=1, keepdims=True)

    def axial_force(u: np.ndarray, N_used: np.ndarray | None) -> np.ndarray:
        uf = T @ u
        du = uf.reshape(-1, 6)[st.n2, :3] - uf.reshape(-1, 6)[st.n1, :3]
        N = st.EA_L * np.sum(du * st.axis, axis=1)
        if rows is None:
            return N
        n_elem = np.zeros(ne + masters.size)  # the elements' forces, not the links' own
        if N_used is not None:
            n_elem[:ne] = N_used[:ne]
        # what the link must apply: (K + K_g) uf - f on the slaves' translations
        link_force = (rows.times(n_elem, uf) - f_full[rows.dofs]).reshape(-1, 3)
        return np.concatenate([N, -np.sum(link_force * e_link, axis=1)])

    return preload_iteration(
        K1,
        M1,
        f,
        axial_force,
        kg_red,
        n_fixed=tension,
        tol=frame.gravity_tol,
        max_iter=frame.max_gravity_iterations,
    )



class _SlaveRows:
    """The rows ``dofs`` of the full ``K + K_g(N)`` (triplets ``full``, ``n`` full DOFs) times a
    vector: only the triplets on those rows, summed per entry in their order and each row's
    entries in column order, as a CSR matrix of the whole would (the same sums)."""

    def __init__(self, full: _Trip, dofs: np.ndarray, n: int) -> None:
        where = np.full(n, -1)
        where[dofs] = np.arange(dofs.size)
        sel = np.flatnonzero(where[full.rows] >= 0)
        lin = where[full.rows[sel]].astype(np.int64) * n + full.cols[sel]
        uniq, self.pos = np.unique(lin, return_inverse=True)
        self.row, self.col = uniq // n, uniq % n
        self.k, self.g, self.tag = full.vals[sel, _K], full.vals[sel, _G], full.tag[sel]
        self.dofs, self.nnz = dofs, uniq.size

    def times(self, n_elem: np.ndarray, x: np.ndarray) -> np.ndarray:
        """``((K + K_g(n_elem)) x)[dofs]``."""
        data = np.bincount(self.pos, weights=self.k + self.g * n_elem[self.tag], minlength=self.nnz)
        return np.bincount(self.row, weights=data * x[self.col], minlength=self.dofs.size)


def _kept(frame: Structure, geo: _Geometry, keep: np.ndarray) -> _Kept:
    """The constraint transform, DOF numbers, signal matrices and labels of the kept DOFs,
    made once per geometry and keep mask (the signals are checked on the dropped DOFs first)."""
    key = keep.tobytes()
    with _GEOMETRY_LOCK:
        found = geo.kept.get(key)
    if found is not None:
        return found
    T, dof_of_col, names = geo.T, geo.dof_of_col, geo.names
    B1, Cy1 = T.T @ geo.B_full, np.asarray((T.T @ geo.C_full.T).T)
    _check_signals_on_empty(frame, keep, dof_of_col, B1, Cy1, names)
    labels = tuple(f"{names[d // 6]} {_DOF_NAMES[d % 6]}" for d in dof_of_col[keep])
    found = _Kept(T[:, keep].tocsr(), dof_of_col[keep], B1[keep], Cy1[:, keep], labels)
    with _GEOMETRY_LOCK:
        found = geo.kept.setdefault(key, found)
        while len(geo.kept) > 8:
            geo.kept.pop(next(iter(geo.kept)))
    return found


def _check_signals_on_empty(frame, keep, dof_of_col, B1, Cy1, names) -> None:
    empty = np.flatnonzero(~keep)
    for what, P, sigs in (("input", B1, frame._inputs), ("output", Cy1.T, frame._outputs)):
        bad = np.argwhere(np.abs(P[empty]) > 0)
        if bad.size:
            d = dof_of_col[empty[bad[0, 0]]]
            sig = list(sigs)[bad[0, 1]]
            raise ModelError(
                f"{what} {sig!r} acts on DOF {_DOF_NAMES[d % 6]} of node {names[d // 6]!r}, which "
                "has neither mass nor stiffness (e.g. a rotation of a node joined only by rods). "
                "Point it along a translation, or give the node rotary inertia / a beam."
            )


def _condense(Kt, M1, C1, B1, Cy1, labels, frame) -> StructuralMatrices:
    """Statically condense DOFs without mass (Guyan) and package the matrices."""
    kinds = tuple(s.kind for s in frame._outputs.values())
    common = dict(
        output_kinds=kinds,
        inputs=tuple(frame._inputs),
        outputs=tuple(frame._outputs),
        modal_damping_bands=frame.modal_damping_bands(),
    )
    md = M1.diagonal()
    massless = md <= 1e-14 * max(md.max(initial=0.0), 1e-300)
    if not massless.any():
        return StructuralMatrices(
            mass=M1,
            stiffness=Kt,
            damping=C1,
            input_matrix=np.asarray(B1),
            output_matrix=Cy1,
            dof_labels=tuple(labels),
            **common,
        )
    s, m = np.flatnonzero(massless), np.flatnonzero(~massless)
    if abs(C1[s]).sum() > 0:
        bad = labels[s[np.flatnonzero(abs(C1[s]).sum(axis=1).A.ravel())[0]]]
        raise ModelError(f"a dashpot acts on {bad}, which has no mass; add mass or inertia at that node.")
    Kss = Kt[s][:, s].toarray()
    try:
        factor = sla.cho_factor(Kss)
    except np.linalg.LinAlgError:
        raise ModelError(
            f"DOFs without mass are not held by any stiffness (e.g. {labels[s[0]]}): add mass/inertia "
            "at that node, or a spring/support, so every DOF with stiffness has mass or is restrained."
        ) from None
    X = -sla.cho_solve(factor, Kt[s][:, m].toarray())
    _refuse_direct_static_path(factor, np.asarray(B1)[s], Cy1[:, s], frame, labels, s)
    Tm = np.zeros((len(labels), m.size))
    Tm[m, np.arange(m.size)] = 1.0
    Tm[s] = X
    Kc = Kt[m][:, m].toarray() + Kt[m][:, s].toarray() @ X
    Kc = 0.5 * (Kc + Kc.T)
    return StructuralMatrices(
        mass=M1[m][:, m],
        stiffness=sp.csr_matrix(Kc),
        damping=C1[m][:, m],
        input_matrix=Tm.T @ np.asarray(B1),
        output_matrix=Cy1 @ Tm,
        dof_labels=tuple(labels[i] for i in m),
        **common,
    )


def _refuse_direct_static_path(factor, Bs, Cs, frame, labels, s) -> None:
    """An input and an output both on massless DOFs would need a static feedthrough
    ``Cs Kss^-1 Bs`` that a second-order model without a D term cannot carry."""
    if not (np.any(Bs) and np.any(Cs)):
        return
    D = Cs @ sla.cho_solve(factor, Bs)
    bound = np.abs(Cs) @ np.abs(sla.cho_solve(factor, np.eye(len(s)))) @ np.abs(Bs)
    bad = np.argwhere(np.abs(D) > 1e-9 * bound.max())
    if bad.size:
        out, inp = list(frame._outputs)[bad[0, 0]], list(frame._inputs)[bad[0, 1]]
        raise ModelError(
            f"input {inp!r} and output {out!r} both act on DOFs without mass (e.g. {labels[s[0]]}), "
            "so the output would respond instantly to the input; add a small mass/inertia at that "
            "node, or move the sensor or actuator to a node with mass."
        )
