"""Exceptions raised by robustctl.

Every error a user can trigger by bad input is a :class:`RobustctlError` subclass whose
message says what was wrong and what to do about it. They derive from ``ValueError`` so
that code written against numpy/scipy conventions keeps working.

The one rule for arguments (enforced through :mod:`robustctl.checks`):

* **Every** refused argument -- a wrong value, a wrong range *and a wrong type* -- raises a
  :class:`RobustctlError` subclass, never a bare ``TypeError``/``AttributeError``/
  ``LinAlgError`` from inside. The subclass names the *stage that owns the argument*, not the
  kind of mistake: :class:`DataError` for data, files and signal settings,
  :class:`ModelError` for model settings, :class:`FitError` for fit/update/diagnose
  settings, :class:`SynthesisError` for controller synthesis and robustness analysis. So
  ``except RobustctlError`` (or ``except ValueError``) catches every bad input, and there is
  no separate TypeError branch to remember. (A wrong type is a bad value of the argument.)
* The message names the argument, shows the value given (``repr``) and says the fix.
* Flags are real booleans (``overwrite="False"`` is refused, not read as truthy).
* Numbers are real and finite (NaN, inf, complex, bool and strings are refused); counts are
  ``int`` (``2.5`` is refused); time budgets and tolerances are positive.
"""

from __future__ import annotations

__all__ = [
    "RobustctlError", "DataError", "ModelError", "FitError", "SynthesisError", "PlantError",
    "RobustctlWarning", "DataWarning", "SynthesisWarning", "ParallelWarning", "SetupWarning",
    "RobustctlDeprecationWarning",
]


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


class PlantError(ModelError, SynthesisError):
    """A generalized plant ``[w; u] -> [z; y]`` cannot be formed from what was passed.

    Both a model error (the partitioned plant is ill-posed) and a synthesis error (the
    argument of ``hinfsyn``, ``h2syn`` or ``dksyn`` is refused), so either is caught.
    """


class RobustctlWarning(UserWarning):
    """Base class of robustctl's warnings: a result that holds with a caveat the user must see.

    Every warning robustctl issues derives from it (``tests/test_warnings.py`` checks every
    ``warnings.warn`` call of the package), so
    ``warnings.filterwarnings("error", category=rc.RobustctlWarning)`` turns all of them into
    errors and ``"ignore"`` silences all of them.
    """


class SynthesisWarning(RobustctlWarning, RuntimeWarning):
    """A synthesis or robustness analysis returned a result whose check found a caveat
    (e.g. a mu peak the iteration grid missed)."""


class ParallelWarning(RobustctlWarning, RuntimeWarning):
    """Work meant for worker processes ran in the calling process instead (same result, slower)."""


class SetupWarning(RobustctlWarning, RuntimeWarning):
    """A setting from the environment was refused and a safe default is used instead."""


class RobustctlDeprecationWarning(RobustctlWarning, DeprecationWarning):
    """An argument name or order that still works but is deprecated (hidden by Python's default
    filters outside ``__main__``, as every ``DeprecationWarning``)."""


class DataWarning(RobustctlWarning):
    """The data hold something a result works around and the user should look at (e.g. a channel
    that is identically zero: a dead or disconnected sensor or actuator)."""
