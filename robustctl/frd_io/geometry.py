"""Test and FE geometry (nodes, trace lines, sensors) and mode shapes over nodes.

Two plain types shared by every file format that carries a structure's geometry (UFF
datasets 15/2411/82/2412/55, a Nastran BDF and OP2):

* :class:`Geometry` — node coordinates, trace lines between nodes, and where each sensor
  channel sits (node and direction), so measured channels map to the structure without a
  hand-written table.
* :class:`ModeShapes` — frequencies, damping, generalised masses and the six components of
  each mode at each node (the content of UFF dataset 55 or a Nastran eigenvector table).

A DOF is named ``"node:direction"``: ``"1001:T3"`` (Nastran component), ``"12:+Z"``, ``"12:-3"``
(UFF direction code), ``"12:RX"``. Direction tokens: ``T1 T2 T3 R1 R2 R3``, ``X Y Z RX RY RZ``,
``1``..``6`` (with an optional sign).
"""

from __future__ import annotations

import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from ..errors import DataError

__all__ = ["Geometry", "ModeShapes", "COMPONENTS", "parse_dof", "dof_label"]

#: Component names of the six DOFs of a node, in Nastran order.
COMPONENTS = ("T1", "T2", "T3", "R1", "R2", "R3")
_TOKENS = {
    "T1": 0,
    "T2": 1,
    "T3": 2,
    "R1": 3,
    "R2": 4,
    "R3": 5,
    "X": 0,
    "Y": 1,
    "Z": 2,
    "RX": 3,
    "RY": 4,
    "RZ": 5,
    "UX": 0,
    "UY": 1,
    "UZ": 2,
    "1": 0,
    "2": 1,
    "3": 2,
    "4": 3,
    "5": 4,
    "6": 5,
}
_DOF_RE = re.compile(r"^\s*(-?\d+)\s*[:\s]\s*([+-]?)\s*([A-Za-z0-9]+)\s*$")


def parse_dof(label: str) -> tuple[int, np.ndarray]:
    """``"1001:T3"`` -> ``(1001, e_3)``: the node id and a unit 6-vector over ``T1..R3``.

    Parameters
    ----------
    label : str
        ``"node:direction"``; direction one of ``T1..R3``, ``X, Y, Z, RX, RY, RZ`` or ``1..6``,
        with an optional sign (``"12:-Z"`` points along -Z).

    Returns
    -------
    node : int
    direction : ndarray (6,)

    Raises
    ------
    DataError
        The label is not of that form.
    """
    m = _DOF_RE.match(str(label))
    token = m.group(3).upper() if m else ""
    if m is None or token not in _TOKENS:
        raise DataError(
            f"{label!r} is not a DOF name; write 'node:direction' such as '1001:T3', '12:+Z' or '12:-3' "
            "(directions T1..R3, X/Y/Z/RX/RY/RZ or 1..6)."
        )
    vec = np.zeros(6)
    vec[_TOKENS[token]] = -1.0 if m.group(2) == "-" else 1.0
    return int(m.group(1)), vec


def dof_label(node: int, component: int) -> str:
    """``dof_label(1001, 2) == "1001:T3"`` (component 0-based)."""
    return f"{int(node)}:{COMPONENTS[component]}"


def _direction(spec: Any, what: str) -> np.ndarray:
    """A sensor direction as a unit translation 3-vector (from a token or a vector)."""
    if isinstance(spec, str):
        _, vec = parse_dof(f"0:{spec}")
        if np.any(vec[3:]):
            raise DataError(
                f"{what}: direction {spec!r} is a rotation; sensors measure translations (X, Y, Z)."
            )
        return vec[:3]
    v = np.asarray(spec, dtype=float).reshape(-1)
    if v.size != 3 or not np.all(np.isfinite(v)) or np.linalg.norm(v) == 0:
        raise DataError(f"{what}: direction must be 'X'/'+Z'/'T3'... or a non-zero 3-vector; got {spec!r}.")
    return v / np.linalg.norm(v)


@dataclass(frozen=True, eq=False)
class Geometry:
    """Nodes, trace lines and sensor placement of a structure (a test or an FE model).

    Attributes
    ----------
    node_ids : ndarray of int, shape (n_nodes,)
    xyz : ndarray, shape (n_nodes, 3)
        Node coordinates in ``unit`` (global Cartesian frame).
    lines : ndarray of int, shape (n_lines, 2)
        Node-id pairs drawn as straight lines (UFF trace lines, FE element edges).
    sensors : mapping channel -> (node id, unit direction (3,))
        Where each output channel measures, and along which direction.
    unit : str
        Length unit of ``xyz`` (``"m"``, ``"mm"`` ...).
    name : str
    """

    node_ids: np.ndarray
    xyz: np.ndarray
    lines: np.ndarray = field(default_factory=lambda: np.zeros((0, 2), int))
    sensors: Mapping[str, tuple[int, np.ndarray]] = field(default_factory=dict)
    unit: str = "m"
    name: str = ""

    def __post_init__(self) -> None:
        ids = np.asarray(self.node_ids).reshape(-1)
        if ids.dtype.kind not in "iu":
            if ids.size and not np.all(np.equal(np.mod(np.asarray(ids, float), 1), 0)):
                raise DataError(f"node ids must be integers; got {ids[:5]}.")
            ids = ids.astype(np.int64)
        xyz = np.asarray(self.xyz, dtype=float).reshape(-1, 3) if np.size(self.xyz) else np.zeros((0, 3))
        if xyz.shape[0] != ids.size:
            raise DataError(
                f"{ids.size} node ids but {xyz.shape[0]} coordinate rows; give one (x, y, z) per node."
            )
        if not np.all(np.isfinite(xyz)):
            raise DataError("node coordinates contain NaN or inf.")
        uniq, count = np.unique(ids, return_counts=True)
        if np.any(count > 1):
            raise DataError(f"node {int(uniq[count > 1][0])} is defined twice; node ids must be unique.")
        lines = (
            np.asarray(self.lines, dtype=np.int64).reshape(-1, 2)
            if np.size(self.lines)
            else np.zeros((0, 2), int)
        )
        missing = sorted(set(lines.ravel().tolist()) - set(ids.tolist()))
        if missing:
            raise DataError(
                f"trace lines use node(s) {missing[:5]} that have no coordinates; add them to the nodes."
            )
        sensors = {}
        for ch, spec in dict(self.sensors).items():
            node, direction = spec
            if int(node) not in set(ids.tolist()):
                raise DataError(f"sensor {ch!r} sits at node {node}, which the geometry does not have.")
            sensors[str(ch)] = (int(node), _direction(direction, f"sensor {ch!r}"))
        object.__setattr__(self, "node_ids", ids)
        object.__setattr__(self, "xyz", xyz)
        object.__setattr__(self, "lines", lines)
        object.__setattr__(self, "sensors", sensors)

    @property
    def n_nodes(self) -> int:
        return int(self.node_ids.size)

    def __repr__(self) -> str:
        return (
            f"Geometry({self.name or 'unnamed'}: {self.n_nodes} nodes, {len(self.lines)} lines, "
            f"{len(self.sensors)} sensors, {self.unit})"
        )

    def index(self, nodes: Sequence[int]) -> np.ndarray:
        """Row of each node id in :attr:`xyz` (DataError naming a missing node)."""
        where = {int(n): k for k, n in enumerate(self.node_ids)}
        out = []
        for n in nodes:
            if int(n) not in where:
                raise DataError(
                    f"node {n} is not in the geometry ({self.n_nodes} nodes); check the node ids."
                )
            out.append(where[int(n)])
        return np.asarray(out, dtype=int)

    def with_sensors(self, sensors: Mapping[str, Any]) -> Geometry:
        """A copy with more sensors: ``{"S1": "12:+Z", "S2": (13, (0, 0.6, 0.8))}``."""
        new = dict(self.sensors)
        for ch, spec in sensors.items():
            if isinstance(spec, str):
                node, vec = parse_dof(spec)
                if np.any(vec[3:]):
                    raise DataError(f"sensor {ch!r}: {spec!r} is a rotation; sensors measure translations.")
                new[str(ch)] = (node, vec[:3])
            else:
                new[str(ch)] = (int(spec[0]), spec[1])
        return replace(self, sensors=new)

    def sensor(self, channel: str) -> tuple[int, np.ndarray]:
        """Node and unit direction of ``channel``: from :attr:`sensors`, else from a
        ``"node:direction"`` name; DataError naming the channel and the fix otherwise."""
        if channel in self.sensors:
            return self.sensors[channel]
        try:
            node, vec = parse_dof(channel)
        except DataError:
            node, vec = None, None
        if node is None or np.any(vec[3:]) or node not in set(self.node_ids.tolist()):
            raise DataError(
                f"channel {channel!r} has no node in the geometry {self.name or ''}".rstrip() + "; "
                f"add it with geometry.with_sensors({{{channel!r}: 'node:+Z'}}) or name the channel "
                "'node:direction' after a node of the geometry."
            )
        return node, vec[:3]

    def channel_map(self, channels: Sequence[str]) -> tuple[np.ndarray, np.ndarray]:
        """Row in :attr:`xyz` and unit direction (n, 3) of each channel."""
        pairs = [self.sensor(str(c)) for c in channels]
        rows = self.index([p[0] for p in pairs]) if pairs else np.zeros(0, int)
        dirs = np.array([p[1] for p in pairs]).reshape(-1, 3)
        return rows, dirs


@dataclass(frozen=True, eq=False)
class ModeShapes:
    """Mode shapes over the nodes of a structure (UFF dataset 55, a Nastran eigenvector table).

    Attributes
    ----------
    f_hz : ndarray (n_modes,)
        Natural frequencies, Hz.
    node_ids : ndarray of int (n_nodes,)
    shapes : ndarray (n_modes, n_nodes, 6), real or complex
        Components ``T1 T2 T3 R1 R2 R3`` of each mode at each node (length / rad per unit
        modal coordinate).
    present : ndarray of bool (n_nodes, 6)
        Which components the source had (a component the FE model lacks is False, its shape 0).
    zeta : ndarray (n_modes,)
        Damping ratios (NaN when the source gives none).
    generalized_mass : ndarray (n_modes,)
        ``phi^T M phi`` of each shape as stored (1 for mass-normalised shapes).
    unit : str
        Length unit of the translations.
    name : str
    """

    f_hz: np.ndarray
    node_ids: np.ndarray
    shapes: np.ndarray
    present: np.ndarray | None = None
    zeta: np.ndarray | None = None
    generalized_mass: np.ndarray | None = None
    unit: str = "m"
    name: str = ""

    def __post_init__(self) -> None:
        f = np.asarray(self.f_hz, dtype=float).reshape(-1)
        ids = np.asarray(self.node_ids).reshape(-1).astype(np.int64)
        shapes = np.asarray(self.shapes)
        if shapes.dtype.kind not in "fc":
            shapes = shapes.astype(float)
        if shapes.shape != (f.size, ids.size, 6):
            raise DataError(
                f"mode shapes have shape {shapes.shape}; expected (n_modes={f.size}, n_nodes={ids.size}, 6)."
            )
        if not np.all(np.isfinite(f)) or np.any(f < 0):
            raise DataError(f"natural frequencies must be finite and >= 0 Hz; got {f}.")
        if not np.all(np.isfinite(shapes)):
            raise DataError("mode shapes contain NaN or inf.")
        present = np.ones((ids.size, 6), bool) if self.present is None else np.asarray(self.present, bool)
        zeta = np.full(f.size, np.nan) if self.zeta is None else np.asarray(self.zeta, float).reshape(-1)
        gm = np.ones(f.size) if self.generalized_mass is None else np.asarray(self.generalized_mass, float)
        if present.shape != (ids.size, 6) or zeta.size != f.size or gm.shape != (f.size,):
            raise DataError("present must be (n_nodes, 6); zeta and generalized_mass one value per mode.")
        if np.any(~np.isfinite(gm)) or np.any(gm <= 0):
            raise DataError(f"generalised masses must be finite and > 0; got {gm}.")
        for name, value in (
            ("f_hz", f),
            ("node_ids", ids),
            ("shapes", shapes),
            ("present", present),
            ("zeta", zeta),
            ("generalized_mass", gm),
        ):
            object.__setattr__(self, name, value)

    @property
    def n_modes(self) -> int:
        return int(self.f_hz.size)

    def __repr__(self) -> str:
        return f"ModeShapes({self.name or 'unnamed'}: {self.n_modes} modes at {self.node_ids.size} nodes)"

    def mass_normalized(self) -> np.ndarray:
        """Shapes scaled to unit generalised mass, ``phi_k / sqrt(m_k)`` (n_modes, n_nodes, 6)."""
        return self.shapes / np.sqrt(self.generalized_mass)[:, None, None]

    def at(
        self,
        dofs: Sequence[Any],
        *,
        geometry: Geometry | None = None,
        what: str = "channel",
        mass_normalized: bool = True,
    ) -> np.ndarray:
        """Shapes along DOFs or sensors, (n_dofs, n_modes).

        Parameters
        ----------
        dofs : sequence of str
            ``"node:direction"`` names, or channel names placed by ``geometry.sensors``.
        geometry : Geometry, optional
            Resolves channel names to a node and a direction (any unit vector).
        what : str
            Word used in error messages (``"input"``, ``"output"``).
        mass_normalized : bool
            Divide by ``sqrt(generalized_mass)`` (MACE eq. 3 needs unit modal mass).

        Raises
        ------
        DataError
            A DOF at a node the shapes lack, or along a component the model does not have.
        """
        where = {int(n): k for k, n in enumerate(self.node_ids)}
        phi = self.mass_normalized() if mass_normalized else self.shapes
        cols = []
        for d in dofs:
            name = str(d)
            if geometry is not None and name in geometry.sensors:
                node, dir3 = geometry.sensors[name]
                vec = np.concatenate([dir3, np.zeros(3)])
            else:
                try:
                    node, vec = parse_dof(name)
                except DataError:
                    raise DataError(
                        f"{what} {name!r} is neither 'node:direction' (e.g. '1001:T3') nor a sensor of the "
                        "geometry; name it after its grid point or pass geometry= with sensors mapping it "
                        "to a node."
                    ) from None
            if node not in where:
                raise DataError(
                    f"{what} {name!r}: node {node} has no mode shape ({self.node_ids.size} nodes in "
                    f"{self.name or 'the shapes'}); check the node id or export shapes at that node."
                )
            k = where[node]
            used = np.flatnonzero(np.abs(vec) > 1e-12)
            lacking = [COMPONENTS[c] for c in used if not self.present[k, c]]
            if lacking:
                raise DataError(
                    f"{what} {name!r} uses direction(s) {lacking} at node {node}, which the model lacks "
                    f"(it has {[COMPONENTS[c] for c in np.flatnonzero(self.present[k])]}); use a direction "
                    "the model has or export the missing components."
                )
            cols.append(phi[:, k, :] @ vec)
        return np.array(cols).reshape(len(cols), self.n_modes)

    def select(self, modes: Sequence[int]) -> ModeShapes:
        """A subset of the modes (0-based indices)."""
        idx = np.asarray(modes, dtype=int)
        return replace(
            self,
            f_hz=self.f_hz[idx],
            shapes=self.shapes[idx],
            zeta=self.zeta[idx],
            generalized_mass=self.generalized_mass[idx],
        )
