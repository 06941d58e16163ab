"""Effects that describe themselves: every effect class registers itself with all its traits
(kind, sweep, calibration, reduced-path form, sentence), nothing outside the effect classes
switches on a kind string, and a new effect is one class (it then appears in the candidates,
in diagnose's ranking and in its sentence with no other edit)."""

from __future__ import annotations

import functools
import pathlib
import re
import warnings
from dataclasses import dataclass
from typing import ClassVar

import numpy as np
import pytest
import verdict_corpus as vc

import robustctl as rc
from robustctl.physical import effects as fx
from robustctl.physical.effects.base import CALIBRATIONS, SWEEPS

ROOT = pathlib.Path(rc.__file__).parent
F_CHAIN = np.arange(2.0, 40.0, 0.125)


@functools.cache
def _corpus_candidates() -> tuple:
    models = (vc.chain_model(), vc.frame_model(), vc.frame_model(hinge=1500.0))
    named = dict(joints={"j23": ("dof 2", "dof 3", 7e3)}, supports={"ground": ("dof 1", 1.2e4)})
    return tuple(c for m in models for c in fx.candidates(m, calibrate=False)) + tuple(
        fx.candidates(vc.chain_model(), calibrate=False, **named))


def _instance(cls):
    """One instance of a registered class from the candidates of the corpus models, or None."""
    return next((c for c in _corpus_candidates() if type(c) is cls), None)


def test_every_effect_class_of_the_package_is_registered_under_its_own_kind():
    exported = [getattr(fx, n) for n in fx.__all__]
    classes = [c for c in exported if isinstance(c, type) and issubclass(c, fx.Effect) and c is not fx.Effect]
    assert len(classes) >= 24
    for cls in classes:
        assert fx.Effect.registry[cls.kind] is cls, cls
    assert fx.EFFECT_KINDS is fx.Effect.registry
    assert len(set(fx.Effect.registry)) == len(fx.Effect.registry)


@pytest.mark.parametrize("kind", sorted(fx.Effect.registry))
def test_every_registered_effect_has_every_trait(kind):
    cls = fx.Effect.registry[kind]
    assert isinstance(cls.kind, str) and cls.kind == kind
    assert cls.domain in ("io", "structure")
    assert cls.sweep is None or cls.sweep in SWEEPS
    assert cls.calibration in CALIBRATIONS
    assert cls.point_unit is None or (len(cls.point_unit) == 3 and sum(v != 0 for v in cls.point_unit) == 1)
    assert cls.switch in (True, False) and isinstance(cls.toggle, bool)  # gravity: a 0/1 field
    assert cls._value_fields, "an effect has at least one parameter"
    # a class that is generated somewhere and is not hand-made only must make its candidates itself
    if cls.sweep is not None:
        assert "candidates_at" in {k for c in cls.__mro__ if c is not fx.Effect for k in vars(c)}
    e = _instance(cls)
    if e is None:
        return  # a kind no corpus model carries (gravity, pendulum: a frame under gravity)
    phrase = e.phrase()
    assert isinstance(phrase, str) and phrase and "{" not in phrase
    assert e.describe_value() in phrase or e.switch or e.toggle
    assert isinstance(e.name, str) and isinstance(e.description, str)
    assert len(e.parameters) == len(cls._value_fields)


def test_no_module_outside_the_effect_classes_switches_on_a_kind_string():
    kinds = [k for k in fx.Effect.registry if k != "gravity"]  # "gravity" is also a parameter tag
    named = re.compile("|".join(re.escape(f'"{k}"') for k in kinds))
    effects_dir = ROOT / "physical" / "effects"
    found = []
    for path in ROOT.rglob("*.py"):
        if effects_dir in path.parents:
            continue
        for n, line in enumerate(path.read_text().splitlines(), start=1):
            if ".kind" in line and named.search(line):
                found.append(f"{path.relative_to(ROOT)}:{n}: {line.strip()}")
    switch = re.compile(r"\.kind\s*(?:==|!=)\s*[\"']|\.kind\s+(?:not\s+)?in\s*\(")
    for path in (effects_dir / "catalogue.py", ROOT / "physical" / "reduction.py"):
        found += [f"{path.name}: {m.group(0)}" for m in switch.finditer(path.read_text())]
    assert not found, "\n".join(found)


# ---------------------------------------------------------------------------- one new class
@dataclass(frozen=True)
class CommonSensorGain(fx.Effect):
    """One gain error shared by every sensor (a wrong sensitivity typed into every channel)."""

    error: float = 0.0

    kind: ClassVar[str] = "test_common_sensor_gain"
    sweep: ClassVar[str | None] = "signals"
    _value_fields: ClassVar[tuple[str, ...]] = ("error",)

    @classmethod
    def candidates_at(cls, ctx, where):
        return [cls()]

    @property
    def name(self) -> str:
        return "common gain error of all sensors"

    @property
    def description(self) -> str:
        return "The same relative gain error on every sensor."

    def _specs(self):
        return [fx.ParamSpec(base="common_gain_error", unit="", bounds=(-0.9, 2.0), neutral=0.0,
                             default_scale=0.05, meaning="relative gain error of every sensor")]

    def _stage_fn(self):
        pname = self.param_names[0]

        def fn(theta, sys):
            g = 1.0 + float(theta[pname])
            return sys if g == 1.0 else rc.scale_outputs(sys, dict.fromkeys(sys.output_labels, g))

        return fn

    def phrase(self) -> str:
        return f"a common sensor gain error of {self.describe_value()}"


@pytest.fixture
def registered():
    yield CommonSensorGain
    fx.Effect.registry.pop(CommonSensorGain.kind, None)


def test_a_kind_already_taken_is_refused():
    with pytest.raises(rc.errors.ModelError, match="already taken"):

        @dataclass(frozen=True)
        class OtherMass(fx.AddedMass):
            kind: ClassVar[str] = "added_mass"


def test_one_new_class_is_a_candidate_is_ranked_and_is_named_in_the_sentence(registered):
    fx.Effect.registry[registered.kind] = registered  # re-registered after another test popped it
    chain = vc.chain_model()
    cands = fx.candidates(chain)
    assert sum(type(c) is registered for c in cands) == 1
    M, K, B, C, kinds = vc.chain_matrices(s_k=1.03)
    g = 1.12 * vc.modal_frf(M, K, B, C, kinds, F_CHAIN)  # every sensor 12 % high
    data = vc.periodic_h1(g, n_avg=32, noise=0.05, seed=4, inputs=chain.inputs, outputs=chain.outputs,
                          f_hz=F_CHAIN)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        diag = rc.diagnose(chain, data, cands, workers=1)
    assert type(diag.best) is registered
    assert "a common sensor gain error of" in diag.summary().lower()
    upd = rc.update(chain.with_effect(diag.best), data)
    value, se = upd.model.param("common_gain_error").value, upd.std_errors["common_gain_error"]
    assert abs(value - 0.12) < 3 * se, (value, se)
