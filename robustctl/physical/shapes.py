"""Geometry and mode shapes over the nodes of a model's structure, for drawing.

A :class:`~robustctl.physical.fem.Frame` knows its nodes, its members and where its sensors
sit; a user's matrices know them when their DOFs are named ``"node:direction"`` and node
coordinates are given. Both give

* a :class:`~robustctl.frd_io.geometry.Geometry` (node coordinates, members or trace lines as
  lines, each output's node and direction as a sensor), and
* :class:`~robustctl.frd_io.geometry.ModeShapes` (every node's translation in each
  undamped mode, ``K phi = w^2 M phi`` with ``phi^T M phi = I``),

which :func:`robustctl.plot_mode_shapes` and :func:`robustctl.animate_mode_shape` draw.

A frame's node translations come from its own assembly: a copy of the frame carries one
displacement sensor per node and direction, so rigid links (a slave follows its master),
supports (zero) and the static condensation of massless DOFs (Guyan) apply to the drawn
shape exactly as they apply to the sensors.
"""

from __future__ import annotations

import copy
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from ..errors import ModelError
from ..frd_io.geometry import Geometry, ModeShapes, parse_dof
from ..threads import limit_blas
from .eigen import solve_modes

__all__ = ["frame_geometry", "frame_mode_shapes", "matrix_geometry", "matrix_mode_shapes"]

_AXES = ("x", "y", "z")


def _used_nodes(frame: Any) -> list[str]:
    """Nodes that something holds (an element, link, mass, spring or support), in insertion order."""
    used: set[str] = set()
    for e in frame._elements.values():
        used.update((e.n1, e.n2))
    for link in frame._links:
        used.update((link.master, link.slave))
    used.update(m.node for m in frame._masses)
    for s in frame._springs:
        used.add(s.node)
        if s.node2 is not None:
            used.add(s.node2)
    used.update(f.node for f in frame._fixes)
    return [n for n in frame._nodes if n in used]


def frame_geometry(frame: Any) -> Geometry:
    """The frame's nodes, members and sensors as a :class:`Geometry`.

    Node ``k`` (1-based) is the ``k``-th node added to the frame (``frame.locations()``);
    lines are the beam and rod elements, the rigid links and the two-node springs; a sensor is
    an output that reads one node along one translation.

    Parameters
    ----------
    frame : Frame

    Returns
    -------
    Geometry
        In metres, named after the frame.
    """
    names = list(frame._nodes)
    ids = {n: k + 1 for k, n in enumerate(names)}
    pairs = [(e.n1, e.n2) for e in frame._elements.values()]
    pairs += [(link.master, link.slave) for link in frame._links]
    pairs += [(s.node, s.node2) for s in frame._springs if s.node2 is not None]
    lines = [(ids[a], ids[b]) for a, b in pairs]
    sensors = {}
    for name, sig in frame._outputs.items():
        if sig.strain is None and len(sig.terms) == 1:
            node, vec = sig.terms[0]
            vec = np.asarray(vec, dtype=float)
            if np.linalg.norm(vec[:3]) > 0 and not np.any(vec[3:]):
                sensors[name] = (ids[node], vec[:3] / np.linalg.norm(vec[:3]))
    xyz = np.array([frame._nodes[n].xyz for n in names]).reshape(-1, 3)
    return Geometry(np.arange(1, len(names) + 1), xyz, np.array(lines, int).reshape(-1, 2), sensors,
                    unit="m", name=frame.name)


def _modes_in(mass: Any, stiffness: Any, n_modes: int | None, band_hz: Sequence[float] | None):
    options = {} if band_hz is None else {"band_hz": tuple(band_hz)}
    w, phi = limit_blas(solve_modes)(mass, stiffness, n_modes=n_modes, **options)
    return w / (2 * np.pi), phi


def frame_mode_shapes(
    frame: Any, n_modes: int | None = None, band_hz: Sequence[float] | None = None
) -> ModeShapes:
    """Every node's translation in the frame's undamped modes.

    Parameters
    ----------
    frame : Frame
    n_modes : int, optional
        The lowest ``n_modes`` modes (all by default).
    band_hz : (lo, hi), optional
        Only the modes in this band (Hz).

    Returns
    -------
    ModeShapes
        Mass-normalised (``phi^T M phi = I``, metres per unit modal coordinate), over the node
        ids of :func:`frame_geometry`; rotations are not drawn (``present`` is False for them).
    """
    probe = copy.deepcopy(frame)
    used = _used_nodes(frame)
    ids = {n: k + 1 for k, n in enumerate(frame._nodes)}
    first = len(probe._outputs)
    for k, node in enumerate(used):
        for ax in _AXES:
            probe.add_output(f"\x00shape {k} {ax}", node, ax, kind="displacement")
    sm = probe.matrices()
    f_hz, phi = _modes_in(sm.mass, sm.stiffness, n_modes, band_hz)
    rows = np.asarray(sm.output_matrix)[first:] @ phi  # (3 n_used, n_modes)
    shapes = np.zeros((f_hz.size, len(frame._nodes), 6))
    cols = [ids[n] - 1 for n in used]
    shapes[:, cols, :3] = rows.T.reshape(f_hz.size, len(used), 3)
    present = np.zeros((len(frame._nodes), 6), bool)
    present[cols, :3] = True
    return ModeShapes(f_hz, np.arange(1, len(frame._nodes) + 1), shapes, present=present, unit="m",
                      name=f"{frame.name} modes")


def _node_dofs(labels: Sequence[str]) -> list[tuple[int, int, float]]:
    """``(node, translation axis, sign)`` of each DOF label ``"node:direction"``; ModelError otherwise."""
    out = []
    for label in labels:
        try:
            node, vec = parse_dof(label)
        except Exception:
            raise ModelError(
                f"DOF label {label!r} does not name a node and direction; for a geometry, label the DOFs "
                "'node:direction' (e.g. '3:X', '12:+Z') with integer node ids given in nodes=."
            ) from None
        axis = int(np.flatnonzero(vec)[0])
        out.append((node, axis, float(vec[axis])))
    return out


def matrix_geometry(
    nodes: Mapping[int, Sequence[float]],
    dof_labels: Sequence[str],
    outputs: Mapping[str, Any],
    lines: Sequence[tuple[int, int]] = (),
    name: str = "",
) -> Geometry:
    """A :class:`Geometry` for a matrix model whose DOFs are labelled ``"node:direction"``.

    Parameters
    ----------
    nodes : mapping node id -> (x, y, z)
        Node coordinates, m.
    dof_labels : sequence of str
        The matrices' DOF labels (``"3:X"``); each names a node of ``nodes``.
    outputs : mapping name -> (DOF label or vector, kind)
        The model's outputs; one that reads a single translational DOF becomes a sensor.
    lines : sequence of (int, int)
        Node pairs to draw (springs, members).
    name : str

    Returns
    -------
    Geometry
    """
    dofs = _node_dofs(dof_labels)
    missing = sorted({n for n, _, _ in dofs} - {int(k) for k in nodes})
    if missing:
        raise ModelError(f"DOF labels name node(s) {missing[:5]} without coordinates; add them to nodes=.")
    ids = np.array(sorted(int(k) for k in nodes))
    xyz = np.array([nodes[k] for k in sorted(nodes, key=int)], dtype=float).reshape(-1, 3)
    sensors = {}
    labels = list(dof_labels)
    for out_name, (where, _kind) in outputs.items():
        if isinstance(where, str) and where in labels:
            node, axis, sign = dofs[labels.index(where)]
            if axis < 3:
                direction = np.zeros(3)
                direction[axis] = sign
                sensors[str(out_name)] = (node, direction)
    return Geometry(ids, xyz, np.array(list(lines), int).reshape(-1, 2), sensors, unit="m", name=name)


def matrix_mode_shapes(
    mass: Any,
    stiffness: Any,
    dof_labels: Sequence[str],
    node_ids: Sequence[int],
    n_modes: int | None = None,
    band_hz: Sequence[float] | None = None,
    name: str = "",
) -> ModeShapes:
    """Mode shapes of ``K phi = w^2 M phi`` placed on the nodes named by ``"node:direction"`` labels.

    Parameters
    ----------
    mass, stiffness : (n, n) array or sparse
        kg and N/m.
    dof_labels : sequence of str
        ``"node:direction"`` per DOF.
    node_ids : sequence of int
        The geometry's nodes, in its order.
    n_modes, band_hz :
        As for :func:`frame_mode_shapes`.
    name : str

    Returns
    -------
    ModeShapes
        Mass-normalised; components a DOF does not carry are zero and not ``present``.
    """
    dofs = _node_dofs(dof_labels)
    f_hz, phi = _modes_in(mass, stiffness, n_modes, band_hz)
    where = {int(n): k for k, n in enumerate(node_ids)}
    shapes = np.zeros((f_hz.size, len(where), 6))
    present = np.zeros((len(where), 6), bool)
    for row, (node, axis, sign) in enumerate(dofs):
        shapes[:, where[node], axis] += sign * phi[row]
        present[where[node], axis] = True
    return ModeShapes(f_hz, np.asarray(node_ids), shapes, present=present, unit="m", name=name)
