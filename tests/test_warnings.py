"""One warning family: every warning robustctl issues derives from ``rc.RobustctlWarning``.

The source is read with :mod:`ast`: every ``warnings.warn`` call of the package must name its
category, and that category, evaluated in the calling module's namespace, must be a
:class:`~robustctl.errors.RobustctlWarning` subclass; every ``Warning`` subclass robustctl
defines must derive from it too. Two warnings are triggered for real under
``filterwarnings("error", category=rc.RobustctlWarning)``.
"""

from __future__ import annotations

import ast
import importlib
import inspect
import warnings
from pathlib import Path

import numpy as np
import pytest

import robustctl as rc

ROOT = Path(rc.__file__).resolve().parent


def _module_name(path: Path) -> str:
    parts = list(path.relative_to(ROOT.parent).with_suffix("").parts)
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def _warn_calls():
    """``(module, line, category expression or None)`` of every ``warnings.warn`` call."""
    calls = []
    for path in sorted(ROOT.rglob("*.py")):
        if path.name == "__main__.py":
            continue
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if not (isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute)):
                continue
            if not (node.func.attr == "warn" and isinstance(node.func.value, ast.Name)
                    and node.func.value.id == "warnings"):
                continue
            category = node.args[1] if len(node.args) > 1 else next(
                (kw.value for kw in node.keywords if kw.arg == "category"), None)
            calls.append((_module_name(path), node.lineno, category))
    return calls


WARN_CALLS = _warn_calls()


def test_the_scan_sees_the_package_warnings():
    modules = {module for module, _, _ in WARN_CALLS}
    # one call site per kind of source the family spans (a scan that finds nothing passes nothing)
    assert {"robustctl.budget", "robustctl.export.controller", "robustctl.robust.yardsticks",
            "robustctl.measure.estimate", "robustctl.threads"} <= modules
    assert len(WARN_CALLS) >= 20


@pytest.mark.parametrize("module, line, category", WARN_CALLS, ids=[f"{m}:{ln}" for m, ln, _ in WARN_CALLS])
def test_every_warn_call_names_a_robustctl_warning(module, line, category):
    assert category is not None, (
        f"{module}:{line} warns without a category (a plain UserWarning): pass a RobustctlWarning subclass"
    )
    namespace = vars(importlib.import_module(module))
    value = eval(compile(ast.Expression(category), module, "eval"), dict(namespace))  # noqa: S307
    assert isinstance(value, type) and issubclass(value, rc.RobustctlWarning), (
        f"{module}:{line} warns with {value!r}, which does not derive from rc.RobustctlWarning"
    )


def _warning_classes():
    found = {}
    for path in sorted(ROOT.rglob("*.py")):
        if path.name == "__main__.py":
            continue
        module = importlib.import_module(_module_name(path))
        for obj in vars(module).values():
            if inspect.isclass(obj) and issubclass(obj, Warning) and obj.__module__.startswith("robustctl"):
                found[f"{obj.__module__}.{obj.__qualname__}"] = obj
    return found


def test_every_warning_class_derives_from_the_base_and_is_exported():
    classes = _warning_classes()
    assert len(classes) >= 12
    stray = sorted(name for name, cls in classes.items() if not issubclass(cls, rc.RobustctlWarning))
    assert not stray, f"warning classes outside the family: {stray}"
    hidden = sorted(name for name, cls in classes.items() if getattr(rc, cls.__name__, None) is not cls)
    assert not hidden, f"warning classes a user cannot filter by rc.<name>: {hidden}"


def test_runtime_and_deprecation_kinds_are_kept():
    """Filters on the standard categories keep working: numerical caveats stay RuntimeWarnings and
    deprecations DeprecationWarnings (hidden outside ``__main__`` by Python's default filters)."""
    for cls in (rc.SynthesisWarning, rc.ExportWarning, rc.ParallelWarning, rc.SetupWarning, rc.BudgetWarning):
        assert issubclass(cls, RuntimeWarning)
    assert issubclass(rc.RobustctlDeprecationWarning, DeprecationWarning)


def test_one_filter_turns_the_family_into_errors():
    rng = np.random.default_rng(0)
    u = rng.standard_normal(8500)
    y = np.convolve(u, [1.0, 0.5], mode="same")
    with warnings.catch_warnings():
        warnings.filterwarnings("error", category=rc.RobustctlWarning)
        with pytest.raises(rc.EstimateWarning, match="leaves 3 averages"):
            rc.estimate_frf(u, y, fs=1024.0)  # 3 Welch averages instead of the advised 8
        with pytest.raises(rc.RobustctlDeprecationWarning, match="deprecated"):
            rc.checks.renamed_keyword(None, 1.0, "point_weights", "weights")  # the old weights=
