"""The plant's path through ``rc.dksyn``: few modules, few climbs back up the floors.

A profiler hook records, in call order, the module of every robustctl function that is called
with the plant (a :class:`~robustctl.robust.partitioned.PartitionedPlant`, the one plant type
of the design half) among its arguments. Consecutive calls in one module are one visit. The
path is measured by

- the modules it visits (distinct);
- its climbs back up: distinct steps from a module to one on a higher floor
  (``tests/test_architecture.py``'s ``FLOORS``, and ``ROBUST_FLOORS`` inside ``robust/``), the
  plant handed back up to be taken apart again. A step repeated by the iteration (every
  gamma-bisection step of every K step) counts once.

The issue that asked for one plant type measured 20 modules and 34 climbs for the repacked
``(P, nmeas, ncon, blocks)`` tuples; the target is fewer than 10 and fewer than 8.
"""

from __future__ import annotations

import sys
import warnings

import pytest
from test_architecture import FLOORS, ROBUST_FLOORS

import robustctl as rc
from robustctl.examples import (
    DISTILLATION_BLOCKS,
    TWO_MASS_BLOCKS,
    distillation_plant,
    two_mass_spring_plant,
)
from robustctl.robust.partitioned import PartitionedPlant


def _floor(module: str) -> tuple[int, int]:
    """(package floor, floor inside robust/) of a robustctl module."""
    parts = module.split(".")[1:]
    top = parts[0] if parts else ""
    for i, names in enumerate(FLOORS):
        if top in names:
            if top == "robust":
                sub = parts[1] if len(parts) > 1 else ""
                return i, next(j for j, inner in enumerate(ROBUST_FLOORS) if sub in inner)
            return i, 0
    raise AssertionError(f"{module} has no floor")


def _plant_path(fn, *args, **kwargs) -> list[str]:
    """Modules of the robustctl functions called with a PartitionedPlant argument, in call order,
    consecutive repeats merged."""
    path: list[str] = []

    def hook(frame, event, _arg):
        if event != "call":
            return
        module = frame.f_globals.get("__name__", "")
        if not module.startswith("robustctl"):
            return
        code = frame.f_code
        names = code.co_varnames[: code.co_argcount + code.co_kwonlyargcount]
        held = any(isinstance(frame.f_locals.get(n), PartitionedPlant) for n in names)
        if held and (not path or path[-1] != module):
            path.append(module)

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        sys.setprofile(hook)
        try:
            fn(*args, **kwargs)
        finally:
            sys.setprofile(None)
    return path


def _climbs(path: list[str]) -> set[tuple[str, str]]:
    return {(a, b) for a, b in zip(path, path[1:]) if _floor(b) > _floor(a)}


def test_the_floor_of_a_module_and_a_climb():
    """The measure itself: a step from lti up to robust.dk is a climb, the reverse is not, and
    robust's sub-packages are ordered by ROBUST_FLOORS."""
    lti, hinf, dk = "robustctl.lti", "robustctl.robust.hinf.synthesis", "robustctl.robust.dk.scales"
    assert _floor(lti) < _floor(hinf) < _floor(dk)
    assert _climbs([dk, lti, dk, lti, hinf]) == {(lti, dk), (lti, hinf)}


@pytest.mark.parametrize(
    "plant, real",
    [
        # the profiler hook makes the distillation column's D-K 23 s
        pytest.param((distillation_plant(), 2, 2, DISTILLATION_BLOCKS), "complex", marks=pytest.mark.slow),
        ((two_mass_spring_plant(), 1, 1, TWO_MASS_BLOCKS), "mixed"),
    ],
    ids=["distillation-complex", "two-mass-mixed"],
)
def test_following_the_plant_through_dksyn_visits_few_modules_and_climbs_little(plant, real):
    gp = rc.robust.partitioned.as_partitioned(*plant)
    path = _plant_path(rc.dksyn, gp, real=real, max_iter=2, autoscale=False, progress=False)
    modules = set(path)
    assert "robustctl.robust.hinf.synthesis" in modules  # the K steps were followed
    if real == "mixed":
        assert any(m.startswith("robustctl.robust.dk.") for m in modules)
    assert len(modules) < 10, sorted(modules)
    assert len(_climbs(path)) < 8, sorted(_climbs(path))
