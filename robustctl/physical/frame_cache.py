"""Process-wide caches of the frame assembly, shared by the frames a diagnosis builds.

A diagnosis builds one :class:`~robustctl.physical.fem.Frame` per candidate effect; the
candidates differ only in point masses, springs, tensions or gravity, so the geometry part of
the assembly (element stacks, constraint transform, signal matrices, the reduced element
triplets and their sparsity patterns) is computed once and looked up by the identities of the
frozen components (the entry keeps them alive, so an ``id()`` cannot be reused while it
exists), then by a digest of their values. Gravity preloads are kept beside it.
"""

from __future__ import annotations

import hashlib
import pickle
import threading
from collections import OrderedDict
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import scipy.sparse as sp

from .frame_kernels import (
    _G,
    _K,
    _M,
    _constraint_transform,
    _element_stacks,
    _ElementStacks,
    _link_geometric_triplets,
    _link_pairs,
    _Pattern,
    _signal_matrix,
    _Trip,
)
from .structure_base import Structure


@dataclass
class _Geometry:
    """What the assembly computes from the nodes, elements, links, supports and signals alone
    (no point masses, springs, tensions or gravity): shared by the frames a diagnosis builds
    for its candidates, which differ only in those (:func:`_geometry`)."""

    names: tuple[str, ...]
    index: dict[str, int]
    X: np.ndarray
    st: _ElementStacks
    links: tuple[np.ndarray, np.ndarray]
    elements: _Trip  # beams, rods and the links' geometric stiffness, over the full DOFs
    T: sp.csr_matrix
    dof_of_col: np.ndarray
    B_full: np.ndarray
    C_full: np.ndarray
    reduced: dict  # keep-mask bytes -> (elements reduced, {point pattern key: _Pattern})
    kept: dict = field(default_factory=dict)  # keep-mask bytes -> _Kept


@dataclass(frozen=True)
class _Kept:
    """The parts of an assembly fixed by the geometry and the kept DOFs: the constraint
    transform, DOF numbers and signal matrices restricted to them, the DOF labels."""

    T: sp.csr_matrix
    dof_of_col: np.ndarray
    B1: np.ndarray
    Cy1: np.ndarray
    labels: tuple[str, ...]


class _LRU:
    """A small thread-safe least-recently-used store."""

    def __init__(self, size: int) -> None:
        self._size, self._store, self._lock = size, OrderedDict(), threading.Lock()

    def get(self, key: Any) -> Any:
        with self._lock:
            value = self._store.get(key)
            if value is not None:
                self._store.move_to_end(key)
            return value

    def put(self, key: Any, value: Any) -> Any:
        with self._lock:
            self._store[key] = value
            while len(self._store) > self._size:
                self._store.popitem(last=False)
        return value


#: Geometry parts of recent assemblies, keyed on the identities of the frozen components
#: (the value keeps them alive, so an id cannot be reused while its entry exists) and on a
#: digest of their values (:func:`_content_key`).
_GEOMETRY = _LRU(12)
#: Gravity preloads of recent assemblies, keyed on the geometry and a digest of the loads.
_PRELOADS = _LRU(16)
_GEOMETRY_LOCK = threading.Lock()


def _geometry_key(frame: Structure) -> tuple[tuple, tuple]:
    """The frozen components the geometry depends on and a hashable key of their identities."""
    parts = (
        tuple(frame._nodes.items()), tuple(frame._elements.values()), tuple(frame._links),
        tuple(frame._fixes), tuple(frame._inputs.values()), tuple(frame._outputs.values()),
    )  # fmt: skip
    ids = tuple(id(x) for x in parts[0] for x in x) + tuple(id(x) for part in parts[1:] for x in part)
    lengths = tuple(len(part) for part in parts)
    scale = tuple(sorted(frame._group_scale.items()))
    return parts, (ids, lengths, scale, tuple(frame._nodes), tuple(frame._inputs), tuple(frame._outputs))


def _content_key(parts: tuple, key: tuple) -> tuple:
    """A digest of the frozen components' values: frames rebuilt node by node with equal
    geometry (an update of a point mass, which rebuilds the frame) share one geometry."""
    h = hashlib.blake2b(digest_size=20)
    h.update(pickle.dumps((parts, key[1:]), protocol=pickle.HIGHEST_PROTOCOL))
    return ("content", h.digest())


def _geometry(frame: Structure) -> _Geometry:
    """The geometry part of the assembly, computed once per set of frozen components (looked
    up by their identities, then by their values)."""
    parts, key = _geometry_key(frame)
    found = _GEOMETRY.get(key)
    if found is not None:
        return found[1]
    content = _content_key(parts, key)
    found = _GEOMETRY.get(content)
    if found is not None:
        return _GEOMETRY.put(key, (parts, found[1]))[1]
    names = tuple(frame._nodes)
    index = {n: i for i, n in enumerate(names)}
    X = np.array([frame._nodes[n].xyz for n in names])
    n_full = 6 * len(names)
    st = _element_stacks(frame, index, X)
    links = _link_pairs(frame, index, X)
    elements = _Trip.cat(
        [
            _Trip.from_blocks(st.dofs_beam, {_K: st.K_beam, _M: st.M_beam, _G: st.G_beam}, st.beam_idx),
            _Trip.from_blocks(st.dofs_rod, {_K: st.K_rod, _M: st.M_rod, _G: st.G_rod}, st.rod_idx),
            _link_geometric_triplets(X, links, len(frame._elements)),
        ]
    )
    T, dof_of_col = _constraint_transform(frame, index, X)
    B_full = _signal_matrix(frame, frame._inputs, index, st, n_full)
    C_full = _signal_matrix(frame, frame._outputs, index, st, n_full).T
    geo = _Geometry(names, index, X, st, links, elements, T, dof_of_col, B_full, C_full, {})
    _GEOMETRY.put(content, (None, geo))
    return _GEOMETRY.put(key, (parts, geo))[1]


def _full_triplets(geo: _Geometry, points: _Trip) -> _Trip:
    """All triplets in the order of the original assembly (elements, points, links)."""
    n_link = 36 * geo.links[0].size
    e = geo.elements
    cut = e.rows.size - n_link
    return _Trip.cat([_Trip(e.rows[:cut], e.cols[:cut], e.vals[:cut], e.tag[:cut]), points,
                      _Trip(e.rows[cut:], e.cols[cut:], e.vals[cut:], e.tag[cut:])])  # fmt: skip


def _reduced(
    geo: _Geometry, points: _Trip, keep: np.ndarray, new_index: np.ndarray
) -> tuple[_Trip, _Pattern]:
    """``full.reduce`` and its sparsity pattern; the element part and the pattern are reused
    (reduction maps each triplet on its own, so it commutes with concatenation)."""
    n_link = 36 * geo.links[0].size
    e = geo.elements
    cut = e.rows.size - n_link
    key = keep.tobytes()
    with _GEOMETRY_LOCK:
        entry = geo.reduced.get(key)
    if entry is None:
        head = _Trip(e.rows[:cut], e.cols[:cut], e.vals[:cut], e.tag[:cut]).reduce(geo.T, new_index)
        tail = _Trip(e.rows[cut:], e.cols[cut:], e.vals[cut:], e.tag[cut:]).reduce(geo.T, new_index)
        with _GEOMETRY_LOCK:
            entry = geo.reduced.setdefault(key, (head, tail, {}))
            while len(geo.reduced) > 8:
                geo.reduced.pop(next(iter(geo.reduced)))
    head, tail, patterns = entry
    pts = points.reduce(geo.T, new_index)
    red = _Trip.cat([head, pts, tail])
    pkey = pts.rows.tobytes() + b"|" + pts.cols.tobytes()  # head and tail are the keep mask's
    with _GEOMETRY_LOCK:
        pattern = patterns.get(pkey)
    if pattern is None:
        pattern = _Pattern(red.rows, red.cols, int(keep.sum()))
        with _GEOMETRY_LOCK:
            pattern = patterns.setdefault(pkey, pattern)
            while len(patterns) > 32:
                patterns.pop(next(iter(patterns)))
    return red, pattern
