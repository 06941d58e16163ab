"""Named uncertain elements: real parameters, complex scalars and unmodelled dynamics.

Each element is the upper LFT of a constant matrix and a normalised perturbation ``delta``
in the unit ball (Zhou, Doyle & Glover 1996, "Robust and Optimal Control", sec. 10.2):

* :func:`ureal` -- a real parameter ``p = c + h delta``, ``delta`` real in [-1, 1]
  (``c`` the centre of its range, ``h`` the half-width): ``p = Fu([[0, 1], [h, c]], delta)``.
  MATLAB ``ureal``, RobustAndOptimalControl.jl ``δr``.
* :func:`ucomplex` -- a complex scalar ``p = c + r delta``, ``|delta| <= 1``; MATLAB
  ``ucomplex``, RobustAndOptimalControl.jl ``δc``.
* :func:`ultidyn` -- unmodelled stable dynamics ``Delta(s)`` of size ``ny x nu`` with
  ``||Delta||_inf <= bound``: ``Fu([[0, I], [bound I, 0]], Delta_n)``, ``||Delta_n||_inf <= 1``;
  MATLAB ``ultidyn``, RobustAndOptimalControl.jl ``uss(δc ...)`` of a full block.

They combine with systems by ordinary arithmetic into an
:class:`~robustctl.robust.uncertainty.system.UncertainSystem`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from ...checks import finite_number, integer, positive_number
from ...errors import SynthesisError

__all__ = ["register_system", "UncertainReal", "UncertainComplex", "UncertainDynamics",
           "ureal", "ucomplex", "ultidyn"]


def _name(name: Any) -> str:
    if not isinstance(name, str) or not name.strip():
        raise SynthesisError(f"an uncertain element needs a non-empty name (a str); got {name!r}.")
    return name


class _Element:
    """Arithmetic of an element goes through its one-element uncertain system, whose
    constructor :mod:`.system` registers here (``_to_system``) when it is imported."""

    kind: str = ""
    _to_system: Any = None

    def as_system(self):
        """This element as a one-element :class:`~robustctl.robust.uncertainty.system.UncertainSystem`."""
        return type(self)._to_system(self)

    def __add__(self, other):
        return self.as_system() + other

    def __radd__(self, other):
        return other + self.as_system() if hasattr(other, "as_system") else self.as_system().__radd__(other)

    def __sub__(self, other):
        return self.as_system() - other

    def __rsub__(self, other):
        return self.as_system().__rsub__(other)

    def __mul__(self, other):
        return self.as_system() * other

    def __rmul__(self, other):
        return self.as_system().__rmul__(other)

    def __truediv__(self, other):
        return self.as_system() / other

    def __rtruediv__(self, other):
        return self.as_system().__rtruediv__(other)

    def __neg__(self):
        return -self.as_system()

    def __pow__(self, n):
        return self.as_system() ** n

    __array_priority__ = 1000  # numpy scalars and arrays defer to these operators


def register_system(constructor: Any) -> None:
    """Install the one-element system constructor used by the elements' arithmetic."""
    _Element._to_system = staticmethod(constructor)


@dataclass(frozen=True, eq=False)
class UncertainReal(_Element):
    """A named real parameter ``p = center + half_range * delta``, ``delta`` in [-1, 1].

    Attributes
    ----------
    name : str
    nominal : float
        The value the nominal model uses (the centre for a symmetric range).
    low, high : float
        The range (parameter units).
    """

    name: str
    nominal: float
    low: float
    high: float
    kind = "real"
    shape = (1, 1)

    @property
    def center(self) -> float:
        return 0.5 * (self.low + self.high)

    @property
    def half_range(self) -> float:
        return 0.5 * (self.high - self.low)

    def to_normalized(self, value: Any) -> float:
        """``delta = (p - center) / half_range`` for a parameter value ``p``."""
        v = finite_number(value, f"the value of {self.name}", SynthesisError)
        return (v - self.center) / self.half_range

    def from_normalized(self, delta: Any) -> float:
        return float(self.center + self.half_range * np.real(delta))

    def sample(self, rng: np.random.Generator) -> float:
        """A value uniform in ``[low, high]``."""
        return float(rng.uniform(self.low, self.high))

    def describe(self) -> str:
        c, h = self.nominal, self.half_range
        if abs(c - self.center) <= 1e-12 * max(abs(c), h):
            pct = f" ({100 * h / abs(c):.3g} %)" if c != 0 else ""
            return f"{self.name}: real {c:.4g} +- {h:.4g}{pct}"
        return f"{self.name}: real {c:.4g} in [{self.low:.4g}, {self.high:.4g}]"

    def __repr__(self) -> str:
        return f"UncertainReal({self.describe()})"


@dataclass(frozen=True, eq=False)
class UncertainComplex(_Element):
    """A named complex scalar ``p = nominal + radius * delta``, ``|delta| <= 1``."""

    name: str
    nominal: complex
    radius: float
    kind = "complex"
    shape = (1, 1)

    @property
    def center(self) -> complex:
        return self.nominal

    def to_normalized(self, value: Any) -> complex:
        v = complex(value)
        if not (math.isfinite(v.real) and math.isfinite(v.imag)):
            raise SynthesisError(f"the value of {self.name} must be a finite complex number; got {value!r}.")
        return (v - self.nominal) / self.radius

    def from_normalized(self, delta: Any) -> complex:
        return complex(self.nominal + self.radius * complex(delta))

    def sample(self, rng: np.random.Generator) -> complex:
        """A value uniform in the disc ``|p - nominal| <= radius``."""
        r = self.radius * math.sqrt(rng.uniform())
        return complex(self.nominal + r * np.exp(2j * np.pi * rng.uniform()))

    def describe(self) -> str:
        return f"{self.name}: complex {self.nominal:.4g} +- {self.radius:.4g}"

    def __repr__(self) -> str:
        return f"UncertainComplex({self.describe()})"


@dataclass(frozen=True, eq=False)
class UncertainDynamics(_Element):
    """Named unmodelled stable dynamics ``Delta(s)`` (``ny x nu``), ``||Delta||_inf <= bound``."""

    name: str
    ny: int
    nu: int
    bound: float
    kind = "dynamics"

    @property
    def shape(self) -> tuple[int, int]:
        return (self.ny, self.nu)

    @property
    def nominal(self) -> np.ndarray:
        return np.zeros((self.ny, self.nu))

    def sample(self, rng: np.random.Generator, dt: float = 0.0):
        """A stable real system of norm ``<= bound``: ``bound rho U diag(a_i(s)) V^T`` with
        all-pass sections ``a_i(s) = +-(s - p_i) / (s + p_i)`` (``p_i`` log-uniform in
        [0.1, 100] rad/s), orthogonal ``U``, ``V`` and ``rho`` uniform in [0, 1]: its
        H-infinity norm is exactly ``bound rho``."""
        import control

        k = min(self.ny, self.nu)
        U = np.linalg.qr(rng.standard_normal((self.ny, self.ny)))[0][:, :k]
        V = np.linalg.qr(rng.standard_normal((self.nu, self.nu)))[0][:, :k]
        p = 10 ** rng.uniform(-1, 2, k)
        sg = rng.choice([-1.0, 1.0], k)
        rho = self.bound * rng.uniform()
        # (s - p)/(s + p) = 1 - 2p/(s + p): A = -p, B = 1, C = -2p, D = 1
        A, B, C, D = np.diag(-p), V.T, U @ np.diag(-2 * p * sg * rho), rho * U @ np.diag(sg) @ V.T
        sysc = control.ss(A, B, C, D)
        return sysc if not dt else control.c2d(sysc, dt, method="bilinear")

    def describe(self) -> str:
        return f"{self.name}: dynamics {self.ny}x{self.nu}, norm <= {self.bound:.4g}"

    def __repr__(self) -> str:
        return f"UncertainDynamics({self.describe()})"


def ureal(name: str, nominal: float, *, percent: Any = None, plusminus: Any = None,
          range: Any = None) -> UncertainReal:  # noqa: A002 - MATLAB's name for the option
    """A named uncertain real parameter (MATLAB ``ureal``, RobustAndOptimalControl.jl ``δr``).

    Give exactly one of ``percent``, ``plusminus`` or ``range``.

    Parameters
    ----------
    name : str
    nominal : float
        Nominal value (parameter units).
    percent : float or (float, float), optional
        ``+-percent`` % of ``|nominal|`` (or ``(-lo %, +hi %)``).
    plusminus : float or (float, float), optional
        ``nominal +- plusminus`` (or ``(nominal + lo, nominal + hi)`` with ``lo < 0 < hi``).
    range : (float, float), optional
        ``[low, high]`` containing ``nominal``.

    Returns
    -------
    UncertainReal
        ``p = center + half_range * delta`` with real ``delta`` in [-1, 1]; robust margins
        scale the range about its centre (the nominal for a symmetric range).

    Examples
    --------
    >>> import robustctl as rc
    >>> k = rc.ureal("k", 2.0, percent=30)
    >>> (k.low, k.high)
    (1.4, 2.6)
    """
    name = _name(name)
    nominal = finite_number(nominal, "nominal", SynthesisError)
    given = [x is not None for x in (percent, plusminus, range)]
    if sum(given) != 1:
        raise SynthesisError(
            f"ureal({name!r}) needs exactly one of percent=, plusminus= or range=; got {sum(given)}.")

    def pair(v, what):
        arr = np.atleast_1d(np.asarray(v, dtype=float))
        if arr.size == 1:
            arr = np.array([-abs(arr[0]), abs(arr[0])])
        if arr.size != 2 or not np.all(np.isfinite(arr)):
            raise SynthesisError(f"{what} must be a finite number or a pair (lo, hi); got {v!r}.")
        return arr

    if percent is not None:
        lo, hi = nominal + pair(percent, "percent") * abs(nominal) / 100.0
    elif plusminus is not None:
        lo, hi = nominal + pair(plusminus, "plusminus")
    else:
        arr = np.asarray(range, dtype=float).reshape(-1)
        if arr.size != 2 or not np.all(np.isfinite(arr)):
            raise SynthesisError(f"range must be a pair (low, high); got {range!r}.")
        lo, hi = arr
    lo, hi = float(np.round(lo, 14)), float(np.round(hi, 14))
    if not lo <= nominal <= hi or not hi > lo:
        raise SynthesisError(
            f"ureal({name!r}): the range [{lo:.6g}, {hi:.6g}] must be non-empty and contain the "
            f"nominal {nominal:.6g} (a zero nominal needs plusminus= or range=, not percent=).")
    return UncertainReal(name, nominal, lo, hi)


def ucomplex(name: str, nominal: complex, radius: float) -> UncertainComplex:
    """A named uncertain complex scalar ``nominal + radius * delta``, ``|delta| <= 1``
    (MATLAB ``ucomplex``, RobustAndOptimalControl.jl ``δc``).

    Parameters
    ----------
    name : str
    nominal : complex
    radius : float
        Radius of the disc of values (> 0).

    Returns
    -------
    UncertainComplex

    Examples
    --------
    >>> import robustctl as rc
    >>> rc.ucomplex("c", 1 + 1j, 0.5).radius
    0.5
    """
    name = _name(name)
    v = complex(nominal)
    if not (math.isfinite(v.real) and math.isfinite(v.imag)):
        raise SynthesisError(f"ucomplex({name!r}): the nominal must be finite; got {nominal!r}.")
    return UncertainComplex(name, v, positive_number(radius, "radius", SynthesisError))


def ultidyn(name: str, size: Any = (1, 1), bound: float = 1.0) -> UncertainDynamics:
    """Named unmodelled stable dynamics of ``size = (ny, nu)`` with ``||Delta||_inf <= bound``
    (MATLAB ``ultidyn``; a full complex block in mu-analysis).

    Parameters
    ----------
    name : str
    size : int or (int, int)
        ``(ny, nu)``: outputs and inputs of the dynamics (an int: square).
    bound : float
        H-infinity norm bound (> 0), e.g. 1 for dynamics scaled by a weight outside.

    Returns
    -------
    UncertainDynamics

    Examples
    --------
    >>> import robustctl as rc
    >>> rc.ultidyn("unmod", (2, 1)).shape
    (2, 1)
    """
    name = _name(name)
    sz = np.atleast_1d(np.asarray(size)).reshape(-1)
    if sz.size == 1:
        sz = np.array([sz[0], sz[0]])
    if sz.size != 2:
        raise SynthesisError(f"ultidyn({name!r}): size must be (ny, nu); got {size!r}.")
    ny = integer(sz[0], "ny", SynthesisError, lo=1)
    nu = integer(sz[1], "nu", SynthesisError, lo=1)
    return UncertainDynamics(name, ny, nu, positive_number(bound, "bound", SynthesisError))
