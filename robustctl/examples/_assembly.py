"""Building blocks shared by the embedded example structures.

Small pieces the frame FEM and the electronics module do not provide themselves:

* cross-section and rigid-body inertia formulas (solid rod, thin-walled tube, equilateral
  triangular plate, solid cylinder), all textbook results in SI units;
* a ``dynamics`` wrapper applying static channel combinations (``robustctl.signals``: a
  torque *pair* acting on two bodies from two single torques, a *relative* rotation read
  by an encoder from two absolute rotations) right after the modal state space;
* parameter helpers that tolerate the parameters dropped by ``PhysicalModel.without``.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from typing import Any

import numpy as np

from ..checks import check_band, flag, integer
from ..errors import DataError, ModelError
from ..physical.electronics import pd_controller
from ..physical.parameters import Parameter
from ..signals import combine_inputs, combine_outputs, select_signals

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
    return integer(value, name, ModelError, lo=lo, hi=hi)


def check_band_hz(band_hz: Any) -> tuple[float, float] | None:
    """A model's modal band ``(lo, hi)`` in Hz with ``0 <= lo < hi`` (or None), else a ModelError."""
    try:
        band = check_band(band_hz, "band_hz")
    except DataError as exc:
        raise ModelError(str(exc)) from None
    if band is not None and band[0] < 0:
        raise ModelError(f"band_hz must be (lo, hi) in Hz with 0 <= lo < hi; got {band_hz!r}.")
    return band


def check_flags(**flags: Any) -> None:
    """Every keyword a real boolean (``gravity="False"`` would otherwise be truthy)."""
    for name, value in flags.items():
        flag(value, name, ModelError)


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
