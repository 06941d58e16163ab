"""The package's layout: floors that only look down, no import circles, submodules that are modules.

The import graph is read from the source with :mod:`ast`, so imports inside functions count
as much as those at the top of a module (a function-level import that dodges a circle is
still a circle). Relative imports are resolved against the importing module's package.
"""

from __future__ import annotations

import ast
import functools
import importlib
import pkgutil
import types
from pathlib import Path

import pytest

import robustctl

PACKAGE = "robustctl"
ROOT = Path(robustctl.__file__).resolve().parent

#: The floors, lowest first. A module may import from its own floor (without a circle) and
#: the floors below it, never from a floor above. Entries name a module or a package (a package
#: entry covers every module below it). The same table is in the module docstring of
#: robustctl/__init__.py.
FLOORS: tuple[tuple[str, ...], ...] = (
    ("errors", "_version", "threads", "table", "executors", "_lapack"),  # the base: no imports but errors
    ("checks", "budget"),  # argument checks: imports only errors; the time-budget policy (Deadline)
    ("frd", "frd_io", "plots"),  # FrequencyData, its files, the plotting primitives
    ("lti", "signals", "modes", "balanced"),  # systems, fast responses; named signals; Mode; reduction
    ("measure", "cost"),  # how data are made (H1, impact, estimator view, noise); the MACE eq. 5 cost
    ("physical",),
    ("interconnect",),
    ("correlate",),
    ("identify",),
    ("robust",),
    ("export",),
    # the surface: figures, report, embedded examples, demo, command line, the flat public API ("")
    ("figures", "report", "examples", "demo", "demo_design", "demo_mace", "demo_lqg", "cli", "cli_inputs",
     "cli_results", "cli_design",
     "__main__", ""),
)

#: The floors inside ``robust/``, lowest first, by the same rule (an entry names a module or a
#: sub-package of ``robust``; ``""`` is ``robust/__init__.py``, which re-exports them all). The
#: same table is in the module docstring of robustctl/robust/__init__.py.
ROBUST_FLOORS: tuple[tuple[str, ...], ...] = (
    ("uncertainty", "conventions"),  # blocks, weights, covers, uncertain systems; the loop sign
    ("plant", "partitioned", "sampled", "continuous_equivalent", "mu"),  # the plant, its coercion; d2c; mu
    ("hinf",),  # H-infinity norm and synthesis
    ("h2",),  # H2 norm and synthesis, LQG
    ("analysis",),  # disk margins, nu-gap, coprime factors, loop shaping
    ("reduction",),  # controller reduction
    ("dk",),  # D-K and D-G-K iteration, design sweeps
    ("yardsticks", ""),  # controllers designed on several models, scored on the data; the re-exports
)

#: Modules of the lowest floors that may import only the listed modules of robustctl.
ONLY_IMPORTS = {"checks": {"errors"}, "errors": set(), "budget": {"errors", "checks"}}


def _modules() -> dict[str, tuple[Path, bool]]:
    found = {}
    for path in sorted(ROOT.rglob("*.py")):
        parts = list(path.relative_to(ROOT).with_suffix("").parts)
        is_package = parts[-1] == "__init__"
        if is_package:
            parts = parts[:-1]
        found[".".join([PACKAGE, *parts])] = (path, is_package)
    return found


def _targets(module: str, is_package: bool, node: ast.AST, modules) -> list[str]:
    if isinstance(node, ast.Import):
        return [alias.name for alias in node.names if alias.name.split(".")[0] == PACKAGE]
    assert isinstance(node, ast.ImportFrom)
    if node.level:
        base = module.split(".") if is_package else module.split(".")[:-1]
        base = base[: len(base) - (node.level - 1)]
        target = ".".join(base + ([node.module] if node.module else []))
    else:
        target = node.module or ""
    if target.split(".")[0] != PACKAGE:
        return []
    # ``from pkg import sub`` imports the submodule ``pkg.sub``; ``from pkg import name`` the package
    return [f"{target}.{a.name}" if f"{target}.{a.name}" in modules else target for a in node.names]


@functools.cache
def _import_nodes() -> dict[str, list[ast.AST]]:
    """Every ``import``/``from ... import`` node of each module, parsed once per session."""
    return {
        name: [node for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"), filename=str(path)))
               if isinstance(node, (ast.Import, ast.ImportFrom))]
        for name, (path, _) in _modules().items()
    }


@functools.cache
def import_graph() -> dict[str, frozenset[str]]:
    """Edges ``module -> imported module`` of robustctl, function-level imports included."""
    modules = _modules()
    graph: dict[str, set[str]] = {name: set() for name in modules}
    for name, (_, is_package) in modules.items():
        for node in _import_nodes()[name]:
            graph[name].update(t for t in _targets(name, is_package, node, modules) if t != name)
    return {name: frozenset(targets) for name, targets in graph.items()}


def floor_of(module: str, floors=FLOORS, package: str = PACKAGE) -> int:
    """The floor of a module: the longest matching entry of ``floors`` (:data:`FLOORS`) below
    ``package``."""
    rel = module[len(package) + 1 :] if module != package else ""
    best, best_len = None, -1
    for level, entries in enumerate(floors):
        for entry in entries:
            matches = rel == entry or (entry and rel.startswith(entry + "."))
            if matches and len(entry) > best_len:
                best, best_len = level, len(entry)
    if best is None:
        table = "FLOORS" if floors is FLOORS else "ROBUST_FLOORS"
        raise AssertionError(f"{module} has no floor: add it to {table} in tests/test_architecture.py")
    return best


def upward_edges(graph) -> list[str]:
    return sorted(
        f"{a} (floor {floor_of(a)}) -> {b} (floor {floor_of(b)})"
        for a, targets in graph.items()
        for b in targets
        if floor_of(b) > floor_of(a)
    )


ROBUST = f"{PACKAGE}.robust"


def _in_robust(module: str) -> bool:
    return module == ROBUST or module.startswith(ROBUST + ".")


def robust_upward_edges(graph) -> list[str]:
    """Edges between two modules of ``robust/`` that point to a higher floor of :data:`ROBUST_FLOORS`."""

    def level(module: str) -> int:
        return floor_of(module, ROBUST_FLOORS, ROBUST)

    return sorted(
        f"{a} (robust floor {level(a)}) -> {b} (robust floor {level(b)})"
        for a, targets in graph.items()
        if _in_robust(a)
        for b in targets
        if _in_robust(b) and level(b) > level(a)
    )


def import_cycles(graph) -> list[list[str]]:
    """Strongly connected components of more than one module (Tarjan's algorithm)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    components: list[list[str]] = []
    counter = [0]

    def visit(v: str) -> None:
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on_stack.add(v)
        for w in sorted(graph.get(v, ())):
            if w not in graph:
                continue
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                component.append(w)
                if w == v:
                    break
            if len(component) > 1:
                components.append(sorted(component))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return components


def test_every_module_has_a_floor():
    for module in _modules():
        floor_of(module)


def test_no_import_points_to_a_higher_floor():
    edges = upward_edges(import_graph())
    assert not edges, "imports that look up the pipeline:\n" + "\n".join(edges)


def test_no_import_cycles():
    graph = import_graph()
    report = []
    for component in import_cycles(graph):
        inside = set(component)
        report.append("; ".join(f"{a} -> {b}" for a in component for b in sorted(graph[a] & inside)))
    assert not report, "import circles (edges inside each):\n" + "\n".join(report)


def test_every_robust_module_has_a_robust_floor():
    for module in _modules():
        if _in_robust(module):
            floor_of(module, ROBUST_FLOORS, ROBUST)


def test_no_import_inside_robust_points_to_a_higher_robust_floor():
    edges = robust_upward_edges(import_graph())
    assert not edges, "imports inside robust/ that look up its floors:\n" + "\n".join(edges)


def test_robust_floors_see_an_edge_up_and_name_every_subpackage():
    up = {
        f"{ROBUST}.mu.bounds": {f"{ROBUST}.dk.iteration"},
        f"{ROBUST}.dk.iteration": {f"{ROBUST}.mu.bounds"},
    }
    assert robust_upward_edges(up) == [
        f"{ROBUST}.mu.bounds (robust floor 1) -> {ROBUST}.dk.iteration (robust floor 6)"
    ]
    on_disk = {p.parent.name for p in (ROOT / "robust").glob("*/__init__.py")}
    on_disk |= {p.stem for p in (ROOT / "robust").glob("*.py") if p.stem != "__init__"}
    named = {entry.split(".")[0] for entries in ROBUST_FLOORS for entry in entries if entry}
    assert on_disk == named
    for path in (ROOT / "robust").glob("*/*.py"):
        floor_of(f"{ROBUST}.{path.parent.name}.{path.stem}", ROBUST_FLOORS, ROBUST)
    doc = robustctl.robust.__doc__
    for level, entries in enumerate(ROBUST_FLOORS):
        for entry in filter(None, entries):
            top = entry.split(".")[0]
            name = f"``{top}/``" if (ROOT / "robust" / top).is_dir() else f"``{top}``"
            line = next((ln for ln in doc.splitlines() if ln.startswith(f"{level}. ")), "")
            block = doc[doc.index(line) :].split(f"\n{level + 1}. ")[0] if line else ""
            assert name in block, f"robust/__init__.py's floor {level} does not name {name}"


def _package_of(module: str, is_package: bool) -> str:
    return module if is_package else module.rsplit(".", 1)[0]


def private_imports_across_packages() -> list[str]:
    """``from <module of another package> import _name`` anywhere in robustctl (function-level
    imports included). A helper another package needs has a public name in its home module."""
    modules = _modules()
    found = []
    for name, (_, is_package) in modules.items():
        for node in _import_nodes()[name]:
            if not isinstance(node, ast.ImportFrom):
                continue
            private = [a.name for a in node.names if a.name.startswith("_") and not a.name.startswith("__")]
            targets = _targets(name, is_package, node, modules)
            if not private or not targets:
                continue
            target = targets[0]
            if _package_of(target, modules.get(target, (None, False))[1]) != _package_of(name, is_package):
                found.append(f"{name}:{node.lineno} imports {', '.join(private)} from {target}")
    return sorted(found)


def test_no_module_imports_a_private_name_from_another_package():
    found = private_imports_across_packages()
    assert not found, "private names imported across packages (give them a public name):\n" + "\n".join(found)


def test_no_package_reexports_a_private_name():
    """A package's ``__init__`` exports its public API only; its private helpers are imported,
    where a test needs them, from the submodule that defines them."""
    reexported = []
    for name, (path, is_package) in _modules().items():
        if not is_package:
            continue
        for node in ast.parse(path.read_text(encoding="utf-8")).body:
            if isinstance(node, ast.ImportFrom):
                bound = [a.asname or a.name for a in node.names]
                reexported += [f"{name}: {b}" for b in bound if b.startswith("_") and not b.startswith("__")]
    assert not reexported, "private names re-exported by a package:\n" + "\n".join(reexported)


def test_private_import_scan_resolves_relative_imports():
    modules = _modules()
    node = ast.parse("from ..lti import _blocks, schur_eval").body[0]
    assert _targets(f"{PACKAGE}.robust.analysis", True, node, modules) == [f"{PACKAGE}.robust.lti"] * 2
    node = ast.parse("from ...lti import _blocks").body[0]
    target = _targets(f"{PACKAGE}.robust.hinf.norm", False, node, modules)[0]
    assert target == f"{PACKAGE}.lti"
    assert _package_of(target, False) == PACKAGE != _package_of(f"{PACKAGE}.robust.hinf.norm", False)


@pytest.mark.parametrize("module, allowed", sorted(ONLY_IMPORTS.items()))
def test_base_modules_import_only_the_base(module, allowed):
    name = f"{PACKAGE}.{module}"
    imported = {t[len(PACKAGE) + 1 :] for t in import_graph()[name]}
    assert imported <= allowed, f"{name} imports {sorted(imported - allowed)}; it may import only {allowed}"


def test_the_graph_sees_function_level_and_relative_imports():
    graph = import_graph()
    # function-level, relative, two dots: robustctl.measure.estimator imports lti inside functions
    assert f"{PACKAGE}.errors" in graph[f"{PACKAGE}.checks"]
    assert f"{PACKAGE}.measure.estimator" in graph[f"{PACKAGE}.measure.estimate"]
    assert f"{PACKAGE}.lti" in graph[f"{PACKAGE}.measure.estimate"]
    toy = {"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}
    assert import_cycles(toy) == [["a", "b", "c"]]
    assert import_cycles({"a": {"b"}, "b": set()}) == []


def _public_submodules():
    names = []
    for info in pkgutil.walk_packages(robustctl.__path__, PACKAGE + "."):
        if info.name.endswith("__main__"):  # running it is the command line
            continue
        names.append(info.name)
    return names


@pytest.mark.parametrize("name", _public_submodules())
def test_submodule_is_reachable_as_a_module(name):
    module = importlib.import_module(name)
    assert isinstance(module, types.ModuleType)
    parent_name, last = name.rsplit(".", 1)
    attribute = getattr(importlib.import_module(parent_name), last)
    assert attribute is module, (
        f"{parent_name}.{last} is {type(attribute).__name__} {attribute!r}, not the module {name}: "
        "a name exported by the package hides the submodule; rename the module."
    )
