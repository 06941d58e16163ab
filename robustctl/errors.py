"""Exceptions raised by robustctl.

Every error a user can trigger by bad input is a :class:`RobustctlError` subclass whose
message says what was wrong and what to do about it. They derive from ``ValueError`` so
that code written against numpy/scipy conventions keeps working.
"""

from __future__ import annotations

__all__ = ["RobustctlError", "DataError", "ModelError", "FitError", "SynthesisError"]


class RobustctlError(ValueError):
    """Base class of every error robustctl raises on purpose."""


class DataError(RobustctlError):
    """Measured or computed data is malformed (shape, NaN, names, file content)."""


class ModelError(RobustctlError):
    """A physical or state-space model is ill-posed (singular mass, unknown node, ...)."""


class FitError(RobustctlError):
    """A fit (rational, modal, uncertainty weight, model update) cannot be carried out."""


class SynthesisError(RobustctlError):
    """A controller synthesis or robustness analysis cannot be carried out."""
