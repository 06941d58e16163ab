"""Named physical parameters of a model (the update variables of MACE's updating)."""

from __future__ import annotations

import math
import numbers
from dataclasses import dataclass, replace

import numpy as np

from ..checks import finite_number, flag
from ..errors import ModelError

__all__ = ["Parameter"]


def _scalar(value: object) -> object:
    """A 0-d numpy array as its item (optimisers hand those over); anything else unchanged."""
    return value.item() if isinstance(value, np.ndarray) and value.ndim == 0 else value


def _bounds_pair(name: str, bounds: object) -> tuple[float, float]:
    """``(lo, hi)`` as floats; infinite ends allowed, NaN, strings and other lengths refused."""
    items = list(bounds) if isinstance(bounds, (tuple, list, np.ndarray)) else []
    ok = len(items) == 2 and all(
        isinstance(b, (numbers.Real, np.floating, np.integer)) and not isinstance(b, (bool, np.bool_))
        and not math.isnan(float(b)) for b in items
    )
    if not ok:
        raise ModelError(
            f"parameter {name!r}: bounds must be a pair (lo, hi) of real numbers (inf allowed); "
            f"got {bounds!r}."
        )
    return float(items[0]), float(items[1])


@dataclass(frozen=True)
class Parameter:
    """A physical parameter of a model.

    Parameters
    ----------
    name : str
        Identifier, unique within a model (``E_aluminium``, ``m_platform_1``).
    value : float
        Current value in ``unit``.
    unit : str
        SI unit of ``value`` (``"Pa"``, ``"kg"``, ``"s"``).
    bounds : (float, float)
        Physically admissible range; updating never leaves it.
    rel_step : float
        Relative finite-difference step for sensitivities (MACE eq. 7).
    abs_step : float
        Absolute step used when ``value`` is zero or tiny (effects at their neutral value).
    meaning : str
        One line of physics ("Young's modulus of the aluminium longerons").
    tags : tuple of str
        Groups such as ``"suspension"``, ``"gravity"``, ``"electronics"``, ``"effect"``.
    free : bool
        Whether ``update`` may change it by default.
    neutral : float or None
        For an effect's parameter, the value at which the effect vanishes.
    """

    name: str
    value: float
    unit: str = ""
    bounds: tuple[float, float] = (-math.inf, math.inf)
    rel_step: float = 1e-3
    abs_step: float = 0.0
    meaning: str = ""
    tags: tuple[str, ...] = ()
    free: bool = True
    neutral: float | None = None

    def __post_init__(self) -> None:
        if not self.name or not isinstance(self.name, str):
            raise ModelError("a Parameter needs a non-empty string name.")
        value = finite_number(_scalar(self.value), f"parameter {self.name!r}: value", ModelError)
        lo, hi = _bounds_pair(self.name, self.bounds)
        if lo > hi:
            raise ModelError(f"parameter {self.name!r} has bounds {self.bounds} with lower > upper.")
        if not lo <= value <= hi:
            raise ModelError(
                f"parameter {self.name!r} = {value:g} {self.unit} lies outside its bounds "
                f"[{lo:g}, {hi:g}]; widen the bounds or change the value."
            )
        rel_step = abs_step = math.nan
        steps = (self.rel_step, self.abs_step)
        if all(isinstance(x, numbers.Real) and not isinstance(x, bool) for x in steps):
            rel_step, abs_step = float(self.rel_step), float(self.abs_step)
        if not (math.isfinite(rel_step) and rel_step > 0 and math.isfinite(abs_step) and abs_step >= 0):
            raise ModelError(
                f"parameter {self.name!r}: rel_step must be a finite number > 0 and abs_step a "
                f"finite number >= 0; got rel_step={self.rel_step!r}, abs_step={self.abs_step!r}."
            )
        if self.neutral is not None:
            neutral = finite_number(self.neutral, f"parameter {self.name!r}: neutral", ModelError)
            if not lo <= neutral <= hi:
                raise ModelError(
                    f"parameter {self.name!r}: neutral={neutral:g} (the value at which the effect vanishes) "
                    f"lies outside the bounds [{lo:g}, {hi:g}]; widen the bounds or fix the neutral value."
                )
            object.__setattr__(self, "neutral", neutral)
        object.__setattr__(self, "free", flag(self.free, f"parameter {self.name!r}: free", ModelError))
        object.__setattr__(self, "value", value)
        object.__setattr__(self, "rel_step", rel_step)
        object.__setattr__(self, "abs_step", abs_step)
        object.__setattr__(self, "bounds", (lo, hi))
        # one tag may be given as a bare string, as for Frame's tags (not one tag per letter)
        object.__setattr__(self, "tags", (self.tags,) if isinstance(self.tags, str) else tuple(self.tags))

    def with_value(self, value: float) -> Parameter:
        """A copy holding ``value`` (checked against the bounds)."""
        value = finite_number(_scalar(value), f"parameter {self.name!r}: value", ModelError)
        return replace(self, value=value)

    def step(self, value: float | None = None) -> float:
        """Finite-difference step at ``value`` (default: the current value)."""
        v = self.value if value is None else value
        return max(self.rel_step * abs(v), self.abs_step, 1e-12)
