"""Test-setup errors: swapped cables, a sign flip, a units slip, a sensor or actuator elsewhere.

The commonest errors of a real modal test are not in the structure but in its instrumentation:
two cables plugged into each other's channels, a sensor mounted upside down, a channel
calibrated in g while the model reads m/s^2, a sensor on the neighbouring node or along another
axis. Each is a *switched* effect (``switch = True``): a parameter ``t`` in [0, 1], neutral 0
(the setup as modelled), whose state 1 is the error (a units slip's parameter is the factor
itself, neutral 1, states the usual slips). ``rc.diagnose`` screens a switched effect at its
:attr:`~robustctl.physical.effects.base.Effect.states` and fits the update parameters with the
state set; intermediate values are a continuous blend (a partial swap mixes the two channels),
used only to keep the parameter continuous.

Signals change through :mod:`robustctl.signals` (rows of ``C``, ``D`` or columns of ``B``,
``D``); a moved sensor or actuator through
:meth:`~robustctl.physical.structure_base.Structure.move_signal` (a frame node and direction, a
matrix model's DOF).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from ...errors import ModelError
from ...signals import abcd_matrices, named_statespace, signal_index
from ..model import PhysicalModel
from .base import CandidateContext, Effect, ParamSpec, _require, _signals, _slug, _structure_info

#: Units slips tried per channel, with what each usually is.
UNIT_SLIPS: tuple[tuple[float, str], ...] = (
    (9.81, "g read as m/s^2"),
    (1.0 / 9.81, "m/s^2 read as g"),
    (1000.0, "mm read as m, or mV as V"),
    (1e-3, "m read as mm, or V as mV"),
    (2.0 * math.pi, "Hz read as rad/s"),
    (1.0 / (2.0 * math.pi), "rad/s read as Hz"),
)


def _mix(sys, side: str, idx: list[int], T: np.ndarray):
    """``sys`` with rows (``side="output"``) or columns (inputs) ``idx`` mixed by ``T``."""
    A, B, C, D = abcd_matrices(sys)
    if side == "output":
        C, D = C.copy(), D.copy()
        C[idx], D[idx] = T @ C[idx], T @ D[idx]
    else:
        B, D = B.copy(), D.copy()
        B[:, idx], D[:, idx] = B[:, idx] @ T.T, D[:, idx] @ T.T
    return named_statespace(A, B, C, D, sys.input_labels, sys.output_labels)


@dataclass(frozen=True)
class _SetupEffect(Effect):
    side: ClassVar[str] = "output"
    switch: ClassVar[bool] = True

    @property
    def states(self) -> tuple[float, ...]:
        """The parameter values that are the error itself (screened by ``rc.diagnose``)."""
        return (1.0,)

    def _labels(self, sys) -> tuple[str, ...]:
        return tuple(sys.output_labels if self.side == "output" else sys.input_labels)

    def _check_location(self, model: PhysicalModel) -> None:
        _require(self.location, _signals(model, self.side), self.side, self)

    @property
    def _channel(self) -> str:
        return "sensor" if self.side == "output" else "actuator"

    def describe_value(self, values=None) -> str:
        vals = self.values if values is None else values
        t = float(vals.get(self.param_names[0], getattr(self, self._value_fields[0])))
        return "yes" if t >= 0.5 else ("no" if t == 0 else f"{100 * t:.3g} % blend")

    def phrase(self) -> str:
        return f"{self.name} ({self.description})"


@dataclass(frozen=True)
class SwappedOutputs(_SetupEffect):
    """Two sensor cables swapped: output ``location`` reads ``partner``'s sensor and vice versa.

    Parameters
    ----------
    location, partner : str
        The two output names.
    swap : float
        0: as modelled; 1: swapped (a blend between).
    """

    partner: str | None = None
    swap: float = 0.0

    kind: ClassVar[str] = "swapped_outputs"
    sweep: ClassVar[str | None] = "signals"

    @classmethod
    def candidates_at(cls, ctx, where):
        """Each pair of channels of its side (neighbours only beyond :data:`ALL_PAIRS_MAX`)."""
        names = ctx.outputs if cls.side == "output" else ctx.inputs
        return [cls(a, partner=b) for a, b in _swap_pairs(names)]
    _value_fields: ClassVar[tuple[str, ...]] = ("swap",)

    @property
    def name(self) -> str:
        return f"{self.side}s {self.location} and {self.partner} swapped"

    @property
    def description(self) -> str:
        return (
            f"The {self._channel} cables of {self.location} and {self.partner} are plugged into each "
            f"other's channels: each {self.side} column of the data belongs to the other {self._channel}."
        )

    def _suffix(self) -> str:
        return f"__{_slug(self.location)}_{_slug(self.partner)}"

    def _check_location(self, model):
        names = _signals(model, self.side)
        _require(self.location, names, self.side, self)
        _require(self.partner, names, self.side, self)
        if self.partner == self.location:
            raise ModelError(f"a swap needs two different {self.side}s; got {self.location!r} twice.")

    def _specs(self):
        return [ParamSpec(base=f"swap_{self.side}s", unit="", bounds=(0.0, 1.0), neutral=0.0,
                          default_scale=1.0,
                          meaning=f"swap of {self.side}s {self.location} and {self.partner} (1: swapped)")]

    def _stage_fn(self):
        pname, pair, side = self.param_names[0], (self.location, self.partner), self.side

        def fn(theta, sys):
            t = float(theta[pname])
            if t == 0.0:
                return sys
            idx = [signal_index(self._labels(sys), p, side) for p in pair]
            return _mix(sys, side, idx, np.array([[1.0 - t, t], [t, 1.0 - t]]))

        return fn


@dataclass(frozen=True)
class SwappedInputs(SwappedOutputs):
    """Two actuator (force) channels swapped; see :class:`SwappedOutputs`."""

    kind: ClassVar[str] = "swapped_inputs"
    side: ClassVar[str] = "input"


@dataclass(frozen=True)
class SensorSignFlip(_SetupEffect):
    """A sensor mounted the other way round (or a cable with its poles swapped): ``y <- -y``.

    Parameters
    ----------
    location : str
        The output name.
    flip : float
        0: as modelled; 1: flipped (the gain is ``1 - 2 flip``).
    """

    flip: float = 0.0

    kind: ClassVar[str] = "sensor_sign"
    sweep: ClassVar[str | None] = "signals"

    @classmethod
    def candidates_at(cls, ctx, where):
        """One per channel of its side."""
        return [cls(n) for n in (ctx.outputs if cls.side == "output" else ctx.inputs)]
    _value_fields: ClassVar[tuple[str, ...]] = ("flip",)

    @property
    def name(self) -> str:
        return f"sign flip of {self.side} {self.location}"

    @property
    def description(self) -> str:
        return (
            f"The {self._channel} of {self.side} {self.location} is mounted the other way round, or its "
            "cable's poles are swapped: the data read minus the response (a phase of 180 degrees)."
        )

    def _specs(self):
        return [ParamSpec(base=f"{self._channel}_sign_flip", unit="", bounds=(0.0, 1.0), neutral=0.0,
                          default_scale=1.0, meaning=f"sign flip of {self.location} (1: flipped)")]

    def _stage_fn(self):
        pname, side = self.param_names[0], self.side

        def fn(theta, sys):
            t = float(theta[pname])
            if t == 0.0:
                return sys
            idx = [signal_index(self._labels(sys), self.location, side)]
            return _mix(sys, side, idx, np.array([[1.0 - 2.0 * t]]))

        return fn


@dataclass(frozen=True)
class ActuatorSignFlip(SensorSignFlip):
    """A force channel (load cell or shaker cable) the other way round; see :class:`SensorSignFlip`."""

    kind: ClassVar[str] = "actuator_sign"
    side: ClassVar[str] = "input"


@dataclass(frozen=True)
class SensorUnits(_SetupEffect):
    """A units or calibration slip of one channel: ``y <- factor y`` with a usual factor.

    Parameters
    ----------
    location : str
        The output name.
    factor : float
        1: as modelled; a slip is one of :data:`UNIT_SLIPS` (9.81: g read as m/s^2 ...).
    """

    factor: float = 1.0

    kind: ClassVar[str] = "sensor_units"
    sweep: ClassVar[str | None] = "signals"
    #: Its states are factors on one channel (screening tries those nearest the channel's offset).
    gain_states: ClassVar[bool] = True

    @classmethod
    def candidates_at(cls, ctx, where):
        """One per channel of its side."""
        return [cls(n) for n in (ctx.outputs if cls.side == "output" else ctx.inputs)]

    def phrase(self) -> str:
        return f"a units slip {self.describe_value()} on {self.side} {self.location}"
    _value_fields: ClassVar[tuple[str, ...]] = ("factor",)

    @property
    def states(self) -> tuple[float, ...]:
        return tuple(f for f, _ in UNIT_SLIPS)

    @property
    def name(self) -> str:
        return f"units slip on {self.side} {self.location}"

    @property
    def description(self) -> str:
        return (
            f"{self.side.capitalize()} {self.location} is scaled by a usual units factor (g vs m/s^2, mm vs "
            "m, Hz vs rad/s): the same magnitude offset at every frequency, no phase change."
        )

    def _specs(self):
        return [ParamSpec(base=f"{self._channel}_units_factor", unit="", bounds=(1e-4, 1e4), neutral=1.0,
                          default_scale=1.0, meaning=f"units factor of {self.location} (1: as modelled)")]

    def _stage_fn(self):
        pname, side = self.param_names[0], self.side

        def fn(theta, sys):
            f = float(theta[pname])
            if f == 1.0:
                return sys
            idx = [signal_index(self._labels(sys), self.location, side)]
            return _mix(sys, side, idx, np.array([[f]]))

        return fn

    def describe_value(self, values=None) -> str:
        vals = self.values if values is None else values
        f = float(vals.get(self.param_names[0], self.factor))
        what = next((w for v, w in UNIT_SLIPS if abs(v - f) <= 1e-9 * v), "")
        return f"x {f:.4g}" + (f" ({what})" if what else "")


@dataclass(frozen=True)
class ActuatorUnits(SensorUnits):
    """A units slip of one force channel; see :class:`SensorUnits`."""

    kind: ClassVar[str] = "actuator_units"
    side: ClassVar[str] = "input"


@dataclass(frozen=True)
class SensorMoved(_SetupEffect):
    """A sensor at another place than modelled: a neighbouring node or DOF, or another direction.

    Parameters
    ----------
    location : str
        The output name.
    to : str
        The node (frame FEM) or DOF label (matrix model) it really sits at.
    direction : str or None
        The axis it really reads along (``"x"``, ``"y"``, ``"z"``; frame FEM), None: as modelled.
    moved : float
        0: as modelled; 1: at ``to`` (a blend between).
    """

    to: str | None = None
    direction: str | None = None
    moved: float = 0.0

    kind: ClassVar[str] = "sensor_moved"
    sweep: ClassVar[str | None] = "signals"

    @classmethod
    def candidates_at(cls, ctx, where):
        """Each structural sensor (actuator) at a neighbouring node or DOF, or along another axis."""
        if ctx.structure is None:
            return []
        return [cls(name, to=to, direction=direction)
                for name in _structure_signals(ctx.model, cls.side)
                for to, direction in ctx.structure.signal_moves(cls.side, name)]
    domain: ClassVar[str] = "structure"
    _value_fields: ClassVar[tuple[str, ...]] = ("moved",)

    @property
    def name(self) -> str:
        where = f" along {self.direction}" if self.direction else ""
        return f"{self.side} {self.location} at {self.to}{where}"

    @property
    def description(self) -> str:
        where = f" along {self.direction}" if self.direction else ""
        return (
            f"The {self._channel} of {self.location} sits at {self.to}{where}, not where the model puts it "
            "(a neighbouring node, or mounted along another axis)."
        )

    def _suffix(self) -> str:
        d = "" if self.direction is None else "_" + _slug(self.direction)
        return f"__{_slug(self.location)}_to_{_slug(self.to)}{d}"

    def _check_location(self, model: PhysicalModel) -> None:
        _require(self.location, _structure_signals(model, self.side), f"structural {self.side}", self)

    def _specs(self):
        return [ParamSpec(base=f"{self._channel}_moved", unit="", bounds=(0.0, 1.0), neutral=0.0,
                          default_scale=1.0, meaning=f"{self.location} at {self.to} (1: moved)")]

    def _stage_fn(self):
        pname, side, to, direction = self.param_names[0], self.side, self.to, self.direction

        def fn(theta, struct):
            t = float(theta[pname])
            if t == 0.0:
                return struct
            return struct.move_signal(side, self.location, to, direction, t)

        return fn


@dataclass(frozen=True)
class ActuatorMoved(SensorMoved):
    """A force applied at another place or along another axis; see :class:`SensorMoved`."""

    kind: ClassVar[str] = "actuator_moved"
    side: ClassVar[str] = "input"


#: Up to this many channels on a side, every pair is a swap candidate; beyond, only channels next
#: to each other in the data's order (neighbouring connectors), so the count grows linearly.
ALL_PAIRS_MAX = 8


def _swap_pairs(names: tuple[str, ...]) -> list[tuple[str, str]]:
    if len(names) <= ALL_PAIRS_MAX:
        return [(a, b) for i, a in enumerate(names) for b in names[i + 1:]]
    return list(zip(names[:-1], names[1:]))


def _structure_signals(model: PhysicalModel, side: str) -> tuple[str, ...]:
    """The sensor (``side="output"``) or force names of the model's structure (before any I/O stage
    renames them: an electronics stage may call an output "S1 (V)")."""
    _structure_info(model)  # a structural model is needed
    info = _structure_info(model)
    key = "structure_" + side
    if key not in info:
        mats = model.build_structure().matrices()
        info["structure_output"], info["structure_input"] = tuple(mats.outputs), tuple(mats.inputs)
    return info[key]


def setup_candidates(model: PhysicalModel) -> list[Effect]:
    """The test-setup errors of ``model``'s channels: swapped pairs (every pair up to
    :data:`ALL_PAIRS_MAX` channels on a side, else neighbours in order), sign flips and units slips of
    every output and input, and (structural models) each sensor and actuator moved to a
    neighbouring node or DOF or turned to another axis
    (:meth:`~robustctl.physical.structure_base.Structure.signal_moves`)."""
    struct = model.build_structure() if model.structure is not None else None
    ctx = CandidateContext(model, _signals(model, "output"), _signals(model, "input"), struct)
    return [c for cls in Effect.registry.values() if issubclass(cls, _SetupEffect) and cls.sweep == "signals"
            for c in cls.candidates_at(ctx, None)]
