"""Structural effects: added mass, suspension, dashpots, pendulums, element groups, gravity, damping."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from ...errors import ModelError
from .base import (
    Effect,
    ParamSpec,
    _require,
    _slug,
    _structure_info,
    article,
)


@dataclass(frozen=True)
class _StructEffect(Effect):
    domain: ClassVar[str] = "structure"
    calibration: ClassVar[str] = "shift"
    _where_word: ClassVar[str] = "node"

    def _check_location(self, model):
        info = _structure_info(model)
        _require(self.location, info["locations"], "location", self)

    def _at(self) -> str:
        word = "dof" if str(self.location).startswith("dof") else self._where_word
        loc = str(self.location)
        return loc if loc.startswith(word) else f"{word} {loc}"


@dataclass(frozen=True)
class _DirectedEffect(_StructEffect):
    direction: str | None = None

    def _suffix(self) -> str:
        d = "" if self.direction is None else "_" + _slug(self.direction)
        return "__" + _slug(self.location) + d

    def _dir_text(self) -> str:
        return "" if self.direction is None else f" along {self.direction}"


@dataclass(frozen=True)
class AddedMass(_StructEffect):
    """A point mass at a node or DOF (a sensor, cable clamp, bracket, bolt...).

    Parameters
    ----------
    location : str
        Node (frame FEM) or DOF (``"dof k"``) name.
    mass : float
        Added mass in kg (neutral 0).
    """

    mass: float = 0.0

    kind: ClassVar[str] = "added_mass"
    sweep: ClassVar[str | None] = "location"
    point_unit: ClassVar[tuple[float, float, float] | None] = (1.0, 0.0, 0.0)
    _value_fields: ClassVar[tuple[str, ...]] = ("mass",)

    @classmethod
    def candidates_at(cls, ctx, where):
        """One mass at the location."""
        return [cls(where)]

    def phrase(self) -> str:
        return f"{self.describe_value()} of {self.name}"

    def changes_preload(self, gravity_direction) -> bool:
        return True  # more weight in the suspension

    @property
    def name(self) -> str:
        return f"added mass at {self._at()}"

    @property
    def description(self) -> str:
        return (
            f"Unmodelled mass at {self._at()} (hardware, cabling, a sensor): lowers the frequencies "
            "of the modes that move that point, most where the mode shape is largest."
        )

    def _specs(self):
        return [
            ParamSpec(
                base="added_mass",
                unit="kg",
                bounds=(0.0, 1e6),
                neutral=0.0,
                default_scale=0.01,
                meaning=f"point mass added at {self._at()}",
            )
        ]

    def _stage_fn(self):
        pname, loc = self.param_names[0], self.location

        def fn(theta, struct):
            m = float(theta[pname])
            return struct if m == 0.0 else struct.add_mass(loc, m)

        return fn


@dataclass(frozen=True)
class SuspensionSpring(_DirectedEffect):
    """A grounded spring at a node (suspension device, cable, support flexibility).

    Parameters
    ----------
    location : str
    direction : str or None
        ``"x"``, ``"y"``, ``"z"`` for frame nodes; ``None`` for a scalar DOF.
    stiffness : float
        Spring stiffness in N/m (neutral 0).
    """

    stiffness: float = 0.0

    kind: ClassVar[str] = "suspension_spring"
    sweep: ClassVar[str | None] = "location"
    point_unit: ClassVar[tuple[float, float, float] | None] = (0.0, 1.0, 0.0)
    _value_fields: ClassVar[tuple[str, ...]] = ("stiffness",)
    _extra_tags: ClassVar[tuple[str, ...]] = ("suspension",)

    @classmethod
    def candidates_at(cls, ctx, where):
        """One spring per translational direction of the location."""
        return [cls(where, direction=d) for d in ctx.directions[where]]

    def changes_preload(self, gravity_direction) -> bool:
        axis = {"x": 0, "y": 1, "z": 2}.get(self.direction or "")
        return axis is not None and abs(float(gravity_direction[axis])) > 1e-9  # takes some weight

    @property
    def name(self) -> str:
        return f"suspension spring at {self._at()}{self._dir_text()}"

    @property
    def description(self) -> str:
        return (
            f"A spring from {self._at()} to ground{self._dir_text()} (suspension device, support or "
            "cable): raises the frequencies of modes moving that point, above all the "
            "low (suspension / rigid-body) ones."
        )

    def _specs(self):
        return [
            ParamSpec(
                base="suspension_spring",
                unit="N/m",
                bounds=(0.0, 1e12),
                neutral=0.0,
                default_scale=100.0,
                meaning=f"grounded spring at {self._at()}{self._dir_text()}",
            )
        ]

    def _stage_fn(self):
        pname, loc, d = self.param_names[0], self.location, self.direction

        def fn(theta, struct):
            k = float(theta[pname])
            return struct if k == 0.0 else struct.add_spring(loc, k, d)

        return fn


@dataclass(frozen=True)
class Dashpot(_DirectedEffect):
    """A grounded viscous damper at a node (a suspension device's dashpot, a joint).

    Parameters
    ----------
    location, direction : see :class:`SuspensionSpring`
    damping : float
        Damping coefficient in N s/m (neutral 0).
    """

    damping: float = 0.0

    kind: ClassVar[str] = "dashpot"
    sweep: ClassVar[str | None] = "location"
    calibration: ClassVar[str] = "damping"
    point_unit: ClassVar[tuple[float, float, float] | None] = (0.0, 0.0, 1.0)
    _value_fields: ClassVar[tuple[str, ...]] = ("damping",)

    @classmethod
    def candidates_at(cls, ctx, where):
        """One dashpot per translational direction of the location."""
        return [cls(where, direction=d) for d in ctx.directions[where]]

    @property
    def name(self) -> str:
        return f"dashpot at {self._at()}{self._dir_text()}"

    @property
    def description(self) -> str:
        return (
            f"A concentrated viscous damper at {self._at()}{self._dir_text()} (MACE's suspension "
            "dashpots): widens and lowers the resonance peaks of the modes that move that point."
        )

    def _specs(self):
        return [
            ParamSpec(
                base="dashpot",
                unit="N s/m",
                bounds=(0.0, 1e9),
                neutral=0.0,
                default_scale=1.0,
                meaning=f"grounded dashpot at {self._at()}{self._dir_text()}",
            )
        ]

    def _stage_fn(self):
        pname, loc, d = self.param_names[0], self.location, self.direction

        def fn(theta, struct):
            c = float(theta[pname])
            return struct if c == 0.0 else struct.add_dashpot(loc, c, d)

        return fn


@dataclass(frozen=True)
class Pendulum(_StructEffect):
    """Pendular stiffness of a suspension rod or cable holding a node: ``k = W / L``.

    A weight ``W`` hanging on a rod of length ``L`` resists horizontal motion of its
    attachment with stiffness ``W / L`` (N/m) in both horizontal directions (MACE's 5 m
    load rods gave 0.23 Hz pendulum modes).

    Parameters
    ----------
    location : str
    stiffness : float
        ``W / L`` in N/m (neutral 0).
    directions : tuple of str
        The horizontal directions (default ``("x", "y")``: gravity along z).
    """

    stiffness: float = 0.0
    directions: tuple[str, ...] = ("x", "y")

    kind: ClassVar[str] = "pendulum"
    sweep: ClassVar[str | None] = "location"
    _value_fields: ClassVar[tuple[str, ...]] = ("stiffness",)
    _extra_tags: ClassVar[tuple[str, ...]] = ("suspension",)

    @classmethod
    def candidates_at(cls, ctx, where):
        """A pendulum at a location moving in x and y, on a structure under gravity."""
        return [cls(where)] if ctx.info["gravity_on"] and {"x", "y"} <= set(ctx.directions[where]) else []

    @property
    def name(self) -> str:
        return f"suspension pendulum at {self._at()}"

    @property
    def description(self) -> str:
        return (
            f"A suspension rod or cable at {self._at()}: horizontal stiffness W/L in "
            f"{' and '.join(self.directions)}, raising the pendulum (rigid-body) frequencies."
        )

    def _specs(self):
        return [
            ParamSpec(
                base="pendulum_stiffness",
                unit="N/m",
                bounds=(0.0, 1e12),
                neutral=0.0,
                default_scale=100.0,
                meaning=f"pendular stiffness W/L at {self._at()}",
            )
        ]

    def _stage_fn(self):
        pname, loc, dirs = self.param_names[0], self.location, tuple(self.directions)

        def fn(theta, struct):
            k = float(theta[pname])
            if k == 0.0:
                return struct
            for d in dirs:
                struct = struct.add_spring(loc, k, d)
            return struct

        return fn


@dataclass(frozen=True)
class GroupStiffness(_StructEffect):
    """A relative change of the elastic stiffness of an element group (joints, material, section).

    Parameters
    ----------
    location : str
        Element group name.
    change : float
        Relative stiffness change (``K_group <- (1 + change) K_group``; neutral 0).
    """

    change: float = 0.0

    kind: ClassVar[str] = "group_stiffness"
    sweep: ClassVar[str | None] = "group"
    calibration_unit: ClassVar[float] = 0.1
    _value_fields: ClassVar[tuple[str, ...]] = ("change",)

    @classmethod
    def candidates_at(cls, ctx, where):
        """One stiffness change per element group."""
        return [cls(where)]
    _where_word: ClassVar[str] = "group"

    @property
    def name(self) -> str:
        return f"stiffness change of {self.location}"

    @property
    def description(self) -> str:
        return (
            f"The elements of {self.location} are stiffer or softer than modelled (joints, "
            "material, cross-section): shifts the modes that strain them."
        )

    def _check_location(self, model):
        _require(self.location, _structure_info(model)["groups"], "element group", self)

    def _specs(self):
        return [
            ParamSpec(
                base="stiffness_change",
                unit="",
                bounds=(-0.95, 10.0),
                neutral=0.0,
                default_scale=0.05,
                meaning=f"relative stiffness change of {self.location}",
            )
        ]

    def _stage_fn(self):
        pname, group = self.param_names[0], self.location

        def fn(theta, struct):
            c = float(theta[pname])
            return struct if c == 0.0 else struct.scale_group_stiffness(group, 1.0 + c)

        return fn


@dataclass(frozen=True)
class GroupTension(_StructEffect):
    """Axial tension along an element group: taut wires or cables fixed to its members.

    The Caltech truss authors explain their FEM error this way: "the wires to the
    accelerometers were tightly fixed to the columns and pulled taut, thereby adding
    stiffness to the longerons". The tension's geometric stiffness stiffens the members in
    bending (``Structure.add_group_tension``).

    Parameters
    ----------
    location : str
        Element group name (e.g. ``"longerons_story_1"``).
    tension : float
        Tension in N (neutral 0; negative is compression).
    """

    tension: float = 0.0

    kind: ClassVar[str] = "group_tension"
    sweep: ClassVar[str | None] = "group"
    _value_fields: ClassVar[tuple[str, ...]] = ("tension",)

    @classmethod
    def candidates_at(cls, ctx, where):
        """A tension along each group with geometric stiffness (a matrix group without one cannot)."""
        return [cls(where)] if where in ctx.info["tension_groups"] else []

    def phrase(self) -> str:
        size = self.describe_value()
        return f"{article(size)} {size} tension along {self.location} (taut wires or cables)"
    _where_word: ClassVar[str] = "group"

    @property
    def name(self) -> str:
        return f"taut wires (tension) along {self.location}"

    @property
    def description(self) -> str:
        return (
            f"Axial tension along {self.location} (taut wires or cables fixed to the members): "
            "geometric stiffness stiffens their bending, raising the modes that bend them."
        )

    def _check_location(self, model):
        info = _structure_info(model)
        _require(self.location, info["groups"], "element group", self)
        if self.location not in info["tension_groups"]:
            raise ModelError(
                f"{self.kind}: group {self.location!r} has no geometric stiffness, so it cannot carry a "
                "tension; give rc.structural_model geometric_stiffness={group: K_G_per_newton}, or use "
                "GroupStiffness."
            )

    def _specs(self):
        return [
            ParamSpec(
                base="tension",
                unit="N",
                bounds=(-1e7, 1e7),
                neutral=0.0,
                default_scale=10.0,
                meaning=f"axial tension along {self.location}",
            )
        ]

    def _stage_fn(self):
        pname, group = self.param_names[0], self.location

        def fn(theta, struct):
            t = float(theta[pname])
            return struct if t == 0.0 else struct.add_group_tension(group, t)

        return fn


@dataclass(frozen=True)
class GravityStiffening(_StructEffect):
    """Gravity preload (stress stiffening) switched on (``enabled=True``) or off.

    A discrete effect: its parameter ``gravity_on``/``gravity_off`` is 0 (neutral, the
    model as it is) or 1 (gravity preload forced on / off). It is not fitted
    (``free=False``); diagnose compares the two states.
    """

    enabled: bool = True
    switch: float = 0.0

    kind: ClassVar[str] = "gravity"
    sweep: ClassVar[str | None] = "structure"
    toggle: ClassVar[bool] = True
    calibration: ClassVar[str] = "none"
    _value_fields: ClassVar[tuple[str, ...]] = ("switch",)

    @classmethod
    def candidates_at(cls, ctx, where):
        """Only the switch that changes the model's current state (frame FEM with a preload)."""
        if not ctx.info["gravity"]:
            return []
        state = ctx.info["gravity_on"]
        return [cls(enabled=on) for on in (True, False) if state is None or on != state]

    def phrase(self) -> str:
        return self.name
    _extra_tags: ClassVar[tuple[str, ...]] = ("gravity",)

    @property
    def name(self) -> str:
        return f"gravity stiffening switched {'on' if self.enabled else 'off'}"

    @property
    def description(self) -> str:
        return (
            "The static gravity preload and its stress stiffening (MACE's 1-g model) "
            f"{'added to' if self.enabled else 'removed from'} the structure: shifts modes whose "
            "members carry the weight, and pendulum modes."
        )

    def _check_location(self, model):
        info = _structure_info(model)
        if not info["gravity"]:
            raise ModelError(
                f"{self.name}: the model's structure has no gravity preload to switch (only the "
                "built-in frame FEM has one); drop this effect."
            )

    def _suffix(self) -> str:
        return ""

    def _specs(self):
        return [
            ParamSpec(
                base="gravity_on" if self.enabled else "gravity_off",
                unit="switch",
                bounds=(0.0, 1.0),
                neutral=0.0,
                default_scale=1.0,
                free=False,
                meaning=f"1: gravity preload {'on' if self.enabled else 'off'}; 0: as modelled",
            )
        ]

    def _stage_fn(self):
        pname, enabled = self.param_names[0], bool(self.enabled)

        def fn(theta, struct):
            return struct.set_gravity(enabled) if float(theta[pname]) >= 0.5 else struct

        return fn

    def describe_value(self, values=None) -> str:
        vals = self.values if values is None else values
        on = float(vals.get(self.param_names[0], self.switch)) >= 0.5
        return "switched" if on else "as modelled"


@dataclass(frozen=True)
class ModalDamping(_StructEffect):
    """A relative change of the modal damping ratios of a group of modes.

    The group is either a range of mode numbers (``modes=(1, 2)``: the elastic modes 1 and
    2, counted by ascending frequency, rigid-body modes left out), which follows its modes
    wherever parameter changes move them, or a frequency band (``lo_hz``, ``hi_hz``), which
    holds whatever modes sit in it. The candidates of :func:`candidates` use mode numbers:
    a band placed at the nominal model's modes loses them when parameter errors shift the
    modes by more than its margin (E -30 % moves them by 16 %). Mode numbers count the modes
    the model's dynamics keep (:func:`~robustctl.physical.modal.modal_dynamics`), while the
    candidates number the structure's modes from its lowest: the two agree unless the
    dynamics truncate to a band above the lowest mode (``band_hz=(5.0, 60.0)``). Modes that
    cross (a change moves one past another) swap numbers.

    Parameters
    ----------
    modes : (int, int), optional
        First and last elastic mode of the group (1-based, inclusive). Given, the band is
        not used.
    lo_hz, hi_hz : float
        The band in Hz holding the mode group (when ``modes`` is not given).
    change : float
        Relative change (``zeta <- (1 + change) zeta``; neutral 0).
    """

    lo_hz: float = 0.0
    hi_hz: float = math.inf
    change: float = 0.0
    modes: tuple[int, int] | None = None

    kind: ClassVar[str] = "modal_damping"
    sweep: ClassVar[str | None] = "modes"
    calibration: ClassVar[str] = "none"
    _value_fields: ClassVar[tuple[str, ...]] = ("change",)

    @classmethod
    def candidates_at(cls, ctx, where):
        """One change per octave-wide group and per cluster of the modes in the band."""
        f_hz, number = ctx.modes
        return _modal_damping_groups(cls, f_hz, number)

    def __post_init__(self) -> None:
        if self.modes is not None:
            try:
                first, last = (int(k) for k in self.modes)
                ok = (first, last) == tuple(self.modes) and 1 <= first <= last
            except (TypeError, ValueError):
                ok = False
            if not ok:
                raise ModelError(
                    f"modal damping modes needs (first, last) mode numbers with 1 <= first <= last; "
                    f"got {self.modes!r}."
                )
            object.__setattr__(self, "modes", (first, last))
            if self.location is None:
                where = f"mode {first}" if first == last else f"modes {first}-{last}"
                object.__setattr__(self, "location", where)
        elif not 0 <= self.lo_hz < self.hi_hz:
            raise ModelError(
                f"modal damping band needs 0 <= lo_hz < hi_hz (Hz); got ({self.lo_hz}, {self.hi_hz})."
            )
        if self.location is None:
            object.__setattr__(self, "location", f"modes {self.lo_hz:.3g}-{self.hi_hz:.3g} Hz")
        super().__post_init__()

    @property
    def name(self) -> str:
        return f"modal damping change of the {self.location}"

    @property
    def description(self) -> str:
        return (
            f"The damping of the {self.location} differs from the model (joints, friction, "
            "cabling): changes peak heights and widths, not frequencies."
        )

    def _check_location(self, model):
        _structure_info(model)

    def _suffix(self) -> str:
        if self.modes is not None:
            return f"__modes_{self.modes[0]}_{self.modes[1]}"
        return f"__{_slug(f'{self.lo_hz:.3g}')}_{_slug(f'{self.hi_hz:.3g}')}Hz"

    def _specs(self):
        return [
            ParamSpec(
                base="modal_damping_change",
                unit="",
                bounds=(-0.95, 20.0),
                neutral=0.0,
                default_scale=0.2,
                meaning=f"relative modal damping change of the {self.location}",
            )
        ]

    def _stage_fn(self):
        pname, lo, hi = self.param_names[0], float(self.lo_hz), float(self.hi_hz)
        modes = self.modes

        def fn(theta, struct):
            c = float(theta[pname])
            if c == 0.0:
                return struct
            if modes is not None:
                return struct.scale_mode_damping(modes[0], modes[1], 1.0 + c)
            return struct.scale_modal_damping(lo, hi, 1.0 + c)

        return fn



@dataclass(frozen=True)
class JointSpring(_StructEffect):
    """A semi-rigid beam joint: a rotational spring between a member and the rest of a frame joint.

    Frame FE models take every beam-to-beam connection as rigid; bolted, welded or clamped joints
    are often softer, which lowers the modes that bend the members through the joint (one of the
    commonest FE errors). The parameter is the joint's rotational *compliance* ``c`` (rad/(N m)),
    neutral 0 (rigid); the spring ``1 / c`` acts about each axis
    (:meth:`robustctl.physical.fem.Frame.add_joint_flexibility`), or about one global axis only
    (``axis``: a hinge; the other rotations stay rigid). Frame FEM only.

    The compliance reaches the whole range, rigid (0) to pinned (a spring far softer than the
    member, ``c >> L / (4 E I)``), which first-order screening at rigid cannot see (the mode shapes
    change with the size): ``coarse_screen`` makes ``rc.diagnose`` try it at sizes a decade apart.

    Parameters
    ----------
    location : str
        The joint's node.
    group : str
        The element group whose beams connect to the joint through the spring.
    compliance : float
        ``c`` in rad/(N m) (neutral 0).
    axis : str or None
        ``"rx"``, ``"ry"`` or ``"rz"``: a hinge about that global axis; None: the same spring about
        each axis.
    """

    group: str | None = None
    compliance: float = 0.0
    axis: str | None = None

    kind: ClassVar[str] = "joint_spring"
    sweep: ClassVar[str | None] = "joint"
    calibration: ClassVar[str] = "none"
    coarse_screen: ClassVar[bool] = True
    _value_fields: ClassVar[tuple[str, ...]] = ("compliance",)

    @classmethod
    def candidates_at(cls, ctx, where):
        """One per beam joint; typical size a spring 20 x stiffer than the member's end
        (``4 E I / L``): a few % on the modes."""
        node, group = where
        step = 0.05 / ctx.structure.joint_stiffness(node, group)
        return [cls(node, group=group, axis=axis).with_scale(step) for axis in (None, "rx", "ry", "rz")]

    def phrase(self) -> str:
        return f"a {self.name} ({self.describe_value()})"

    def __post_init__(self) -> None:
        if self.axis not in (None, "rx", "ry", "rz"):
            raise ModelError(f"a joint's axis is 'rx', 'ry', 'rz' or None (every axis); got {self.axis!r}.")
        super().__post_init__()

    @property
    def name(self) -> str:
        if self.axis is not None:
            return f"flexible hinge of {self.group} at {self._at()} about {self.axis[1]}"
        return f"semi-rigid joint of {self.group} at {self._at()}"

    @property
    def description(self) -> str:
        return (
            f"The connection of {self.group} at {self._at()} is not rigid: a rotational spring (a bolted, "
            "welded or clamped joint softer than modelled) lowers the modes that bend the members through it."
        )

    def _suffix(self) -> str:
        axis = "" if self.axis is None else f"_{self.axis}"
        return f"__{_slug(self.location)}_{_slug(self.group)}{axis}"

    def _check_location(self, model):
        struct = model.build_structure()
        joints = getattr(struct, "joints", None)
        if joints is None:
            raise ModelError(
                f"{self.kind} needs a frame FEM (rc.Frame) with beam joints; {type(struct).__name__} "
                "has none."
            )
        found = joints()
        if (self.location, self.group) not in found:
            raise ModelError(
                f"no joint of group {self.group!r} at node {self.location!r}; the joints are {found}."
            )

    def _specs(self):
        return [
            ParamSpec(
                base="joint_compliance",
                unit="rad/(N m)",
                bounds=(0.0, 1.0),
                neutral=0.0,
                default_scale=1e-6,
                meaning=f"rotational compliance of the joint of {self.group} at {self.location}",
            )
        ]

    def _stage_fn(self):
        pname, node, group = self.param_names[0], self.location, self.group
        axes = ("rx", "ry", "rz") if self.axis is None else (self.axis,)

        def fn(theta, struct):
            c = float(theta[pname])
            return struct if c == 0.0 else struct.add_joint_flexibility(node, group, c, axes)

        return fn

    def describe_value(self, values=None) -> str:
        vals = self.values if values is None else values
        c = float(vals.get(self.param_names[0], self.compliance))
        return "rigid" if c <= 0 else f"{1.0 / c:.3g} N m/rad"


#: Consecutive modes closer than this frequency ratio form a cluster (a close pair of a
#: symmetric structure, bending in x and y) that gets a damping candidate of its own.
_CLUSTER_RATIO = 1.1


def _modal_damping_groups(cls: type, f_modes: np.ndarray, number: np.ndarray) -> list[Effect]:
    """Damping changes of the modes ``f_modes`` (Hz, ascending) by their mode numbers
    ``number`` (1-based among the elastic modes), not by Hz, so each follows its modes when
    parameter errors or the update move them (a band at the nominal modes loses them beyond
    its margin: E -30 % moves every mode by 16 %).

    One candidate per octave-wide group of modes, and one per cluster of modes closer than
    :data:`_CLUSTER_RATIO` (a lone mode is its own cluster) when it is not already a group:
    a change on a close pair alone (joints of one bending plane pair) is then fitted exactly,
    not spread over the octave."""
    f = np.asarray(f_modes, dtype=float)
    keep = f > 0
    f, number = f[keep], np.asarray(number)[keep]
    if f.size == 0:
        return []

    def runs(joined) -> list[tuple[int, int]]:
        out, first = [], 0
        for k in range(1, f.size):
            if not joined(first, k):
                out.append((first, k - 1))
                first = k
        out.append((first, f.size - 1))
        return out

    octaves = runs(lambda first, k: f[k] <= 2.0 * f[first])
    clusters = runs(lambda first, k: f[k] < _CLUSTER_RATIO * f[k - 1])
    spans = list(dict.fromkeys(octaves + clusters))
    return [cls(modes=(int(number[a]), int(number[b]))) for a, b in spans]
