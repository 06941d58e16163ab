"""Building blocks shared by the embedded example structures.

Small pieces the frame FEM and the electronics module do not provide themselves:

* cross-section and rigid-body inertia formulas (solid rod, thin-walled tube, equilateral
  triangular plate, solid cylinder), all textbook results in SI units;
* static channel combinations of a named ``control.StateSpace`` (a torque *pair* acting on
  two bodies from two single torques, a *relative* rotation read by an encoder from two
  absolute rotations, keeping a subset of channels) and a ``dynamics`` wrapper applying
  them right after the modal state space;
* a PD servo compensator with roll-off and sampling delay (MACE Fig. 1 gimbal servo: the
  encoder angle is differentiated digitally and fed back as angle and rate) and its Stage;
* parameter helpers that tolerate the parameters dropped by ``PhysicalModel.without``.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from typing import Any

import numpy as np

from ..errors import ModelError
from ..physical.electronics import close_servo_loop, pade_delay, series
from ..physical.model import Stage
from ..physical.parameters import Parameter

__all__ = [
    "param",
    "get_param",
    "rod_section",
    "tube_section",
    "triangle_plate_inertia",
    "cylinder_inertia",
    "unit",
    "combine_inputs",
    "combine_outputs",
    "select_signals",
    "mapped_dynamics",
    "pd_controller",
    "pd_servo_stage",
    "check_int",
]

G_STANDARD = 9.80665  # m/s^2, standard gravity (kgf -> N and g -> m/s^2 conversions)


# ============================================================================ parameters
def param(
    name: str,
    value: float,
    unit: str,
    bounds: tuple[float, float],
    meaning: str,
    tags: Sequence[str] = (),
    *,
    free: bool = True,
    rel_step: float = 1e-3,
) -> Parameter:
    """A :class:`Parameter` with the fields the examples always give."""
    return Parameter(
        name=name, value=value, unit=unit, bounds=bounds, meaning=meaning, tags=tuple(tags),
        free=free, rel_step=rel_step,
    )


def get_param(theta: Mapping[str, float], name: str, default: float) -> float:
    """``theta[name]`` when the model still has that parameter (dropped by ``without``), else ``default``."""
    return float(theta.get(name, default))


def check_int(value: Any, name: str, lo: int, hi: int) -> int:
    """An integer option in ``[lo, hi]`` or a ModelError saying so."""
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or not lo <= value <= hi:
        raise ModelError(f"{name} must be an integer in {lo}..{hi}; got {value!r}.")
    return int(value)


# ============================================================================ sections
def rod_section(diameter: float) -> dict[str, float]:
    """Solid circular rod: ``A = pi d^2/4``, ``I = pi d^4/64``, ``J = 2 I`` (m^2, m^4)."""
    d = float(diameter)
    if not d > 0:
        raise ModelError(f"a rod diameter must be > 0 m; got {diameter!r}.")
    inertia = math.pi * d**4 / 64
    return {"A": math.pi * d**2 / 4, "Iy": inertia, "Iz": inertia, "J": 2 * inertia}


def tube_section(outer_diameter: float, wall: float) -> dict[str, float]:
    """Circular tube: ``A = pi (D^2 - d^2)/4``, ``I = pi (D^4 - d^4)/64``, ``J = 2 I``."""
    D, t = float(outer_diameter), float(wall)
    if not (D > 0 and 0 < t <= D / 2):
        raise ModelError(f"a tube needs outer diameter > 0 and 0 < wall <= D/2; got D={D!r}, wall={t!r}.")
    d = D - 2 * t
    inertia = math.pi * (D**4 - d**4) / 64
    return {"A": math.pi * (D**2 - d**2) / 4, "Iy": inertia, "Iz": inertia, "J": 2 * inertia}


def triangle_plate_inertia(mass: float, side: float) -> tuple[float, float, float]:
    """Thin equilateral triangular plate about its centroid, plate in the x-y plane.

    ``I_zz = m a^2 / 12`` (polar) and ``I_xx = I_yy = m a^2 / 24`` (perpendicular-axis
    theorem with the in-plane symmetry of the equilateral triangle), in kg m^2.
    """
    m, a = float(mass), float(side)
    return (m * a * a / 24, m * a * a / 24, m * a * a / 12)


def cylinder_inertia(
    mass: float, radius: float, length: float, axis: str = "z"
) -> tuple[float, float, float]:
    """Solid cylinder about its centre: ``m r^2/2`` about its axis, ``m (3 r^2 + l^2)/12`` across."""
    m, r, length_ = float(mass), float(radius), float(length)
    axial = m * r * r / 2
    across = m * (3 * r * r + length_ * length_) / 12
    if axis not in ("x", "y", "z"):
        raise ModelError(f"axis must be 'x', 'y' or 'z'; got {axis!r}.")
    return tuple(axial if a == axis else across for a in "xyz")  # type: ignore[return-value]


def unit(v: Sequence[float]) -> np.ndarray:
    """``v / |v|``."""
    v = np.asarray(v, dtype=float)
    n = float(np.linalg.norm(v))
    if n == 0:
        raise ModelError("a direction vector must not be zero.")
    return v / n


# ============================================================================ channel maps
def _ss(A, B, C, D, inputs, outputs):
    import control

    return control.ss(A, B, C, D, inputs=list(inputs), outputs=list(outputs))


def _combination(labels: Sequence[str], combos: Mapping[str, Mapping[str, float]], what: str):
    """Matrix T (old x new) and the new labels: each combo replaces the channels it uses."""
    labels = list(labels)
    used: dict[str, str] = {}
    for new, parts in combos.items():
        if not parts:
            raise ModelError(f"the {what} combination {new!r} uses no {what}s.")
        for old in parts:
            if old not in labels:
                raise ModelError(
                    f"the {what} combination {new!r} uses unknown {what} {old!r}; have {labels}."
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
    """
    T, names = _combination(sys.input_labels, combos, "input")
    A, B, C, D = (np.asarray(m, float) for m in (sys.A, sys.B, sys.C, sys.D))
    return _ss(A, B @ T, C, D @ T, names, sys.output_labels)


def combine_outputs(sys: Any, combos: Mapping[str, Mapping[str, float]]):
    """Replace outputs by static combinations: ``y_new = sum_old coeff * y_old``.

    ``combine_outputs(sys, {"encoder x": {"payload rx": 1, "bus rx": -1}})`` is the
    relative rotation an encoder reads between a gimbal payload and the bus.
    """
    T, names = _combination(sys.output_labels, combos, "output")
    A, B, C, D = (np.asarray(m, float) for m in (sys.A, sys.B, sys.C, sys.D))
    return _ss(A, B, T.T @ C, T.T @ D, sys.input_labels, names)


def select_signals(sys: Any, inputs: Sequence[str] | None = None, outputs: Sequence[str] | None = None):
    """Keep the named inputs and outputs (in the given order); ``None`` keeps all."""
    ins = list(sys.input_labels) if inputs is None else list(inputs)
    outs = list(sys.output_labels) if outputs is None else list(outputs)
    for name, labels, what in [(n, sys.input_labels, "input") for n in ins] + [
        (n, sys.output_labels, "output") for n in outs
    ]:
        if name not in labels:
            raise ModelError(f"unknown {what} {name!r}; the system has {list(labels)}.")
    ii = [list(sys.input_labels).index(n) for n in ins]
    oo = [list(sys.output_labels).index(n) for n in outs]
    A, B, C, D = (np.asarray(m, float) for m in (sys.A, sys.B, sys.C, sys.D))
    return _ss(A, B[:, ii], C[oo], D[np.ix_(oo, ii)], ins, outs)


def mapped_dynamics(
    dynamics: Callable[[Mapping[str, float], Any], Any],
    *,
    inputs: Mapping[str, Mapping[str, float]] | None = None,
    outputs: Mapping[str, Mapping[str, float]] | None = None,
) -> Callable[[Mapping[str, float], Any], Any]:
    """Wrap a PhysicalModel ``dynamics`` callable with static input/output combinations.

    The result stays in the cached structural part of the build (stages 1-3), so the
    combination costs nothing when only electronics parameters change.
    """

    def wrapped(theta: Mapping[str, float], structure: Any):
        sys = dynamics(theta, structure)
        if inputs:
            sys = combine_inputs(sys, inputs)
        if outputs:
            sys = combine_outputs(sys, outputs)
        return sys

    return wrapped


# ============================================================================ servo
def pd_controller(
    gain: float,
    lead_hz: float,
    *,
    lowpass_hz: float = math.inf,
    delay_s: float = 0.0,
    rolloff_order: int = 2,
    pade_order: int = 2,
):
    """PD servo compensator ``K(s) = gain (1 + s / w_d) R(s) e^{-s delay}`` with roll-off R.

    ``R(s) = w_c / (s + w_c)`` (``rolloff_order=1``) or the Butterworth pair
    ``w_c^2 / (s^2 + sqrt(2) w_c s + w_c^2)`` (``rolloff_order=2``), unit gain at DC.

    Parameters
    ----------
    gain : float
        Proportional gain (actuator units per sensor unit, e.g. V/rad).
    lead_hz : float
        Derivative corner ``w_d / 2 pi`` in Hz (the rate feedback of MACE's digitally
        differentiated encoder); must be finite and > 0.
    lowpass_hz : float
        Roll-off corner ``w_c / 2 pi`` in Hz (> ``lead_hz``); must be finite (a PD without
        roll-off is improper).
    delay_s : float
        Sampling delay of the digital loop in s (Pade approximant of ``pade_order``).
    rolloff_order : {1, 2}
        Order of the roll-off.

    Returns
    -------
    control.StateSpace
        SISO, input ``u`` (error), output ``y`` (actuator command).
    """
    wd = 2 * math.pi * float(lead_hz)
    wc = 2 * math.pi * float(lowpass_hz)
    if not (math.isfinite(wd) and wd > 0):
        raise ModelError(f"the PD lead corner must be a finite frequency > 0 Hz; got {lead_hz!r}.")
    if not (math.isfinite(wc) and wc > wd):
        raise ModelError(
            f"the PD roll-off ({lowpass_hz!r} Hz) must be finite and above the lead corner ({lead_hz!r} Hz)."
        )
    if rolloff_order not in (1, 2):
        raise ModelError(f"rolloff_order must be 1 or 2; got {rolloff_order!r}.")
    g = float(gain)
    if rolloff_order == 1:
        # gain (1 + s/wd) wc/(s + wc) = gain wc/wd + gain wc (1 - wc/wd)/(s + wc)
        pd = _ss([[-wc]], [[wc]], [[g * (1 - wc / wd)]], [[g * wc / wd]], ["u"], ["y"])
    else:
        # states scaled by wc: x1' = wc x2, x2' = -wc x1 - sqrt2 wc x2 + wc u; R = x1
        z = math.sqrt(2.0)
        A = [[0.0, wc], [-wc, -z * wc]]
        pd = _ss(A, [[0.0], [wc]], [[g, g * wc / wd]], [[0.0]], ["u"], ["y"])
    if delay_s:
        pd = series(pd, pade_delay(delay_s, pade_order))
    return pd


def pd_servo_stage(
    sensor: str,
    actuator: str,
    gain: str | float,
    lead_hz: str | float,
    *,
    lowpass_hz: str | float,
    delay_s: str | float = 0.0,
    rolloff_order: int = 2,
    reference_input_name: str | None = None,
    name: str | None = None,
    tags: Sequence[str] = ("electronics", "servo"),
) -> Stage:
    """Stage closing ``u_actuator = K_PD (r - y_sensor)`` with numbers or parameter names."""

    def value(theta: Mapping[str, float], v: str | float) -> float:
        return float(theta[v]) if isinstance(v, str) else float(v)

    def fn(theta: Mapping[str, float], sys: Any):
        k = pd_controller(
            value(theta, gain), value(theta, lead_hz), lowpass_hz=value(theta, lowpass_hz),
            delay_s=value(theta, delay_s), rolloff_order=rolloff_order,
        )
        return close_servo_loop(sys, sensor, actuator, k, reference_input_name)

    return Stage(name or f"PD servo {sensor} -> {actuator}", fn, tuple(tags))
