"""The built-in frame FEM: beams, rods, point masses, springs, dashpots, rigid links, supports.

A :class:`Frame` is the 1-g finite-element model of MACE (Glaese & Miller): a 3-D frame of
Euler-Bernoulli beams and rods with lumped masses and inertias, suspension springs and
dashpots, and gravity applied through the iterative stress-stiffening procedure of
:mod:`robustctl.physical.gravity`. It implements the :class:`Structure` contract, so
physical effects (added mass, suspension spring, stiffer element group, wire tension) and
``without("suspension", "gravity")`` -- MACE's step from the 1-g to the 0-g model -- work on it.

DOFs are six per node ``[ux uy uz rx ry rz]`` in global axes (m, rad). On assembly
(:meth:`Frame.matrices`):

1. element matrices are built in vectorised stacks and assembled sparsely;
2. rigid links and supports are applied by a transformation ``q_full = T q`` (slave
   nodes follow their master rigidly; fixed DOFs are dropped);
3. DOFs that have neither mass nor stiffness (rotations of nodes joined only by rods) are
   dropped; an input or output on such a DOF is an error;
4. with gravity on, the preload iteration (:func:`~robustctl.physical.gravity.preload_iteration`)
   gives the member axial forces -- and the forces rigid links carry -- and ``K + K_g(N)``;
5. DOFs with stiffness but no mass are condensed statically (Guyan): their motion is the
   static response to the massive DOFs, and the input/output pointing matrices are
   transformed with the same matrix, so sensors and actuators on them keep working.
"""

from __future__ import annotations

import copy
import hashlib
import pickle
import threading
from collections import OrderedDict
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, replace
from typing import Any

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp

from ..checks import flag, is_real_number
from ..errors import ModelError
from ..threads import limit_blas
from . import elements as el
from .eigen import SPARSE_THRESHOLD, solve_modes
from .gravity import PreloadResult, preload_iteration
from .structure_base import OUTPUT_KINDS, StructuralMatrices, Structure

__all__ = ["Frame", "DIRECTIONS"]

#: Direction names and their index among a node's six DOFs.
DIRECTIONS = {"x": 0, "y": 1, "z": 2, "rx": 3, "ry": 4, "rz": 5}
_DOF_NAMES = ("ux", "uy", "uz", "rx", "ry", "rz")
_STRAIN_KINDS = ("axial", "bending_y", "bending_z")


# ---------------------------------------------------------------------- components
@dataclass(frozen=True)
class _Node:
    name: str
    xyz: np.ndarray
    tags: tuple[str, ...] = ()


@dataclass(frozen=True)
class _Element:
    name: str
    group: str
    kind: str  # "beam" or "rod"
    n1: str
    n2: str
    E: float
    A: float
    rho: float
    G: float = 0.0
    Iy: float = 0.0
    Iz: float = 0.0
    J: float = 0.0
    orient: np.ndarray | None = None
    lumped: bool = False
    rotary_inertia: bool = False
    tags: tuple[str, ...] = ()


@dataclass(frozen=True)
class _Mass:
    node: str
    mass: float
    inertia: np.ndarray
    tags: tuple[str, ...] = ()


@dataclass(frozen=True)
class _Spring:
    node: str
    node2: str | None
    value: float
    vec: np.ndarray  # 6-vector
    kind: str  # "spring" or "dashpot"
    tags: tuple[str, ...] = ()


@dataclass(frozen=True)
class _Link:
    master: str
    slave: str
    tags: tuple[str, ...] = ()


@dataclass(frozen=True)
class _Fix:
    node: str
    dofs: tuple[int, ...]
    tags: tuple[str, ...] = ()


@dataclass(frozen=True)
class _Signal:
    """An input or an output: a sum of 6-vector pointings at nodes, or a strain gauge."""

    name: str
    terms: list[tuple[str, np.ndarray]]
    kind: str = "force"
    strain: tuple | None = None  # (element names, positions, strain kind, fiber)
    tags: tuple[str, ...] = ()


@dataclass
class _Assembly:
    """Everything :meth:`Frame.matrices` computes, kept for inspection methods."""

    matrices: StructuralMatrices
    node_names: tuple[str, ...]
    element_names: tuple[str, ...]
    T_red: sp.csr_matrix  # full DOFs -> DOFs of the preload solve
    preload: PreloadResult | None
    axial: np.ndarray


# ---------------------------------------------------------------------- validation helpers
def _finite(name: str, value, *, positive: bool = False, nonneg: bool = False) -> float:
    if not is_real_number(value):  # no strings, no booleans
        raise ModelError(f"{name} must be a number; got {value!r}.")
    v = float(value)
    if not np.isfinite(v):
        raise ModelError(f"{name} must be finite; got {v!r}.")
    if positive and v <= 0:
        raise ModelError(f"{name} must be positive; got {v!r}. Give a value > 0 in SI units.")
    if nonneg and v < 0:
        raise ModelError(f"{name} must not be negative; got {v!r}. Give a value >= 0 in SI units.")
    return v


def _tags(tags) -> tuple[str, ...]:
    if isinstance(tags, str):
        return (tags,)
    return tuple(str(t) for t in tags)


def _vector3(name: str, value) -> np.ndarray:
    try:
        items = list(np.asarray(value, dtype=object).reshape(-1))
    except (TypeError, ValueError):
        items = [None]
    if not all(is_real_number(x) for x in items):  # no strings, no booleans
        raise ModelError(f"{name} must be 3 numbers; got {value!r}.")
    v = np.array(items, dtype=float)
    if v.size != 3 or not np.all(np.isfinite(v)):
        raise ModelError(f"{name} must be 3 finite numbers (x, y, z); got {value!r}.")
    return v


def direction_vector(direction, *, rotation: bool = False) -> np.ndarray:
    """The unit 6-vector (over ``[ux uy uz rx ry rz]``) of a direction.

    Parameters
    ----------
    direction : str or 3-vector
        ``'x'``, ``'y'``, ``'z'``, ``'rx'``, ``'ry'``, ``'rz'`` (an optional leading ``'-'``
        reverses it) or a 3-vector in global axes, normalised to unit length.
    rotation : bool
        Whether a 3-vector means a rotation axis (torques, rotation outputs) rather than a
        translation.
    """
    vec = np.zeros(6)
    if isinstance(direction, str):
        key = direction.strip().lower()
        sign = -1.0 if key.startswith("-") else 1.0
        key = key.lstrip("+-")
        if key not in DIRECTIONS:
            raise ModelError(
                f"unknown direction {direction!r}; use one of {list(DIRECTIONS)} "
                "(optionally with a leading '-') or a 3-vector such as (0, 0, 1)."
            )
        vec[DIRECTIONS[key]] = sign
        return vec
    v = _vector3("direction", direction)
    norm = np.linalg.norm(v)
    if norm == 0:
        raise ModelError("a direction vector must not be zero; give e.g. (0, 0, 1).")
    vec[3 * rotation : 3 * rotation + 3] = v / norm
    return vec


def _skew(r: np.ndarray) -> np.ndarray:
    return np.array([[0.0, -r[2], r[1]], [r[2], 0.0, -r[0]], [-r[1], r[0], 0.0]])


# ---------------------------------------------------------------------- the frame
class Frame(Structure):
    """A 3-D frame finite-element model (beams, rods, masses, springs, dashpots, links).

    Parameters
    ----------
    gravity : float, optional
        Gravitational acceleration in m/s^2 (9.81 on earth). When given and non-zero, the
        gravity preload (MACE's stress-stiffening iteration) is on; ``set_gravity(False)``
        or ``without("gravity")`` switches it off.
    gravity_direction : 3-vector
        Direction of gravity in global axes (normalised), default ``(0, 0, -1)``.
    max_gravity_iterations : int
        Cap on the preload iteration (1 = one linear differential-stiffness step).
    gravity_tol : float
        Relative convergence tolerance of the element axial forces.
    name : str
        A label.

    Examples
    --------
    >>> fr = Frame(gravity=9.81)
    >>> for name, xyz in (("top", (0, 0, 1.0)), ("bob", (0, 0, 0))):
    ...     _ = fr.add_node(name, xyz)
    >>> _ = fr.add_rod("wire", "top", "bob", E=2e11, rho=10.0, A=1e-6)
    >>> _ = fr.add_mass("bob", 1.0).fix("top")
    >>> f_hz, _ = fr.modes(n_modes=2)  # two pendulum modes at sqrt(g/L)/(2 pi)
    >>> np.round(f_hz, 3).tolist()
    [0.498, 0.498]
    """

    def __init__(
        self,
        gravity: float | None = None,
        gravity_direction: Sequence[float] = (0.0, 0.0, -1.0),
        *,
        max_gravity_iterations: int = 50,
        gravity_tol: float = 1e-8,
        name: str = "frame",
    ) -> None:
        self.name = name
        self._g = 0.0 if gravity is None else _finite("gravity", gravity, nonneg=True)
        gdir = _vector3("gravity_direction", gravity_direction)
        if np.linalg.norm(gdir) == 0:
            raise ModelError("gravity_direction must not be zero; e.g. (0, 0, -1).")
        self._gdir = gdir / np.linalg.norm(gdir)
        self._gravity_on = self._g > 0
        self.max_gravity_iterations = max_gravity_iterations
        self.gravity_tol = gravity_tol
        self._nodes: dict[str, _Node] = {}
        self._elements: dict[str, _Element] = {}
        self._masses: list[_Mass] = []
        self._springs: list[_Spring] = []
        self._links: list[_Link] = []
        self._fixes: list[_Fix] = []
        self._inputs: dict[str, _Signal] = {}
        self._outputs: dict[str, _Signal] = {}
        self._group_scale: dict[str, float] = {}
        self._group_tension: dict[str, float] = {}
        self._group_count: dict[str, int] = {}
        self._cache: _Assembly | None = None

    @property
    def max_gravity_iterations(self) -> int:
        """Cap on the gravity preload iteration (1 = one differential-stiffness step)."""
        return self._max_gravity_iterations

    @max_gravity_iterations.setter
    def max_gravity_iterations(self, value: int) -> None:
        if not isinstance(value, (int, np.integer)) or value < 1:
            raise ModelError(f"max_gravity_iterations must be an integer >= 1; got {value!r}.")
        self._max_gravity_iterations = int(value)
        self._cache = None

    @property
    def gravity_tol(self) -> float:
        """Relative convergence tolerance of the preload's element axial forces."""
        return self._gravity_tol

    @gravity_tol.setter
    def gravity_tol(self, value: float) -> None:
        self._gravity_tol = _finite("gravity_tol", value, positive=True)
        self._cache = None

    # ------------------------------------------------------------------ nodes
    def add_node(self, name: str, xyz: Sequence[float], tags: Iterable[str] = ()) -> str:
        """Add a node at ``xyz`` (m). Names must be unique non-empty strings; returns the name."""
        if not isinstance(name, str) or not name:
            raise ModelError(f"a node name must be a non-empty string; got {name!r}.")
        if name in self._nodes:
            raise ModelError(f"duplicate node name {name!r}: every node needs its own name.")
        self._nodes[name] = _Node(name, _vector3(f"coordinates of node {name!r}", xyz), _tags(tags))
        self._cache = None
        return name

    def _node(self, name: str) -> _Node:
        try:
            return self._nodes[name]
        except (KeyError, TypeError):
            known = list(self._nodes)
            hint = f"known nodes: {known[:12]}{' ...' if len(known) > 12 else ''}"
            raise ModelError(f"unknown node {name!r}; add it with add_node first ({hint}).") from None

    def node_xyz(self, name: str) -> np.ndarray:
        """Coordinates (m) of node ``name``."""
        return self._node(name).xyz.copy()

    def locations(self) -> tuple[str, ...]:
        """Node names (the locations where point effects may act)."""
        return tuple(self._nodes)

    def element_groups(self) -> tuple[str, ...]:
        """Names of the element groups, in the order they were first used."""
        return tuple(dict.fromkeys(e.group for e in self._elements.values()))

    def element_names(self, group: str | None = None) -> tuple[str, ...]:
        """Element names (all, or those of ``group``)."""
        if group is not None and group not in self.element_groups():
            raise ModelError(f"unknown element group {group!r}; groups: {list(self.element_groups())}.")
        return tuple(n for n, e in self._elements.items() if group is None or e.group == group)

    # ------------------------------------------------------------------ elements
    def _chain(self, group: str, n1: str, n2: str, n_elements: int, tags) -> list[tuple[str, str]]:
        """Split the member n1-n2 into ``n_elements`` pieces with new intermediate nodes."""
        if not isinstance(group, str) or not group:
            raise ModelError(f"an element group must be a non-empty string; got {group!r}.")
        a, b = self._node(n1), self._node(n2)
        if n1 == n2 or np.linalg.norm(b.xyz - a.xyz) <= 1e-12 * max(1.0, np.abs(a.xyz).max()):
            raise ModelError(
                f"zero-length element between {n1!r} and {n2!r}: the nodes coincide. Use "
                "add_rigid_link or add_spring to join coincident nodes."
            )
        if not isinstance(n_elements, (int, np.integer)) or n_elements < 1:
            raise ModelError(f"n_elements must be a positive integer; got {n_elements!r}.")
        names = [n1]
        for j in range(1, int(n_elements)):
            base = name = f"{n1}-{n2}/{j}"
            k = 1
            while name in self._nodes:
                name, k = f"{base}#{k}", k + 1
            self.add_node(name, a.xyz + (b.xyz - a.xyz) * j / n_elements, tags=tags)
            names.append(name)
        names.append(n2)
        return list(zip(names[:-1], names[1:]))

    def _element_name(self, group: str) -> str:
        k = self._group_count.get(group, 0)
        while f"{group}[{k}]" in self._elements:
            k += 1
        self._group_count[group] = k + 1
        return f"{group}[{k}]"

    def add_beam(
        self,
        group: str,
        n1: str,
        n2: str,
        *,
        E: float,
        G: float,
        rho: float,
        A: float,
        Iy: float,
        Iz: float,
        J: float,
        orient: Sequence[float] | None = None,
        n_elements: int = 1,
        rotary_inertia: bool = False,
        tags: Iterable[str] = (),
    ) -> list[str]:
        """Add a member of 3-D Euler-Bernoulli frame elements (12 DOFs each).

        Parameters
        ----------
        group : str
            Element group (an update parameter or effect acts on a whole group).
        n1, n2 : str
            End nodes.
        E, G : float
            Young's and shear moduli, Pa.
        rho : float
            Density, kg/m^3.
        A : float
            Area, m^2.
        Iy, Iz : float
            Second moments of area about the local y and z axes, m^4 (``Iy`` governs bending
            in the local x-z plane).
        J : float
            Torsion constant, m^4.
        orient : 3-vector, optional
            A vector in the local x-z plane (global axes); default global Z, or global X for
            members within 26 degrees of vertical.
        n_elements : int
            Subdivision; intermediate nodes ``"n1-n2/1"``, ... are created.
        rotary_inertia : bool
            Add the cross-section's rotary inertia to the consistent mass (Rayleigh beam).
        tags : iterable of str
            Labels for :meth:`without` (``"suspension"``); the new nodes get them too.

        Returns
        -------
        list of str
            The element names ``"group[k]"``.
        """
        props = {
            "E": _finite("E", E, positive=True),
            "G": _finite("G", G, positive=True),
            "rho": _finite("rho", rho, positive=True),
            "A": _finite("A", A, positive=True),
            "Iy": _finite("Iy", Iy, positive=True),
            "Iz": _finite("Iz", Iz, positive=True),
            "J": _finite("J", J, positive=True),
        }
        o = None if orient is None else _vector3("orient", orient)
        if o is not None:
            axis = self._node(n2).xyz - self._node(n1).xyz
            el.beam_axes(np.zeros((1, 3)), axis[None], o[None])  # refuses a parallel orient
        tags = _tags(tags)
        out = []
        for a, b in self._chain(group, n1, n2, n_elements, tags):
            name = self._element_name(group)
            self._elements[name] = _Element(
                name, group, "beam", a, b, orient=o, rotary_inertia=bool(rotary_inertia), tags=tags, **props
            )
            out.append(name)
        self._cache = None
        return out

    def add_rod(
        self,
        group: str,
        n1: str,
        n2: str,
        *,
        E: float,
        rho: float,
        A: float,
        n_elements: int = 1,
        mass: str = "consistent",
        tags: Iterable[str] = (),
    ) -> list[str]:
        """Add a member of rod (truss) elements: axial stiffness ``EA/L``, no bending.

        Under tension ``T`` its geometric stiffness ``T/L`` across the rod makes it a pendulum
        suspension, and a subdivided rod a vibrating string (violin modes).

        Parameters
        ----------
        group, n1, n2, n_elements, tags
            As in :meth:`add_beam`.
        E : float
            Young's modulus, Pa.
        rho : float
            Density, kg/m^3.
        A : float
            Area, m^2.
        mass : {"consistent", "lumped"}
            Mass model.

        Returns
        -------
        list of str
            The element names.
        """
        if mass not in ("consistent", "lumped"):
            raise ModelError(f"mass must be 'consistent' or 'lumped'; got {mass!r}.")
        props = {
            "E": _finite("E", E, positive=True),
            "rho": _finite("rho", rho, positive=True),
            "A": _finite("A", A, positive=True),
        }
        tags = _tags(tags)
        out = []
        for a, b in self._chain(group, n1, n2, n_elements, tags):
            name = self._element_name(group)
            self._elements[name] = _Element(
                name, group, "rod", a, b, lumped=mass == "lumped", tags=tags, **props
            )
            out.append(name)
        self._cache = None
        return out

    # ------------------------------------------------------------------ point components
    def add_mass(self, node: str, mass: float, inertia=None, tags: Iterable[str] = ()) -> Frame:
        """Add a rigid body's mass (kg) and optionally its inertia (kg m^2) at ``node``.

        ``inertia`` is ``(Ixx, Iyy, Izz)`` or a symmetric positive semi-definite 3x3 tensor
        about the node, in global axes.
        """
        self._node(node)
        m = _finite(f"mass at {node!r}", mass, positive=True)
        if inertia is None:
            J = np.zeros((3, 3))
        else:
            J = np.asarray(inertia, dtype=float)
            if J.shape == (3,):
                J = np.diag(J)
            if J.shape != (3, 3) or not np.all(np.isfinite(J)):
                raise ModelError(f"inertia at {node!r} must be (Ixx, Iyy, Izz) or a 3x3 tensor in kg m^2.")
            if np.abs(J - J.T).max() > 1e-12 * max(np.abs(J).max(), 1e-300):
                raise ModelError(f"the inertia tensor at {node!r} must be symmetric.")
            if np.linalg.eigvalsh(J).min() < -1e-12 * max(np.abs(J).max(), 1e-300):
                raise ModelError(f"the inertia at {node!r} must not be negative (principal moments >= 0).")
        self._masses.append(_Mass(node, m, J, _tags(tags)))
        self._cache = None
        return self

    def _add_spring(self, kind, node, value, direction, node2, tags) -> Frame:
        self._node(node)
        if node2 is not None:
            self._node(node2)
            if node2 == node:
                raise ModelError(f"a {kind} needs two different nodes; got {node!r} twice.")
        if direction is None:
            raise ModelError(
                f"a frame {kind} needs a direction: 'x', 'y', 'z', 'rx', 'ry', 'rz' or a 3-vector."
            )
        unit = "N/m or N m/rad" if kind == "spring" else "N s/m or N m s/rad"
        v = _finite(f"{kind} value at {node!r} ({unit})", value, nonneg=True)
        self._springs.append(_Spring(node, node2, v, direction_vector(direction), kind, _tags(tags)))
        self._cache = None
        return self

    def add_spring(
        self, node: str, k: float, direction=None, node2: str | None = None, tags: Iterable[str] = ()
    ) -> Frame:
        """Add a spring of stiffness ``k`` (N/m, or N m/rad for ``'rx'``..) along ``direction``.

        Grounded when ``node2`` is None, else between ``node`` and ``node2`` (relative motion
        along ``direction``).
        """
        return self._add_spring("spring", node, k, direction, node2, tags)

    def add_dashpot(
        self, node: str, c: float, direction=None, node2: str | None = None, tags: Iterable[str] = ()
    ) -> Frame:
        """Add a dashpot (N s/m, or N m s/rad) along ``direction``; conventions as add_spring.

        Dashpots form the concentrated damping matrix (MACE eq. 2's ``C_s``).
        """
        return self._add_spring("dashpot", node, c, direction, node2, tags)

    def add_rigid_link(self, master: str, slave: str, tags: Iterable[str] = ()) -> Frame:
        """Make ``slave`` follow ``master`` rigidly (``u_s = u_m + theta_m x r``, ``theta_s =
        theta_m``); the slave's DOFs are eliminated."""
        self._node(master)
        self._node(slave)
        if master == slave:
            raise ModelError(f"a rigid link needs two different nodes; got {master!r} twice.")
        if any(lk.slave == slave for lk in self._links):
            raise ModelError(
                f"node {slave!r} is already the slave of a rigid link; a node can follow only one master."
            )
        self._links.append(_Link(master, slave, _tags(tags)))
        self._cache = None
        return self

    def fix(self, node: str, dofs="all", tags: Iterable[str] = ()) -> Frame:
        """Clamp DOFs of ``node``: ``"all"``, or a string/list of ``'x','y','z','rx','ry','rz'``."""
        self._node(node)
        if isinstance(dofs, str) and dofs.strip().lower() == "all":
            idx = tuple(range(6))
        else:
            items = [dofs] if isinstance(dofs, str) else list(dofs)
            idx = []
            for d in items:
                key = str(d).strip().lower()
                if key not in DIRECTIONS:
                    raise ModelError(f"unknown DOF {d!r} in fix(); use 'all' or some of {list(DIRECTIONS)}.")
                idx.append(DIRECTIONS[key])
            idx = tuple(sorted(set(idx)))
        self._fixes.append(_Fix(node, idx, _tags(tags)))
        self._cache = None
        return self

    # ------------------------------------------------------------------ inputs and outputs
    def _new_signal(self, table: dict, name: str, what: str) -> None:
        if not isinstance(name, str) or not name:
            raise ModelError(f"an {what} name must be a non-empty string; got {name!r}.")
        if name in table:
            raise ModelError(f"duplicate {what} name {name!r}; signal names must be unique.")

    def add_force_input(
        self, name: str, node: str, direction, kind: str = "force", tags: Iterable[str] = ()
    ) -> Frame:
        """A point force (N, ``kind="force"``) or torque (N m, ``kind="torque"``) input.

        ``direction`` is ``'x'``..``'rz'`` or a 3-vector (a rotation axis for torques). A load
        on a fixed DOF goes straight into the support (its input column is zero there).
        """
        self._new_signal(self._inputs, name, "input")
        self._node(node)
        if kind not in ("force", "torque"):
            raise ModelError(f"input kind must be 'force' or 'torque'; got {kind!r}.")
        vec = direction_vector(direction, rotation=kind == "torque")
        if isinstance(direction, str):
            is_rot = direction.strip().lstrip("+-").lower().startswith("r")
            if is_rot != (kind == "torque"):
                raise ModelError(
                    f"input {name!r}: direction {direction!r} does not match kind={kind!r}; use "
                    "'x'/'y'/'z' for forces and 'rx'/'ry'/'rz' for torques."
                )
        self._inputs[name] = _Signal(name, [(node, vec)], kind, tags=_tags(tags))
        self._cache = None
        return self

    def add_pair_input(self, name: str, n1: str, n2: str, tags: Iterable[str] = ()) -> Frame:
        """Equal and opposite forces (N) along the axis n1->n2 (a voice coil or active strut).

        A positive input pushes the nodes apart: ``+e`` on ``n2`` and ``-e`` on ``n1``.
        """
        self._new_signal(self._inputs, name, "input")
        a, b = self._node(n1), self._node(n2)
        d = b.xyz - a.xyz
        if np.linalg.norm(d) == 0:
            raise ModelError(
                f"pair input {name!r}: nodes {n1!r} and {n2!r} coincide, so the axis is undefined."
            )
        e = np.concatenate([d / np.linalg.norm(d), np.zeros(3)])
        self._inputs[name] = _Signal(name, [(n1, -e), (n2, e)], "force", tags=_tags(tags))
        self._cache = None
        return self

    def add_output(
        self, name: str, node: str, direction, kind: str = "acceleration", tags: Iterable[str] = ()
    ) -> Frame:
        """A sensor at ``node``: displacement (m, rad), velocity or acceleration along ``direction``.

        ``direction`` is ``'x'``..``'rz'`` or a 3-vector (a translation). On a fixed DOF the
        sensor reads zero; on a slave node it reads the master's rigid motion; on a DOF
        without mass it reads the statically condensed motion.
        """
        self._new_signal(self._outputs, name, "output")
        self._node(node)
        if kind not in OUTPUT_KINDS:
            raise ModelError(f"output kind must be one of {OUTPUT_KINDS}; got {kind!r}.")
        self._outputs[name] = _Signal(name, [(node, direction_vector(direction))], kind, tags=_tags(tags))
        self._cache = None
        return self

    def add_relative_output(
        self, name: str, n1: str, n2: str, direction, kind: str = "displacement", tags: Iterable[str] = ()
    ) -> Frame:
        """A sensor reading the motion of ``n2`` relative to ``n1`` along ``direction``."""
        self._new_signal(self._outputs, name, "output")
        self._node(n1)
        self._node(n2)
        if kind not in OUTPUT_KINDS:
            raise ModelError(f"output kind must be one of {OUTPUT_KINDS}; got {kind!r}.")
        v = direction_vector(direction)
        self._outputs[name] = _Signal(name, [(n2, v), (n1, -v)], kind, tags=_tags(tags))
        self._cache = None
        return self

    def add_strain_output(
        self,
        name: str,
        group_or_element: str,
        *,
        kind: str = "bending_z",
        position: float = 0.5,
        fiber: float = 1.0,
        tags: Iterable[str] = (),
    ) -> Frame:
        """A strain gauge on a member (output kind "displacement", in m/m).

        Parameters
        ----------
        name : str
            Output name.
        group_or_element : str
            An element name (``"strut[0]"``) or a group; for a group, ``position`` runs along
            its elements in order of creation (a member subdivided by one ``add_beam``).
        kind : {"axial", "bending_y", "bending_z"}
            Axial strain ``du/dx``, or the bending strain at the fiber at local ``+z``
            (``"bending_y"``, bending about local y: ``-fiber * w''``) or at local ``+y``
            (``"bending_z"``: ``-fiber * v''``).
        position : float
            Fraction in [0, 1] along the element or group.
        fiber : float
            Distance (m) of the gauge from the neutral axis (the outer radius).
        """
        self._new_signal(self._outputs, name, "output")
        if kind not in _STRAIN_KINDS:
            raise ModelError(f"strain kind must be one of {_STRAIN_KINDS}; got {kind!r}.")
        pos = _finite("position", position)
        if not 0.0 <= pos <= 1.0:
            raise ModelError(f"position must lie in [0, 1] along the member; got {pos}.")
        fib = _finite("fiber", fiber, positive=True)
        if group_or_element in self._elements:
            elems = [group_or_element]
        elif group_or_element in self.element_groups():
            elems = list(self.element_names(group_or_element))
        else:
            raise ModelError(
                f"unknown element or group {group_or_element!r}; groups: {list(self.element_groups())}."
            )
        if kind != "axial" and any(self._elements[e].kind == "rod" for e in elems):
            raise ModelError(f"strain output {name!r}: rods carry no bending; use kind='axial'.")
        self._outputs[name] = _Signal(
            name, [], "displacement", strain=(tuple(elems), pos, kind, fib), tags=_tags(tags)
        )
        self._cache = None
        return self

    @property
    def inputs(self) -> tuple[str, ...]:
        return tuple(self._inputs)

    @property
    def outputs(self) -> tuple[str, ...]:
        return tuple(self._outputs)

    # ------------------------------------------------------------------ Structure contract
    def scale_group_stiffness(self, group: str, factor: float) -> Frame:
        """Multiply the elastic stiffness (E and G) of element group ``group`` by ``factor``."""
        if group not in self.element_groups():
            raise ModelError(f"unknown element group {group!r}; groups: {list(self.element_groups())}.")
        f = _finite("stiffness factor", factor, positive=True)
        self._group_scale[group] = self._group_scale.get(group, 1.0) * f
        self._cache = None
        return self

    def add_group_tension(self, group: str, tension: float) -> Frame:
        """Add an axial tension (N, negative = compression) to every element of ``group``.

        It enters only the geometric stiffness (taut wires fixed along a member stiffen its
        bending; Caltech truss), with or without gravity.
        """
        if group not in self.element_groups():
            raise ModelError(f"unknown element group {group!r}; groups: {list(self.element_groups())}.")
        t = _finite("tension", tension)
        self._group_tension[group] = self._group_tension.get(group, 0.0) + t
        self._cache = None
        return self

    def set_gravity(self, enabled: bool) -> Frame:
        """Switch the gravity preload on or off (on needs a non-zero ``gravity``)."""
        self._gravity_on = flag(enabled, "enabled", ModelError) and self._g > 0
        self._cache = None
        return self

    @property
    def gravity_enabled(self) -> bool:
        return self._gravity_on

    def without(self, *tags) -> Frame:
        """A copy without every component tagged with one of ``tags``.

        Elements, masses, springs, dashpots, links, supports, signals and nodes with a tag
        are dropped, then nodes left unconnected (with their supports). The tag
        ``"gravity"`` switches the gravity preload off. Accepts ``without("a", "b")`` or
        ``without({"a", "b"})``.
        """
        if len(tags) == 1 and not isinstance(tags[0], str):
            tags = tuple(tags[0])
        drop = frozenset(str(t) for t in tags)
        new = copy.copy(self)  # components are frozen: share them, copy the containers
        new._cache = None
        new._group_count = dict(self._group_count)
        new._modal_damping_bands = self.modal_damping_bands()
        if "gravity" in drop:
            new._gravity_on = False

        def hit(obj) -> bool:
            return bool(drop.intersection(obj.tags))

        gone = {n for n, nd in new._nodes.items() if hit(nd)}
        new._elements = {k: e for k, e in new._elements.items() if not (hit(e) or {e.n1, e.n2} & gone)}
        new._masses = [m for m in new._masses if not (hit(m) or m.node in gone)]
        new._springs = [s for s in new._springs if not (hit(s) or {s.node, s.node2} & gone)]
        new._links = [lk for lk in new._links if not (hit(lk) or {lk.master, lk.slave} & gone)]
        used = {n for e in new._elements.values() for n in (e.n1, e.n2)}
        used |= (
            {m.node for m in new._masses} | {lk.master for lk in new._links} | {lk.slave for lk in new._links}
        )
        used |= {s.node for s in new._springs} | {s.node2 for s in new._springs if s.node2 is not None}
        new._nodes = {k: nd for k, nd in new._nodes.items() if k in used}
        new._fixes = [f for f in new._fixes if not hit(f) and f.node in new._nodes]
        new._inputs = {k: s for k, s in new._inputs.items() if not hit(s)}
        new._outputs = {k: s for k, s in new._outputs.items() if not hit(s)}
        groups = set(new.element_groups())
        new._group_scale = {g: v for g, v in new._group_scale.items() if g in groups}
        new._group_tension = {g: v for g, v in new._group_tension.items() if g in groups}
        return new

    def tags(self) -> tuple[str, ...]:
        """Tags of the components :meth:`without` can remove (``"gravity"`` when a preload is on)."""
        parts = [*self._nodes.values(), *self._elements.values(), *self._masses, *self._springs,
                 *self._links, *self._fixes, *self._inputs.values(), *self._outputs.values()]
        found = {t for part in parts for t in getattr(part, "tags", ())}
        if self._g > 0:
            found.add("gravity")
        return tuple(sorted(found))

    # ------------------------------------------------------------------ test-setup and joints
    def _signal(self, side: str, name: str) -> _Signal:
        table = self._outputs if side == "output" else self._inputs
        if name not in table:
            raise ModelError(f"unknown {side} {name!r}; the frame has {side}s {list(table)}.")
        return table[name]

    def _neighbours(self, node: str) -> list[str]:
        """Nodes sharing an element or a rigid link with ``node``, in order of creation; a node
        fixed in every translation is left out (a sensor there reads nothing)."""
        near = [e.n2 if e.n1 == node else e.n1 for e in self._elements.values() if node in (e.n1, e.n2)]
        near += [lk.slave if lk.master == node else lk.master for lk in self._links
                 if node in (lk.master, lk.slave)]
        held = {f.node for f in self._fixes if {0, 1, 2} <= set(f.dofs)}
        return [n for n in dict.fromkeys(near) if n != node and n not in held]

    def signal_moves(self, side: str, name: str) -> list[tuple[str, str | None]]:
        """Where a point sensor or force could really be: the same direction at each neighbouring
        node (:meth:`_neighbours`), and the global axes ``x``, ``y``, ``z`` at its own node that are
        not (nearly) its direction. Signals on several nodes, strain gauges and torques: none."""
        sig = self._signal(side, name)
        if sig.strain is not None or len(sig.terms) != 1 or sig.kind == "torque":
            return []
        node, vec = sig.terms[0]
        if np.linalg.norm(vec[3:]) > 0:
            return []
        moves: list[tuple[str, str | None]] = [(n, None) for n in self._neighbours(node)]
        d = vec[:3] / np.linalg.norm(vec[:3])
        moves += [(node, ax) for k, ax in enumerate("xyz") if abs(d[k]) < 0.9]
        return moves

    def move_signal(self, side: str, name: str, location: str, direction: str | None, weight: float) -> Frame:
        """Point sensor or force ``name`` at node ``location`` along ``direction`` (None: its own):
        the pointing becomes ``(1 - weight) old + weight new``."""
        sig = self._signal(side, name)
        self._node(location)
        if len(sig.terms) != 1:
            raise ModelError(f"{side} {name!r} acts on {len(sig.terms)} nodes; only a point signal can move.")
        node, vec = sig.terms[0]
        new_vec = vec if direction is None else direction_vector(direction)
        w = _finite("weight", weight)
        terms = [(node, (1.0 - w) * vec), (location, w * new_vec)] if w < 1.0 else [(location, new_vec)]
        table = dict(self._outputs if side == "output" else self._inputs)
        table[name] = _Signal(name, terms, sig.kind, sig.strain, sig.tags)
        if side == "output":
            self._outputs = table
        else:
            self._inputs = table
        self._cache = None
        return self

    def joints(self) -> list[tuple[str, str]]:
        """Beam joints as ``(node, group)``: each node where beams of two or more element groups meet,
        with every group there but the first (by creation): the member whose connection to the
        others may be semi-rigid (:meth:`add_joint_flexibility`)."""
        at: dict[str, list[str]] = {}
        for e in self._elements.values():
            if e.kind != "beam":
                continue
            for n in (e.n1, e.n2):
                groups = at.setdefault(n, [])
                if e.group not in groups:
                    groups.append(e.group)
        return [(n, g) for n, groups in at.items() if len(groups) > 1 for g in groups[1:]]

    def joint_stiffness(self, node: str, group: str) -> float:
        """``4 E I / L`` (N m/rad) of the stiffest beam of ``group`` at ``node``: the rotational
        stiffness of the member's end (``I`` the larger second moment), the scale a joint's spring is
        compared with."""
        k = 0.0
        for e in self._elements.values():
            if e.group == group and e.kind == "beam" and node in (e.n1, e.n2):
                L = float(np.linalg.norm(self._nodes[e.n2].xyz - self._nodes[e.n1].xyz))
                k = max(k, 4.0 * e.E * self._group_scale.get(group, 1.0) * max(e.Iy, e.Iz) / L)
        if k == 0.0:
            raise ModelError(f"no beam of group {group!r} ends at node {node!r}; joints: {self.joints()}.")
        return k

    def add_joint_flexibility(self, node: str, group: str, compliance: float) -> Frame:
        """Make the connection of ``group``'s beams at ``node`` semi-rigid: a rotational spring of
        ``1 / compliance`` (N m/rad) about each axis between them and the rest of the joint.

        The group's beam ends at ``node`` move to a new node at the same place (``"node~group"``),
        tied to ``node`` in translation by springs far stiffer than the members (10^5 x the largest
        axial stiffness ``E A / L`` at the joint) and in rotation by the joint's springs. Compliance
        0 leaves the frame unchanged (a rigid joint); a large one approaches a pin (the
        semi-rigid connections of steel frames, e.g. Chen & Lui, *Stability Design of Steel
        Frames*, ch. 5).
        """
        c = _finite("joint compliance (rad/(N m))", compliance, nonneg=True)
        if c == 0.0:
            return self
        if (node, group) not in self.joints():
            raise ModelError(
                f"node {node!r} is not a joint of group {group!r} with other beams; the joints are "
                f"{self.joints()}."
            )
        twin = f"{node}~{group}"
        if twin in self._nodes:
            raise ModelError(f"the joint of {group!r} at {node!r} is already flexible.")
        nodes = dict(self._nodes)
        nodes[twin] = _Node(twin, self._nodes[node].xyz, self._nodes[node].tags)
        k_axial = 0.0
        elements = {}
        for name, e in self._elements.items():
            if node in (e.n1, e.n2):
                L = float(np.linalg.norm(self._nodes[e.n2].xyz - self._nodes[e.n1].xyz))
                k_axial = max(k_axial, e.E * e.A / L)
            if e.group == group and e.kind == "beam" and node in (e.n1, e.n2):
                e = replace(e, n1=twin if e.n1 == node else e.n1, n2=twin if e.n2 == node else e.n2)
            elements[name] = e
        self._nodes, self._elements, self._springs = nodes, elements, list(self._springs)
        for ax in ("x", "y", "z"):
            self._add_spring("spring", node, 1e5 * k_axial, ax, twin, ("joint",))
        for ax in ("rx", "ry", "rz"):
            self._add_spring("spring", node, 1.0 / c, ax, twin, ("joint",))
        return self

    # ------------------------------------------------------------------ assembly
    def matrices(self, *, sparse: bool | None = None) -> StructuralMatrices:
        """Assemble mass, stiffness (elastic + geometric) and dashpot damping of the free DOFs.

        Parameters
        ----------
        sparse : bool, optional
            Return ``scipy.sparse.csr_matrix`` (True) or dense ``ndarray`` (False). By default
            dense up to :data:`~robustctl.physical.eigen.SPARSE_THRESHOLD` (600) DOFs, where
            :func:`solve_modes` solves densely anyway, and sparse above.

        Returns
        -------
        StructuralMatrices
            ``dof_labels`` like ``"node3 uz"``; inputs in N or N m, outputs in m, rad (or
            their rates), strain outputs in m/m.
        """
        sm = self._assembly().matrices
        use_sparse = sparse if sparse is not None else sm.n_dof > SPARSE_THRESHOLD
        conv = (
            (lambda a: sp.csr_matrix(a)) if use_sparse else (lambda a: a.toarray() if sp.issparse(a) else a)
        )
        return StructuralMatrices(
            mass=conv(sm.mass),
            stiffness=conv(sm.stiffness),
            damping=conv(sm.damping),
            input_matrix=sm.input_matrix.copy(),
            output_matrix=sm.output_matrix.copy(),
            output_kinds=sm.output_kinds,
            inputs=sm.inputs,
            outputs=sm.outputs,
            dof_labels=sm.dof_labels,
            modal_damping_bands=self.modal_damping_bands(),
        )

    def modes(
        self,
        n_modes: int | None = None,
        band_hz: tuple[float, float] | None = None,
        sparse: bool | None = None,
    ) -> tuple[np.ndarray, np.ndarray]:
        """Natural frequencies and mass-normalised mode shapes (via :func:`solve_modes`).

        Parameters
        ----------
        n_modes : int, optional
            Number of lowest modes (all when omitted).
        band_hz : (float, float), optional
            Keep the modes in this band, Hz.
        sparse : bool, optional
            Force the sparse shift-invert (True) or dense (False) eigensolver.

        Returns
        -------
        f_hz : ndarray
            Natural frequencies in Hz, ascending (0 for rigid-body modes).
        phi : ndarray, shape (n_dof, n)
            Mode shapes over the free DOFs of :meth:`matrices` (``dof_labels``),
            ``phi.T M phi = I``.
        """
        sm = self.matrices()  # dense up to SPARSE_THRESHOLD DOFs, as solve_modes prefers
        w, phi = limit_blas(solve_modes)(
            sm.mass, sm.stiffness, n_modes=n_modes, band_hz=band_hz, sparse=sparse
        )
        return w / (2 * np.pi), phi

    def preload(self) -> PreloadResult | None:
        """The gravity preload iteration result (None with gravity off)."""
        return self._assembly().preload

    def axial_forces(self) -> dict[str, float]:
        """Axial force (N, tension positive) of every element (gravity plus added tension), and
        of every rigid link with an offset (keys ``"master->slave"``; from gravity only)."""
        asm = self._assembly()
        return dict(zip(asm.element_names, asm.axial.tolist()))

    def static_deflection(self) -> dict[str, np.ndarray]:
        """Gravity sag per node: ``[ux uy uz rx ry rz]`` in m and rad (zeros with gravity off)."""
        asm = self._assembly()
        n = len(asm.node_names)
        u = np.zeros(6 * n) if asm.preload is None else asm.T_red @ asm.preload.displacement
        return {name: u[6 * i : 6 * i + 6].copy() for i, name in enumerate(asm.node_names)}

    def _assembly(self) -> _Assembly:
        if self._cache is None:
            self._cache = _assemble(self)
        return self._cache

    def __repr__(self) -> str:
        return (
            f"Frame({self.name!r}: {len(self._nodes)} nodes, {len(self._elements)} elements, "
            f"{len(self._masses)} masses, {len(self._springs)} springs/dashpots, "
            f"gravity {'on' if self._gravity_on else 'off'})"
        )


# ---------------------------------------------------------------------- assembly kernels
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


def _element_stacks(frame: Frame, index: dict[str, int], X: np.ndarray) -> _ElementStacks:
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


def _point_triplets(frame: Frame, index: dict[str, int]) -> _Trip:
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


def _link_roots(frame: Frame) -> dict[str, str]:
    """Each rigid-link slave's ultimate master (chains of links resolved)."""
    master_of = {lk.slave: lk.master for lk in frame._links}
    root = {}
    for s in master_of:
        m, seen = master_of[s], {s}
        while m in master_of:
            if m in seen:
                raise ModelError(
                    f"rigid links form a loop through node {m!r}; a chain of links must end at a master."
                )
            seen.add(m)
            m = master_of[m]
        root[s] = m
    return root


def _link_pairs(frame: Frame, index: dict[str, int], X: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(root master, slave) node indices of the rigid links with an offset."""
    pairs = [(index[m], index[s]) for s, m in _link_roots(frame).items()]
    pairs = [(m, s) for m, s in pairs if np.linalg.norm(X[s] - X[m]) > 0]
    arr = np.array(pairs, dtype=int).reshape(-1, 2)
    return arr[:, 0], arr[:, 1]


def _constraint_transform(
    frame: Frame, index: dict[str, int], X: np.ndarray
) -> tuple[sp.csr_matrix, np.ndarray]:
    """``q_full = T q``: rigid-link slaves follow their (root) master; fixed DOFs dropped.

    Returns ``T`` and, per column, the full DOF it stands for."""
    n_full = 6 * len(index)
    root = _link_roots(frame)
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
            for j in range(6):
                if link[i, j] != 0 and col[mi + j] >= 0:
                    rows.append(si + i)
                    cols.append(col[mi + j])
                    vals.append(link[i, j])
    T = sp.csr_matrix((vals, (rows, cols)), shape=(n_full, int(indep.sum())))
    return T, np.flatnonzero(indep)


def _signal_matrix(
    frame: Frame, signals: dict[str, _Signal], index, stacks: _ElementStacks, n_full: int
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


def _strain_row(frame: Frame, sig: _Signal, elem_pos, stacks: _ElementStacks, n_full: int) -> np.ndarray:
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


def _geometry_key(frame: Frame) -> tuple[tuple, tuple]:
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


def _geometry(frame: Frame) -> _Geometry:
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
    red = _Trip.cat([head, points.reduce(geo.T, new_index), tail])
    pkey = red.rows.tobytes() + b"|" + red.cols.tobytes()
    with _GEOMETRY_LOCK:
        pattern = patterns.get(pkey)
    if pattern is None:
        pattern = _Pattern(red.rows, red.cols, int(keep.sum()))
        with _GEOMETRY_LOCK:
            pattern = patterns.setdefault(pkey, pattern)
            while len(patterns) > 32:
                patterns.pop(next(iter(patterns)))
    return red, pattern


@limit_blas
def _assemble(frame: Frame) -> _Assembly:
    if not frame._nodes:
        raise ModelError("the frame has no nodes; add nodes and elements first.")
    geo = _geometry(frame)
    names, X, st, links = geo.names, geo.X, geo.st, geo.links
    n_full = 6 * len(names)
    points = _point_triplets(frame, geo.index)
    full = _full_triplets(geo, points)
    T, dof_of_col = geo.T, geo.dof_of_col
    # DOFs with neither mass nor stiffness (nor damping, nor geometric stiffness) are dropped
    weight_full = np.bincount(full.rows, weights=np.abs(full.vals).sum(axis=1), minlength=n_full)
    keep = abs(T).T @ weight_full > 0
    B1, Cy1 = T.T @ geo.B_full, np.asarray((T.T @ geo.C_full.T).T)
    _check_signals_on_empty(frame, keep, dof_of_col, B1, Cy1, names)
    new_index = np.append(-np.ones(T.shape[1], dtype=int), -1)
    new_index[np.flatnonzero(keep)] = np.arange(keep.sum())
    red, pattern = _reduced(geo, points, keep, new_index)
    T, dof_of_col, B1, Cy1 = T[:, keep].tocsr(), dof_of_col[keep], B1[keep], Cy1[:, keep]
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
    labels = [f"{names[d // 6]} {_DOF_NAMES[d % 6]}" for d in dof_of_col]
    mats = _condense(Kt, M1, C1, B1, Cy1, labels, frame)
    link_names = tuple(f"{names[m]}->{names[k]}" for m, k in zip(*links))
    return _Assembly(mats, names, tuple(frame._elements) + link_names, T, preload, axial)


def _preload_key(frame: Frame, geo: _Geometry, points: _Trip, keep: np.ndarray, tension: np.ndarray) -> tuple:
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
    full_pattern = _Pattern(full.rows, full.cols, n_full) if masters.size else None
    e_link = (X[slaves] - X[masters]) / np.linalg.norm(X[slaves] - X[masters], axis=1, keepdims=True)

    def axial_force(u: np.ndarray, N_used: np.ndarray | None) -> np.ndarray:
        uf = T @ u
        du = uf.reshape(-1, 6)[st.n2, :3] - uf.reshape(-1, 6)[st.n1, :3]
        N = st.EA_L * np.sum(du * st.axis, axis=1)
        if full_pattern is None:
            return N
        n_elem = np.zeros(ne + masters.size)  # the elements' forces, not the links' own
        if N_used is not None:
            n_elem[:ne] = N_used[:ne]
        K = full_pattern.matrix(full.vals[:, _K] + full.vals[:, _G] * n_elem[full.tag])
        link_force = (K @ uf - f_full).reshape(-1, 6)[slaves, :3]  # what the link must apply
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


def _link_geometric_triplets(X: np.ndarray, links, offset: int) -> _Trip:
    """Unit geometric stiffness of each rigid link as a rod from master to slave."""
    masters, slaves = links
    if masters.size == 0:
        return _Trip.cat([])
    ones = np.ones(masters.size)
    _, _, G = el.rod_matrices(X[masters], X[slaves], ones, ones, ones)
    dofs = np.concatenate([6 * masters[:, None] + np.arange(3), 6 * slaves[:, None] + np.arange(3)], axis=1)
    return _Trip.from_blocks(dofs, {_G: G}, offset + np.arange(masters.size))


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
