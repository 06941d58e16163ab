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

Layout: :mod:`.base` (the ``Effect`` base class and its typed :class:`ParamSpec`),
:mod:`.io_effects`, :mod:`.structural` (with semi-rigid frame joints and hinges), :mod:`.lab` (the
transducers' own mass, attached resonators), :mod:`.setup` (test-setup errors: swapped cables, sign
flips, units slips, a sensor or actuator elsewhere),
:mod:`.catalogue` (candidates and calibration).

Examples
--------
>>> import robustctl as rc
>>> e = rc.effects.OutputDelay(delay=3.6e-3)                       # doctest: +SKIP
>>> model_1g = model.with_effect(e)                                 # doctest: +SKIP
>>> [c.name for c in rc.effects.candidates(model)][:3]              # doctest: +SKIP
['output delay', 'input delay', 'first-order sensor low-pass']
"""

from __future__ import annotations

from ..model import register_effects
from .base import (
    DAMPING_TARGET,
    EFFECT_TAG,
    SHIFT_TARGET,
    Effect,
    ParamSpec,
)
from .catalogue import EFFECT_KINDS, calibrate, candidates
from .io_effects import (
    ActuatorGain,
    ActuatorLowPass,
    InputDelay,
    OutputDelay,
    SensorGain,
    SensorLowPass,
    SensorMisalignment,
)
from .lab import (
    RESONATORS_MAX,
    RESONATORS_PER_OCTAVE,
    AttachedResonator,
    DofPairJoint,
    DofSupportFlexibility,
    FrameJointDamping,
    JointDamping,
    StingerConstraint,
    SupportFlexibility,
    TransducerMass,
)
from .setup import (
    UNIT_SLIPS,
    ActuatorMoved,
    ActuatorSignFlip,
    ActuatorUnits,
    SensorMoved,
    SensorSignFlip,
    SensorUnits,
    SwappedInputs,
    SwappedOutputs,
    setup_candidates,
)
from .structural import (
    AddedMass,
    Dashpot,
    GravityStiffening,
    GroupStiffness,
    GroupTension,
    JointSpring,
    ModalDamping,
    Pendulum,
    SuspensionSpring,
)

__all__ = [
    "Effect",
    "ParamSpec",
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
    "JointSpring",
    "TransducerMass",
    "AttachedResonator",
    "DofPairJoint",
    "SupportFlexibility",
    "JointDamping",
    "FrameJointDamping",
    "DofSupportFlexibility",
    "StingerConstraint",
    "RESONATORS_MAX",
    "RESONATORS_PER_OCTAVE",
    "SwappedOutputs",
    "SwappedInputs",
    "SensorSignFlip",
    "ActuatorSignFlip",
    "SensorUnits",
    "ActuatorUnits",
    "SensorMoved",
    "ActuatorMoved",
    "UNIT_SLIPS",
    "setup_candidates",
    "candidates",
    "calibrate",
    "EFFECT_KINDS",
    "EFFECT_TAG",
    "SHIFT_TARGET",
    "DAMPING_TARGET",
]

register_effects(Effect, candidates)
