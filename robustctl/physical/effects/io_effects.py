"""Input/output effects: delays, sensor and actuator filters, gains and misalignment."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, ClassVar

from ...errors import ModelError
from .. import electronics as el
from ..model import PhysicalModel
from .base import (
    Effect,
    ParamSpec,
    _require,
    _signals,
    _slug,
)


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
    sweep: ClassVar[str | None] = "signals"
    dac_hold: ClassVar[bool] = True
    _value_fields: ClassVar[tuple[str, ...]] = ("delay",)

    @classmethod
    def candidates_at(cls, ctx, where):
        """One delay common to all channels of its side."""
        return [cls()]

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
            ParamSpec(
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
    sweep: ClassVar[str | None] = "signals"
    _value_fields: ClassVar[tuple[str, ...]] = ("time_constant",)
    _what: ClassVar[str] = "sensor"

    @classmethod
    def candidates_at(cls, ctx, where):
        """A first- and a second-order low-pass on all channels of its side."""
        return [cls(order=1), cls(order=2)]

    def phrase(self) -> str:
        return f"a {self.name} at {self.describe_value()}"

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
            ParamSpec(
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
    sweep: ClassVar[str | None] = "signals"
    _value_fields: ClassVar[tuple[str, ...]] = ("error",)

    @classmethod
    def candidates_at(cls, ctx, where):
        """A gain error of each sensor."""
        return [cls(o) for o in ctx.outputs]

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
            ParamSpec(
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
    sweep: ClassVar[str | None] = None  # the force is measured: a gain error is the sensor's or the data's


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
    sweep: ClassVar[str | None] = "signals"
    _value_fields: ClassVar[tuple[str, ...]] = ("angle",)

    @classmethod
    def candidates_at(cls, ctx, where):
        """A common misalignment of each pair of sensors."""
        outs = ctx.outputs
        return [cls(a, partner=b) for i, a in enumerate(outs) for b in outs[i + 1:]]

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
            ParamSpec(
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
