"""Effects a laboratory brings to the structure: the transducers' own mass, the stingers, attached
resonators, and the joints and supports a test finds softer or more damped than modelled.

A modal test adds hardware to what the model describes. Every accelerometer and its mount adds
the same mass at each measured point (one physical cause acting at many places, invisible to a
screen that tries one point mass at a time); each stinger restrains its driving point across the
drive axis where the force gauge does not see it; a payload on a soft mount, fuel slosh or a hanging
cable adds a *mode* no parameter of the model has. These are given here for any structural model
(``rc.Frame``, a user's matrices, FE imports), found from the model's own sensors and forces
(:meth:`~robustctl.physical.structure_base.Structure.signal_location`). Joints and supports come from
the model where it says where they are (a frame's flexible joints), else from the user
(``candidates(model, joints=..., supports=...)``).

References: Ewins, *Modal Testing: Theory, Practice and Application* (2000), sec. 3.9 (transducer
mass loading) and sec. 3.6 (attachment); Den Hartog, *Mechanical Vibrations*, sec. 3.2 (a spring-mass
absorber adds a mode and splits the host's).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from ...errors import ModelError
from ..structure_base import STINGER_LENGTH
from .base import _DIR_RE, ParamSpec, _slug, _structure_info
from .setup import _structure_signals
from .structural import _StructEffect  # defined (and registered) before the laboratory's effects


def _mounts(ctx, side: str) -> list[tuple[str, str | None]]:
    """``(location, direction)`` of each point sensor (``side="output"``) or force of the model's
    structure, in signal order, one per location."""
    found: dict[str, str | None] = {}
    mats = None
    for name in _structure_signals(ctx.model, side):
        loc = ctx.structure.signal_location(side, name)
        if loc is None or loc in found:
            continue
        if mats is None:
            mats = ctx.structure.matrices()
        found[loc] = _signal_axis(ctx, mats, side, name, loc)
    return list(found.items())


def _signal_mounts(ctx, side: str) -> list[str]:
    """The location of each point sensor (or force) of the model's structure, one per signal: a node
    with two single-axis accelerometers appears twice (it carries both)."""
    found = (ctx.structure.signal_location(side, name) for name in _structure_signals(ctx.model, side))
    return [loc for loc in found if loc is not None]


def _signal_axis(ctx, mats, side: str, name: str, loc: str) -> str | None:
    """The translational axis a point signal at ``loc`` points along most (None: a scalar DOF)."""
    dirs = [d for d in ctx.directions.get(loc, [None]) if d is not None]
    if not dirs:
        return None
    names = mats.outputs if side == "output" else mats.inputs
    if name not in names:
        return dirs[0]
    k = list(names).index(name)
    v = np.abs(np.asarray(mats.output_matrix)[k] if side == "output" else np.asarray(mats.input_matrix)[:, k])
    best, best_v = dirs[0], -1.0
    for j, lab in enumerate(mats.dof_labels):
        m = _DIR_RE.match(lab)
        if m and m.group("loc") == loc and m.group("dir") in dirs and v[j] > best_v:
            best, best_v = m.group("dir"), float(v[j])
    return best


@dataclass(frozen=True)
class TransducerMass(_StructEffect):
    """The mass of the transducers: the same mass ``m`` at the mount of every sensor (and, with
    ``location="sensors and drive points"``, of every force gauge's structure side).

    One parameter for all: the accelerometer with its mount and cable clamp is the same hardware
    at each point (Ewins 2000, sec. 3.9). Each mount's single mass alone explains little of what
    they do together, so a screen of single masses misses it.

    Parameters
    ----------
    location : str
        ``"sensors"`` or ``"sensors and drive points"`` (a label: the mounts are ``mounts``).
    mounts : tuple of str
        The locations (nodes or DOFs) that carry the mass.
    mass : float
        Mass at each mount in kg (neutral 0).
    """

    mounts: tuple[str, ...] = ()
    mass: float = 0.0

    kind: ClassVar[str] = "transducer_mass"
    domain: ClassVar[str] = "structure"
    sweep: ClassVar[str | None] = "structure"
    calibration: ClassVar[str] = "shift"
    point_unit: ClassVar[tuple[float, float, float] | None] = (1.0, 0.0, 0.0)
    _value_fields: ClassVar[tuple[str, ...]] = ("mass",)

    def __post_init__(self) -> None:
        object.__setattr__(self, "mounts", tuple(str(m) for m in self.mounts))
        if not self.mounts:
            raise ModelError("a transducer mass needs the mounts that carry it: mounts=('n1', 'n2', ...).")
        super().__post_init__()

    @classmethod
    def candidates_at(cls, ctx, where):
        """One mass for every point sensor (two or more; a node carrying two single-axis sensors
        carries two masses), one for every sensor mount when some carry several sensors (a triaxial
        accelerometer: one mass), and one for every sensor and drive point when forces act elsewhere."""
        sensors = _signal_mounts(ctx, "output")
        mounts = list(dict.fromkeys(sensors))
        drives = [loc for loc in dict.fromkeys(_signal_mounts(ctx, "input")) if loc not in mounts]
        out = [cls("sensors", mounts=tuple(sensors))] if len(sensors) >= 2 else []
        if len(mounts) >= 2 and len(mounts) < len(sensors):
            out.append(cls("sensor mounts", mounts=tuple(mounts)))
        if sensors and drives:
            out.append(cls("sensors and drive points", mounts=tuple(sensors + drives)))
        return out

    @property
    def name(self) -> str:
        return f"transducer mass at each of the {len(self.mounts)} {self.location}"

    @property
    def description(self) -> str:
        return (
            f"The same unmodelled mass at each of {', '.join(self.mounts)} (the accelerometers, their "
            "mounts and cable clamps; a location named twice carries two): lowers the modes that move "
            "the measured points."
        )

    def _check_location(self, model):
        info = _structure_info(model)
        unknown = [m for m in self.mounts if m not in info["locations"]]
        if unknown:
            raise ModelError(f"{self.kind}: unknown mounts {unknown}; give nodes or DOFs of the model.")

    def _suffix(self) -> str:
        return "__" + _slug(self.location or "mounts")

    def _specs(self):
        return [ParamSpec(base="transducer_mass", unit="kg", bounds=(0.0, 1e3), neutral=0.0,
                          default_scale=0.01, meaning=f"mass of each transducer at the {self.location}")]

    def _stage_fn(self):
        pname, mounts = self.param_names[0], self.mounts

        def fn(theta, struct):
            m = float(theta[pname])
            if m == 0.0:
                return struct
            for loc in mounts:
                struct = struct.add_mass(loc, m)
            return struct

        return fn

    def phrase(self) -> str:
        return f"{self.describe_value()} of transducer mass at each of the {len(self.mounts)} {self.location}"

    def changes_preload(self, gravity_direction) -> bool:
        return True  # more weight in the suspension


#: Frequencies at which a resonator candidate's screen is tried besides the misfit's peaks: this many
#: per octave of the band (``rc.diagnose`` retunes it; see :attr:`AttachedResonator.retune`).
RESONATORS_PER_OCTAVE = 0
#: At most this many resonator candidates per model: the sensor and drive-point mounts along their
#: axes first, then every location carrying a lumped mass (``Structure.mass_locations``: equipment and
#: payload mounts) along each of its directions (diagnose screens each at the misfit's largest peak
#: and retunes only the best few, so each costs one or two evaluations).
RESONATORS_MAX = 96


@dataclass(frozen=True)
class AttachedResonator(_StructEffect):
    """A spring-mass attached at a point: a payload on a soft mount, fuel slosh, a hanging cable.

    It adds a mode at about ``frequency`` (Hz) and splits the host's modes near it (Den Hartog,
    *Mechanical Vibrations*, sec. 3.2): no parameter of the model can make that mode, and first
    order at mass 0 sees it only near its own frequency. The candidates sit at the sensor and
    drive-point mounts along their axes, then at every location carrying a lumped mass along each
    direction (:data:`RESONATORS_MAX` at most), one each, at the band's geometric middle; ``rc.diagnose``
    screens each at the largest peak of the misfit the update leaves and the best few at more peaks
    and around them (:attr:`retune`: the added mode sits where the model has none), and fits mass
    and frequency.

    Parameters
    ----------
    location : str
        Node or DOF carrying the resonator.
    direction : str or None
        ``"x"``, ``"y"``, ``"z"`` on a frame; None on a scalar DOF.
    mass : float
        Moving mass in kg (neutral 0).
    frequency : float
        Natural frequency of the mass on its mount when the attachment point is held, in Hz.
    """

    direction: str | None = None
    mass: float = 0.0
    frequency: float = 10.0

    kind: ClassVar[str] = "attached_resonator"
    domain: ClassVar[str] = "structure"
    sweep: ClassVar[str | None] = "structure"
    calibration: ClassVar[str] = "none"
    retune: ClassVar[str | None] = "frequency"
    _value_fields: ClassVar[tuple[str, ...]] = ("mass", "frequency")

    @classmethod
    def candidates_at(cls, ctx, where):
        """At each sensor and drive-point mount along its axis, then at every location carrying a lumped
        mass along each direction, at the band's geometric middle (the screening moves it to the
        misfit's peaks); typical mass 1 % of the structure's."""
        band = ctx.band
        if band is None or not band[1] > band[0] > 0:
            return []  # no band given: no frequencies to screen it at
        places = list(dict.fromkeys([*_mounts(ctx, "output"), *_mounts(ctx, "input")]))
        masses = getattr(ctx.structure, "mass_locations", None)
        where = masses() if masses is not None else ctx.info["locations"]
        places += [(loc, d) for loc in where for d in ctx.directions.get(loc, [None])]
        places = list(dict.fromkeys(places))[:RESONATORS_MAX]
        n = max(1, int(math.floor(RESONATORS_PER_OCTAVE * math.log2(band[1] / band[0]))))
        grid = band[0] * (band[1] / band[0]) ** ((np.arange(n) + 0.5) / n)
        step = 0.01 * _structure_mass(ctx)
        return [cls(loc, direction=d, frequency=float(f)).with_scale(step) for loc, d in places for f in grid]

    @property
    def name(self) -> str:
        along = "" if self.direction is None else f" along {self.direction}"
        return f"attached resonator at {self.location}{along} ({self.frequency:.3g} Hz)"

    @property
    def description(self) -> str:
        return (
            f"A mass on a soft mount at {self.location} (a payload, fuel slosh, a cable): adds a mode "
            "near its own frequency and splits the structure's modes there."
        )

    def _check_location(self, model):
        info = _structure_info(model)
        if self.location not in info["locations"]:
            raise ModelError(f"{self.kind}: unknown location {self.location!r}.")

    def _suffix(self) -> str:
        d = "" if self.direction is None else "_" + _slug(self.direction)
        return f"__{_slug(self.location)}{d}_{_slug(f'{self.frequency:.3g}')}Hz"

    def _specs(self):
        f = float(self.frequency)
        return [
            ParamSpec(base="resonator_mass", unit="kg", bounds=(0.0, 1e4), neutral=0.0, default_scale=0.1,
                      meaning=f"moving mass of the resonator at {self.location}"),
            ParamSpec(base="resonator_frequency", unit="Hz", bounds=(1e-3, 1e5), neutral=f,
                      default_scale=0.1 * f,
                      meaning=f"natural frequency of the resonator at {self.location} on its mount"),
        ]

    def _stage_fn(self):
        pm, pf = self.param_names
        loc, d = self.location, self.direction

        def fn(theta, struct):
            m, f = float(theta[pm]), float(theta[pf])
            if m == 0.0:
                return struct
            return struct.add_resonator(loc, m, m * (2.0 * math.pi * f) ** 2, d)

        return fn

    def phrase(self) -> str:
        along = "" if self.direction is None else f" along {self.direction}"
        return f"a {self.describe_value()} mass on a {self.frequency:.3g} Hz mount at {self.location}{along}"


def _structure_mass(ctx) -> float:
    """The structure's total translational mass per direction (kg): trace of ``M`` over the
    translational DOFs, divided by the number of directions."""
    mats = ctx.structure.matrices()
    diag = np.asarray(mats.mass.diagonal()).reshape(-1)
    found = [_DIR_RE.match(lab) for lab in mats.dof_labels]
    trans = [j for j, m in enumerate(found) if m]
    if not trans:  # scalar DOFs (a user's matrices): their masses
        return float(np.sum(diag))
    return float(np.sum(diag[trans])) / len({found[j].group("dir") for j in trans})


def _check_dof_pair(effect, model) -> None:
    """Both DOF labels of a joint effect are DOFs of ``model`` (ModelError naming the unknown ones)."""
    info = _structure_info(model)
    unknown = [d for d in effect.dofs if d not in info["locations"]]
    if unknown:
        raise ModelError(f"joint {effect.location!r}: unknown DOFs {unknown}; give DOF labels of the model.")


@dataclass(frozen=True)
class DofPairJoint(_StructEffect):
    """A joint of a user's matrix model between two DOFs, from as modelled to pinned.

    The model joins DOFs ``a`` and ``b`` by a connection of stiffness ``k0`` (a CBUSH, a stiff
    spring, an RBE replaced by one); the effect puts a compliance ``c`` in series with it,
    ``k = k0 / (1 + c k0)``: ``c = 0`` is the model, a large ``c`` a pin. Named by the user
    (``rc.effects.candidates(model, joints={"hinge": ("dof 7", "dof 8", 2e5)})``): a matrix model
    does not say where its joints are. Screened over its whole range (``coarse_screen``).

    Parameters
    ----------
    location : str
        The joint's name.
    dofs : (str, str)
        The two DOF labels it joins.
    stiffness : float
        ``k0``, the connection's stiffness in the model (N/m or N m/rad).
    compliance : float
        ``c`` in m/N (rad/(N m) between rotations), neutral 0.
    """

    dofs: tuple[str, str] = ("", "")
    stiffness: float = 1.0
    compliance: float = 0.0

    kind: ClassVar[str] = "dof_pair_joint"
    sweep: ClassVar[str | None] = "structure"
    calibration: ClassVar[str] = "none"
    coarse_screen: ClassVar[bool] = True
    _value_fields: ClassVar[tuple[str, ...]] = ("compliance",)

    def __post_init__(self) -> None:
        k0 = float(self.stiffness)
        if len(tuple(self.dofs)) != 2 or not (np.isfinite(k0) and k0 > 0):
            raise ModelError(
                "a joint needs two DOF labels and the model's connection stiffness k0 > 0; got "
                f"dofs={self.dofs!r}, stiffness={self.stiffness!r}."
            )
        object.__setattr__(self, "dofs", tuple(str(d) for d in self.dofs))
        super().__post_init__()

    @classmethod
    def candidates_at(cls, ctx, where):
        """One per joint the user named (``candidates(..., joints=...)``); typical size: 5 % softer."""
        return [cls(name, dofs=(a, b), stiffness=float(k0)).with_scale(0.05 / float(k0))
                for name, (a, b, k0) in ctx.joints.items()]

    @property
    def name(self) -> str:
        return f"flexible joint {self.location} ({self.dofs[0]} - {self.dofs[1]})"

    @property
    def description(self) -> str:
        return (f"The connection {self.location} between {self.dofs[0]} and {self.dofs[1]} is softer than "
                "modelled (a bolted or hinged joint): lowers the modes that strain it.")

    def _check_location(self, model):
        _check_dof_pair(self, model)

    def _specs(self):
        k0 = float(self.stiffness)
        return [ParamSpec(base="joint_compliance", unit="m/N", bounds=(0.0, 1e3 / k0), neutral=0.0,
                          default_scale=0.05 / k0, meaning=f"series compliance of joint {self.location}")]

    def _stage_fn(self):
        pname, (a, b), k0 = self.param_names[0], self.dofs, float(self.stiffness)

        def fn(theta, struct):
            c = float(theta[pname])
            return struct if c == 0.0 else struct.add_coupling(a, b, -c * k0 * k0 / (1.0 + c * k0))

        return fn

    def describe_value(self, values=None) -> str:
        vals = self.values if values is None else values
        c = float(vals.get(self.param_names[0], self.compliance))
        k0 = float(self.stiffness)
        return "as modelled" if c <= 0 else f"{k0 / (1.0 + c * k0):.3g} instead of {k0:.3g}"

    def phrase(self) -> str:
        return f"a {self.name} of stiffness {self.describe_value()}"


@dataclass(frozen=True)
class JointDamping(_StructEffect):
    """Local (non-proportional) damping at a joint of a user's matrix model: a dashpot across the
    connection between two DOFs (friction and micro-slip in a bolted or hinged joint damp the modes
    that strain it, not every mode alike). Named by the user with the joint
    (``rc.effects.candidates(model, joints={"hinge": ("dof 7", "dof 8", k0)})``), as
    :class:`DofPairJoint`; the step is calibrated to change the most affected modal damping ratio
    by :data:`~robustctl.physical.effects.base.DAMPING_TARGET`.

    Parameters
    ----------
    location : str
        The joint's name.
    dofs : (str, str)
        The two DOF labels it joins.
    damping : float
        Dashpot in N s/m (N m s/rad between rotations), neutral 0.
    """

    dofs: tuple[str, str] = ("", "")
    damping: float = 0.0

    kind: ClassVar[str] = "joint_damping"
    sweep: ClassVar[str | None] = "structure"
    calibration: ClassVar[str] = "damping"
    _value_fields: ClassVar[tuple[str, ...]] = ("damping",)

    def __post_init__(self) -> None:
        if len(tuple(self.dofs)) != 2:
            raise ModelError(f"a joint's damping needs the two DOF labels it joins; got dofs={self.dofs!r}.")
        object.__setattr__(self, "dofs", tuple(str(d) for d in self.dofs))
        super().__post_init__()

    @classmethod
    def candidates_at(cls, ctx, where):
        """One per joint the user named (``candidates(..., joints=...)``)."""
        return [cls(name, dofs=(a, b)) for name, (a, b, _k0) in ctx.joints.items()]

    @property
    def name(self) -> str:
        return f"damping across joint {self.location} ({self.dofs[0]} - {self.dofs[1]})"

    @property
    def description(self) -> str:
        return (f"A dashpot across the connection {self.location} between {self.dofs[0]} and {self.dofs[1]} "
                "(friction in a bolted or hinged joint): damps the modes that strain it.")

    def _check_location(self, model):
        _check_dof_pair(self, model)

    def _specs(self):
        return [ParamSpec(base="joint_damping", unit="N s/m", bounds=(0.0, 1e9), neutral=0.0,
                          default_scale=1.0, meaning=f"dashpot across joint {self.location}")]

    def _stage_fn(self):
        pname, (a, b) = self.param_names[0], self.dofs

        def fn(theta, struct):
            c = float(theta[pname])
            return struct if c == 0.0 else struct.add_coupling_damping(a, b, c)

        return fn


@dataclass(frozen=True)
class SupportFlexibility(_StructEffect):
    """A clamped support that is really a rotational spring: a base plate, bolts or a foundation
    softer than a clamp (one of the commonest boundary errors of a frame model).

    The parameter is the support's rotational compliance ``c`` (rad/(N m)) about every rotation the
    support clamps (:meth:`robustctl.physical.fem.Frame.soften_support`), neutral 0 (the clamp),
    a large one a pin: screened over its whole range (``coarse_screen``), as a joint's. Frame FEM
    supports only (a matrix model's supports are eliminated already; its grounded springs are the
    :class:`SuspensionSpring` candidates at every DOF).

    Parameters
    ----------
    location : str
        The supported node.
    compliance : float
        ``c`` in rad/(N m) (neutral 0).
    """

    compliance: float = 0.0

    kind: ClassVar[str] = "support_flexibility"
    sweep: ClassVar[str | None] = "structure"
    calibration: ClassVar[str] = "none"
    coarse_screen: ClassVar[bool] = True
    _value_fields: ClassVar[tuple[str, ...]] = ("compliance",)

    @classmethod
    def candidates_at(cls, ctx, where):
        """One per clamped node of a frame; typical size a spring 20 x stiffer than the members' end."""
        supports = getattr(ctx.structure, "supports", None)
        if supports is None:
            return []
        return [cls(node).with_scale(0.05 / ctx.structure.support_stiffness(node)) for node, _ in supports()]

    @property
    def name(self) -> str:
        return f"flexible support at {self._at()}"

    @property
    def description(self) -> str:
        return (f"The clamp at {self._at()} is a rotational spring (a base plate, bolts, a foundation): "
                "lowers the modes that bend the members at the support.")

    def _check_location(self, model):
        struct = model.build_structure()
        supports = getattr(struct, "supports", None)
        if supports is None or self.location not in dict(supports()):
            found = supports() if supports is not None else []
            raise ModelError(f"{self.kind} needs a clamped node of a frame FEM; {self.location!r} is not one "
                             f"(supports: {found}).")

    def _specs(self):
        return [ParamSpec(base="support_compliance", unit="rad/(N m)", bounds=(0.0, 1.0), neutral=0.0,
                          default_scale=1e-6,
                          meaning=f"rotational compliance of the support at {self.location}")]

    def _stage_fn(self):
        pname, node = self.param_names[0], self.location

        def fn(theta, struct):
            c = float(theta[pname])
            return struct if c == 0.0 else struct.soften_support(node, c)

        return fn

    def describe_value(self, values=None) -> str:
        vals = self.values if values is None else values
        c = float(vals.get(self.param_names[0], self.compliance))
        return "clamped" if c <= 0 else f"{1.0 / c:.3g} N m/rad"

    def phrase(self) -> str:
        return f"a {self.name} ({self.describe_value()})"


@dataclass(frozen=True)
class FrameJointDamping(_StructEffect):
    """Local (non-proportional) damping at a flexible joint of a frame: a rotational dashpot across the
    rotations the joint releases, in parallel with its spring (friction and micro-slip in a bolted or
    hinged connection damp the modes that rotate the joint, not every mode alike; e.g. Gaul & Nitsche,
    "The role of friction in mechanical joints", *Appl. Mech. Rev.* 54(2), 2001).

    Made at every joint the frame models as flexible (:meth:`robustctl.physical.fem.Frame.flexible_joints`:
    a hinge or semi-rigid joint made with ``add_joint_flexibility``, twin nodes tied by a rigid link that
    releases those rotations): a joint the model takes as rigid has no relative rotation to damp (its
    flexibility is the :class:`~robustctl.physical.effects.structural.JointSpring` candidate). Frame FEM
    only; a matrix model's joints are :class:`JointDamping`. The step is calibrated to change the most
    affected modal damping ratio by :data:`~robustctl.physical.effects.base.DAMPING_TARGET`.

    Parameters
    ----------
    location : str
        The joint's node.
    group : str
        The element group whose beams the joint connects to the node.
    damping : float
        Rotational dashpot in N m s/rad about each released rotation (neutral 0).
    """

    group: str | None = None
    damping: float = 0.0

    kind: ClassVar[str] = "frame_joint_damping"
    sweep: ClassVar[str | None] = "structure"
    calibration: ClassVar[str] = "damping"
    _value_fields: ClassVar[tuple[str, ...]] = ("damping",)

    @classmethod
    def candidates_at(cls, ctx, where):
        """One per flexible joint of a frame whose released rotations carry inertia (a rotation without
        any is condensed out of the matrices and cannot carry a dashpot)."""
        flexible = getattr(ctx.structure, "flexible_joints", None)
        if flexible is None:
            return []
        labels = set(ctx.structure.matrices().dof_labels)
        return [cls(node, group=group) for node, group, axes in flexible()
                if all(f"{node}~{group} {ax}" in labels for ax in axes)]

    @property
    def name(self) -> str:
        return f"damping in the joint of {self.group} at {self._at()}"

    @property
    def description(self) -> str:
        return (f"A rotational dashpot across the flexible joint of {self.group} at {self._at()} (friction "
                "in a bolted or hinged connection): damps the modes that rotate the joint, not every mode "
                "alike.")

    def _suffix(self) -> str:
        return f"__{_slug(self.location)}_{_slug(self.group)}"

    def _check_location(self, model):
        struct = model.build_structure()
        flexible = getattr(struct, "flexible_joints", None)
        found = [(n, g) for n, g, _ in flexible()] if flexible is not None else []
        if (self.location, self.group) not in found:
            raise ModelError(
                f"{self.kind} needs a flexible joint of a frame FEM (rc.Frame.add_joint_flexibility); the "
                f"joint of {self.group!r} at {self.location!r} is not one (flexible joints: {found})."
            )

    def _specs(self):
        return [ParamSpec(base="joint_damping", unit="N m s/rad", bounds=(0.0, 1e9), neutral=0.0,
                          default_scale=1.0,
                          meaning=f"rotational dashpot across the joint of {self.group} at {self.location}")]

    def _stage_fn(self):
        pname, node, group = self.param_names[0], self.location, self.group

        def fn(theta, struct):
            c = float(theta[pname])
            return struct if c == 0.0 else struct.add_joint_damping(node, group, c)

        return fn

    def phrase(self) -> str:
        return f"a {self.describe_value()} dashpot {self.name[len('damping '):]}"


def _check_support_dofs(effect, model) -> None:
    """The support's DOFs are DOFs of ``model`` and each carries at least its modelled stiffness on the
    diagonal of ``K`` (ModelError saying which do not)."""
    info = _structure_info(model)
    unknown = [d for d in effect.dofs if d not in info["locations"]]
    if unknown:
        raise ModelError(f"support {effect.location!r}: unknown DOFs {unknown}; give DOF labels of the "
                         "model.")
    mats = model.build_structure().matrices()
    diag = np.asarray(mats.stiffness.diagonal()).reshape(-1)
    labels = list(mats.dof_labels)
    short = [(d, k0) for d, k0 in zip(effect.dofs, effect.stiffness)
             if diag[labels.index(d)] < k0 * (1 - 1e-9)]
    if short:
        d, k0 = short[0]
        raise ModelError(
            f"support {effect.location!r}: the modelled stiffness {k0:g} at {d} exceeds the model's own "
            f"K[{d}, {d}] = {diag[labels.index(d)]:g}; give the grounded spring the model has there."
        )


@dataclass(frozen=True)
class DofSupportFlexibility(_StructEffect):
    """A support of a user's matrix or FE model softer than modelled, from as modelled to free.

    The model grounds DOFs ``dofs`` through springs of stiffness ``k0`` (a foundation, a mount, a CBUSH
    to ground, a clamp the user modelled as a stiff spring); the effect puts one compliance ``c`` in
    series with each, ``k = k0 / (1 + c k0)``: ``c = 0`` is the model, a large ``c`` a free DOF. Named
    by the user (``rc.effects.candidates(model, supports={"base": (["1:Z", "9:Z"], 2e6)})``): a
    matrix model does not say which of its springs hold it to the ground. Screened over its whole range
    (``coarse_screen``), as :class:`DofPairJoint`. Name the translations and the rotations of a support
    as two supports (their compliances have different units). A support eliminated from the matrices (a
    clamp, an SPC) has no DOF left to soften; a frame's clamps are :class:`SupportFlexibility`.

    Parameters
    ----------
    location : str
        The support's name.
    dofs : tuple of str
        The DOF labels it holds.
    stiffness : tuple of float
        ``k0`` at each DOF, the grounded spring in the model (N/m, or N m/rad at rotations).
    compliance : float
        ``c`` in m/N (rad/(N m) at rotations), neutral 0.
    """

    dofs: tuple[str, ...] = ()
    stiffness: tuple[float, ...] = ()
    compliance: float = 0.0

    kind: ClassVar[str] = "dof_support_flexibility"
    sweep: ClassVar[str | None] = "structure"
    calibration: ClassVar[str] = "none"
    coarse_screen: ClassVar[bool] = True
    _value_fields: ClassVar[tuple[str, ...]] = ("compliance",)

    def __post_init__(self) -> None:
        dofs = (self.dofs,) if isinstance(self.dofs, str) else tuple(str(d) for d in self.dofs)
        k0 = np.atleast_1d(np.asarray(self.stiffness, dtype=float)).reshape(-1)
        if k0.size == 1 and len(dofs) > 1:
            k0 = np.full(len(dofs), float(k0[0]))
        ok = bool(dofs) and k0.size == len(dofs) and len(set(dofs)) == len(dofs)
        if not ok or not np.all(np.isfinite(k0) & (k0 > 0)):
            raise ModelError(
                "a support needs its DOF labels (each once) and the model's grounded stiffness k0 > 0 at "
                "each "
                f"(one number for all, or one per DOF); got dofs={self.dofs!r}, stiffness={self.stiffness!r}."
            )
        object.__setattr__(self, "dofs", dofs)
        object.__setattr__(self, "stiffness", tuple(float(k) for k in k0))
        super().__post_init__()

    @classmethod
    def candidates_at(cls, ctx, where):
        """One per support the user named (``candidates(..., supports=...)``); typical size: the stiffest
        DOF 5 % softer."""
        return [cls(name, dofs=dofs, stiffness=k0).with_scale(0.05 / max(k0))
                for name, (dofs, k0) in ctx.supports.items()]

    @property
    def name(self) -> str:
        return f"flexible support {self.location} ({', '.join(self.dofs)})"

    @property
    def description(self) -> str:
        return (f"The support {self.location} holding {', '.join(self.dofs)} is softer than modelled (a "
                "foundation, a mount, bolts): lowers the modes that load it, towards those of a free end.")

    def _check_location(self, model):
        _check_support_dofs(self, model)

    def _specs(self):
        k0 = max(self.stiffness)
        return [ParamSpec(base="support_compliance", unit="m/N", bounds=(0.0, 1e3 / min(self.stiffness)),
                          neutral=0.0, default_scale=0.05 / k0,
                          meaning=f"series compliance of support {self.location} at each of its DOFs")]

    def _stage_fn(self):
        pname, dofs, k0 = self.param_names[0], self.dofs, self.stiffness

        def fn(theta, struct):
            c = float(theta[pname])
            if c == 0.0:
                return struct
            for d, k in zip(dofs, k0):
                struct = struct.add_spring(d, -c * k * k / (1.0 + c * k))
            return struct

        return fn

    def describe_value(self, values=None) -> str:
        vals = self.values if values is None else values
        c = float(vals.get(self.param_names[0], self.compliance))
        k0 = max(self.stiffness)
        return "as modelled" if c <= 0 else f"{k0 / (1.0 + c * k0):.3g} instead of {k0:.3g}"

    def phrase(self) -> str:
        return f"a {self.name} of stiffness {self.describe_value()}"


@dataclass(frozen=True)
class StingerConstraint(_StructEffect):
    """The stinger's restraint of a driving point: the grounded lateral, rotational and torsional
    stiffness of the drive rod between shaker and force gauge, which the gauge does not measure.

    A stinger is meant to pass only an axial force; with the force gauge at the structure (Ewins,
    *Modal Testing: Theory, Practice and Application*, 2000, sec. 3.6) its axial stiffness and the
    shaker sit behind the gauge and change the force, not the measured FRF, while its bending and
    torsion restrain the drive point unmeasured: a short or thick rod stiffens the modes that move or
    rotate the drive point across the drive axis. Modelled as a round rod of length ``length``
    clamped in the armature (:func:`~robustctl.physical.structure_base.stinger_stiffness`), one
    parameter: its lateral stiffness ``k = 12 E I / L^3``. Made at every point force of a frame, and
    of a matrix or FE model whose drive DOF is labelled ``"node:direction"``; the mass between gauge
    and structure is the drive point's :class:`~robustctl.physical.effects.structural.AddedMass`
    (and :class:`TransducerMass` with the drive points).

    Parameters
    ----------
    location : str
        The drive point (node or DOF).
    drive : str
        The force input the stinger carries.
    stiffness : float
        Lateral stiffness ``12 E I / L^3`` in N/m (neutral 0: an ideal stinger).
    length : float
        The rod's free length in m (default :data:`~robustctl.physical.structure_base.STINGER_LENGTH`).
    """

    drive: str = ""
    stiffness: float = 0.0
    length: float = STINGER_LENGTH

    kind: ClassVar[str] = "stinger"
    sweep: ClassVar[str | None] = "structure"
    calibration: ClassVar[str] = "shift"
    _value_fields: ClassVar[tuple[str, ...]] = ("stiffness",)

    def __post_init__(self) -> None:
        if not self.drive or not (np.isfinite(float(self.length)) and float(self.length) > 0):
            raise ModelError(f"a stinger needs the force input it carries (drive=) and a length > 0 (m); got "
                             f"drive={self.drive!r}, length={self.length!r}.")
        super().__post_init__()

    @classmethod
    def candidates_at(cls, ctx, where):
        """One per point force whose drive point can carry one (a frame node; a matrix DOF labelled
        ``"node:direction"``), at :data:`~robustctl.physical.structure_base.STINGER_LENGTH`."""
        out = []
        for name in _structure_signals(ctx.model, "input"):
            loc = ctx.structure.signal_location("input", name)
            if loc is None or not _carries_stinger(ctx.structure, name):
                continue
            out.append(cls(loc, drive=name))
        return out

    @property
    def name(self) -> str:
        return f"stinger restraint of {self.drive} at {self._at()}"

    @property
    def description(self) -> str:
        return (f"The drive rod of {self.drive} restrains {self._at()} across its axis and in rotation, "
                "unmeasured by the force gauge: stiffens the modes that move the drive point sideways or "
                "rotate it.")

    def _suffix(self) -> str:
        return "__" + _slug(self.drive)

    def _check_location(self, model):
        struct = model.build_structure()
        if (self.drive not in struct.matrices().inputs
                or struct.signal_location("input", self.drive) != self.location):
            raise ModelError(f"{self.kind}: the model has no point force {self.drive!r} at "
                             f"{self.location!r}.")
        if not _carries_stinger(struct, self.drive):
            raise ModelError(f"{self.kind}: the drive point of {self.drive!r} cannot carry a stinger (a "
                             "frame's point force, or a matrix DOF labelled 'node:direction').")

    def _specs(self):
        return [ParamSpec(base="stinger_stiffness", unit="N/m", bounds=(0.0, 1e12), neutral=0.0,
                          default_scale=100.0,
                          meaning=f"lateral stiffness 12 E I / L^3 of the stinger of {self.drive} "
                                  f"(L = {self.length:g} m)")]

    def _stage_fn(self):
        pname, drive, length = self.param_names[0], self.drive, float(self.length)

        def fn(theta, struct):
            k = float(theta[pname])
            return struct if k == 0.0 else struct.add_stinger(drive, k, length)

        return fn

    def changes_preload(self, gravity_direction) -> bool:
        """Its lateral springs carry weight whenever gravity has a component across the drive axis,
        which the effect does not know without the structure: taken as changing the preload."""
        return True

    def phrase(self) -> str:
        return (f"a stinger of {self.describe_value()} lateral stiffness on {self.drive} at {self._at()} "
                f"({self.length * 1e3:.3g} mm rod)")


def _carries_stinger(struct, name: str) -> bool:
    """Whether force input ``name`` of ``struct`` can carry a stinger (its ``add_stinger`` works at a unit
    stiffness on a copy)."""
    copy = struct.copy() if hasattr(struct, "copy") else struct.without(())
    try:
        copy.add_stinger(name, 1.0)
    except ModelError:
        return False
    return True


__all__ = ["TransducerMass", "AttachedResonator", "DofPairJoint", "SupportFlexibility", "JointDamping",
           "FrameJointDamping", "DofSupportFlexibility", "StingerConstraint", "RESONATORS_PER_OCTAVE",
           "RESONATORS_MAX"]
