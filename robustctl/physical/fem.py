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
from collections.abc import Iterable, Sequence
from dataclasses import replace
from typing import Any

import numpy as np
import scipy.sparse as sp

from ..checks import flag
from ..errors import ModelError
from ..frd_io.geometry import Geometry, ModeShapes
from ..threads import limit_blas
from . import elements as el
from .eigen import SPARSE_THRESHOLD, solve_modes
from .frame_assembly import _assemble
from .frame_cache import _GEOMETRY as _GEOMETRY  # the assembly caches, for inspection
from .frame_cache import _PRELOADS as _PRELOADS
from .frame_cache import _geometry as _geometry
from .frame_parts import (
    _STRAIN_KINDS,
    DIRECTIONS,
    _Assembly,
    _Element,
    _finite,
    _Fix,
    _Link,
    _Mass,
    _Node,
    _Signal,
    _Spring,
    _tags,
    _vector3,
    direction_vector,
)
from .gravity import PreloadResult
from .shapes import frame_geometry, frame_mode_shapes
from .structure_base import OUTPUT_KINDS, STINGER_LENGTH, StructuralMatrices, Structure, stinger_stiffness

__all__ = ["Frame", "DIRECTIONS"]

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

    def add_resonator(self, location: str, mass: float, stiffness: float, direction=None) -> Frame:
        """Attach a spring-mass at node ``location`` along ``direction`` (``"x"``, ``"y"``, ``"z"``):
        a new node ``"<location>~resonator"`` at the same place carrying ``mass`` (kg), free only
        along ``direction`` and joined to ``location`` by a spring of ``stiffness`` (N/m)."""
        self._node(location)
        axis = str(direction).strip().lower() if direction is not None else ""
        if axis not in ("x", "y", "z"):
            raise ModelError(f"a frame resonator acts along 'x', 'y' or 'z'; got direction={direction!r}.")
        twin = f"{location}~resonator"
        while twin in self._nodes:
            twin += "'"
        self.add_node(twin, self._nodes[location].xyz, ("resonator",))
        self.fix(twin, [d for d in ("x", "y", "z", "rx", "ry", "rz") if d != axis])
        self.add_mass(twin, mass)
        return self.add_spring(location, stiffness, axis, node2=twin, tags=("resonator",))

    def signal_location(self, side: str, name: str) -> str | None:
        """The node of a point sensor or force (None: a strain gauge or a signal on several nodes)."""
        sig = self._signal(side, name)
        return sig.terms[0][0] if sig.strain is None and len(sig.terms) == 1 else None

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

    def mass_locations(self) -> tuple[str, ...]:
        """Nodes carrying a point mass (:meth:`add_mass`), in order of creation."""
        return tuple(dict.fromkeys(m.node for m in self._masses))

    def supports(self) -> list[tuple[str, tuple[str, ...]]]:
        """Clamped nodes that beams hold, with the rotations their supports clamp:
        ``[(node, ("rx", "ry", "rz")), ...]`` (a support that clamps no rotation is a pin: left out)."""
        held = {n for e in self._elements.values() if e.kind == "beam" for n in (e.n1, e.n2)}
        out: dict[str, set[int]] = {}
        for f in self._fixes:
            rot = {d for d in f.dofs if d >= 3}
            if rot and f.node in held:
                out.setdefault(f.node, set()).update(rot)
        return [(n, tuple(("rx", "ry", "rz")[d - 3] for d in sorted(rot))) for n, rot in out.items()]

    def support_stiffness(self, node: str) -> float:
        """``4 E I / L`` (N m/rad) of the stiffest beam at ``node``: the rotational stiffness of the
        members' end, the scale a support's rotational spring is compared with."""
        groups = {e.group for e in self._elements.values() if e.kind == "beam" and node in (e.n1, e.n2)}
        if not groups:
            raise ModelError(f"no beam ends at node {node!r}; supports: {self.supports()}.")
        return max(self.joint_stiffness(node, g) for g in groups)

    def soften_support(self, node: str, compliance: float,
                       axes: tuple[str, ...] = ("rx", "ry", "rz")) -> Frame:
        """Make the clamp of ``node``'s rotations ``axes`` a rotational spring of ``1 / compliance``
        (N m/rad) to ground about each (a base plate, bolts, a foundation softer than a clamp): the
        rotations become DOFs of their own. Compliance 0 leaves the clamp; a large one approaches a
        pin. Rotations ``axes`` that no support clamps are left as they are."""
        c = _finite("support compliance (rad/(N m))", compliance, nonneg=True)
        axes = (axes,) if isinstance(axes, str) else tuple(axes)
        if not axes or not set(axes) <= {"rx", "ry", "rz"}:
            raise ModelError(f"support axes are among 'rx', 'ry', 'rz'; got {axes!r}.")
        clamped = dict(self.supports())
        if node not in clamped:
            raise ModelError(f"node {node!r} has no clamped rotation a beam holds; the supports are "
                             f"{self.supports()}.")
        if c == 0.0:
            return self
        released = {3 + ("rx", "ry", "rz").index(a) for a in axes if a in clamped[node]}
        fixes = []
        for f in self._fixes:
            if f.node == node:
                kept = tuple(d for d in f.dofs if d not in released)
                if kept:
                    fixes.append(_Fix(f.node, kept, f.tags))
            else:
                fixes.append(f)
        self._fixes = fixes
        self._cache = None
        for d in sorted(released):
            self._add_spring("spring", node, 1.0 / c, ("rx", "ry", "rz")[d - 3], None, ("support",))
        return self

    def _released_links(self) -> list[tuple[str, str, tuple[str, ...], str]]:
        """``(node, group, axes, twin)`` of each flexible joint (:meth:`flexible_joints`), with its twin."""
        out = []
        for lk in self._links:
            if not lk.released:
                continue
            groups = [e.group for e in self._elements.values()
                      if e.kind == "beam" and lk.slave in (e.n1, e.n2)]
            if groups:
                axes = tuple(("rx", "ry", "rz")[d - 3] for d in lk.released)
                out.append((lk.master, groups[0], axes, lk.slave))
        return out

    def flexible_joints(self) -> list[tuple[str, str, tuple[str, ...]]]:
        """Joints made flexible (:meth:`add_joint_flexibility`): ``(node, group, axes)`` with the global
        rotations each releases (``("ry",)`` for a hinge about y), in order of creation."""
        return [(n, g, ax) for n, g, ax, _ in self._released_links()]

    def add_joint_damping(self, node: str, group: str, damping: float,
                          axes: tuple[str, ...] | None = None) -> Frame:
        """A rotational dashpot of ``damping`` (N m s/rad) across a flexible joint (:meth:`flexible_joints`)
        about each rotation it releases (or about ``axes``, some of them): local, non-proportional damping
        of the joint (friction and micro-slip in a bolted or hinged connection), in parallel with the
        joint's spring. A rigid joint has no relative rotation to damp: make it flexible first."""
        c = _finite("joint damping (N m s/rad)", damping, nonneg=True)
        found = {(n, g): (ax, twin) for n, g, ax, twin in self._released_links()}
        if (node, group) not in found:
            raise ModelError(
                f"the joint of {group!r} at {node!r} releases no rotation (a rigid joint has none to damp); "
                f"the flexible joints are {self.flexible_joints()} (Frame.add_joint_flexibility makes one)."
            )
        released, twin = found[(node, group)]
        axes = released if axes is None else ((axes,) if isinstance(axes, str) else tuple(axes))
        if not axes or not set(axes) <= set(released):
            raise ModelError(f"the joint of {group!r} at {node!r} releases {released}; got axes={axes!r}.")
        if c == 0.0:
            return self
        for ax in axes:
            self._add_spring("dashpot", node, c, ax, twin, ("joint",))
        return self

    def add_stinger(self, input_name: str, lateral_stiffness: float, length: float = STINGER_LENGTH) -> Frame:
        """Restrain the drive point of the point force ``input_name`` as its stinger does: the grounded
        lateral, rotational and torsional stiffness of a drive rod clamped in the shaker
        (:func:`~robustctl.physical.structure_base.stinger_stiffness`; ``lateral_stiffness`` in N/m,
        ``length`` in m), as springs tagged ``"stinger"``."""
        sig = self._signal("input", input_name)
        if sig.kind != "force" or sig.strain is not None or len(sig.terms) != 1:
            raise ModelError(f"input {input_name!r} is not a point force; a stinger drives one node along "
                             "one axis.")
        node, vec = sig.terms[0]
        k = _finite(f"stinger lateral stiffness of {input_name!r} (N/m)", lateral_stiffness)
        if k == 0.0:
            return self
        lam, vecs = np.linalg.eigh(stinger_stiffness(vec[:3], k, _finite("stinger length (m)", length,
                                                                          positive=True)))
        for value, u in zip(lam, vecs.T):
            if abs(value) > 1e-12 * np.abs(lam).max():
                self._springs.append(_Spring(node, None, float(value), u.copy(), "spring", ("stinger",)))
        self._cache = None
        return self

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

    def add_joint_flexibility(self, node: str, group: str, compliance: float,
                              axes: tuple[str, ...] = ("rx", "ry", "rz")) -> Frame:
        """Make the connection of ``group``'s beams at ``node`` semi-rigid: a rotational spring of
        ``1 / compliance`` (N m/rad) about each axis of ``axes`` (global ``"rx"``, ``"ry"``,
        ``"rz"``; one axis: a hinge) between them and the rest of the joint; rotations about the
        other axes stay tied as the translations are.

        The group's beam ends at ``node`` move to a new node at the same place (``"node~group"``)
        that follows ``node`` exactly (a rigid link, its DOFs eliminated) in translation and in the
        rotations the joint does not release; each released rotation is a DOF of its own, joined to
        ``node``'s by the joint's spring (ties by penalty springs far stiffer than the members would
        put modes near 10^7 rad/s beside a suspension's 1 rad/s, beyond what a double precision
        eigensolver separates). Compliance 0 leaves the frame unchanged (a rigid joint); a large one
        approaches a pin (the semi-rigid connections of steel frames, e.g. Chen & Lui, *Stability
        Design of Steel Frames*, ch. 5).
        """
        c = _finite("joint compliance (rad/(N m))", compliance, nonneg=True)
        axes = (axes,) if isinstance(axes, str) else tuple(axes)
        if not axes or not set(axes) <= {"rx", "ry", "rz"}:
            raise ModelError(f"joint axes are among 'rx', 'ry', 'rz'; got {axes!r}.")
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
        elements = {}
        for name, e in self._elements.items():
            if e.group == group and e.kind == "beam" and node in (e.n1, e.n2):
                e = replace(e, n1=twin if e.n1 == node else e.n1, n2=twin if e.n2 == node else e.n2)
            elements[name] = e
        self._nodes, self._elements, self._springs = nodes, elements, list(self._springs)
        released = tuple(3 + ("rx", "ry", "rz").index(ax) for ax in ("rx", "ry", "rz") if ax in axes)
        self._links = [*self._links, _Link(node, twin, ("joint",), released)]
        self._cache = None
        for ax in ("rx", "ry", "rz"):
            if ax in axes:
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
        return sm.copy(conv, modal_damping_bands=self.modal_damping_bands())

    def modes(self, n_modes: int | None = None, **options: Any) -> tuple[np.ndarray, np.ndarray]:
        """Natural frequencies and mass-normalised mode shapes: :func:`solve_modes` of :meth:`matrices`.

        Parameters
        ----------
        n_modes : int, optional
            Number of lowest modes (all when omitted).
        **options
            ``band_hz`` (keep the modes in this band, Hz) and ``sparse`` (force the sparse
            shift-invert or the dense eigensolver) of :func:`solve_modes`.

        Returns
        -------
        f_hz : ndarray
            Natural frequencies in Hz, ascending (0 for rigid-body modes).
        phi : ndarray, shape (n_dof, n)
            Mode shapes over the free DOFs of :meth:`matrices` (``dof_labels``),
            ``phi.T M phi = I``.
        """
        sm = self.matrices()  # dense up to SPARSE_THRESHOLD DOFs, as solve_modes prefers
        w, phi = limit_blas(solve_modes)(sm.mass, sm.stiffness, n_modes=n_modes, **options)
        return w / (2 * np.pi), phi

    def geometry(self) -> Geometry:
        """Nodes (id ``k`` is the ``k``-th node added), members, links and sensors as a
        :class:`~robustctl.frd_io.geometry.Geometry` (:func:`~robustctl.physical.shapes.frame_geometry`)."""
        return frame_geometry(self)

    def mode_shapes(self, n_modes: int | None = None, band_hz: Sequence[float] | None = None) -> ModeShapes:
        """Every node's translation per undamped mode, mass-normalised, over :meth:`geometry`'s nodes
        (:func:`~robustctl.physical.shapes.frame_mode_shapes`)."""
        return frame_mode_shapes(self, n_modes, band_hz)

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
