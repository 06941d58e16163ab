"""PhysicalModel: named physical parameters plus a staged build ``theta -> StateSpace``.

The build runs four stages, left to right (MACE Fig. 1):

1. ``structure(theta) -> Structure`` — the FE frame or a user's matrices (optional);
2. ``structure_stages`` — physical effects that change the structure (added mass,
   suspension spring, stiffer element group ...);
3. ``dynamics(theta, structure) -> StateSpace`` — the modal state space in physical units
   (MACE eqs. 1-4), or a model built directly from modal data;
4. ``io_stages`` — electronics, servo loops, delays and I/O effects, in order, giving the
   I/O model in volts that the controller sees.

The output of stages 1-3 is cached, keyed on the parameter values those stages actually
read, so that perturbing an electronics parameter (or an I/O effect's) for a sensitivity
does not solve the eigenproblem again.
"""

from __future__ import annotations

import copy
import functools
import math
import threading
import weakref
from collections import OrderedDict
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass, field, replace
from typing import Any

import control
import numpy as np

from ..checks import finite_number
from ..errors import ModelError
from ..lti import freqresp
from ..threads import limit_blas
from .fem import Frame
from .parameters import Parameter
from .structure_base import Structure

__all__ = ["Stage", "PhysicalModel"]

Theta = Mapping[str, float]


@dataclass(frozen=True)
class Stage:
    """One named step of a model build.

    ``fn(theta, x) -> x``: for a structure stage ``x`` is a :class:`Structure`, for an I/O
    stage it is a ``control.StateSpace``. ``tags`` let ``PhysicalModel.without`` drop it.

    Parameters
    ----------
    name : str
        Shown in the model's build list.
    fn : callable ``(theta, x) -> x``
        The step; ``theta`` maps parameter names to values.
    tags : tuple of str
        Labels that :meth:`PhysicalModel.without` removes (e.g. ``"suspension"``).
    """

    name: str
    fn: Callable[[Theta, Any], Any]
    tags: tuple[str, ...] = ()


class _DynamicsCache:
    """A small thread-safe LRU of structural state spaces keyed on the values read.

    It is dropped when a model is pickled (for a process or cluster executor) and starts
    empty on the other side.
    """

    def __init__(self, size: int = 8):
        self._entries: OrderedDict = OrderedDict()
        self._lock = threading.Lock()
        self._size = size

    def lookup(self, theta: Mapping[str, float]) -> Any | None:
        with self._lock:
            for read, vals in reversed(self._entries.keys()):
                if all(theta.get(k) == v for k, v in zip(read, vals)):
                    self._entries.move_to_end((read, vals))
                    return self._entries[(read, vals)]
        return None

    def store(self, read: tuple[str, ...], theta: Mapping[str, float], value: Any) -> None:
        with self._lock:
            self._entries[(read, tuple(theta[k] for k in read))] = value
            while len(self._entries) > self._size:
                self._entries.popitem(last=False)

    def __getstate__(self) -> dict:
        return {"size": self._size}

    def __setstate__(self, state: dict) -> None:
        self.__init__(state["size"])


_MISSING = object()
#: Recently built frames per structure callable: ``(reads, template)``, most recent last.
_BASES: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()
_BASES_LOCK = threading.Lock()
_BASES_KEEP = 4


class _LoggingTheta(Mapping):
    """Passes reads through to ``theta`` and logs each key asked for with what it found
    (``_MISSING`` when absent); iterating over all keys marks the build as not cacheable."""

    def __init__(self, theta: Mapping[str, float]):
        self._theta = theta
        self.log: dict[str, Any] = {}
        self.iterated = False

    def __getitem__(self, key: str) -> float:
        value = self._theta[key]
        self.log[key] = value
        return value

    def get(self, key: str, default: Any = None) -> Any:
        if key in self._theta:
            return self[key]
        self.log[key] = _MISSING
        return default

    def __contains__(self, key: object) -> bool:
        found = key in self._theta
        if not found:
            self.log[key] = _MISSING
        return found

    def __iter__(self):
        self.iterated = True
        return iter(self._theta)

    def __len__(self) -> int:
        self.iterated = True
        return len(self._theta)


def _same_reads(theta: Mapping[str, float], log: dict[str, Any]) -> bool:
    """Whether ``theta`` gives every logged read the same answer (reading it through ``theta``,
    so a recording mapping notes the reads the build would have made)."""
    for key, value in log.items():
        if value is _MISSING:
            if key in theta:
                return False
        elif key not in theta or theta[key] != value:
            return False
    return True


def _base_structure(build: Callable[[Mapping[str, float]], Any], theta: Mapping[str, float]) -> Any:
    """``build(theta)``, or a copy of a frame it built recently from the same parameter values.

    Rebuilding a large :class:`~robustctl.physical.fem.Frame` node by node for every model
    evaluation (a diagnosis makes hundreds, mostly with the base parameters unchanged) costs
    more than a copy; effects then change the copy in place (``Frame.without()`` copies the
    containers and shares the frozen parts). Only frames are reused, and only when the build
    read its parameters by name (the reads, found or missing, are the cache key).
    """
    try:
        with _BASES_LOCK:
            entries = list(_BASES.get(build, ()))
    except TypeError:  # not weak-referenceable
        return build(theta)
    for log, template in reversed(entries):
        if _same_reads(theta, log):
            return template.without()
    logged = _LoggingTheta(theta)
    struct = build(logged)
    if not isinstance(struct, Frame) or logged.iterated:
        return struct
    with _BASES_LOCK:
        kept = _BASES.setdefault(build, [])
        kept.append((dict(logged.log), struct))
        del kept[:-_BASES_KEEP]
    return struct.without()


class _RecordingTheta(Mapping):
    """A read-only parameter mapping that records which keys were read."""

    def __init__(self, values: Mapping[str, float]):
        self._values = values
        self.read: set[str] = set()

    def __getitem__(self, key: str) -> float:
        try:
            value = self._values[key]
        except KeyError:
            raise ModelError(
                f"the model build asked for parameter {key!r}, which the model does not have; "
                f"known parameters: {sorted(self._values)}."
            ) from None
        self.read.add(key)
        return value

    def get(self, key: str, default: Any = None) -> Any:
        """``theta[key]`` (recorded as read) when present, else ``default``: a build may
        read a parameter that ``PhysicalModel.without`` dropped, with a fallback."""
        return self[key] if key in self._values else default

    def __contains__(self, key: object) -> bool:
        return key in self._values

    def __iter__(self):
        return iter(self._values)

    def __len__(self) -> int:
        return len(self._values)


#: Structures handed to a build (id -> weak reference): effects change a structure in place,
#: so a structure callable that returns one shared object would accumulate them build by build.
_HANDED_OUT: dict[int, weakref.ref] = {}
_HANDED_OUT_LOCK = threading.Lock()


def _fresh(struct: Any, name: str) -> Any:
    """``struct`` if no earlier build has seen it; refuses a structure returned twice.

    A structure callable must return a new object per call (build it inside the callable, or
    return ``template.copy()``): effect stages such as an added mass change the structure in
    place, so a shared object would carry the mass of the first build into the second.
    """
    try:
        ref = weakref.ref(struct, functools.partial(_forget, id(struct)))
    except TypeError:  # not weak-referenceable: copy it every time instead
        return copy.deepcopy(struct)
    with _HANDED_OUT_LOCK:
        seen = _HANDED_OUT.get(id(struct))
        if seen is not None and seen() is struct:
            raise ModelError(
                f"the structure callable of model {name!r} returned the same {type(struct).__name__} "
                "object as an earlier build; effects change the structure in place, so an added mass "
                "would count twice. Return a fresh structure on every call (build it inside the "
                "callable, or return template.copy())."
            )
        _HANDED_OUT[id(struct)] = ref
    return struct


def _forget(key: int, ref: weakref.ref) -> None:
    with _HANDED_OUT_LOCK:
        if _HANDED_OUT.get(key) is ref:
            del _HANDED_OUT[key]


def _model_from_bytes(payload: bytes) -> PhysicalModel:
    import pickle

    return PhysicalModel(**pickle.loads(payload))


#: The physical effects stand on the model (:mod:`robustctl.physical.effects` builds on
#: PhysicalModel), so the model does not import them: the effects package registers here what
#: :meth:`PhysicalModel.with_effect` needs, the ``Effect`` class and ``candidates``, when it is
#: imported (``import robustctl`` imports it before any model exists).
_EFFECTS: dict[str, Any] = {}


def register_effects(effect_class: type, candidates: Any) -> None:
    """Register the ``Effect`` base class and the ``candidates`` function (see :data:`_EFFECTS`).

    Parameters
    ----------
    effect_class : type
        :class:`robustctl.physical.effects.Effect`.
    candidates : callable
        :func:`robustctl.physical.effects.candidates`.
    """
    _EFFECTS["Effect"] = effect_class
    _EFFECTS["candidates"] = candidates


@dataclass(frozen=True, eq=False)
class PhysicalModel:
    """A physical model: parameters and a staged build into a ``control.StateSpace``.

    Users rarely build this directly: use :func:`robustctl.structural_model`,
    :func:`robustctl.modal_model` or an example in :mod:`robustctl.examples`.

    Parameters
    ----------
    params : sequence of Parameter
        The model's named physical parameters (unique names).
    dynamics : callable ``(theta, structure_or_None) -> control.StateSpace``
        Builds the structural state space in physical units.
    structure : callable ``theta -> Structure``, optional
        Builds a fresh structure for the parameter values.
    structure_stages, io_stages : sequence of Stage
        Effects and electronics applied in order.
    excluded_tags : set of str
        Tags removed by :meth:`without`.
    name : str
        A short description used in tables and plots.
    meta : mapping
        Free-form facts about the model (e.g. an example's source, reference frequencies and
        sample rate), carried through copies.
    """

    params: tuple[Parameter, ...]
    dynamics: Callable[[Theta, Structure | None], Any]
    structure: Callable[[Theta], Structure] | None = None
    structure_stages: tuple[Stage, ...] = ()
    io_stages: tuple[Stage, ...] = ()
    excluded_tags: frozenset[str] = frozenset()
    name: str = "model"
    meta: Mapping[str, Any] = field(default_factory=dict)
    _cache: _DynamicsCache = field(default_factory=_DynamicsCache, repr=False, compare=False)

    def __reduce__(self):
        """Pickle by value (closures included) so process and cluster executors can ship
        models: the build stages are often closures, which plain pickle refuses."""
        import cloudpickle

        fields = {name: getattr(self, name) for name in self.__dataclass_fields__ if name != "_cache"}
        return (_model_from_bytes, (cloudpickle.dumps(fields),))

    def __post_init__(self) -> None:
        params = tuple(self.params)
        names = [p.name for p in params]
        if len(set(names)) != len(names):
            dup = sorted({n for n in names if names.count(n) > 1})
            raise ModelError(f"parameter names must be unique; repeated: {dup}.")
        object.__setattr__(self, "params", params)
        object.__setattr__(self, "structure_stages", tuple(self.structure_stages))
        object.__setattr__(self, "io_stages", tuple(self.io_stages))
        object.__setattr__(self, "excluded_tags", frozenset(self.excluded_tags))

    # ------------------------------------------------------------------ parameters
    @property
    def param_names(self) -> tuple[str, ...]:
        return tuple(p.name for p in self.params)

    @property
    def values(self) -> dict[str, float]:
        """Current parameter values by name."""
        return {p.name: p.value for p in self.params}

    @property
    def free_params(self) -> tuple[Parameter, ...]:
        return tuple(p for p in self.params if p.free)

    def param(self, name: str) -> Parameter:
        """The parameter called ``name``."""
        for p in self.params:
            if p.name == name:
                return p
        raise ModelError(f"the model has no parameter {name!r}; it has {list(self.param_names)}.")

    def _theta(self, overrides: Mapping[str, float]) -> dict[str, float]:
        theta = self.values
        for key, value in overrides.items():
            if key not in theta:
                raise ModelError(
                    f"unknown parameter {key!r}; the model has {list(self.param_names)}."
                )
            if isinstance(value, np.ndarray) and value.ndim == 0:
                value = value.item()
            theta[key] = finite_number(value, f"parameter {key!r} (override)", ModelError)
        return theta

    def with_values(self, **values: float) -> PhysicalModel:
        """A copy with some parameter values changed (checked against bounds)."""
        self._theta(values)
        params = tuple(p.with_value(values[p.name]) if p.name in values else p for p in self.params)
        return self._copy(params=params)

    def with_params(self, params: Iterable[Parameter]) -> PhysicalModel:
        """A copy with parameters replaced by name (or added when new)."""
        new = {p.name: p for p in params}
        kept = tuple(new.pop(p.name, p) for p in self.params)
        return self._copy(params=kept + tuple(new.values()))

    def _copy(self, **changes: Any) -> PhysicalModel:
        changes.setdefault("_cache", _DynamicsCache(self._cache._size))
        return replace(self, **changes)

    # ------------------------------------------------------------------ composition
    def add_structure_stage(self, stage: Stage, params: Sequence[Parameter] = ()) -> PhysicalModel:
        """A copy with a structural effect appended (and its parameters)."""
        if self.structure is None:
            raise ModelError(
                f"stage {stage.name!r} changes the structure, but model {self.name!r} has no "
                "structural description (it was built from modal data or a state space); "
                "use an input/output effect, or build the model with rc.structural_model."
            )
        return self.with_params(params)._copy(structure_stages=self.structure_stages + (stage,))

    def add_io_stage(self, stage: Stage, params: Sequence[Parameter] = ()) -> PhysicalModel:
        """A copy with an input/output stage appended (and its parameters)."""
        return self.with_params(params)._copy(io_stages=self.io_stages + (stage,))

    def with_effect(self, effect: Any) -> PhysicalModel:
        """A copy with a physical ``Effect`` added (see :mod:`robustctl.effects`).

        Parameters
        ----------
        effect : Effect, str or CandidateResult
            An effect instance (e.g. ``diag.best``, with its fitted values); a candidate's name
            as :func:`robustctl.diagnose` prints it (``"suspension spring at dof 6"``), which adds
            that candidate at its neutral value for :func:`robustctl.update` to fit; or a row of
            ``diag.ranking``.
        """
        Effect = _EFFECTS["Effect"]
        if effect is None:
            raise ModelError("with_effect got None: the diagnosis found no significant effect.")
        if isinstance(effect, type):
            raise ModelError(
                f"with_effect needs an Effect instance, not the class {effect.__name__}; give its "
                f"location and value, e.g. rc.effects.{effect.__name__}(...), or pass a candidate name."
            )
        if isinstance(effect, str):
            effect = self._candidate_named(effect)
        elif not isinstance(effect, Effect) and isinstance(getattr(effect, "effect", None), Effect):
            effect = effect.effect  # a diagnosis row (CandidateResult)
        if not isinstance(effect, Effect):
            raise ModelError(
                "with_effect needs an Effect (rc.effects.*) or a candidate name; "
                f"got {type(effect).__name__}."
            )
        return effect.apply(self)

    def _candidate_named(self, name: str) -> Any:
        """The candidate effect of :func:`robustctl.effects.candidates` called ``name``."""
        import difflib

        candidates = _EFFECTS["candidates"]
        found = {" ".join(c.name.lower().split()): c for c in candidates(self, calibrate=False)}
        key = " ".join(name.lower().split())
        if key in found:
            return found[key]
        names = [c.name for c in found.values()]
        close = difflib.get_close_matches(name, names, n=5, cutoff=0.5)
        hint = f"close matches: {close}" if close else f"the {len(names)} candidates include {names[:8]}"
        raise ModelError(
            f"no candidate effect of model {self.name!r} is called {name!r}; {hint}. "
            "List them with [c.name for c in rc.effects.candidates(model)]."
        )

    def known_tags(self) -> tuple[str, ...]:
        """Tags :meth:`without` can remove: of parameters, stages and structure components.

        ``"gravity"`` is always known (a model without a gravity preload is its own 0-g model).
        """
        found = {"gravity"} | {t for p in self.params for t in p.tags}
        found |= {t for s in self.structure_stages + self.io_stages for t in s.tags}
        if self.structure is not None:
            tags = getattr(self.build_structure(), "tags", None)
            found |= set(tags()) if callable(tags) else set()
        return tuple(sorted(found))

    def without(self, *tags: str) -> PhysicalModel:
        """A copy with every component tagged by one of ``tags`` removed.

        ``model.without("suspension", "gravity")`` gives MACE's 0-g model: suspension
        devices and their parameters are dropped and the gravity preload is not applied.

        Raises
        ------
        ModelError
            A tag that nothing in the model carries (a typo would silently give the 1-g model);
            the message lists :meth:`known_tags`.
        """
        tags = frozenset(tags)
        unknown = sorted(tags - self.excluded_tags - set(self.known_tags()))
        if unknown:
            raise ModelError(
                f"model {self.name!r} has nothing tagged {unknown}; known tags: {list(self.known_tags())}."
            )
        params = tuple(p for p in self.params if not tags.intersection(p.tags))
        return self._copy(
            params=params,
            io_stages=tuple(s for s in self.io_stages if not tags.intersection(s.tags)),
            structure_stages=tuple(
                s for s in self.structure_stages if not tags.intersection(s.tags)
            ),
            excluded_tags=self.excluded_tags | tags,
        )

    def select(
        self, inputs: Sequence[str] | str | None = None, outputs: Sequence[str] | str | None = None
    ) -> PhysicalModel:
        """A copy whose I/O model keeps only the named inputs and outputs, in the order given.

        For a test with fewer shakers or sensors than the model has, e.g.
        ``model.select(inputs=["A1"])`` against single-shaker data. The selection is the last
        I/O stage: add effects before selecting.

        Parameters
        ----------
        inputs, outputs : str or sequence of str, optional
            Signal names (``None`` keeps all).
        """
        sys = self.statespace()
        in_idx = _signal_indices(inputs, tuple(sys.input_labels), "inputs", self.name)
        out_idx = _signal_indices(outputs, tuple(sys.output_labels), "outputs", self.name)

        def pick(theta: Theta, ss: Any) -> Any:
            ins, outs = list(ss.input_labels), list(ss.output_labels)
            return control.ss(
                ss.A, ss.B[:, in_idx], ss.C[out_idx], ss.D[np.ix_(out_idx, in_idx)],
                inputs=[ins[k] for k in in_idx], outputs=[outs[k] for k in out_idx],
                states=list(ss.state_labels), dt=ss.dt,
            )

        stage = Stage(f"select outputs {[sys.output_labels[k] for k in out_idx]}, "
                      f"inputs {[sys.input_labels[k] for k in in_idx]}", pick)
        return self._copy(io_stages=self.io_stages + (stage,))

    # ------------------------------------------------------------------ building
    def build_structure(self, **overrides: float) -> Structure:
        """The structure for the current (or overridden) values, effects included."""
        if self.structure is None:
            raise ModelError(f"model {self.name!r} has no structural description.")
        return self._structure(self._theta(overrides))

    def geometry(self, **overrides: float) -> Any:
        """The structure's nodes, lines and sensors (:class:`~robustctl.frd_io.geometry.Geometry`),
        for :func:`robustctl.plot_mode_shapes` and :func:`robustctl.animate_mode_shape`.

        Raises
        ------
        ModelError
            The model has no structure, or its structure has no node coordinates.
        """
        return self.build_structure(**overrides).geometry()

    def mode_shapes(
        self, n_modes: int | None = None, band_hz: Sequence[float] | None = None, **overrides: float
    ) -> Any:
        """Every node's translation in the structure's undamped modes (effects included), as
        :class:`~robustctl.frd_io.geometry.ModeShapes` over :meth:`geometry`'s nodes.

        Parameters
        ----------
        n_modes : int, optional
            The lowest ``n_modes`` modes (all by default).
        band_hz : (lo, hi), optional
            Only the modes in this band (Hz).
        **overrides : float
            Parameter values to use instead of the model's.
        """
        return self.build_structure(**overrides).mode_shapes(n_modes, band_hz)

    def _structure(self, theta: Mapping[str, float], n_stages: int | None = None) -> Structure:
        stages = self.structure_stages if n_stages is None else self.structure_stages[:n_stages]
        struct = _base_structure(self.structure, theta)
        if stages:  # effects change the structure in place
            struct = _fresh(struct, self.name)
        if self.excluded_tags:
            struct = struct.without(self.excluded_tags)
        for stage in stages:
            struct = stage.fn(theta, struct)
        return struct

    def _anchor_matrices(self, theta: Mapping[str, float], rung: bool = False) -> Any:
        """The matrices of the structure without the last effect (a candidate's: the model it
        modifies), for a dynamics callable that takes an ``anchor`` (a band-limited model's); with
        ``rung``, the structure with it, its own parameters (those the structure without it does not
        read) each at the power of two at or below its magnitude (0 kept): one structure for a range
        of the effect's sizes, the anchor of an effect that adds DOFs (a resonator)."""
        n = len(self.structure_stages)
        if not rung:
            return self._structure(theta, n - 1).matrices()
        values = theta._values if isinstance(theta, _RecordingTheta) else theta
        reads = _RecordingTheta(values)
        self._structure(reads, n - 1)

        def ladder(v: float) -> float:
            if v == 0.0 or not math.isfinite(v):
                return v
            return math.copysign(2.0 ** math.floor(math.log2(abs(v))), v)

        rungs = {k: (v if k in reads.read else ladder(float(v))) for k, v in values.items()}
        return self._structure(rungs).matrices()

    def _dynamics(self, theta: dict[str, float]) -> Any:
        cached = self._cache.lookup(theta)
        if cached is not None:
            return cached
        recorder = _RecordingTheta(theta)
        struct = self._structure(recorder) if self.structure is not None else None
        if struct is not None and self.structure_stages and getattr(self.dynamics, "takes_anchor", False):
            sys = self.dynamics(recorder, struct, anchor=functools.partial(self._anchor_matrices, recorder))
        else:
            sys = self.dynamics(recorder, struct)
        self._cache.store(tuple(sorted(recorder.read)), theta, sys)
        return sys

    @limit_blas
    def statespace(self, **overrides: float):
        """The I/O model as a ``control.StateSpace`` with named signals.

        Runs under robustctl's BLAS thread limit (:func:`robustctl.set_blas_threads`): the
        eigen-solves here are small, and OpenBLAS's default thread pool makes them slower."""
        theta = self._theta(overrides)
        sys = self._dynamics(theta)
        for stage in self.io_stages:
            sys = stage.fn(theta, sys)
        return sys

    def freqresp(self, f_hz: Any, **overrides: float):
        """Frequency response at ``f_hz`` (Hz) as :class:`~robustctl.frd.FrequencyData`."""
        return freqresp(self.statespace(**overrides), f_hz)

    @property
    def inputs(self) -> tuple[str, ...]:
        return tuple(self.statespace().input_labels)

    @property
    def outputs(self) -> tuple[str, ...]:
        return tuple(self.statespace().output_labels)

    def __repr__(self) -> str:
        return (
            f"PhysicalModel({self.name!r}, {len(self.params)} parameters, "
            f"{len(self.structure_stages)} structural and {len(self.io_stages)} I/O stages"
            f"{', without ' + ', '.join(sorted(self.excluded_tags)) if self.excluded_tags else ''})"
        )

    def _repr_html_(self) -> str:
        import html

        free = [p.name for p in self.free_params]
        try:
            signals = f"outputs {', '.join(self.outputs)}; inputs {', '.join(self.inputs)}"
        except Exception as exc:  # a broken build must not break the notebook display
            signals = f"(build failed: {exc})"
        rows = [
            ("parameters", f"{len(self.params)} ({len(free)} free: {', '.join(free[:8])}"
                           f"{' ...' if len(free) > 8 else ''})"),
            ("stages", ", ".join(s.name for s in self.structure_stages + self.io_stages) or "none"),
            ("signals", signals),
            ("without", ", ".join(sorted(self.excluded_tags)) or "nothing"),
        ]
        body = "".join(f"<tr><th>{html.escape(k)}</th><td>{html.escape(v)}</td></tr>" for k, v in rows)
        return f"<table><caption>PhysicalModel {html.escape(self.name)}</caption>{body}</table>"


def _signal_indices(
    wanted: Sequence[str] | str | None, names: tuple[str, ...], what: str, model: str
) -> list[int]:
    """Indices of the ``wanted`` signal names among ``names``; all when ``wanted`` is None."""
    if wanted is None:
        return list(range(len(names)))
    wanted = [wanted] if isinstance(wanted, str) else list(wanted)
    unknown = [w for w in wanted if w not in names]
    if unknown or not wanted:
        raise ModelError(
            f"model {model!r} has no {what} {unknown or '(empty selection)'}; its {what} are {list(names)}."
        )
    if len(set(wanted)) != len(wanted):
        raise ModelError(f"{what} {wanted} name a signal twice; give each once.")
    return [names.index(w) for w in wanted]
