"""A representative set of robustctl results, hashed: ``python tests/_reproducible_run.py [names]``.

Prints one JSON object ``{case: sha256 of the case's arrays}`` (and, with ``--times``, the
seconds each case took on stderr); ``--workers=N`` runs diagnose in N worker processes.
``test_reproducible.py`` runs it in fresh processes, one of them beside a CPU load, and
compares the hashes bit for bit. No case passes a time budget: the results must depend on the
inputs alone.
"""

from __future__ import annotations

import functools
import hashlib
import json
import sys
import time
import warnings

import numpy as np


def _digest(*arrays) -> str:
    h = hashlib.sha256()
    for a in arrays:
        a = np.ascontiguousarray(np.asarray(a))
        h.update(str(a.dtype).encode() + str(a.shape).encode())
        h.update(a.tobytes())
    return h.hexdigest()


def _ss(sys_) -> tuple:
    from robustctl.lti import as_statespace

    s = as_statespace(sys_)
    return tuple(np.asarray(m, dtype=float) for m in (s.A, s.B, s.C, s.D))


@functools.cache
def _truss():
    from robustctl.examples import caltech_truss, caltech_truss_experiment

    data, _ = caltech_truss_experiment(seed=0)
    return data, caltech_truss()


@functools.cache
def _measurement_model(leak: bool):
    from robustctl.identify import fit_measurement_model

    data, _ = _truss()
    return fit_measurement_model(data, n_modes=6, band=(0.5, 5.5), correct_leakage=leak, time_budget_s=None)


def measurement_models() -> dict:
    """The demo's six-mode yardstick model, without and with the leakage correction."""
    data, _ = _truss()
    out = {}
    for leak in (False, True):
        mm = _measurement_model(leak)
        out[f"measurement_model_leakage_{leak}"] = _digest(*_ss(mm), mm.freqresp(data.f_hz[:400]).response)
    return out


def diagnosis(workers: int = 1) -> dict:
    """diagnose on the Caltech truss (the hidden taut wires) over stiffness and tension candidates,
    serially (``workers=1``) or in worker processes."""
    from robustctl.correlate import diagnose
    from robustctl.physical import effects

    data, model = _truss()
    cands = effects.candidates(model, band=(0.5, 20), kinds=["group_stiffness", "group_tension"])
    diag = diagnose(model, data, cands, band=(0.5, 20), workers=workers)
    costs = [(r.cost if np.isfinite(r.cost) else -1.0) for r in diag.ranking]
    names = "|".join(r.effect.name for r in diag.ranking).encode()
    return {"diagnose_truss": _digest(np.frombuffer(names, np.uint8), costs, diag.residual_update,
                                      list(diag.update_values.values()))}


def dk_distillation() -> dict:
    """D-K iteration on the distillation column (Skogestad & Postlethwaite's mu-synthesis example)."""
    from robustctl.examples import DISTILLATION_BLOCKS, distillation_plant
    from robustctl.robust.dk.iteration import dksyn

    dk = dksyn((distillation_plant(), 2, 2, DISTILLATION_BLOCKS), max_iter=3, progress=False)
    return {"dksyn_distillation": _digest(*_ss(dk.K), dk.mu.upper, dk.mu.lower,
                                          [h.gamma for h in dk.history])}


def small_yardstick() -> dict:
    """The demo's yardstick recipe on two models (nominal and measurement model), two D-K iterations."""
    from robustctl.examples import caltech_design_plant
    from robustctl.robust.yardsticks import yardstick

    data, model = _truss()
    mm = _measurement_model(False)
    yard = yardstick(data, {"nominal": model, "measurement": mm}, caltech_design_plant, band=(0.5, 5.5),
                     max_iter=2, progress=False)
    labels = yard.labels
    parts = [yard.closed_loop[lab] for lab in labels] + [_ss(yard.designs[lab].K)[0] for lab in labels]
    return {"yardstick_small": _digest(*parts, yard.mu_cross, [yard.attenuation_db[lab] for lab in labels])}


CASES = {f.__name__: f for f in (measurement_models, diagnosis, dk_distillation, small_yardstick)}


def main(argv: list[str]) -> None:
    times = "--times" in argv
    workers = int(next((a.split("=")[1] for a in argv if a.startswith("--workers=")), 1))
    names = [a for a in argv if not a.startswith("--")] or list(CASES)
    out = {}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for name in names:
            t0 = time.perf_counter()
            out.update(CASES[name](workers) if name == "diagnosis" else CASES[name]())
            if times:
                print(f"{name}: {time.perf_counter() - t0:.1f} s", file=sys.stderr)
    print(json.dumps(out, sort_keys=True))


if __name__ == "__main__":
    main(sys.argv[1:])
