"""The Effect base class and its typed parameter spec (:class:`ParamSpec`)."""

from __future__ import annotations

import math
import re
import weakref
from abc import ABC, abstractmethod
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace
from typing import Any, ClassVar

from ...errors import ModelError
from ..model import PhysicalModel, Stage
from ..parameters import Parameter
from ..structure_base import Structure

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


@dataclass(frozen=True)
class ParamSpec:
    """The typed description of one effect parameter (what ``Effect._specs`` returns, one per
    value field).

    Attributes
    ----------
    base : str
        Parameter name before the location suffix (``"added_mass"`` -> ``added_mass__p2_c``).
    unit : str
        SI unit of the value.
    bounds : (float, float)
        Admissible range.
    neutral : float
        The value at which the effect vanishes exactly.
    default_scale : float
        Typical size (the secant step from neutral) when the effect is not calibrated.
    meaning : str
        One line of physics.
    free : bool
        Whether updating may change it.
    """

    base: str
    unit: str
    bounds: tuple[float, float]
    neutral: float
    default_scale: float
    meaning: str
    free: bool = True


#: The places where candidates are made, in the order :func:`candidates` visits them:
#: ``"signals"`` once per model (input/output and test-setup effects), ``"location"`` at each
#: node or DOF, ``"joint"`` at each beam joint of a frame, ``"group"`` at each element group,
#: ``"structure"`` once per structural model, ``"modes"`` once per group of modes in the band.
SWEEPS = ("signals", "location", "joint", "group", "structure", "modes")
#: How a candidate's step is calibrated (:attr:`Effect.calibration`).
CALIBRATIONS = ("shift", "damping", "none")


@dataclass(frozen=True)
class CandidateContext:
    """What candidate generation knows of a model: its signals and, for a structural model, its
    structure's locations, translational directions per location, joints, groups and gravity.

    Attributes
    ----------
    model : PhysicalModel
    outputs, inputs : tuple of str
        The model's output and input names.
    structure : Structure or None
        The built structure (None: a model without one).
    info : dict
        :func:`_structure_info` of the model (empty without a structure).
    directions : dict
        Translational directions per location (``[None]`` for a scalar DOF).
    modes : tuple
        ``(f_hz, number)`` of the modes in the band (the ``"modes"`` sweep), or empty.
    band : (float, float) or None
        The frequency band of interest in Hz, when the caller gave one.
    joints : dict
        Joints the user named in a matrix model: ``name -> (dof_a, dof_b, k0)``.
    supports : dict
        Supports the user named in a matrix model: ``name -> (dofs, k0s)`` (DOF labels and the
        grounded stiffness the model has at each).
    """

    model: PhysicalModel
    outputs: tuple[str, ...]
    inputs: tuple[str, ...]
    structure: Any = None
    info: Mapping[str, Any] = field(default_factory=dict)
    directions: Mapping[str, Any] = field(default_factory=dict)
    modes: tuple = ()
    band: tuple[float, float] | None = None
    joints: Mapping[str, tuple[str, str, float]] = field(default_factory=dict)
    supports: Mapping[str, tuple[tuple[str, ...], tuple[float, ...]]] = field(default_factory=dict)

    def places(self, sweep: str) -> tuple:
        """The places of one sweep (see :data:`SWEEPS`)."""
        if sweep == "signals":
            return (None,)
        if self.structure is None:
            return ()
        if sweep == "location":
            return tuple(self.info["locations"])
        if sweep == "joint":
            joints = getattr(self.structure, "joints", None)
            return tuple(joints()) if joints is not None else ()
        if sweep == "group":
            return tuple(self.info["groups"])
        return (None,) if sweep == "structure" or self.modes else ()


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


def article(size: str) -> str:
    """``"a"`` or ``"an"`` before a number written out (``"an 8 ms"``, ``"an 11 %"``)."""
    return "an" if size[:1] == "8" or size[:2] in ("11", "18") else "a"


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
    #: A switched effect has discrete states (:attr:`states`) rather than a size: a test-setup error.
    switch: ClassVar[bool] = False
    #: An on/off change of the model's own state (gravity preload): not fitted, compared as is.
    toggle: ClassVar[bool] = False
    #: Where :func:`~robustctl.physical.effects.candidates` makes candidates of this kind: one of
    #: :data:`SWEEPS` (:meth:`candidates_at` is called once per place of that sweep), or None
    #: (made by hand only).
    sweep: ClassVar[str | None] = None
    #: How the candidate step is calibrated on the model: ``"shift"`` (the most affected modal
    #: ``w^2`` by :data:`SHIFT_TARGET`), ``"damping"`` (a damping ratio by :data:`DAMPING_TARGET`)
    #: or ``"none"`` (the step set when the candidate is made, or a switch).
    calibration: ClassVar[str] = "none"
    #: Parameter value of the calibration probe (the change is assumed linear up to it).
    calibration_unit: ClassVar[float] = 1.0
    #: The reduced path's closed form: a constant ``(mass, stiffness, damping)`` per unit of the one
    #: parameter on one DOF (kg, N/m, N s/m), or None when the effect is not such a point change.
    point_unit: ClassVar[tuple[float, float, float] | None] = None
    #: A delay of about half a sample is named as the DAC's zero-order hold.
    dac_hold: ClassVar[bool] = False
    #: A switched effect whose states are factors on one channel (a units slip).
    gain_states: ClassVar[bool] = False
    #: First order says nothing at the neutral value (the effect's shape changes with its size: a
    #: joint from rigid to pinned, an added mode): screened at sizes a decade apart over its range.
    coarse_screen: ClassVar[bool] = False
    #: A second value field whose value the screening chooses (None: none): an attached resonator's
    #: frequency, which first order at mass 0 sees only at that frequency. ``rc.diagnose`` screens the
    #: candidate with it at the peaks of the misfit (:meth:`retuned`) and fits it with the size.
    retune: ClassVar[str | None] = None
    _value_fields: ClassVar[tuple[str, ...]] = ()
    _extra_tags: ClassVar[tuple[str, ...]] = ()
    #: Every concrete effect class by kind, in the order the classes were defined (filled by
    #: ``__init_subclass__``; candidates are made in this order).
    registry: ClassVar[dict[str, type[Effect]]] = {}

    def __init_subclass__(cls, **kwargs: Any) -> None:
        """Register a concrete effect class (one that names its own ``kind``) by that kind."""
        super().__init_subclass__(**kwargs)
        if cls.__name__.startswith("_") or "kind" not in cls.__dict__:
            return
        if cls.sweep is not None and cls.sweep not in SWEEPS:
            raise ModelError(f"effect class {cls.__name__}: sweep {cls.sweep!r} is not one of {SWEEPS}.")
        if cls.calibration not in CALIBRATIONS:
            raise ModelError(
                f"effect class {cls.__name__}: calibration {cls.calibration!r} is not one of {CALIBRATIONS}."
            )
        known = Effect.registry.get(cls.kind)
        if known is not None and known.__qualname__ != cls.__qualname__:
            raise ModelError(
                f"effect kind {cls.kind!r} of {cls.__name__} is already taken by {known.__name__}; "
                "give the new class a kind of its own."
            )
        Effect.registry[cls.kind] = cls

    @classmethod
    def candidates_at(cls, ctx: CandidateContext, where: Any) -> list[Effect]:
        """The candidates of this kind at one place ``where`` of its :attr:`sweep` (a location, a
        joint, a group, or None for the sweeps over the whole model), at their neutral value."""
        return []

    def phrase(self) -> str:
        """The effect with its size in words: ``"a 3.6 ms output delay"``."""
        size = self.describe_value()
        return f"{article(size)} {size} {self.name}"

    def changes_preload(self, gravity_direction: Any) -> bool:
        """Whether the effect changes a frame's gravity preload to first order (more weight in the
        suspension, or a spring that takes some of it); ``gravity_direction`` is a unit 3-vector."""
        return False

    @property
    def states(self) -> tuple[float, ...]:
        """The values of a switched effect's parameter that are the effect itself (empty: a size)."""
        return ()

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
    def _specs(self) -> list[ParamSpec]:
        """One :class:`ParamSpec` per value field."""

    def _suffix(self) -> str:
        return "" if self.location is None else "__" + _slug(self.location)

    # ---------------------------------------------------------------- parameters
    @property
    def parameters(self) -> tuple[Parameter, ...]:
        """The effect's parameters, holding the current values (units in ``Parameter.unit``).

        Made once per (frozen) effect: a diagnosis asks each candidate for them many times."""
        found = self.__dict__.get("_parameters")
        if found is None:
            found = self._make_parameters()
            object.__setattr__(self, "_parameters", found)
        return found

    def _make_parameters(self) -> tuple[Parameter, ...]:
        out = []
        for k, (fname, spec) in enumerate(zip(self._value_fields, self._specs())):
            default = spec.default_scale
            step = self.scale if (k == 0 and self.scale is not None) else default
            lo, hi = spec.bounds
            value = float(getattr(self, fname))
            if not lo <= value <= hi:
                raise ModelError(
                    f"{self.name}: {fname} = {value:g} {spec.unit} lies outside the admissible "
                    f"range [{lo:g}, {hi:g}]; give a value inside it."
                )
            out.append(
                Parameter(
                    name=spec.base + self._suffix(),
                    value=value,
                    unit=spec.unit,
                    bounds=(lo, hi),
                    rel_step=1e-3,
                    abs_step=_FD_FRACTION * abs(float(step)),
                    meaning=spec.meaning,
                    tags=(EFFECT_TAG, self.kind) + self._extra_tags,
                    free=spec.free,
                    neutral=spec.neutral,
                )
            )
        return tuple(out)

    @property
    def typical_size(self) -> float:
        """Typical size of the first parameter (its secant step from neutral), in its unit."""
        return float(self.scale) if self.scale is not None else float(self._specs()[0].default_scale)

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

    def retuned(self, value: float) -> Effect:
        """A copy whose :attr:`retune` field is ``value`` (its parameter's neutral value and its
        name follow); the typical size is kept."""
        if self.retune is None:
            raise ModelError(f"{self.name} has no second value the screening chooses (retune is None).")
        return replace(self, **{self.retune: float(value)})

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
        return _fmt_quantity(v, spec.unit)

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
            tension_groups=tuple(struct.tension_groups()),
            gravity=type(struct).set_gravity is not _base_set_gravity(),
            gravity_on=getattr(struct, "gravity_enabled", None),
        )
    return info


def _base_set_gravity():
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
