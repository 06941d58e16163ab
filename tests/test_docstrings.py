"""Every public name documents every parameter, in the style of python-control's docstring test.

For each function and class that ``import robustctl as rc`` exports (``rc.__all__``), the
numpydoc ``Parameters`` section (for classes also ``Attributes``) must name every parameter
of its signature (the class's ``__init__``); ``*args``/``**kwargs`` are named with or
without their stars, and several parameters may share an entry (``inputs, outputs : ...``).
Exceptions and warnings take ``*args`` and are exempt.
"""

from __future__ import annotations

import inspect
import re

import pytest

import robustctl as rc


def _sections(doc: str | None) -> dict[str, list[str]]:
    lines = inspect.cleandoc(doc or "").splitlines()
    found: dict[str, list[str]] = {}
    current = None
    for i, line in enumerate(lines):
        underline = i + 1 < len(lines) and re.fullmatch(r"-{3,}", lines[i + 1].strip())
        if underline and line.strip() and not line.startswith(" "):
            current = line.strip()
            found[current] = []
        elif current is not None and not re.fullmatch(r"-{3,}", line.strip()):
            found[current].append(line)
    return found


def _documented(lines: list[str]) -> set[str]:
    names = set()
    for line in lines:
        if not line.strip() or line.startswith(" "):
            continue
        head = re.match(r"([\w*, ]+?)\s*(?::|$)", line)
        if head:
            names.update(n.strip().lstrip("*") for n in head.group(1).split(",") if n.strip())
    return names


def _parameters(obj) -> list[str]:
    target = obj.__init__ if inspect.isclass(obj) else obj
    if target is object.__init__:
        return []
    try:
        signature = inspect.signature(target)
    except (TypeError, ValueError):
        return []
    return [p for p in signature.parameters if p not in ("self", "cls") and not p.startswith("_")]


def undocumented(name: str) -> set[str] | None:
    """The parameters of ``rc.<name>`` its docstring leaves out; None for a module or a constant."""
    obj = getattr(rc, name)
    if inspect.ismodule(obj) or not callable(obj):
        return None
    if inspect.isclass(obj) and issubclass(obj, (Exception, Warning)):
        return set()
    sections = _sections(obj.__doc__)
    documented = _documented(sections.get("Parameters", []))
    if inspect.isclass(obj):
        documented |= _documented(sections.get("Attributes", []))
    return {p for p in _parameters(obj) if p not in documented}


PUBLIC = [name for name in rc.__all__ if undocumented(name) is not None]


@pytest.mark.parametrize("name", PUBLIC)
def test_public_name_documents_every_parameter(name):
    assert getattr(rc, name).__doc__, f"rc.{name} has no docstring"
    missing = undocumented(name)
    assert not missing, f"rc.{name}'s docstring does not document {sorted(missing)} (numpydoc Parameters)"


def test_the_parser_reads_numpydoc_entries():
    doc = """Summary.

    Parameters
    ----------
    a, b : int
        Two.
    *systems : system
        Several.
    **options
        Passed on.
    n_modes, band_hz :
        Shared.

    Returns
    -------
    c : int
    """
    assert _documented(_sections(doc)["Parameters"]) == {"a", "b", "systems", "options", "n_modes", "band_hz"}
    assert "c" not in _documented(_sections(doc)["Parameters"])
