"""Named-signal operations on one ``control.StateSpace``: select, rename, scale, combine.

Every function takes a named continuous- or discrete-time system and returns a new
``control.StateSpace`` whose signals keep their names (or get the names asked for); the
state vector is unchanged. They are the static channel maps used by the electronics of
the I/O model (``physical/electronics.py``), the embedded examples and the generalized
plant (``robust/plant.py``); the dynamic interconnections (LFT, star product, series,
parallel, feedback) are in :mod:`robustctl.interconnect`.

Unknown names raise :class:`~robustctl.errors.ModelError` listing the names the system has.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import control
import numpy as np

from .checks import finite_number
from .errors import ModelError
from .lti import as_statespace

__all__ = [
    "rename_signals",
    "scale_inputs",
    "scale_outputs",
    "select_signals",
    "combine_inputs",
    "combine_outputs",
]


# ============================================================================ helpers
def named_statespace(A, B, C, D, inputs: Sequence[str], outputs: Sequence[str], dt: Any = 0):
    """A named ``control.StateSpace`` from arrays (``dt=0``: continuous time)."""
    return control.ss(
        np.asarray(A, float), np.asarray(B, float), np.asarray(C, float), np.asarray(D, float), dt,
        inputs=list(inputs), outputs=list(outputs),
    )


def abcd_matrices(sys: Any, what: str = "system"):
    """Arrays ``(A, B, C, D)`` of a continuous-time LTI system (StateSpace, TransferFunction or number)."""
    if isinstance(sys, (int, float, np.integer, np.floating)):
        return np.zeros((0, 0)), np.zeros((0, 1)), np.zeros((1, 0)), np.array([[float(sys)]])
    if isinstance(sys, control.StateSpace):  # its arrays, copied (control.ss(sys) copies slowly)
        ss = sys
    else:
        try:
            ss = control.ss(sys)
        except Exception as exc:  # python-control raises several types
            raise ModelError(f"cannot use {type(sys).__name__} as a {what}: {exc}") from exc
    if ss.isdtime(strict=True):
        raise ModelError(f"the {what} is discrete-time (dt={ss.dt}); the I/O model is continuous-time.")
    return _arrays(ss)


def _arrays(ss: Any):
    """``(A, B, C, D)`` of a StateSpace as float arrays (copies) of consistent 2-D shapes."""
    return tuple(np.array(m, dtype=float).reshape(s) for m, s in zip(
        (ss.A, ss.B, ss.C, ss.D),
        ((ss.nstates, ss.nstates), (ss.nstates, ss.ninputs), (ss.noutputs, ss.nstates),
         (ss.noutputs, ss.ninputs)),
    ))


def signal_names(names: str | Sequence[str]) -> tuple[str, ...]:
    """One signal name or a sequence of them, as a tuple of names."""
    return (names,) if isinstance(names, str) else tuple(names)


def _system(sys: Any):
    return as_statespace(sys, name="sys")


def _mapping(value: Any, name: str, allow_none: bool = False) -> Mapping:
    """``value`` as a mapping with string keys (``{}`` for None when allowed)."""
    if value is None and allow_none:
        return {}
    if not isinstance(value, Mapping) or not all(isinstance(k, str) for k in value):
        raise ModelError(f"{name} must be a dict signal name -> value; got {value!r}.")
    return value


def _gain(value: Any, name: str, key: str) -> float:
    return finite_number(value, f"{name}[{key!r}]", ModelError)


def _name_list(value: Any, name: str) -> list[str]:
    """A list of signal names (a single str is one name)."""
    items = [value] if isinstance(value, str) else value
    if isinstance(items, (bytes, Mapping)) or not isinstance(items, (Sequence, np.ndarray)):
        raise ModelError(f"{name} must be a list of signal names; got {value!r}.")
    items = list(items)
    if not all(isinstance(n, str) for n in items):
        raise ModelError(f"{name} must be signal names (str); got {value!r}.")
    return items


def signal_index(labels: Sequence[str], name: str, what: str, arg: str = "") -> int:
    """Position of ``name`` in ``labels`` or a ModelError listing the known names."""
    labels = list(labels)
    if name not in labels:
        where = f" (a key of {arg})" if arg else ""
        raise ModelError(f"unknown {what} {name!r}{where}; the system has {what}s {labels}.")
    return labels.index(name)


def _signal_gains(labels: Sequence[str], gains: Mapping[str, float], what: str) -> np.ndarray:
    """One gain per signal of ``labels``: ``gains[name]`` for the named ones, 1 for the others."""
    v = np.ones(len(labels))
    for name, g in _mapping(gains, "gains").items():
        v[signal_index(labels, name, what, "gains")] *= _gain(g, "gains", name)
    return v


# ============================================================================ rename and scale
def scale_outputs(sys: Any, gains: Mapping[str, float]):
    """Multiply named outputs by gains (e.g. V per rad/s of a rate gyro's electronics).

    ``y_name <- gains[name] * y_name``; other outputs and all names are unchanged.

    Parameters
    ----------
    sys, gains
        The system and ``{output name: finite gain}`` (new output units per old), as for
        :func:`scale_inputs`.

    Returns
    -------
    control.StateSpace
        Rows of ``C`` and ``D`` scaled.
    """
    sys = _system(sys)
    A, B, C, D = abcd_matrices(sys)
    g = _signal_gains(sys.output_labels, gains, "output")[:, None]
    return named_statespace(A, B, g * C, g * D, sys.input_labels, sys.output_labels)


def scale_inputs(sys: Any, gains: Mapping[str, float]):
    """Multiply named inputs by gains: ``u_phys = gains[name] * u_name`` (e.g. N m per V).

    Parameters
    ----------
    sys : control.StateSpace, TransferFunction or anything :func:`robustctl.as_statespace` accepts
        The system; its signal names are those matched.
    gains : mapping of str to float
        Input name -> finite gain (units of the physical input per unit of the new one).

    Returns
    -------
    control.StateSpace
        Columns of ``B`` and ``D`` scaled; names unchanged.
    """
    sys = _system(sys)
    A, B, C, D = abcd_matrices(sys)
    g = _signal_gains(sys.input_labels, gains, "input")
    return named_statespace(A, B * g, C, D * g, sys.input_labels, sys.output_labels)


def rename_signals(
    sys: Any, inputs: Mapping[str, str] | None = None, outputs: Mapping[str, str] | None = None
):
    """A copy with signals renamed (``{"gyro x": "gyro x (V)"}``).

    Parameters
    ----------
    sys : control.StateSpace, TransferFunction or anything :func:`robustctl.as_statespace` accepts
        The system; its signal names are those matched.
    inputs, outputs : mapping of str to str, optional
        Old name -> new name; names not listed keep theirs. The new names must stay unique.

    Returns
    -------
    control.StateSpace
        The same matrices with the new names.
    """
    sys = _system(sys)
    ins, outs = list(sys.input_labels), list(sys.output_labels)
    for arg, value, labels, what in (("inputs", inputs, ins, "input"), ("outputs", outputs, outs, "output")):
        for old, new in _mapping(value, arg, allow_none=True).items():
            if not isinstance(new, str) or not new or "\x00" in new:
                raise ModelError(f"{arg}[{old!r}] must be a non-empty signal name (str); got {new!r}.")
            labels[signal_index(labels, old, what, arg)] = new
    if len(set(ins)) != len(ins) or len(set(outs)) != len(outs):
        raise ModelError(f"renaming would repeat a signal name: inputs {ins}, outputs {outs}.")
    return named_statespace(*abcd_matrices(sys), ins, outs)


# ============================================================================ select and combine
def _combination(labels: Sequence[str], combos: Mapping[str, Mapping[str, float]], what: str):
    """Matrix T (old x new) and the new labels: each combo replaces the channels it uses."""
    labels = list(labels)
    used: dict[str, str] = {}
    for new, parts in _mapping(combos, "combos").items():
        _mapping(parts, f"combos[{new!r}]")
        for old, coeff in parts.items():
            _gain(coeff, f"combos[{new!r}]", old)
        if not parts:
            raise ModelError(f"the {what} combination {new!r} (in combos) uses no {what}s.")
        for old in parts:
            if old not in labels:
                raise ModelError(
                    f"the {what} combination {new!r} (in combos) uses unknown {what} {old!r}; have {labels}."
                )
            if old in used:
                raise ModelError(f"{what} {old!r} is used by both {used[old]!r} and {new!r}.")
            used[old] = new
    new_labels: list[str] = []
    for lab in labels:
        target = used.get(lab, lab)
        if target not in new_labels:
            new_labels.append(target)
    if len(set(new_labels)) != len(new_labels):
        raise ModelError(f"a combined {what} name repeats an existing one: {new_labels}.")
    T = np.zeros((len(labels), len(new_labels)))
    for j, lab in enumerate(new_labels):
        if lab in combos:
            for old, coeff in combos[lab].items():
                T[labels.index(old), j] = float(coeff)
        else:
            T[labels.index(lab), j] = 1.0
    return T, new_labels


def combine_inputs(sys: Any, combos: Mapping[str, Mapping[str, float]]):
    """Replace inputs by static combinations: ``u_old = sum_new coeff * u_new``.

    ``combine_inputs(sys, {"gimbal x": {"torque on payload": 1, "torque on bus": -1}})``
    makes one motor torque acting equal and opposite on payload and bus. Inputs not used
    by any combination keep their names; a combination takes the place of its first input.

    Parameters
    ----------
    sys : control.StateSpace, TransferFunction or anything :func:`robustctl.as_statespace` accepts
        The system; its signal names are those matched.
    combos : mapping of str to mapping of str to float
        New input name -> {old input name: coefficient}; every old input appears in at most
        one combination.

    Returns
    -------
    control.StateSpace
        ``B T`` and ``D T`` with ``u_old = T u_new``.
    """
    sys = _system(sys)
    T, names = _combination(sys.input_labels, combos, "input")
    A, B, C, D = (np.asarray(m, float) for m in (sys.A, sys.B, sys.C, sys.D))
    return named_statespace(A, B @ T, C, D @ T, names, sys.output_labels, sys.dt)


def combine_outputs(sys: Any, combos: Mapping[str, Mapping[str, float]]):
    """Replace outputs by static combinations: ``y_new = sum_old coeff * y_old``.

    ``combine_outputs(sys, {"encoder x": {"payload rx": 1, "bus rx": -1}})`` is the
    relative rotation an encoder reads between a gimbal payload and the bus.

    Parameters
    ----------
    sys : control.StateSpace, TransferFunction or anything :func:`robustctl.as_statespace` accepts
        The system; its signal names are those matched.
    combos : mapping of str to mapping of str to float
        New output name -> {old output name: coefficient}; every old output appears in at
        most one combination.

    Returns
    -------
    control.StateSpace
        ``T^T C`` and ``T^T D`` with ``y_new = T^T y_old``.
    """
    sys = _system(sys)
    T, names = _combination(sys.output_labels, combos, "output")
    A, B, C, D = (np.asarray(m, float) for m in (sys.A, sys.B, sys.C, sys.D))
    return named_statespace(A, B, T.T @ C, T.T @ D, sys.input_labels, names, sys.dt)


def select_signals(sys: Any, inputs: Sequence[str] | None = None, outputs: Sequence[str] | None = None):
    """Keep the named inputs and outputs (in the given order); ``None`` keeps all.

    Parameters
    ----------
    sys : control.StateSpace, TransferFunction or anything :func:`robustctl.as_statespace` accepts
        The system; its signal names are those matched.
    inputs, outputs : sequence of str, optional
        Names to keep, in the order wanted; None keeps every input (output).

    Returns
    -------
    control.StateSpace
        Same states; the selected columns of ``B``, ``D`` and rows of ``C``, ``D``.
    """
    sys = _system(sys)
    ins = list(sys.input_labels) if inputs is None else _name_list(inputs, "inputs")
    outs = list(sys.output_labels) if outputs is None else _name_list(outputs, "outputs")
    for name, labels, what in [(n, sys.input_labels, "input") for n in ins] + [
        (n, sys.output_labels, "output") for n in outs
    ]:
        if name not in labels:
            raise ModelError(f"unknown {what} {name!r} (in {what}s); the system has {list(labels)}.")
    ii = [list(sys.input_labels).index(n) for n in ins]
    oo = [list(sys.output_labels).index(n) for n in outs]
    A, B, C, D = _arrays(sys)
    return named_statespace(A, B[:, ii], C[oo], D[np.ix_(oo, ii)], ins, outs, sys.dt)
