"""Physical effects a model may lack, each a named change with a neutral value.

An :class:`Effect` is a physical mechanism that a model may be missing, written as a
small set of :class:`~robustctl.physical.parameters.Parameter` objects whose *neutral*
value makes the mechanism vanish exactly (delay 0, added mass 0, spring stiffness 0,
filter time constant 0 ...). ``effect.apply(model)`` returns a copy of the
:class:`~robustctl.physical.model.PhysicalModel` with the effect's parameters added and a
build :class:`~robustctl.physical.model.Stage` appended:

* ``domain == "io"`` effects change the input/output model (delays, sensor and actuator
  filters, sensor gain and misalignment); they apply to any model and reuse
  :mod:`robustctl.physical.electronics`;
* ``domain == "structure"`` effects change the structure through the
  :class:`~robustctl.physical.structure_base.Structure` methods (added mass, suspension
  spring or pendulum, dashpot, element-group stiffness, taut-wire tension, gravity
  preload, modal damping of a mode group); they need a structural model.

MACE (Glaese & Miller) builds its 1-g model exactly this way: the 0-g FEM plus suspension
springs and dashpots, gravity stiffening, electronics and a 3.6 ms output delay; the
Caltech truss (Balas & Doyle) explains its FEM error by taut accelerometer wires stiffening
the longerons -- :class:`GroupTension`. :func:`candidates` lists the effects applicable to
a model at every location, with secant steps calibrated on the model so that each
candidate's typical size moves the affected modes by about one percent (used by
:func:`robustctl.diagnose`).

Examples
--------
>>> import robustctl as rc
>>> e = rc.effects.OutputDelay(delay=3.6e-3)                       # doctest: +SKIP
>>> model_1g = model.with_effect(e)                                 # doctest: +SKIP
>>> [c.name for c in rc.effects.candidates(model)][:3]              # doctest: +SKIP
['output delay', 'input delay', 'first-order sensor low-pass']
"""

from __future__ import annotations

import math
import re
import weakref
from abc import ABC, abstractmethod
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field, replace
from typing import Any, ClassVar

import numpy as np

from ..checks import check_band
from ..errors import ModelError
from ..threads import limit_blas
from . import electronics as el
from .model import PhysicalModel, Stage
from .parameters import Parameter

__all__ = [
    "Effect",
    "OutputDelay",
    "InputDelay",
    "SensorLowPass",
    "ActuatorLowPass",
    "SensorGain",
    "ActuatorGain",
    "SensorMisalignment",
    "AddedMass",
    "SuspensionSpring",
    "Pendulum",
    "Dashpot",
    "GroupStiffness",
    "GroupTension",
    "GravityStiffening",
    "ModalDamping",
    "candidates",
    "calibrate",
    "EFFECT_KINDS",
]

#: Tag carried by every effect parameter and stage.
EFFECT_TAG = "effect"
#: Relative change of the most affected squared natural frequency that a calibrated
#: candidate step produces (``candidates``): 2 % in w^2, i.e. about 1 % in frequency.
SHIFT_TARGET = 0.02
#: Damping-ratio change that a calibrated dashpot step produces.
DAMPING_TARGET = 0.005
#: Finite-difference step of an effect parameter at (or near) its neutral value, as a
#: fraction of its typical size ``Effect.scale`` (the secant step of ``diagnose``).
_FD_FRACTION = 0.1
#: Modes used for calibration when no band is given.
_N_CAL_MODES = 12


def _slug(text: str) -> str:
    """``"p2 c"`` -> ``"p2_c"``: a location as a parameter-name suffix."""
    slug = re.sub(r"[^0-9A-Za-z]+", "_", str(text)).strip("_")
    return slug or "x"


# ============================================================================ base class
@dataclass(frozen=True)
class Effect(ABC):
    """A physical effect with parameters that vanish at their neutral value.

    Subclasses are frozen dataclasses whose value fields (``delay``, ``mass`` ...) hold the
    parameter values in SI units; ``location`` names where the effect acts (a node or DOF,
    an element group, a signal) or is ``None`` for a global effect.

    Attributes
    ----------
    location : str or None
        Where the effect acts.
    scale : float or None
        Typical size of the (first) parameter: the secant step from the neutral value that
        ``diagnose`` uses; the parameter's finite-difference ``abs_step`` is a tenth of it.
        ``None`` uses the kind's default; :func:`candidates` calibrates it on the model.
    """

    location: str | None = None
    scale: float | None = field(default=None, kw_only=True, repr=False)

    kind: ClassVar[str] = "effect"
    domain: ClassVar[str] = "io"
    _value_fields: ClassVar[tuple[str, ...]] = ()
    _extra_tags: ClassVar[tuple[str, ...]] = ()

    def __post_init__(self) -> None:
        self.parameters  # noqa: B018 - check the values against their bounds now

    # ---------------------------------------------------------------- description
    @property
    @abstractmethod
    def name(self) -> str:
        """Plain-words name, e.g. ``"added mass at node p2_c"``."""

    @property
    @abstractmethod
    def description(self) -> str:
        """One or two sentences of physics."""

    @abstractmethod
    def _specs(self) -> list[dict[str, Any]]:
        """One dict per value field: base, unit, bounds, neutral, default_scale, meaning."""

    def _suffix(self) -> str:
        return "" if self.location is None else "__" + _slug(self.location)

    # ---------------------------------------------------------------- parameters
    @property
    def parameters(self) -> tuple[Parameter, ...]:
        """The effect's parameters, holding the current values (units in ``Parameter.unit``)."""
        out = []
        for k, (fname, spec) in enumerate(zip(self._value_fields, self._specs())):
            default = spec["default_scale"]
            step = self.scale if (k == 0 and self.scale is not None) else default
            lo, hi = spec["bounds"]
            value = float(getattr(self, fname))
            if not lo <= value <= hi:
                raise ModelError(
                    f"{self.name}: {fname} = {value:g} {spec['unit']} lies outside the admissible "
                    f"range [{lo:g}, {hi:g}]; give a value inside it."
                )
            out.append(
                Parameter(
                    name=spec["base"] + self._suffix(),
                    value=value,
                    unit=spec["unit"],
                    bounds=(lo, hi),
                    rel_step=1e-3,
                    abs_step=_FD_FRACTION * abs(float(step)),
                    meaning=spec["meaning"],
                    tags=(EFFECT_TAG, self.kind) + self._extra_tags,
                    free=spec.get("free", True),
                    neutral=spec["neutral"],
                )
            )
        return tuple(out)

    @property
    def typical_size(self) -> float:
        """Typical size of the first parameter (its secant step from neutral), in its unit."""
        return float(self.scale) if self.scale is not None else float(self._specs()[0]["default_scale"])

    @property
    def param_names(self) -> tuple[str, ...]:
        return tuple(p.name for p in self.parameters)

    @property
    def values(self) -> dict[str, float]:
        """Parameter values by parameter name (``{"added_mass__p2_c": 0.12}``)."""
        return {p.name: p.value for p in self.parameters}

    @property
    def neutral_values(self) -> dict[str, float]:
        """Parameter values at which the effect vanishes."""
        return {p.name: float(p.neutral) for p in self.parameters}

    @property
    def is_neutral(self) -> bool:
        return all(p.value == p.neutral for p in self.parameters)

    def with_values(self, **values: float) -> Effect:
        """A copy with values changed, keyed by parameter name or field name.

        ``AddedMass("p2_c").with_values(added_mass__p2_c=0.1)`` and
        ``.with_values(mass=0.1)`` are the same.
        """
        by_param = dict(zip(self.param_names, self._value_fields))
        changes = {}
        for key, value in values.items():
            fname = by_param.get(key, key if key in self._value_fields else None)
            if fname is None:
                raise ModelError(
                    f"{self.name} has no parameter {key!r}; its parameters are "
                    f"{list(self.param_names)} (or fields {list(self._value_fields)})."
                )
            changes[fname] = float(value)
        return replace(self, **changes)

    def with_scale(self, scale: float) -> Effect:
        """A copy whose secant step (typical size of the first parameter) is ``scale``."""
        return replace(self, scale=float(scale))

    # ---------------------------------------------------------------- application
    def check(self, model: PhysicalModel) -> None:
        """Raise ModelError if the effect cannot act on ``model`` (wrong domain, location)."""
        if not isinstance(model, PhysicalModel):
            raise ModelError(f"effects apply to a PhysicalModel; got {type(model).__name__}.")
        taken = [n for n in self.param_names if n in model.param_names]
        if taken:
            raise ModelError(
                f"the model already has parameter(s) {taken}: {self.name} was applied before. "
                "Change its value with model.with_values(...) instead of adding it twice."
            )
        self._check_location(model)

    def _check_location(self, model: PhysicalModel) -> None:  # noqa: B027 - optional hook
        """Subclasses with a location check it against the model (global effects need not)."""

    def apply(self, model: PhysicalModel) -> PhysicalModel:
        """``model`` with this effect: its parameters added and its build stage appended."""
        self.check(model)
        stage = Stage(self.name, self._stage_fn(), (EFFECT_TAG, self.kind) + self._extra_tags)
        if self.domain == "structure":
            return model.add_structure_stage(stage, self.parameters)
        return model.add_io_stage(stage, self.parameters)

    @abstractmethod
    def _stage_fn(self):
        """The build-stage function ``(theta, structure_or_statespace) -> same`` of this effect."""

    def describe_value(self, values: Mapping[str, float] | None = None) -> str:
        """The effect's size in words (``"3.6 ms"``), from ``values`` or its own."""
        vals = self.values if values is None else values
        spec = self._specs()[0]
        v = float(vals.get(self.param_names[0], getattr(self, self._value_fields[0])))
        return _fmt_quantity(v, spec["unit"])

    def __str__(self) -> str:
        vals = ", ".join(
            f"{k} = {_fmt_quantity(v, p.unit)}" for (k, v), p in zip(self.values.items(), self.parameters)
        )
        return f"{self.name} ({vals})"


def _fmt_quantity(value: float, unit: str) -> str:
    if unit == "s":
        return f"{value * 1e3:.3g} ms"
    if unit == "rad":
        return f"{math.degrees(value):.3g} deg"
    if unit in ("", "1"):
        return f"{value * 100:+.3g} %"
    return f"{value:.3g} {unit}"


# ============================================================================ helpers
_model_info: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


def _structure_info(model: PhysicalModel) -> dict[str, Any]:
    """Locations and element groups of a structural model (cached per model object)."""
    if model.structure is None:
        raise ModelError(
            f"model {model.name!r} has no structural description (it was built from modal data or "
            "a state space), so structural effects cannot act on it; use an input/output effect, or "
            "build the model with rc.structural_model / an example with a structure."
        )
    info = _model_info.setdefault(model, {})
    if "locations" not in info:
        struct = model.build_structure()
        info.update(
            locations=tuple(struct.locations()),
            groups=tuple(struct.element_groups()),
            gravity=type(struct).set_gravity is not _base_set_gravity(),
            gravity_on=getattr(struct, "gravity_enabled", None),
        )
    return info


def _base_set_gravity():
    from .structure_base import Structure

    return Structure.set_gravity


def _signals(model: PhysicalModel, side: str) -> tuple[str, ...]:
    info = _model_info.setdefault(model, {})
    key = "signals_" + side
    if key not in info:
        sys = model.statespace()
        info["signals_output"] = tuple(sys.output_labels)
        info["signals_input"] = tuple(sys.input_labels)
    return info[key]


def _close(name: str, options: Sequence[str]) -> str:
    import difflib

    near = difflib.get_close_matches(str(name), list(options), n=3)
    return f" Did you mean {near}?" if near else ""


def _require(name: str | None, options: Sequence[str], what: str, effect: Effect) -> None:
    if name is None:
        raise ModelError(f"{effect.kind} needs a {what}; choose one of {list(options)}.")
    if name not in options:
        raise ModelError(
            f"unknown {what} {name!r} for {effect.kind}; the model has {what}s {list(options)}."
            + _close(name, options)
        )


# ============================================================================ I/O effects
@dataclass(frozen=True)
class _IOEffect(Effect):
    side: ClassVar[str] = "output"

    def _channels(self, sys: Any) -> tuple[str, ...]:
        labels = sys.output_labels if self.side == "output" else sys.input_labels
        return tuple(labels) if self.location is None else (self.location,)

    def _where(self) -> str:
        plural = "outputs" if self.side == "output" else "inputs"
        return f"all {plural}" if self.location is None else f"{self.side} {self.location}"

    def _check_location(self, model: PhysicalModel) -> None:
        if self.location is not None:
            _require(self.location, _signals(model, self.side), self.side, self)


@dataclass(frozen=True)
class OutputDelay(_IOEffect):
    """A pure time delay on the outputs (Pade approximant), e.g. the sampling delay.

    Parameters
    ----------
    location : str, optional
        An output name; ``None``: the same delay on every output.
    delay : float
        Delay in s (neutral 0). MACE measured 3.6 ms.
    pade_order : int
        Order of the Pade approximant (``electronics.pade_delay``).
    """

    delay: float = 0.0
    pade_order: int = 3

    kind: ClassVar[str] = "output_delay"
    _value_fields: ClassVar[tuple[str, ...]] = ("delay",)

    @property
    def name(self) -> str:
        return f"{self.side} delay" + ("" if self.location is None else f" on {self.location}")

    @property
    def description(self) -> str:
        return (
            f"A time delay on {self._where()} (sampling, computation or transport delay): a phase "
            "lag growing linearly with frequency, magnitude unchanged."
        )

    def _specs(self):
        return [
            dict(
                base=f"{self.side}_delay",
                unit="s",
                bounds=(0.0, 0.1),
                neutral=0.0,
                default_scale=1e-3,
                meaning=f"time delay on {self._where()}",
            )
        ]

    def _stage_fn(self):
        pname, order = self.param_names[0], int(self.pade_order)
        apply = el.delay_outputs if self.side == "output" else el.delay_inputs

        def fn(theta, sys):
            tau = float(theta[pname])
            return sys if tau == 0.0 else apply(sys, self._channels(sys), tau, order)

        return fn


@dataclass(frozen=True)
class InputDelay(OutputDelay):
    """A pure time delay on the inputs (actuator command path); see :class:`OutputDelay`."""

    kind: ClassVar[str] = "input_delay"
    side: ClassVar[str] = "input"


@dataclass(frozen=True)
class SensorLowPass(_IOEffect):
    """A sensor low-pass filter (signal conditioning or sensor dynamics) of order 1 or 2.

    The parameter is the time constant ``tau = 1 / (2 pi f_c)`` (s), neutral 0 (an ideal,
    infinitely fast sensor). Order 1: ``1 / (1 + s tau)``; order 2:
    ``1 / (1 + 2 zeta s tau + (s tau)^2)`` (``zeta = damping``, 0.707 Butterworth).

    Parameters
    ----------
    location : str, optional
        An output name; ``None``: every output.
    order : int
        1 or 2.
    time_constant : float
        ``tau`` in s.
    damping : float
        ``zeta`` of the second-order filter.
    """

    order: int = 1
    time_constant: float = 0.0
    damping: float = 1.0 / math.sqrt(2.0)

    kind: ClassVar[str] = "sensor_lowpass"
    _value_fields: ClassVar[tuple[str, ...]] = ("time_constant",)
    _what: ClassVar[str] = "sensor"

    def __post_init__(self) -> None:
        if self.order not in (1, 2):
            raise ModelError(f"a low-pass effect has order 1 or 2; got {self.order!r}.")
        if not self.damping > 0:
            raise ModelError(f"the low-pass damping ratio must be > 0; got {self.damping!r}.")
        super().__post_init__()

    @property
    def name(self) -> str:
        word = "first" if self.order == 1 else "second"
        where = "" if self.location is None else f" on {self.location}"
        return f"{word}-order {self._what} low-pass{where}"

    @property
    def description(self) -> str:
        shape = (
            "1/(1 + s tau)"
            if self.order == 1
            else f"1/(1 + 2 zeta s tau + (s tau)^2), zeta = {self.damping:.3g}"
        )
        return (
            f"A {self.order}{'st' if self.order == 1 else 'nd'}-order low-pass {shape} on "
            f"{self._where()} ({self._what} dynamics or signal conditioning): magnitude roll-off "
            "and phase lag towards the cutoff 1/(2 pi tau)."
        )

    def _specs(self):
        base = f"{self._what}_lowpass{self.order}_tau"
        return [
            dict(
                base=base,
                unit="s",
                bounds=(0.0, 1.0),
                neutral=0.0,
                default_scale=1e-3,
                meaning=f"time constant 1/(2 pi f_c) of the {self.name}",
            )
        ]

    def _stage_fn(self):
        pname, order, zeta = self.param_names[0], self.order, float(self.damping)
        apply = el.filter_outputs if self.side == "output" else el.filter_inputs

        def fn(theta, sys):
            tau = float(theta[pname])
            if tau == 0.0:
                return sys
            fc = 1.0 / (2.0 * math.pi * tau)
            filt = el.lowpass1(fc) if order == 1 else el.lowpass2(fc, zeta)
            return apply(sys, self._channels(sys), filt)

        return fn

    def describe_value(self, values=None) -> str:
        vals = self.values if values is None else values
        tau = float(vals.get(self.param_names[0], self.time_constant))
        return "no filter" if tau <= 0 else f"{1.0 / (2 * math.pi * tau):.3g} Hz cutoff"


@dataclass(frozen=True)
class ActuatorLowPass(SensorLowPass):
    """An actuator low-pass (amplifier or smoothing filter) on the inputs; see :class:`SensorLowPass`."""

    kind: ClassVar[str] = "actuator_lowpass"
    side: ClassVar[str] = "input"
    _what: ClassVar[str] = "actuator"


@dataclass(frozen=True)
class SensorGain(_IOEffect):
    """A relative gain error of one sensor (calibration): ``y <- (1 + error) y``.

    Parameters
    ----------
    location : str
        The output name.
    error : float
        Relative gain error (dimensionless, neutral 0).
    """

    error: float = 0.0

    kind: ClassVar[str] = "sensor_gain"
    _value_fields: ClassVar[tuple[str, ...]] = ("error",)

    @property
    def name(self) -> str:
        return f"{'sensor' if self.side == 'output' else 'actuator'} gain error on {self.location}"

    @property
    def description(self) -> str:
        return (
            f"A calibration error of the gain of {self._where()}: the same relative magnitude "
            "error at every frequency, no phase change."
        )

    def _check_location(self, model):
        _require(self.location, _signals(model, self.side), self.side, self)

    def _specs(self):
        return [
            dict(
                base=f"{'sensor' if self.side == 'output' else 'actuator'}_gain_error",
                unit="",
                bounds=(-0.9, 2.0),
                neutral=0.0,
                default_scale=0.05,
                meaning=f"relative gain error of {self._where()}",
            )
        ]

    def _stage_fn(self):
        pname = self.param_names[0]
        scale = el.scale_outputs if self.side == "output" else el.scale_inputs

        def fn(theta, sys):
            err = float(theta[pname])
            return sys if err == 0.0 else scale(sys, {self.location: 1.0 + err})

        return fn


@dataclass(frozen=True)
class ActuatorGain(SensorGain):
    """A relative gain error of one actuator channel; see :class:`SensorGain`."""

    kind: ClassVar[str] = "actuator_gain"
    side: ClassVar[str] = "input"


@dataclass(frozen=True)
class SensorMisalignment(_IOEffect):
    """Two sensors turned by a common angle: ``[y_a, y_b] <- R(angle) [y_a, y_b]``.

    Parameters
    ----------
    location : str
        Output ``a``.
    partner : str
        Output ``b``.
    angle : float
        Misalignment angle in rad (neutral 0).
    """

    partner: str | None = None
    angle: float = 0.0

    kind: ClassVar[str] = "sensor_misalignment"
    _value_fields: ClassVar[tuple[str, ...]] = ("angle",)

    @property
    def name(self) -> str:
        return f"misalignment of sensors {self.location} and {self.partner}"

    @property
    def description(self) -> str:
        return (
            f"Sensors {self.location} and {self.partner} read along axes turned by a small angle: "
            "each picks up a little of the other's motion (cross-talk), changing zeros more "
            "than poles."
        )

    def _suffix(self) -> str:
        return f"__{_slug(self.location)}_{_slug(self.partner)}"

    def _check_location(self, model):
        outs = _signals(model, "output")
        _require(self.location, outs, "output", self)
        _require(self.partner, outs, "output", self)
        if self.partner == self.location:
            raise ModelError(f"a misalignment needs two different sensors; got {self.location!r} twice.")

    def _specs(self):
        return [
            dict(
                base="sensor_misalignment",
                unit="rad",
                bounds=(-0.5, 0.5),
                neutral=0.0,
                default_scale=math.radians(2.0),
                meaning=f"misalignment angle of {self.location}/{self.partner}",
            )
        ]

    def _stage_fn(self):
        pname, pair = self.param_names[0], (self.location, self.partner)

        def fn(theta, sys):
            ang = float(theta[pname])
            return sys if ang == 0.0 else el.misalign_outputs(sys, pair, ang)

        return fn


# ============================================================================ structural effects
@dataclass(frozen=True)
class _StructEffect(Effect):
    domain: ClassVar[str] = "structure"
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
    _value_fields: ClassVar[tuple[str, ...]] = ("mass",)

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
            dict(
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
    _value_fields: ClassVar[tuple[str, ...]] = ("stiffness",)
    _extra_tags: ClassVar[tuple[str, ...]] = ("suspension",)

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
            dict(
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
    _value_fields: ClassVar[tuple[str, ...]] = ("damping",)

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
            dict(
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
    _value_fields: ClassVar[tuple[str, ...]] = ("stiffness",)
    _extra_tags: ClassVar[tuple[str, ...]] = ("suspension",)

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
            dict(
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
    _value_fields: ClassVar[tuple[str, ...]] = ("change",)
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
            dict(
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
    _value_fields: ClassVar[tuple[str, ...]] = ("tension",)
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
        _require(self.location, _structure_info(model)["groups"], "element group", self)

    def _specs(self):
        return [
            dict(
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
    _value_fields: ClassVar[tuple[str, ...]] = ("switch",)
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
            dict(
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
    """A relative change of the modal damping ratios of the modes in a frequency band.

    Parameters
    ----------
    lo_hz, hi_hz : float
        The band in Hz holding the mode group.
    change : float
        Relative change (``zeta <- (1 + change) zeta``; neutral 0).
    """

    lo_hz: float = 0.0
    hi_hz: float = math.inf
    change: float = 0.0

    kind: ClassVar[str] = "modal_damping"
    _value_fields: ClassVar[tuple[str, ...]] = ("change",)

    def __post_init__(self) -> None:
        if not 0 <= self.lo_hz < self.hi_hz:
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
        return f"__{_slug(f'{self.lo_hz:.3g}')}_{_slug(f'{self.hi_hz:.3g}')}Hz"

    def _specs(self):
        return [
            dict(
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

        def fn(theta, struct):
            c = float(theta[pname])
            return struct if c == 0.0 else struct.scale_modal_damping(lo, hi, 1.0 + c)

        return fn


#: Every effect class by kind.
EFFECT_KINDS: dict[str, type[Effect]] = {
    cls.kind: cls
    for cls in (
        OutputDelay,
        InputDelay,
        SensorLowPass,
        ActuatorLowPass,
        SensorGain,
        ActuatorGain,
        SensorMisalignment,
        AddedMass,
        SuspensionSpring,
        Dashpot,
        Pendulum,
        GroupStiffness,
        GroupTension,
        GravityStiffening,
        ModalDamping,
    )
}


# ============================================================================ candidates
def _io_candidates(model: PhysicalModel) -> list[Effect]:
    outs = _signals(model, "output")
    cands: list[Effect] = [
        OutputDelay(),
        InputDelay(),
        SensorLowPass(order=1),
        SensorLowPass(order=2),
        ActuatorLowPass(order=1),
        ActuatorLowPass(order=2),
    ]
    cands += [SensorGain(o) for o in outs]
    cands += [SensorMisalignment(a, partner=b) for i, a in enumerate(outs) for b in outs[i + 1 :]]
    return cands


_DIR_RE = re.compile(r"^(?:node\s+)?(?P<loc>.+?)[\s_:/-]+u?(?P<dir>[xyz])$")


def _directions(labels: Sequence[str], locations: Sequence[str]) -> dict[str, list[str | None]]:
    """Translational directions present per location, read from the DOF labels.

    A location whose DOF label is the location itself (``"dof 3"``) is scalar (``[None]``).
    """
    out: dict[str, list[str | None]] = {loc: [] for loc in locations}
    for lab in labels:
        if lab in out:
            out[lab] = [None]
            continue
        m = _DIR_RE.match(lab)
        if m and m.group("loc") in out and m.group("dir") not in out[m.group("loc")]:
            out[m.group("loc")].append(m.group("dir"))
    directed = any(d is not None for dirs in out.values() for d in dirs)
    # A location without DOFs of its own (a rigid-link slave) takes the model's directions.
    default: list[str | None] = ["x", "y", "z"] if directed else [None]
    return {loc: (dirs or list(default)) for loc, dirs in out.items()}


def _structure_candidates(model: PhysicalModel, include_points: bool) -> list[Effect]:
    info = _structure_info(model)
    struct = model.build_structure()
    mats = struct.matrices()
    cands: list[Effect] = []
    if include_points:
        dirs = _directions(mats.dof_labels, info["locations"])
        for loc in info["locations"]:
            cands.append(AddedMass(loc))
            for d in dirs[loc]:
                cands.append(SuspensionSpring(loc, direction=d))
            for d in dirs[loc]:
                cands.append(Dashpot(loc, direction=d))
            if info["gravity_on"] and {"x", "y"} <= set(dirs[loc]):  # a hanging rod needs gravity
                cands.append(Pendulum(loc))
    for group in info["groups"]:
        cands += [GroupStiffness(group), GroupTension(group)]
    if info["gravity"]:  # only the switch that changes the model's current state
        state = info["gravity_on"]
        cands += [GravityStiffening(enabled=on) for on in (True, False) if state is None or on != state]
    return cands


def _modal_damping_candidates(f_modes: np.ndarray, band: tuple[float, float] | None) -> list[Effect]:
    f = np.asarray(f_modes, dtype=float)
    f = f[f > 0]
    if band is not None:
        f = f[(f >= band[0]) & (f <= band[1])]
    if f.size == 0:
        return []
    groups, start = [], f[0]
    cur = [f[0]]
    for fk in f[1:]:  # octave-wide groups
        if fk <= 2.0 * start:
            cur.append(fk)
        else:
            groups.append(cur)
            cur, start = [fk], fk
    groups.append(cur)
    return [ModalDamping(lo_hz=0.97 * g[0], hi_hz=1.03 * g[-1]) for g in groups]


@limit_blas
def candidates(
    model: PhysicalModel,
    *,
    band: tuple[float, float] | None = None,
    kinds: Iterable[str] | None = None,
    points: bool = True,
    locations: Iterable[str] | None = None,
    calibrate: bool = True,
) -> list[Effect]:
    """The effects applicable to ``model``, one per kind and location, at their neutral value.

    I/O effects (delays, first- and second-order sensor and actuator low-passes on all
    channels, a gain error per sensor, a misalignment per sensor pair) apply to any model.
    Structural effects need a structural model: an added mass, a suspension spring and a
    dashpot per location and direction (nodes of the frame FEM, each DOF of a user's
    matrices), a suspension pendulum (horizontal x-y stiffness) per node of a structure
    under gravity, a stiffness change and a tension per element group, gravity preload
    on/off (frame FEM), and a modal damping change per octave-wide group of modes.

    Parameters
    ----------
    model : PhysicalModel
    band : (float, float), optional
        Frequency band in Hz of interest: modal damping groups and step calibration use
        the modes inside it.
    kinds : iterable of str, optional
        Keep only these kinds (see :data:`EFFECT_KINDS`).
    points : bool
        Include the point effects (mass, spring, dashpot at every location).
    locations : iterable of str, optional
        Put point effects only at these locations (e.g. where hardware sits); default all.
    calibrate : bool
        Set each structural candidate's secant step (``Effect.scale``) so that it changes
        the most affected modal ``w^2`` by :data:`SHIFT_TARGET` (a dashpot: the damping
        ratio by :data:`DAMPING_TARGET`), from one eigensolution and one assembly per
        candidate (first-order perturbation, ``dw^2 = phi^T (dK - w^2 dM) phi``).

    Returns
    -------
    list of Effect
    """
    if not isinstance(model, PhysicalModel):
        raise ModelError(f"candidates needs a PhysicalModel; got {type(model).__name__}.")
    band = check_band(band)
    if kinds is not None:
        kinds = set(kinds)
        unknown = sorted(kinds - set(EFFECT_KINDS))
        if unknown:
            raise ModelError(f"unknown effect kinds {unknown}; known kinds: {sorted(EFFECT_KINDS)}.")
    cands = _io_candidates(model)
    if model.structure is not None:
        cands += _structure_candidates(model, points)
        if locations is not None:
            cands = _at_locations(model, cands, locations)
        if kinds is not None:
            cands = [c for c in cands if c.kind in kinds]
        if calibrate:
            omega, _, cands = _calibrate(model, cands, band)
        else:
            omega = _modes(model, band)[0]
        cands += _modal_damping_candidates(omega / (2 * np.pi), band)
    taken = set(model.param_names)
    cands = [c for c in cands if not taken.intersection(c.param_names)]
    if kinds is not None:
        cands = [c for c in cands if c.kind in kinds]
    return cands


_POINT_KINDS = ("added_mass", "suspension_spring", "dashpot", "pendulum")


def _at_locations(model: PhysicalModel, cands: list[Effect], locations: Iterable[str]) -> list[Effect]:
    """Keep point effects only at ``locations`` (checked against the model)."""
    locations = (locations,) if isinstance(locations, str) else tuple(locations)
    known = _structure_info(model)["locations"]
    for loc in locations:
        if loc not in known:
            raise ModelError(
                f"unknown location {loc!r}; the model has locations {list(known)}." + _close(loc, known)
            )
    return [c for c in cands if c.kind not in _POINT_KINDS or c.location in locations]


# ---------------------------------------------------------------------------- calibration
def _dense(a) -> np.ndarray:
    return a.toarray() if hasattr(a, "toarray") else np.asarray(a, dtype=float)


def _modes(model: PhysicalModel, band):
    from .eigen import solve_modes

    mats = model.build_structure().matrices()
    M, K = _dense(mats.mass), _dense(mats.stiffness)
    omega, phi = solve_modes(M, K)
    keep = omega > 0
    if band is not None:
        f = omega / (2 * np.pi)
        inside = keep & (f >= band[0]) & (f <= band[1])
        keep = inside if np.any(inside) else keep
    idx = np.flatnonzero(keep)[:_N_CAL_MODES] if band is None else np.flatnonzero(keep)
    return omega[idx], phi[:, idx], (M, K, mats)


@limit_blas
def calibrate(
    model: PhysicalModel, effects: Sequence[Effect], band: tuple[float, float] | None = None
) -> list:
    """Structural effects with secant steps calibrated on ``model`` (I/O effects unchanged).

    Each structural effect's ``scale`` becomes the size that changes the most affected
    modal ``w^2`` (modes in ``band`` Hz, else the lowest 12) by :data:`SHIFT_TARGET` to
    first order (a dashpot: a damping ratio by :data:`DAMPING_TARGET`); effects that cannot
    change the modes at all (a spring on a clamped node) are dropped.

    Parameters
    ----------
    model : PhysicalModel
    effects : sequence of Effect
    band : (float, float), optional
        Hz.

    Returns
    -------
    list of Effect
    """
    if model.structure is None or not any(e.domain == "structure" for e in effects):
        return list(effects)
    return _calibrate(model, list(effects), band)[2]


def _calibrate(model: PhysicalModel, cands: list[Effect], band) -> tuple[np.ndarray, np.ndarray, list]:
    """Give each structural candidate a secant step that moves the modes by about 1 %."""
    omega, phi, (M0, K0, mats0) = _modes(model, band)
    if omega.size == 0:
        return omega, phi, cands
    out = []
    for c in cands:
        if c.domain != "structure" or c.kind == "gravity":
            out.append(c)
            continue
        unit = 1.0 if c.kind not in ("group_stiffness",) else 0.1
        probe = c.with_values(**{c._value_fields[0]: unit})
        struct = model.build_structure()
        mats = probe._stage_fn()({probe.param_names[0]: unit}, struct).matrices()
        if mats.n_dof != M0.shape[0]:
            out.append(c)
            continue
        dM = _dense(mats.mass) - M0
        dK = _dense(mats.stiffness) - K0
        if c.kind == "dashpot":
            C = _dense(mats.damping) if mats.damping is not None else np.zeros_like(M0)
            C0 = _dense(mats0.damping) if mats0.damping is not None else np.zeros_like(M0)
            dz = np.abs(np.einsum("ij,ik,kj->j", phi, C - C0, phi)) / (2 * omega) / unit
            size = DAMPING_TARGET / dz.max() if dz.max() > 0 else None
        else:
            dw2 = (
                np.abs(
                    np.einsum("ij,ik,kj->j", phi, dK, phi) - omega**2 * np.einsum("ij,ik,kj->j", phi, dM, phi)
                )
                / unit
            )
            rel = dw2 / omega**2
            size = SHIFT_TARGET / rel.max() if rel.max() > 0 else None
        if size is None or not np.isfinite(size):
            continue  # the effect cannot change this model's modes (e.g. a spring on a clamped node)
        lo, hi = c.parameters[0].bounds
        size = min(size, 0.5 * (hi - lo) if np.isfinite(hi - lo) else size)
        out.append(c.with_scale(size))
    return omega, phi, out
