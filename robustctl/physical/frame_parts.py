"""The parts a :class:`~robustctl.physical.fem.Frame` is made of and the checks of their values.

Frozen records of nodes, elements, point masses, springs and dashpots, rigid links, supports
and signals (the assembly caches key on their identities, :mod:`.frame_cache`), the record of
one assembly, and the scalar and vector checks of the builder's arguments. DOFs are six per node
``[ux uy uz rx ry rz]`` in global axes (m, rad).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from ..checks import is_real_number
from ..errors import ModelError
from .gravity import PreloadResult
from .structure_base import StructuralMatrices

__all__ = ["DIRECTIONS", "direction_vector"]

#: Direction names and their index among a node's six DOFs.
DIRECTIONS = {"x": 0, "y": 1, "z": 2, "rx": 3, "ry": 4, "rz": 5}
_DOF_NAMES = ("ux", "uy", "uz", "rx", "ry", "rz")
_STRAIN_KINDS = ("axial", "bending_y", "bending_z")


# ---------------------------------------------------------------------- components
@dataclass(frozen=True)
class _Node:
    name: str
    xyz: np.ndarray
    tags: tuple[str, ...] = ()


@dataclass(frozen=True)
class _Element:
    name: str
    group: str
    kind: str  # "beam" or "rod"
    n1: str
    n2: str
    E: float
    A: float
    rho: float
    G: float = 0.0
    Iy: float = 0.0
    Iz: float = 0.0
    J: float = 0.0
    orient: np.ndarray | None = None
    lumped: bool = False
    rotary_inertia: bool = False
    tags: tuple[str, ...] = ()


@dataclass(frozen=True)
class _Mass:
    node: str
    mass: float
    inertia: np.ndarray
    tags: tuple[str, ...] = ()


@dataclass(frozen=True)
class _Spring:
    node: str
    node2: str | None
    value: float
    vec: np.ndarray  # 6-vector
    kind: str  # "spring" or "dashpot"
    tags: tuple[str, ...] = ()


@dataclass(frozen=True)
class _Link:
    """``slave`` follows ``master`` rigidly, except in the DOFs ``released`` (indices 3..5 of
    ``rx, ry, rz``), which stay the slave's own (a hinge's free rotations)."""

    master: str
    slave: str
    tags: tuple[str, ...] = ()
    released: tuple[int, ...] = ()


@dataclass(frozen=True)
class _Fix:
    node: str
    dofs: tuple[int, ...]
    tags: tuple[str, ...] = ()


@dataclass(frozen=True)
class _Signal:
    """An input or an output: a sum of 6-vector pointings at nodes, or a strain gauge."""

    name: str
    terms: list[tuple[str, np.ndarray]]
    kind: str = "force"
    strain: tuple | None = None  # (element names, positions, strain kind, fiber)
    tags: tuple[str, ...] = ()


@dataclass
class _Assembly:
    """Everything :meth:`Frame.matrices` computes, kept for inspection methods."""

    matrices: StructuralMatrices
    node_names: tuple[str, ...]
    element_names: tuple[str, ...]
    T_red: sp.csr_matrix  # full DOFs -> DOFs of the preload solve
    preload: PreloadResult | None
    axial: np.ndarray


# ---------------------------------------------------------------------- validation helpers
def _finite(name: str, value, *, positive: bool = False, nonneg: bool = False) -> float:
    if not is_real_number(value):  # no strings, no booleans
        raise ModelError(f"{name} must be a number; got {value!r}.")
    v = float(value)
    if not np.isfinite(v):
        raise ModelError(f"{name} must be finite; got {v!r}.")
    if positive and v <= 0:
        raise ModelError(f"{name} must be positive; got {v!r}. Give a value > 0 in SI units.")
    if nonneg and v < 0:
        raise ModelError(f"{name} must not be negative; got {v!r}. Give a value >= 0 in SI units.")
    return v


def _tags(tags) -> tuple[str, ...]:
    if isinstance(tags, str):
        return (tags,)
    return tuple(str(t) for t in tags)


def _vector3(name: str, value) -> np.ndarray:
    try:
        items = list(np.asarray(value, dtype=object).reshape(-1))
    except (TypeError, ValueError):
        items = [None]
    if not all(is_real_number(x) for x in items):  # no strings, no booleans
        raise ModelError(f"{name} must be 3 numbers; got {value!r}.")
    v = np.array(items, dtype=float)
    if v.size != 3 or not np.all(np.isfinite(v)):
        raise ModelError(f"{name} must be 3 finite numbers (x, y, z); got {value!r}.")
    return v


def direction_vector(direction, *, rotation: bool = False) -> np.ndarray:
    """The unit 6-vector (over ``[ux uy uz rx ry rz]``) of a direction.

    Parameters
    ----------
    direction : str or 3-vector
        ``'x'``, ``'y'``, ``'z'``, ``'rx'``, ``'ry'``, ``'rz'`` (an optional leading ``'-'``
        reverses it) or a 3-vector in global axes, normalised to unit length.
    rotation : bool
        Whether a 3-vector means a rotation axis (torques, rotation outputs) rather than a
        translation.
    """
    vec = np.zeros(6)
    if isinstance(direction, str):
        key = direction.strip().lower()
        sign = -1.0 if key.startswith("-") else 1.0
        key = key.lstrip("+-")
        if key not in DIRECTIONS:
            raise ModelError(
                f"unknown direction {direction!r}; use one of {list(DIRECTIONS)} "
                "(optionally with a leading '-') or a 3-vector such as (0, 0, 1)."
            )
        vec[DIRECTIONS[key]] = sign
        return vec
    v = _vector3("direction", direction)
    norm = np.linalg.norm(v)
    if norm == 0:
        raise ModelError("a direction vector must not be zero; give e.g. (0, 0, 1).")
    vec[3 * rotation : 3 * rotation + 3] = v / norm
    return vec


def _skew(r: np.ndarray) -> np.ndarray:
    return np.array([[0.0, -r[2], r[1]], [r[2], 0.0, -r[0]], [-r[1], r[0], 0.0]])
