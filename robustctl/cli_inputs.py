"""What the ``robustctl`` command reads: a model named on the command line.

MODEL convention (``robustctl compare MODEL DATA``):

* ``path/to/file.py`` or ``path/to/file.py:NAME`` — a Python file; ``NAME`` defaults to
  ``model``;
* ``package.module`` or ``package.module:NAME`` — an importable module (e.g.
  ``robustctl.examples:caltech_truss``).

``NAME`` is an attribute that is a model (a ``PhysicalModel`` or anything with
``.statespace()``, a ``control.StateSpace`` or transfer function) or a callable taking no
arguments that returns one. The file is run as Python: only name files you trust.
"""

from __future__ import annotations

import importlib
import importlib.util
import re
import sys
from pathlib import Path
from typing import Any

from .errors import RobustctlError

__all__ = ["CommandLineError", "load_model_spec"]

_DEFAULT_NAME = "model"


class CommandLineError(RobustctlError):
    """A command-line argument cannot be used (missing file, unknown name, bad band)."""


def _split(spec: str) -> tuple[str, str]:
    # "C:\\dir\\m.py:model" keeps its drive letter: split on the last colon after the path part
    match = re.fullmatch(r"(.+?)(?::([A-Za-z_][A-Za-z0-9_]*))?", spec)
    if match is None or not match.group(1):
        raise CommandLineError(f"MODEL {spec!r} is empty; give FILE.py[:NAME] or package.module[:NAME].")
    return match.group(1), match.group(2) or _DEFAULT_NAME


def _module_from_file(path: Path) -> Any:
    if not path.is_file():
        raise CommandLineError(f"MODEL file {str(path)!r} does not exist.")
    spec = importlib.util.spec_from_file_location(f"_robustctl_user_model_{abs(hash(path))}", path)
    if spec is None or spec.loader is None:
        raise CommandLineError(f"MODEL file {str(path)!r} is not a Python file.")
    module = importlib.util.module_from_spec(spec)
    sys.path.insert(0, str(path.parent.resolve()))  # the file may import its neighbours
    try:
        spec.loader.exec_module(module)
    except RobustctlError:
        raise
    except Exception as exc:  # the user's code: report it on one line
        raise CommandLineError(f"running {path.name} failed: {type(exc).__name__}: {exc}") from exc
    finally:
        sys.path.pop(0)
    return module


def _module_from_name(name: str) -> Any:
    try:
        return importlib.import_module(name)
    except ModuleNotFoundError as exc:
        raise CommandLineError(
            f"MODEL {name!r} is neither a .py file nor an importable module ({exc}); "
            "give FILE.py[:NAME] or package.module[:NAME]."
        ) from exc
    except Exception as exc:
        raise CommandLineError(f"importing {name} failed: {type(exc).__name__}: {exc}") from exc


def load_model_spec(spec: str) -> Any:
    """The model named by ``spec`` (see the module docstring for the convention).

    Raises
    ------
    CommandLineError
        Missing file or module, unknown attribute (the available names are listed), a
        callable that fails, or an object that is not a model.
    """
    where, name = _split(str(spec))
    module = _module_from_file(Path(where)) if where.endswith(".py") else _module_from_name(where)
    if not hasattr(module, name):
        public = sorted(n for n in vars(module) if not n.startswith("_"))
        raise CommandLineError(
            f"{where} has no {name!r}; name one of its attributes with {where}:NAME "
            f"(it has: {', '.join(public[:15]) or 'nothing public'})."
        )
    obj = getattr(module, name)
    if callable(obj) and not _is_system(obj):
        try:
            obj = obj()
        except RobustctlError:
            raise
        except Exception as exc:
            raise CommandLineError(f"{where}:{name}() failed: {type(exc).__name__}: {exc}") from exc
    if not _is_system(obj):
        raise CommandLineError(
            f"{where}:{name} is a {type(obj).__name__}, not a model; it must be (or return) a "
            "PhysicalModel, an object with .statespace(), or a control.StateSpace."
        )
    return obj


def _is_system(obj: Any) -> bool:
    import control

    return isinstance(obj, control.LTI) or callable(getattr(obj, "statespace", None))

