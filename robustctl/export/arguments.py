"""Argument checks shared by the export modules (same bad input, same error and wording)."""

from __future__ import annotations

from typing import Any

import control
import numpy as np

from ..checks import choice
from ..errors import DataError, ModelError
from ..lti import as_statespace

__all__ = ["positive", "flag", "choice", "unwrap", "is_discrete"]


def positive(value: Any, name: str, fix: str) -> float:
    """``value`` as a positive finite float, else a DataError naming ``name`` and the ``fix``."""
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise DataError(f"{name} must be a positive number; got {value!r}. {fix}")
    if not (np.isfinite(value) and value > 0):
        raise DataError(f"{name} must be a positive finite number; got {value!r}. {fix}")
    return float(value)


def flag(value: Any, name: str) -> bool:
    """A real boolean (``True``/``False``, numpy bools too); ``"yes"``, 1 or None are refused."""
    if not isinstance(value, (bool, np.bool_)):
        raise DataError(f"{name} must be True or False; got {value!r}.")
    return bool(value)


def unwrap(K: Any) -> tuple[Any, dict]:
    """A synthesis result (anything with ``.K``) -> its controller and design figures."""
    if isinstance(K, control.StateSpace) or not hasattr(K, "K"):
        return as_statespace(K, name="K"), {}
    design = {}
    for key, attr in (("gamma", "gamma"), ("mu", "mu_peak")):
        value = getattr(K, attr, None)
        if isinstance(value, (int, float, np.floating)) and np.isfinite(value):
            design[key] = float(value)
    return as_statespace(K.K, name="K.K"), design


def is_discrete(ss: Any) -> bool:
    """True for a sampled system; a discrete system without a sampling time is refused."""
    if ss.dt is True:
        raise ModelError(
            "the controller is discrete with an unspecified sampling time (dt=True); set dt in s."
        )
    return ss.dt not in (0, None)
