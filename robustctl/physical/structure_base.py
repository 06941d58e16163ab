"""The contract between structural models and the rest of robustctl.

A :class:`Structure` is something that can be assembled into mass, stiffness and
concentrated-damping matrices with actuator and sensor pointing vectors
(:class:`StructuralMatrices`). Two kinds implement it: the built-in frame FEM
(:class:`robustctl.physical.fem.Frame`, locations are nodes) and a user's own matrices
(:class:`robustctl.physical.matrices.MatrixStructure`, locations are DOFs).

Effects (``robustctl.effects``) change a structure only through the methods below, so
the same "added mass", "suspension spring" or "stiffer element group" works on both.
Every build of a :class:`~robustctl.physical.model.PhysicalModel` creates a fresh
structure, so these methods may modify ``self`` in place; they return ``self``.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Callable, Iterable
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from ..errors import ModelError

__all__ = ["StructuralMatrices", "Structure", "OUTPUT_KINDS", "STINGER_LENGTH", "stinger_stiffness"]

#: Kinds of structural outputs: the sensor reads the DOF vector's displacement, its rate,
#: or its acceleration (an accelerometer needs the feedthrough term of MACE eq. 4).
OUTPUT_KINDS = ("displacement", "velocity", "acceleration")


@dataclass(frozen=True, eq=False)
class StructuralMatrices:
    """Second-order model ``M q'' + C q' + K q = B u``, ``y = Cy_kind q^(kind)``.

    Attributes
    ----------
    mass, stiffness, damping : ndarray or scipy.sparse matrix, shape (n_dof, n_dof)
        Mass (kg, kg m^2), stiffness including geometric (stress) stiffness (N/m, N m/rad)
        and concentrated (non-modal) damping (N s/m) of the free DOFs.
    input_matrix : ndarray, shape (n_dof, n_in)
        Generalised force per unit input (the pointing matrix b of MACE eq. 3).
    output_matrix : ndarray, shape (n_out, n_dof)
        Output pointing rows (c_d or c_r of MACE eq. 4).
    output_kinds : tuple of str
        One of :data:`OUTPUT_KINDS` per output.
    inputs, outputs : tuple of str
        Signal names.
    dof_labels : tuple of str
        A label per free DOF (``"node 3 ux"``, ``"dof 6"``).
    modal_damping_bands : tuple of (lo_hz, hi_hz, factor) or (first, last, factor, "mode")
        Multiply the modal damping ratio of modes in ``[lo_hz, hi_hz]`` by ``factor``, or of
        the elastic modes ``first`` to ``last`` (1-based, by ascending frequency among the
        kept modes; rigid-body modes not counted) when the entry ends in ``"mode"`` (set by
        the "modal damping change of a mode group" effect).
    """

    mass: object
    stiffness: object
    damping: object
    input_matrix: np.ndarray
    output_matrix: np.ndarray
    output_kinds: tuple[str, ...]
    inputs: tuple[str, ...]
    outputs: tuple[str, ...]
    dof_labels: tuple[str, ...]
    modal_damping_bands: tuple[tuple, ...] = ()

    @property
    def n_dof(self) -> int:
        return self.input_matrix.shape[0]

    def copy(self, convert: Callable[[Any], Any] | None = None, **changes: Any) -> StructuralMatrices:
        """An independent copy: the pointing matrices copied, mass, stiffness and damping (None
        stays None) through ``convert`` (default: their own ``copy``), then ``changes`` set.

        Parameters
        ----------
        convert : callable, optional
            ``matrix -> matrix`` (e.g. to ``scipy.sparse.csr_matrix`` or to a dense array).
        **changes
            Attributes to set instead (``modal_damping_bands=...``).

        Returns
        -------
        StructuralMatrices
        """
        conv = convert or (lambda a: a.copy())
        square = {k: getattr(self, k) for k in ("mass", "stiffness", "damping")}
        square = {k: None if a is None else conv(a) for k, a in square.items()}
        pointing = {"input_matrix": self.input_matrix.copy(), "output_matrix": self.output_matrix.copy()}
        return replace(self, **square, **pointing, **changes)


#: Length (m) of the drive rod (stinger) between shaker and force gauge that the stinger candidates
#: assume: 50 to 150 mm is the usual range (Ewins, *Modal Testing*, 2000, sec. 3.6).
STINGER_LENGTH = 0.1
#: ``G J / (E I)`` of a round rod (``J = 2 I``) of steel or aluminium (Poisson's ratio 0.3):
#: ``2 / (2 (1 + 0.3))``.
_ROD_TORSION = 1.0 / 1.3


def stinger_stiffness(direction: Any, lateral_stiffness: float, length: float = STINGER_LENGTH) -> np.ndarray:
    r"""The 6 x 6 stiffness (over ``[ux uy uz rx ry rz]`` of the drive point, global axes) that a drive rod
    (stinger) clamped in the shaker's armature adds where it meets the structure, without its axial
    stiffness.

    With the force gauge at the structure (the practice Ewins, *Modal Testing: Theory, Practice and
    Application*, 2000, sec. 3.6 recommends) the gauge measures the rod's axial force, so the rod's
    axial stiffness and the shaker change the force that is measured, not the measured FRF; what the
    gauge does not measure is the rod's lateral force and its moments, which restrain the drive point
    as a grounded stiffness (the armature taken as held laterally and in rotation). For a round rod
    of length ``L`` and bending stiffness ``E I`` clamped at both ends, each lateral axis ``a``
    (normal to the drive axis ``d``) gives the end stiffness of a beam element on ``(u_a, theta_n)``,
    ``n = d x a`` (the rod running along ``+d`` from the armature to the structure),

    .. math::

        \frac{E I}{L^3} \begin{bmatrix} 12 & -6 L \\ -6 L & 4 L^2 \end{bmatrix}
        = k \begin{bmatrix} 1 & -L/2 \\ -L/2 & L^2/3 \end{bmatrix}, \quad k = 12 E I / L^3,

    and the rod's torsion ``G J / L = k L^2 / (12 \cdot 1.3)`` acts about ``d`` (Przemieniecki,
    *Theory of Matrix Structural Analysis*, 1968, sec. 5.4).

    Parameters
    ----------
    direction : 3-vector
        The drive axis ``d`` (the force's direction), normalised here.
    lateral_stiffness : float
        ``k = 12 E I / L^3`` in N/m: the rod's lateral stiffness with both ends held in rotation.
    length : float
        ``L`` in m.

    Returns
    -------
    ndarray, shape (6, 6)
        N/m, N/rad and N m/rad blocks.
    """
    d = np.asarray(direction, dtype=float).reshape(-1)
    k, L = float(lateral_stiffness), float(length)
    if d.size != 3 or not np.all(np.isfinite(d)) or np.linalg.norm(d) == 0:
        raise ModelError(f"a stinger's drive axis is a non-zero 3-vector; got {direction!r}.")
    if not (np.isfinite(k) and np.isfinite(L) and L > 0):
        raise ModelError(f"a stinger needs a finite lateral stiffness (N/m) and a length > 0 (m); got {k!r}, "
                         f"{L!r}.")
    d = d / np.linalg.norm(d)
    out = np.zeros((6, 6))
    for a in np.linalg.svd(d[None, :])[2][1:]:  # two unit axes normal to d
        n = np.cross(d, a)
        w = np.concatenate([a, -0.5 * L * n])
        out += k * np.outer(w, w)
        out[3:, 3:] += k * L * L / 12.0 * np.outer(n, n)
    out[3:, 3:] += k * L * L / 12.0 * _ROD_TORSION * np.outer(d, d)
    return out


_NO_GEOMETRY = (
    "this {} has no node coordinates to draw; a Frame has them, and rc.structural_model takes "
    "nodes={{id: (x, y, z)}} with DOFs labelled 'node:direction' (dof_labels=['1:X', ...])."
)


class Structure(ABC):
    """A structural model that can be assembled and changed by physical effects."""

    # ------------------------------------------------------------------ assembly
    @abstractmethod
    def matrices(self) -> StructuralMatrices:
        """Assemble (including any gravity preload iteration) into matrices."""

    @abstractmethod
    def without(self, tags: Iterable[str]) -> Structure:
        """Remove every component carrying one of ``tags`` (``"suspension"``, ``"gravity"``)."""

    # ------------------------------------------------------------------ drawing
    def geometry(self) -> Any:
        """Nodes, lines and sensor placement (:class:`~robustctl.frd_io.geometry.Geometry`)."""
        raise ModelError(_NO_GEOMETRY.format(type(self).__name__))

    def mode_shapes(self, n_modes: int | None = None, band_hz: Any = None) -> Any:
        """Every node's translation per undamped mode (:class:`~robustctl.frd_io.geometry.ModeShapes`)."""
        raise ModelError(_NO_GEOMETRY.format(type(self).__name__))

    # ------------------------------------------------------------------ where effects go
    @abstractmethod
    def locations(self) -> tuple[str, ...]:
        """Names of the points where point effects may act (nodes or DOFs)."""

    @abstractmethod
    def element_groups(self) -> tuple[str, ...]:
        """Names of element groups whose stiffness an effect may change."""

    def mass_locations(self) -> tuple[str, ...]:
        """Locations carrying a lumped mass of their own (equipment, payload mounts): where an attached
        resonator is looked for besides the sensors and forces. Every location by default (a user's
        matrices do not say which of their masses are lumped)."""
        return tuple(self.locations())

    def tension_groups(self) -> tuple[str, ...]:
        """Element groups that can carry a tension (:meth:`add_group_tension`): every group of
        a frame FEM; a matrix structure only those it was given geometric stiffness for."""
        return self.element_groups()

    @abstractmethod
    def add_mass(self, location: str, mass: float) -> Structure:
        """Add a point mass (kg) at ``location`` (translational DOFs only)."""

    @abstractmethod
    def add_spring(self, location: str, stiffness: float, direction: str | None = None) -> Structure:
        """Add a grounded spring (N/m) at ``location`` along ``direction`` (``"x"``, ``"y"``,
        ``"z"``; ``None`` for a scalar DOF)."""

    @abstractmethod
    def add_dashpot(self, location: str, damping: float, direction: str | None = None) -> Structure:
        """Add a grounded dashpot (N s/m) at ``location`` along ``direction``."""

    @abstractmethod
    def scale_group_stiffness(self, group: str, factor: float) -> Structure:
        """Multiply the elastic stiffness of element group ``group`` by ``factor``."""

    @abstractmethod
    def add_group_tension(self, group: str, tension: float) -> Structure:
        """Add an axial tension (N) along the elements of ``group`` (taut wires or cables
        fixed to members): its geometric stiffness stiffens their bending."""

    def scale_modal_damping(self, lo_hz: float, hi_hz: float, factor: float) -> Structure:
        """Multiply the modal damping ratio of the modes in ``[lo_hz, hi_hz]`` by ``factor``.

        Implementations pass :meth:`modal_damping_bands` on in their :meth:`matrices`.
        """
        bands = list(getattr(self, "_modal_damping_bands", ()))
        bands.append((float(lo_hz), float(hi_hz), float(factor)))
        self._modal_damping_bands = tuple(bands)
        return self

    def scale_mode_damping(self, first: int, last: int, factor: float) -> Structure:
        """Multiply the modal damping ratio of the elastic modes ``first`` to ``last`` by ``factor``.

        Modes are counted from 1 by ascending natural frequency among the modes the
        dynamics keep, rigid-body (0 Hz) modes left out, so the change follows its modes
        wherever the parameters move them (a band in Hz, :meth:`scale_modal_damping`, loses
        them once they leave it).
        """
        bands = list(getattr(self, "_modal_damping_bands", ()))
        bands.append((int(first), int(last), float(factor), "mode"))
        self._modal_damping_bands = tuple(bands)
        return self

    def modal_damping_bands(self) -> tuple[tuple, ...]:
        """The damping scalings set by :meth:`scale_modal_damping` and :meth:`scale_mode_damping`."""
        return tuple(getattr(self, "_modal_damping_bands", ()))

    def set_gravity(self, enabled: bool) -> Structure:
        """Switch gravity preloading on or off (structures without gravity ignore this)."""
        return self

    def add_resonator(self, location: str, mass: float, stiffness: float,
                      direction: str | None = None) -> Structure:
        """Attach a spring-mass (a payload on a mount, fuel slosh, a cable): a new DOF of ``mass``
        (kg) joined to ``location`` along ``direction`` by a spring of ``stiffness`` (N/m). It adds
        a mode near ``sqrt(stiffness / mass)``."""
        raise ModelError(f"{type(self).__name__} cannot carry an attached resonator.")

    def add_stinger(self, input_name: str, lateral_stiffness: float,
                    length: float = STINGER_LENGTH) -> Structure:
        """Restrain the drive point of force input ``input_name`` as its stinger does
        (:func:`stinger_stiffness`: lateral stiffness ``lateral_stiffness`` in N/m, rod ``length`` in m;
        the axial stiffness is behind the force gauge and left out)."""
        raise ModelError(f"{type(self).__name__} cannot carry a stinger.")

    def add_coupling(self, location: str, partner: str, stiffness: float) -> Structure:
        """Add a spring of ``stiffness`` (N/m or N m/rad; negative softens) between the DOFs
        ``location`` and ``partner`` (a joint's two sides in a user's matrices)."""
        raise ModelError(f"{type(self).__name__} cannot add a spring between two DOFs.")

    # ------------------------------------------------------------------ where signals are
    def signal_location(self, side: str, name: str) -> str | None:
        """The location (node or DOF) a point sensor (``side="output"``) or force (``"input"``) is
        mounted at, where its own hardware's mass sits; None for a signal spread over several
        locations (a strain gauge, a distributed pointing). Default: None."""
        return None

    def signal_moves(self, side: str, name: str) -> list[tuple[str, str | None]]:
        """Where a sensor (``side="output"``) or actuator (``"input"``) could really be, as
        ``(location, direction)`` pairs for :meth:`move_signal`: its neighbouring nodes or DOFs
        and (where directions exist) its other axes. Default: none."""
        return []

    def move_signal(
        self, side: str, name: str, location: str, direction: str | None, weight: float
    ) -> Structure:
        """Point signal ``name`` at ``location`` (along ``direction``; None: as it was) with
        ``weight`` in [0, 1]: its pointing becomes ``(1 - weight) old + weight new``."""
        raise ModelError(f"{type(self).__name__} cannot move its {side} {name!r}.")
